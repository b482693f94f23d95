"""Load paths ([[load_steps]]): Coulomb's law on each step's slip increment, one step as the static
problem bit for bit, the adjoint backward through the steps against central differences, and the
configuration's bad input."""

from pathlib import Path

import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.errors import ConfigError
from contactopt.fem.loadset import LoadSet
from contactopt.problem import ShapeProblem

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).resolve().parents[1]
SMALL = {"mesh": {"nx": 8, "ny": 4, "nz": 3}}
TOP, SIDE = [0.0, 0.0, -8e-2], [5e-2, 0.0, 0.0]
PATH3 = [{"name": "press", "top_traction": TOP},
         {"name": "shear", "top_traction": TOP, "right_traction": SIDE},
         {"name": "back", "top_traction": TOP, "right_traction": [2e-2, 0.0, 0.0], "substeps": 2}]


def block(steps, **sections):
    """Example 1 on a small mesh with the load path ``steps`` (the block's loads written in the steps)."""
    base = load_config("example1").with_updates(SMALL).data
    data = {**base, "loads": {**base["loads"], "top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
            "load_steps": steps}
    for sec, values in sections.items():
        data[sec] = {**data.get(sec, {}), **values}
    return load_config(data)


def tet_box(steps, tmp_path, objective=""):
    toml = tmp_path / "box.toml"
    text = (f'name = "box"\n[body]\nmesh = "{DATA / "two_groups.msh"}"\nclamped = "top"\ncontact = "bottom"\n'
            '[design]\ndegree = [3, 2]\nC0 = 0.05\nC2 = 0.002\ninitial = 0.002\n'
            '[objective]\ntarget = { kind = "constant", value = 0.001 }\n' + objective)
    for s in steps:
        text += f'[[load_steps]]\nname = "{s["name"]}"\nbody_force = {s["body_force"]}\n'
        if "side" in s:
            text += f'pressure = [{{ on = {{ x1 = 1.0 }}, value = {s["side"]} }}]\n'
    toml.write_text(text)
    return load_config(toml)


def wavy(problem, amp=0.003):
    return problem.model.initial_design() + amp * np.sin(np.arange(problem.model.n_design))


def central_differences(problem, alpha, directions, h=1e-6):
    return np.array([(problem.evaluate_value(alpha + h * d) - problem.evaluate_value(alpha - h * d)) / (2 * h)
                     for d in directions])


# ---------------------------------------------------------------- the mechanics
def test_one_step_is_the_static_problem_bit_for_bit():
    static = load_config("example1").with_updates(SMALL)
    one = load_config({**static.data, "load_steps": [{"name": "all"}]})
    a, b = ShapeProblem(static), ShapeProblem(one)
    alpha = wavy(a)
    (ja, ga), (jb, gb) = a.evaluate(alpha), b.evaluate(alpha)
    assert ja == jb and np.array_equal(ga, gb)
    sa, sb = a.solve_state(alpha), b.solve_state(alpha)
    assert np.array_equal(sa.u, sb.u) and np.array_equal(sa.lam, sb.lam) and np.array_equal(sa.classes, sb.classes)


def test_a_step_that_changes_no_load_sticks_everywhere_and_moves_nothing():
    pr = ShapeProblem(block([{"name": "a", "top_traction": TOP, "right_traction": SIDE},
                             {"name": "again", "top_traction": TOP, "right_traction": SIDE}]))
    (_, _, first), (_, _, second) = pr.step_results() or pr.solve_states(wavy(pr)) and pr.step_results()
    assert first.counts["M1"] > 0                        # the first step slides
    touching = second.lam > 0
    assert touching.any() and np.all(np.isin(second.classes[touching], [CLASS_CODES["M3+"], CLASS_CODES["M3-"]]))
    scale = np.abs(first.u).max()
    assert np.abs(second.u - first.u).max() <= 1e-9 * scale
    assert np.abs(second.slip_increment).max() <= 1e-9 * scale


def test_preload_then_shear_differs_from_shear_at_once():
    steps = [{"name": "press", "top_traction": TOP}, {"name": "shear", "top_traction": TOP, "right_traction": SIDE}]
    path, once = ShapeProblem(block(steps)), ShapeProblem(block(steps[1:]))
    alpha = wavy(path)
    sp, so = path.solve_state(alpha), once.solve_state(alpha)
    # the same final loads, another state: the slip of the shear step is measured from the pressed body
    assert np.abs(sp.u_c[:, :2] - so.u_c[:, :2]).max() > 1e-3 * np.abs(so.u_c).max()
    assert sp.info["step"] == "shear" and sp.slip_ref is not None
    # the sliding nodes' friction force follows the slip increment, not the total slip
    m1 = sp.classes == CLASS_CODES["M1"]
    du = sp.slip_increment[m1]
    law = 0.3 * sp.lam[m1, None] * du / np.linalg.norm(du, axis=1)[:, None]
    assert m1.sum() >= 5 and np.abs(sp.tau[m1] - law).max() <= 1e-8 * sp.lam.max()
    total = sp.u_c[m1, :2] / np.linalg.norm(sp.u_c[m1, :2], axis=1)[:, None]
    assert np.abs(sp.tau[m1] - 0.3 * sp.lam[m1, None] * total).max() > 1e-3 * sp.lam.max()


# ---------------------------------------------------------------- subgradients
@pytest.mark.parametrize("steps, objective, path", [
    (PATH3[:2], "last", "condensation"),
    (PATH3, "last", "condensation"),
    (PATH3, "sum", "condensation"),
    (PATH3, ["shear", "back"], "condensation"),
    (PATH3, "max", "condensation"),
    (PATH3, "sum", "delassus"),
    (PATH3, "sum", "fullspace"),
])
def test_subgradient_through_the_steps_matches_central_differences(steps, objective, path):
    pr = ShapeProblem(block(steps, objective={"steps": objective}, linear_solver={"path": path}))
    alpha = wavy(pr)
    res = pr.subgradient(alpha)
    assert res.n_degenerate == 0
    classes = [st.counts for _, _, st in pr.step_results()]
    assert any(c["M1"] for c in classes)
    assert len(steps) == 2 or any(c["M3+"] for c in classes[2:])      # the unloading step sticks
    rng = np.random.default_rng(3)
    directions = [np.eye(alpha.size)[i] for i in range(0, alpha.size, 3)] + [rng.standard_normal(alpha.size)]
    fd = central_differences(pr, alpha, directions)
    g = np.array([res.gradient @ d for d in directions])
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(fd).max()


@pytest.mark.parametrize("objective", ["last", "sum"])
def test_subgradient_through_the_steps_on_tetrahedra(tmp_path, objective):
    steps = [{"name": "press", "body_force": [0.0, 0.0, -1.0]},
             {"name": "shear", "body_force": [0.0, 0.0, -1.0], "side": 0.05},
             {"name": "ease", "body_force": [0.0, 0.0, -1.0], "side": 0.02}]
    pr = ShapeProblem(tet_box(steps, tmp_path, f'steps = "{objective}"\n'))
    assert pr.model.mesh.cell_type == "tetra"
    alpha = pr.model.initial_design() + 0.002 * np.cos(np.arange(pr.model.n_design))
    _sliding_steps_match_differences(pr, alpha)


def _sliding_steps_match_differences(pr, alpha, h=1e-6):
    """The subgradient at α, with no degenerate node and a sliding node in some step, against
    central differences (h) along three seeded directions, to 1e-6 of the largest."""
    res = pr.subgradient(alpha)
    assert res.n_degenerate == 0
    assert any(st.counts["M1"] for _, _, st in pr.step_results())
    rng = np.random.default_rng(4)
    directions = [rng.standard_normal(alpha.size) for _ in range(3)]
    fd = central_differences(pr, alpha, directions, h=h)
    g = np.array([res.gradient @ d for d in directions])
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(fd).max()


# ---------------------------------------------------------------- objectives of the whole displacement
def check_against_differences(pr, alpha, seed, n_dir=3, rtol=1e-6, h=1e-6):
    res = pr.subgradient(alpha)
    assert res.n_degenerate == 0
    rng = np.random.default_rng(seed)
    directions = [rng.standard_normal(alpha.size) for _ in range(n_dir)]
    fd = central_differences(pr, alpha, directions, h=h)
    g = np.array([res.gradient @ d for d in directions])
    assert np.abs(g - fd).max() <= rtol * np.abs(fd).max()
    return res


@pytest.mark.parametrize("objective, steps, choice, path", [
    ("frictional_dissipation", PATH3, "last", "condensation"),
    ("frictional_dissipation", PATH3[:2], "sum", "condensation"),
    ("frictional_dissipation", PATH3, "last", "delassus"),
    ("frictional_dissipation", PATH3, "sum", "fullspace"),
    ("peak_stress", PATH3, "max", "condensation"),
    ("peak_stress", PATH3[:2], "last", "delassus"),
    ("peak_stress", PATH3, "sum", "fullspace"),
])
def test_whole_displacement_objectives_through_the_steps_match_central_differences(objective, steps, choice, path):
    """The friction work Σ_k τ^k·Δu_t^k (each increment depends on its solve and, through Δu_t's
    reference, on the one before) and the peak stress per step, on 2- and 3-step paths that slide."""
    pr = ShapeProblem(block(steps, objective={"type": objective, "steps": choice}, linear_solver={"path": path}))
    alpha = wavy(pr)
    check_against_differences(pr, alpha, 7, rtol=1e-6)
    assert any(st.counts["M1"] for _, _, st in pr.step_results())


@pytest.mark.parametrize("objective", [
    'type = "frictional_dissipation"\nsteps = "last"\n',
    'type = "peak_stress"\nsteps = "max"\n',
    'steps = "sum"\n[[objective.terms]]\ntype = "pressure_uniformity"\n'
    '[[objective.terms]]\ntype = "frictional_dissipation"\nweight = 0.1\n',
])
def test_whole_displacement_objectives_through_the_steps_on_tetrahedra(tmp_path, objective):
    steps = [{"name": "press", "body_force": [0.0, 0.0, -1.0]},
             {"name": "shear", "body_force": [0.0, 0.0, -1.0], "side": 0.05},
             {"name": "ease", "body_force": [0.0, 0.0, -1.0], "side": 0.02}]
    pr = ShapeProblem(tet_box(steps, tmp_path, objective))
    alpha = pr.model.initial_design() + 0.002 * np.cos(np.arange(pr.model.n_design))
    # h = 1e-7: the friction work curves strongly here (the differences' error falls as h², 6e-2
    # at h = 1e-5, 5e-6 at 1e-6, 5e-8 at 1e-7); the states are solved to round-off
    check_against_differences(pr, alpha, 8, h=1e-7)
    assert any(st.counts["M1"] for _, _, st in pr.step_results())


def test_friction_work_on_a_path_is_the_sum_of_the_increments_and_one_step_is_the_static_one():
    """Θ = Σ over every solve (substeps too) of τ·Δu_t, each ≥ 0 up to the solver's tolerance
    (τ = Fλ Δu_t/‖Δu_t‖ where a node slides, Δu_t = 0 where it sticks); a step's value is the work
    up to its end; one step is the static objective Σ τ·u_t bit for bit."""
    pr = ShapeProblem(block(PATH3, objective={"type": "frictional_dissipation", "steps": "last"}))
    alpha = wavy(pr)
    value = pr.evaluate_value(alpha)
    results = pr.step_results()
    work = [float(np.sum(st.tau * st.slip_increment)) for _, _, st in results]
    assert len(work) == 4 and min(work) >= -1e-9 * max(work)
    assert value == pytest.approx(sum(work), rel=1e-12)
    ends = [st.info["objective"] for _, _, st in results if "objective" in st.info]
    assert ends == pytest.approx(np.cumsum(work)[[0, 1, 3]], rel=1e-12)
    static = load_config("example1").with_updates({**SMALL, "objective": {"type": "frictional_dissipation"}})
    one = load_config({**static.data, "load_steps": [{"name": "all"}]})
    (ja, ga), (jb, gb) = ShapeProblem(static).evaluate(alpha), ShapeProblem(one).evaluate(alpha)
    assert ja == jb and np.array_equal(ga, gb)


# ---------------------------------------------------------------- configuration
def bad(tmp_path, text):
    cfg = tmp_path / "bad.toml"
    cfg.write_text('name = "bad"\n[mesh]\nnx = 4\nny = 2\nnz = 2\n' + text)
    return cfg


BAD = {
    "unknown part": ('[[load_steps]]\nname = "a"\npressure = [{ on = "lid", value = 0.1 }]\n', "load_steps[0].pressure[0]"),
    "one name twice": ('[[load_steps]]\nname = "a"\n[[load_steps]]\nname = "a"\n',
                       "load_steps[1].name = 'a': another step has this name"),
    "substeps < 1": ('[[load_steps]]\nname = "a"\nsubsteps = 0\n', "load_steps[0].substeps = 0: must be an integer ≥ 1"),
    "unknown objective step": ('[objective]\nsteps = ["a", "b"]\n[[load_steps]]\nname = "a"\n',
                               "objective.steps: 'b' is no step of load_steps"),
    "unknown constraint step": ('[[load_steps]]\nname = "a"\n[[constraints]]\ntype = "compliance"\nmax = 1.0\n'
                                'steps = ["b"]\n', "constraints[0].steps: 'b' is no step of load_steps"),
    "constraint steps without a path": ('[[constraints]]\ntype = "peak_stress"\nmax = 1.0\nsteps = ["a"]\n',
                                        "constraints[0].steps = ['a']: names load steps, but the configuration has "
                                        "no [[load_steps]]"),
    "bad constraint steps": ('[[load_steps]]\nname = "a"\n[[constraints]]\ntype = "peak_stress"\nmax = 1.0\n'
                             'steps = "first"\n', "constraints[0].steps = 'first': must be 'max'"),
    "steps twice": ('[[load_steps]]\nname = "a"\n[[load_cases]]\nname = "c"\n[[load_cases.steps]]\nname = "a"\n',
                    "the configuration has [[load_steps]] and [[load_cases.steps]]"),
    "a step's force without force control": ('[[load_steps]]\nname = "a"\nobstacle_force = [0.0, 0.0, 1.0]\n',
                                             "load_steps[0].obstacle_force: needs [obstacle] control = 'force'"),
    "a step's force off the obstacle's": (
        '[obstacle]\nshape = "sphere"\ncenter = [1.0, 0.5, -5.0]\nradius = 5.0\ncontrol = "force"\n'
        'force = [0.0, 0.0, 1.0]\n[[load_steps]]\nname = "a"\nobstacle_force = [0.1, 0.0, 1.0]\n',
        "load_steps[0].obstacle_force = [0.1, 0.0, 1.0]: must be a positive multiple of obstacle.force"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_load_steps_exit_2_and_write_nothing(tmp_path, capsys, case):
    text, message = BAD[case]
    out = tmp_path / "out"
    code = main(["state", str(bad(tmp_path, text)), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err, err
    assert not out.exists()


def test_a_path_without_load_steps_refuses_them_naming_those_that_take_them(tmp_path, capsys, monkeypatch):
    """Every path takes load steps (the PETSc path's are tested in tests/test_petsc.py); the
    refusal, shown on the full-space path with its load steps switched off."""
    from contactopt.paths import PATHS
    assert PATHS["petsc"].takes_steps
    assert [n for n, c in PATHS.items() if c.takes_steps] == ["condensation", "delassus", "fullspace", "petsc"]
    from dataclasses import replace
    monkeypatch.setattr(PATHS["fullspace"], "capabilities", replace(PATHS["fullspace"].capabilities, load_steps=False))
    out = tmp_path / "out"
    code = main(["state", str(bad(tmp_path, '[linear_solver]\npath = "fullspace"\n[[load_steps]]\nname = "a"\n')),
                 "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert ("the 'fullspace' solver path does not take load steps; use linear_solver.path = 'condensation', "
            "'delassus' or 'petsc'") in err, err


def test_substeps_interpolate_the_loads_linearly():
    pr = ShapeProblem(block([{"name": "a", "top_traction": TOP, "substeps": 2},
                             {"name": "b", "top_traction": TOP, "right_traction": SIDE, "substeps": 4}]))
    assert [(s.name, s.substep, s.end) for s in pr.steps[0]][:3] == [("a", 1, False), ("a", 2, True), ("b", 1, False)]
    coords = pr.model.mesh.coordinates(pr.model.initial_design())
    L = [pr.model.load_vector(coords, s.loads) for s in pr.steps[0]]
    assert np.allclose(L[0], 0.5 * L[1], rtol=0, atol=1e-15)
    assert np.allclose(L[2], 0.75 * L[1] + 0.25 * L[5], rtol=0, atol=1e-15)
    with pytest.raises(ConfigError, match="objective.steps = \\['x'\\]: names load steps"):
        load_config({**load_config("example1").data, "objective": {"steps": ["x"]}})


def test_contexts_of_every_step_round_trip_bit_for_bit():
    """What a checkpoint holds of a load path (every solve's warm start, zone and kept Delassus
    design) makes a fresh problem repeat the next evaluation bit for bit."""
    cfg = block(PATH3)
    first, resumed = ShapeProblem(cfg), ShapeProblem(cfg)
    a1 = wavy(first)
    a2 = a1 + 0.001 * np.cos(np.arange(a1.size))
    first.evaluate(a1)
    arrays = first.export_contexts()          # [case][step] -> the step's arrays
    assert "warm" in arrays[0][1] and "zone" in arrays[0][3] and "jacobian_alpha" in arrays[0][2]
    resumed.import_contexts(arrays, "test")
    (j1, g1), (j2, g2) = first.evaluate(a2), resumed.evaluate(a2)
    assert j1 == j2 and np.array_equal(g1, g2)


def test_state_writes_every_step_with_its_slip(tmp_path, capsys):
    import json
    cfg = tmp_path / "pre.toml"
    cfg.write_text('name = "pre"\n[mesh]\nnx = 8\nny = 4\nnz = 3\n[loads]\ntop_traction = [0.0, 0.0, 0.0]\n'
                   'right_traction = [0.0, 0.0, 0.0]\n[[load_steps]]\nname = "press"\ntop_traction = [0.0, 0.0, -8e-2]\n'
                   '[[load_steps]]\nname = "shear"\ntop_traction = [0.0, 0.0, -8e-2]\nright_traction = [5e-2, 0.0, 0.0]\n'
                   'substeps = 2\n')
    out = tmp_path / "out"
    assert main(["state", str(cfg), "--out", str(out)]) == 0
    listing = json.loads((out / "steps.json").read_text())
    assert [s["directory"] for s in listing["steps"]] == ["step-press", "step-shear"]
    assert "step-shear/body.vtu" in (out / "body.pvd").read_text()
    press, shear = (np.load(out / d / "state.npz") for d in ("step-press", "step-shear"))
    # the first step slides from the unloaded body: its increment is its u_t
    assert np.array_equal(press["slip_increment"], press["u_c"][:, :2])
    sliding = np.isin(press["classes"], [CLASS_CODES["M1"], CLASS_CODES["M2"]])
    assert np.array_equal(press["slip"], np.where(sliding[:, None], press["u_c"][:, :2], 0.0))
    # the slip accumulates over the solves where a node slides
    assert np.abs(shear["slip"]).sum() > np.abs(press["slip"]).sum()
    pr = ShapeProblem(load_config(cfg))
    (_, _, s1), (_, _, s2), (_, _, s3) = pr.step_results() or pr.solve_states(pr.model.initial_design()) and pr.step_results()
    expect = s1.info["slip"] + sum(np.where(np.isin(s.classes, [1, 2])[:, None], s.slip_increment, 0.0) for s in (s2, s3))
    assert np.allclose(shear["slip"], expect, rtol=0, atol=1e-15)
    assert np.array_equal(shear["slip_increment"], s3.slip_increment)


@pytest.mark.slow
def test_kill_and_resume_a_load_path_run_repeats_it_bit_for_bit(tmp_path):
    import json
    import signal
    import subprocess
    import sys
    import time
    cfg = tmp_path / "ps.toml"
    text = (Path(__file__).parent.parent / "examples" / "preload_shear.toml").read_text()
    cfg.write_text(text.replace("nx = 16\nny = 8\nnz = 5", "nx = 8\nny = 4\nnz = 3")
                   .replace('right_traction = [5.0e-2, 0.0, 0.0]\n', 'right_traction = [5.0e-2, 0.0, 0.0]\nsubsteps = 2\n'))
    ref, out = tmp_path / "ref", tmp_path / "killed"
    assert main(["run", str(cfg), "--out", str(ref), "--max-iter", "12"]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "contactopt.cli", "run", str(cfg), "--out", str(out),
                             "--max-iter", "12"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline, seen = time.time() + 120, 0
    for line in proc.stdout:
        seen += line.startswith("it ") and "serious" in line
        if seen >= 3 or time.time() > deadline:
            break
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert seen >= 3
    assert main(["run", str(cfg), "--out", str(out), "--resume"]) == 0
    a, b = (json.loads((d / "summary.json").read_text()) for d in (ref, out))
    assert b["alpha"] == a["alpha"] and b["J"] == a["J"] and b["evaluations"] == a["evaluations"]
    assert b["load_steps"] == a["load_steps"]
    ha, hb = ((d / "history.csv").read_text().splitlines() for d in (ref, out))
    assert [r.split(",")[:3] + r.split(",")[-2:] for r in ha] == [r.split(",")[:3] + r.split(",")[-2:] for r in hb]


def paraboloid_on_foundation(n, steps):
    """A paraboloidal pad (gap r²/2R, R = 2) clamped on its top, on a foundation of its own
    material (benchmarks/cattaneo_mindlin.py)."""
    b = np.array([0.25, -0.25, 0.25])
    block = {"size": [2.0, 2.0, 1.0], "cells": [n, n, max(4, n // 2)]}
    return load_config({"name": "cm", "geometry": {"a": 2.0, "b": 2.0, "c": 1.0},
                        "mesh": {"nx": n, "ny": n, "nz": max(4, n // 2)}, "body": {"clamped": "top"},
                        "material": {"E": 1.0, "nu": 0.3}, "friction": {"coefficient": 0.3},
                        "loads": {"top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
                        "design": {"degree": [2, 2], "C0": 0.6, "lower": -0.6,
                                   "initial": (b[:, None] + b[None, :]).tolist()},
                        "foundation": {"block": block, "top": "top", "clamped": "bottom",
                                       "material": {"E": 1.0, "nu": 0.3}},
                        "load_steps": steps})


@pytest.mark.slow
def test_mindlin_deresiewicz_proportional_loading_slips_nowhere_one_step_has_an_annulus():
    """Pressed and sheared together (Q/P < μ): in 8 proportional substeps no node slides and
    ‖τ‖ < Fλ everywhere; the one-step static problem has a slip annulus."""
    out = {}
    for m in (1, 8):
        pr = ShapeProblem(paraboloid_on_foundation(16, [{"name": "all", "body_force": [0.00384, 0.0, -0.08],
                                                         "substeps": m}]))
        st = pr.solve_state(pr.model.initial_design())
        touching = st.lam > 1e-6 * st.lam.max()
        out[m] = (np.sum(st.classes == CLASS_CODES["M3+"]), touching.sum(),
                  (np.linalg.norm(st.tau[touching], axis=1) / (0.3 * st.lam[touching])).max())
        assert st.tau[:, 0].sum() < 0.3 * st.lam.sum()
    assert out[8][0] == out[8][1] and out[8][2] < 0.6
    assert out[1][0] < 0.6 * out[1][1] and out[1][2] == pytest.approx(1.0, abs=1e-8)


class WithNodal(LoadSet):
    """A load set plus a fixed nodal force vector: a prescribed displacement u_d of clamped DOFs
    acts on the free DOFs as the load −K_fd u_d."""

    def __init__(self, base, extra):
        super().__init__(base.tractions, base.pressures, base.body_force)
        self.extra = extra

    def vector(self, coords, assembler):
        return super().vector(coords, assembler) + self.extra


def press_and_move(n, deltas):
    """The paraboloidal pad pressed by f3 = −0.08, then its clamped top moved tangentially by each
    δ of ``deltas`` in turn (one step each, through the equivalent nodal load −K_fd u_d): the
    states of the steps, the press first (benchmarks/mindlin_deresiewicz_loop.py)."""
    steps = [{"name": "press", "body_force": [0.0, 0.0, -0.08]}]
    steps += [{"name": f"d{j}", "body_force": [0.0, 0.0, -0.08]} for j in range(1, len(deltas) + 1)]
    pr = ShapeProblem(paraboloid_on_foundation(n, steps))
    asm = pr.model.assembler
    Kf = asm.full_stiffness(pr.model.mesh.coordinates(pr.model.initial_design()))
    ud = np.zeros(asm.n_full)
    ud[3 * pr.model.body.part("top").nodes] = 1.0
    unit = np.zeros(asm.n_full)
    unit[asm.free] = -(Kf @ ud)[asm.free]
    for step in pr.steps[0][1:]:
        step.loads = WithNodal(step.loads, deltas[step.index - 1] * unit)
    pr.solve_states(pr.model.initial_design())
    return [st for _, _, st in pr.step_results()]


MD_NU, MD_MU = 0.3, 0.3
MD_K = 2 * (2 - MD_NU) * 2 * (1 + MD_NU)                 # K = (2 − ν1)/G1 + (2 − ν2)/G2, E = 1


def mindlin_loading(P, x):
    """Cattaneo–Mindlin's remote displacement at Q = xμP, (3μPK/16a)[1 − (1 − x)^(2/3)], Hertz's a."""
    a = (3 * P * 2.0 / (4 * 1.0 / (2 * (1 - MD_NU ** 2)))) ** (1 / 3)
    return 3 * MD_MU * P * MD_K / (16 * a) * (1 - (1 - x) ** (2 / 3)), a


def loop_deltas(n, m, x=0.7, d0=1e-4):
    """δ of a first increment d0 (sticks everywhere: Q = k0 δ), then up to δ* and round the loop
    δ* → −δ* → δ*, m steps per quarter; δ* from Mindlin's loading curve at Q*/μP = x plus the FE's
    stick compliance beyond K/8a. Returns (P, k0, δ*, the δ list)."""
    sts = press_and_move(n, [d0])
    P, k0 = sts[0].lam.sum(), sts[1].tau[:, 0].sum() / d0
    d, a = mindlin_loading(P, x)
    dstar = d + (1 / k0 - MD_K / (8 * a)) * x * MD_MU * P
    return P, k0, dstar, [d0] + [dstar * j / m for j in range(1, m + 1)] \
        + [dstar * (1 - j / m) for j in range(1, 2 * m + 1)] + [-dstar * (1 - j / m) for j in range(1, 2 * m + 1)]


@pytest.mark.slow
def test_mindlin_deresiewicz_hysteresis_loop_dissipates_the_analytic_energy():
    """The paraboloidal pad pressed, then its clamped top moved by δ: up to δ*, back to −δ*, up to
    δ* (4 steps per quarter, n = 24; benchmarks/mindlin_deresiewicz_loop.py). The loop's area
    ∮δ dQ against Mindlin–Deresiewicz's ΔW = (9μ²P²K/10a)[1 − (1 − x)^(5/3) − (5x/6)(1 + (1 − x)^(2/3))]
    (x = Q*/μP, K = 2(2 − ν)/G, a Hertz's): measured 1.131 ΔW here on every BLAS kernel, of which
    1.4 % the elasticity of the finite bodies (+2.5 %, their discretization −1 %) and the rest the
    slip zone resolved by about one element (docs/load_paths.md), so within 18 %; and the external
    work around the loop equals the friction
    work Σ τ·Δu_t of the cycle's solves (energy balance, two independent sums; measured 1.5 %, the
    trapezoids over 4 steps) to 2 %."""
    n, m = 24, 4
    P, _, _, deltas = loop_deltas(n, m)
    sts = press_and_move(n, deltas)
    Q = np.array([st.tau[:, 0].sum() for st in sts[1:]])
    d = np.array(deltas)
    Ps = np.array([st.lam.sum() for st in sts])
    assert np.ptp(Ps) <= 1e-3 * P                        # P stays constant
    cyc = slice(m, None)
    area = -float(np.sum(0.5 * (d[cyc][1:] + d[cyc][:-1]) * np.diff(Q[cyc])))
    work = sum(float(np.sum(st.tau * st.slip_increment)) for st in sts[m + 2:])
    Qs = 0.5 * (Q[m] - Q[3 * m])
    xs = Qs / (MD_MU * P)
    a = mindlin_loading(P, xs)[1]
    dW = 9 * MD_MU ** 2 * P ** 2 * MD_K / (10 * a) * (1 - (1 - xs) ** (5 / 3) - 5 * xs / 6 * (1 + (1 - xs) ** (2 / 3)))
    assert 0.5 < xs < 0.9 and Q[-1] == pytest.approx(Q[m], rel=0.02)      # the loop closes
    assert work == pytest.approx(area, rel=0.02)
    assert area == pytest.approx(dW, rel=0.18)


@pytest.mark.slow
def test_hysteresis_loop_is_the_masing_loop_of_the_loading_curve():
    """Masing's rule of Mindlin–Deresiewicz (unloading δ* − 2δ_L((Q* − Q)/2)) holds for the discrete
    pad too, whatever its error against the half-space: the friction work of the loop of the test
    above equals the area of the Masing loop of the pad's own virgin loading curve, 4Q*g(Q*) −
    8∫_0^Q* g with g = δ − Q/k0 (24 steps up to δ*, an independent sequence of solves); measured
    0.4 % (docs/load_paths.md)."""
    n, m = 24, 4
    P, k0, dstar, deltas = loop_deltas(n, m)
    sts = press_and_move(n, deltas)
    Q = np.array([st.tau[:, 0].sum() for st in sts[1:]])
    work = sum(float(np.sum(st.tau * st.slip_increment)) for st in sts[m + 2:])
    Qs = 0.5 * (Q[m] - Q[3 * m])
    up = [dstar * j / 24 for j in range(1, 25)]
    sts = press_and_move(n, up)
    Qv = np.concatenate([[0.0], [st.tau[:, 0].sum() for st in sts[1:]]])
    g = np.concatenate([[0.0], up]) - Qv / k0
    s = np.linspace(0.0, Qs, 4001)
    gs = np.interp(s, Qv, g)
    masing = 4 * Qs * gs[-1] - 8 * np.trapezoid(gs, s)
    assert Qv[-1] == pytest.approx(Q[m], rel=1e-4)       # monotone loading: the steps hardly change Q(δ*)
    assert masing == pytest.approx(work, rel=0.01)


def test_subgradient_through_the_steps_on_an_elastic_foundation():
    steps = [{"name": "press", "body_force": [0.0, 0.0, -0.08]},
             {"name": "shear", "body_force": [0.006, 0.0, -0.08]},
             {"name": "back", "body_force": [0.002, 0.0, -0.08]}]
    pr = ShapeProblem(paraboloid_on_foundation(8, steps).with_updates(
        {"objective": {"steps": "sum", "target": {"kind": "constant", "value": 0.002}}}))
    alpha = pr.model.initial_design() + 0.01 * np.cos(np.arange(pr.model.n_design))
    res = pr.subgradient(alpha)
    assert res.n_degenerate == 0
    counts = [st.counts for _, _, st in pr.step_results()]
    assert counts[1]["M1"] and counts[2]["M3+"]
    rng = np.random.default_rng(5)
    directions = [rng.standard_normal(alpha.size) for _ in range(3)]
    fd = central_differences(pr, alpha, directions)
    g = np.array([res.gradient @ d for d in directions])
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(fd).max()


TET_STEPS = [{"name": "press", "body_force": [0.0, 0.0, -1.0]},
             {"name": "shear", "body_force": [0.0, 0.0, -1.0], "side": 0.05},
             {"name": "ease", "body_force": [0.0, 0.0, -1.0], "side": 0.02}]
TET_SLAB = {"block": {"size": [1.4, 0.9, 0.3], "cells": [7, 5, 2], "origin": [-0.2, -0.2]}, "material": {"E": 1.0}}


@pytest.mark.parametrize("body, choice", [("tet-foundation", "sum"), ("tet-foundation", "last"),
                                          ("tet", "sum"), ("hex", "last")])
def test_compliance_through_the_steps_matches_central_differences(tmp_path, body, choice):
    """The compliance L_kᵀu_k at each step's end: its ∂J/∂α at fixed u holds ∂L_k/∂α of the step's
    own loads (the body force over a volume and the pressure on a side, both moving with α), on
    tetrahedra with and without an elastic foundation and on hexahedra. With the derivative of
    the configuration's [loads] in its place the differences were 2e-3 to 0.26 relative."""
    objective = {"type": "compliance", "steps": choice}
    if body == "hex":
        pr = ShapeProblem(block(PATH3, objective=objective))
        alpha = wavy(pr)
    else:
        updates = {"objective": objective, "friction": {"coefficient": 0.3},
                   "state": {"method": "newton", "tol": 1e-12}}
        if body == "tet-foundation":
            updates["foundation"] = TET_SLAB
        pr = ShapeProblem(tet_box(TET_STEPS, tmp_path).with_updates(updates))
        assert pr.model.mesh.cell_type == "tetra"
        alpha = pr.model.initial_design() + 0.001 * np.cos(np.arange(pr.model.n_design))
    _sliding_steps_match_differences(pr, alpha)


@pytest.mark.parametrize("objective", [
    {"type": "frictional_dissipation", "steps": "sum"},
    {"type": "frictional_dissipation", "steps": "last"},
    {"type": "peak_stress", "aggregate": "ks", "rho": 20.0, "steps": "sum"},
    {"type": "sum", "steps": "sum", "terms": [{"type": "compliance", "weight": 1.0},
                                              {"type": "frictional_dissipation", "weight": 0.1}]},
])
def test_whole_displacement_objectives_through_the_steps_on_an_elastic_foundation(tmp_path, objective):
    """∂J/∂u on every DOF of solves that later steps pass a derivative to, on a foundation: that
    derivative is with respect to the state's w (the next step's slip reference is w_t) and joins
    the adjoint after the map of ∂J/∂u (2e-2 to 0.7 relative before); the friction work's reference
    w_t^(k−1) depends on r^(k−1) through C (1.2 relative without); the compliance in a sum on every
    DOF takes its whole-body form (0.77 without)."""
    updates = {"objective": objective, "friction": {"coefficient": 0.3}, "foundation": TET_SLAB,
               "state": {"method": "newton", "tol": 1e-12}}
    pr = ShapeProblem(tet_box(TET_STEPS, tmp_path).with_updates(updates))
    alpha = pr.model.initial_design() + 0.001 * np.cos(np.arange(pr.model.n_design))
    _sliding_steps_match_differences(pr, alpha, h=1e-7)


def test_load_cases_with_their_own_paths(tmp_path):
    """[[load_cases.steps]]: a case with a path and a case without (one step), combined; the
    subgradient against central differences and the state directories case-<case>/step-<name>/."""
    base = load_config("example1").with_updates(SMALL).data
    data = {**base, "loads": {**base["loads"], "top_traction": TOP, "right_traction": [0.0] * 3},
            "load_cases": [{"name": "path", "steps": [{"name": "press"}, {"name": "shear", "right_traction": SIDE}]},
                           {"name": "once", "right_traction": [3e-2, 0.0, 0.0]}],
            "objective": {**base["objective"], "combine": "sum"}}
    pr = ShapeProblem(load_config(data))
    assert pr.steps[1] is None and [s.name for s in pr.steps[0]] == ["press", "shear"]
    assert pr.step_columns() == ["path.press", "path.shear"]
    alpha = wavy(pr)
    res = pr.subgradient(alpha)
    d = np.random.default_rng(6).standard_normal(alpha.size)
    fd = central_differences(pr, alpha, [d])[0]
    assert abs(res.gradient @ d - fd) <= 1e-6 * abs(fd)
    # the case with a path is the path of the same loads without cases
    alone = ShapeProblem(block([{"name": "press", "top_traction": TOP},
                                {"name": "shear", "top_traction": TOP, "right_traction": SIDE}]))
    u1, u2 = alone.solve_state(alpha).u, pr.solve_states(alpha)[0].u
    assert np.abs(u1 - u2).max() <= 1e-10 * np.abs(u1).max()      # up to the warm starts' round-off
    cfg = tmp_path / "c.toml"
    cfg.write_text(load_config(data).to_toml())
    out = tmp_path / "out"
    assert main(["state", str(cfg), "--out", str(out)]) == 0
    assert (out / "case-path" / "step-shear" / "state.npz").is_file()
    assert (out / "case-once" / "step-static" / "state.npz").is_file()


@pytest.mark.parametrize("path", ["delassus", "fullspace"])
def test_load_paths_on_a_force_controlled_obstacle_are_refused_off_the_condensation_path(path):
    """A force-controlled obstacle's translation is an unknown of every step on the condensation path
    only: the other paths refuse with a message naming it, not solved wrongly."""
    steps = [{"name": "press", "top_traction": TOP}, {"name": "shear", "top_traction": TOP, "right_traction": SIDE}]
    with pytest.raises(ConfigError, match="force-controlled sphere \\[obstacle\\].*'condensation'"):
        ShapeProblem(block(steps, obstacle={"shape": "sphere", "center": [1.0, 1.0, -5.0], "radius": 5.0,
                                            "control": "force", "force": [0.0, 0.0, 1.0]},
                           linear_solver={"path": path}))


# ---------------------------------------------------------------- rigid obstacles
def sphere_block(steps, **updates):
    """The 8×8×3 block 2 × 2 × 1 clamped at its top, pushed onto a sphere of radius 5 by the
    sphere's prescribed translation (tests/test_obstacles.py), with the load path ``steps``."""
    base = load_config("example1").data
    data = {**base, "friction": {"coefficient": 0.3}, "linear_solver": {"path": "condensation"},
            "material": {**base["material"], "nu": 0.3}, "state": {**base["state"], "method": "newton", "tol": 1e-12},
            "loads": {**base["loads"], "top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
            "design": {**base["design"], "degree": [3, 2], "initial": 0.0, "C2": 0.0},
            "geometry": {"a": 2.0, "b": 2.0, "c": 1.0}, "mesh": {"nx": 8, "ny": 8, "nz": 3},
            "body": {**base["body"], "clamped": "top"},
            "obstacle": {"shape": "sphere", "center": [1.0, 1.0, -5.0], "radius": 5.0, "control": "displacement",
                         "displacement": [0.0, 0.0, 0.05]}}
    if steps:
        data["load_steps"] = steps
    for sec, values in updates.items():
        data[sec] = {**data.get(sec, {}), **values}
    return load_config(data)


SPHERE_PATH = [{"name": "press"}, {"name": "shear", "body_force": [0.01, 0.0, 0.0]}]


@pytest.mark.parametrize("objective", [
    {"steps": "sum", "target": {"kind": "constant", "value": 0.01}},
    {"type": "peak_stress", "aggregate": "ks", "rho": 5.0, "steps": "sum"},
])
def test_a_load_path_on_a_sphere_matches_central_differences(objective):
    """Pressed by the sphere, then sheared: the friction law in the nodes' frames on the slip
    increment; the subgradient through both steps (a stress objective's right-hand side on every
    DOF is rotated into the frames and back) against central differences."""
    from contactopt.sensitivity.check import check_gradient
    pr = ShapeProblem(sphere_block(SPHERE_PATH, objective=objective))
    assert pr.model.frames is not None
    alpha = 0.002 * np.sin(np.arange(pr.model.n_design)) + 0.001
    rep = check_gradient(pr, alpha, seed=1, n_directions=3)
    pr.solve_states(alpha)
    counts = [st.counts for _, _, st in pr.step_results()]
    assert counts[0]["M1"] and counts[1]["M1"] and counts[1]["M3+"]
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


def test_one_step_on_a_sphere_is_the_static_problem_bit_for_bit():
    a, b = ShapeProblem(sphere_block(None)), ShapeProblem(sphere_block([{"name": "all"}]))
    alpha = 0.002 * np.sin(np.arange(a.model.n_design)) + 0.001
    (ja, ga), (jb, gb) = a.evaluate(alpha), b.evaluate(alpha)
    assert ja == jb and np.array_equal(ga, gb)
    sa, sb = a.solve_state(alpha), b.solve_state(alpha)
    assert np.array_equal(sa.u, sb.u) and np.array_equal(sa.lam, sb.lam) and np.array_equal(sa.classes, sb.classes)


# ---------------------------------------------------------------- a force-controlled obstacle
FORCED_SPHERE = {"shape": "sphere", "center": [1.0, 1.0, -5.0], "radius": 5.0, "control": "force",
                 "force": [0.0, 0.0, 1.2]}
# pressed by the force, then sheared at that force: both steps slide (and stick)
FORCED_PATH = [{"name": "press"}, {"name": "shear", "body_force": [0.06, 0.0, 0.0]}]


def test_one_step_with_a_force_controlled_obstacle_is_the_static_problem_bit_for_bit():
    a = ShapeProblem(sphere_block(None, obstacle=FORCED_SPHERE))
    b = ShapeProblem(sphere_block([{"name": "all"}], obstacle=FORCED_SPHERE))
    alpha = 0.002 * np.sin(np.arange(a.model.n_design)) + 0.001
    (ja, ga), (jb, gb) = a.evaluate(alpha), b.evaluate(alpha)
    assert ja == jb and np.array_equal(ga, gb)
    sa, sb = a.solve_state(alpha), b.solve_state(alpha)
    assert np.array_equal(sa.u, sb.u) and np.array_equal(sa.lam, sb.lam) and np.array_equal(sa.classes, sb.classes)
    assert sa.obstacle == sb.obstacle


def test_a_steps_force_is_ramped_over_its_substeps_and_balanced_in_each():
    steps = [{"name": "half", "obstacle_force": [0.0, 0.0, 0.6], "substeps": 2}, {"name": "full", "substeps": 2}]
    pr = ShapeProblem(sphere_block(steps, obstacle=FORCED_SPHERE))
    pr.solve_states(np.zeros(pr.model.n_design))
    results = pr.step_results()
    assert [(n, k) for n, k, _ in results] == [("half", 1), ("half", 2), ("full", 1), ("full", 2)]
    forces = [st.obstacle.resultant for _, _, st in results]
    assert forces == pytest.approx([0.3, 0.6, 0.9, 1.2], rel=1e-12)
    s = [st.obstacle.translation for _, _, st in results]
    assert np.all(np.diff(s) > 0)                 # pressed further in each solve


def forced_tets(tmp_path, steps):
    """The 2 × 2 × 1 block as linear tetrahedra (8 × 8 × 3 cubes, six each) on the forced sphere."""
    import meshio

    from contactopt.config import validate
    from contactopt.mesh.block import block_mesh
    from contactopt.mesh.tetsplit import hex_to_tets
    hexes = block_mesh(2.0, 2.0, 1.0, 8, 8, 3)
    path = tmp_path / "tets.vtu"
    meshio.write(path, meshio.Mesh(hexes.points, [("tetra", hex_to_tets(hexes.cells))]))
    data = {k: v for k, v in sphere_block(steps, obstacle=FORCED_SPHERE).data.items() if k not in ("geometry", "mesh")}
    data["body"] = {**data["body"], "mesh": str(path), "clamped": {"x3": 1.0}, "contact": {"x3": 0.0}}
    data["loads"] = {"body_force": [0.0, 0.0, 0.0]}
    return validate(data, "tets")


@pytest.mark.parametrize("cells", ["hexahedron", pytest.param("tetra", marks=pytest.mark.slow)])
def test_a_load_path_on_a_force_controlled_sphere_matches_central_differences(tmp_path, cells):
    """Pressed by the force, then sheared at that force: each step's translation balances the force
    (Brent's method), and the subgradient follows every step's translation with α and with the
    previous step's slip, against central differences."""
    from contactopt.sensitivity.check import check_gradient
    objective = {"objective": {"steps": "sum", "target": {"kind": "constant", "value": 0.01}}}
    cfg = (sphere_block(FORCED_PATH, obstacle=FORCED_SPHERE, **objective) if cells == "hexahedron"
           else forced_tets(tmp_path, FORCED_PATH).with_updates(objective))
    pr = ShapeProblem(cfg)
    assert pr.model.body.reference.cell_type == cells
    alpha = 0.002 * np.sin(np.arange(pr.model.n_design)) + 0.001
    pr.solve_states(alpha)
    results = pr.step_results()
    for _, _, st in results:
        assert st.obstacle.resultant == pytest.approx(1.2, rel=1e-12)
        assert st.counts["M1"] > 0 and st.counts["M3+"] > 0
    rep = check_gradient(pr, alpha, seed=1, n_directions=3)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


@pytest.mark.slow
def test_a_whole_displacement_objective_on_a_force_controlled_path_matches_central_differences():
    """The peak stress (KS, summed over the steps) with a force that has a tangential part: the body's
    u_c = w + s e moves with s at fixed w, so its own ∂J/∂u enters ∂Θ/∂s_k, not what later steps pass
    down (paths/force.py)."""
    from contactopt.sensitivity.check import check_gradient
    sphere = {**FORCED_SPHERE, "force": [0.3, 0.0, 1.2]}
    objective = {"type": "peak_stress", "aggregate": "ks", "rho": 5.0, "steps": "sum"}
    pr = ShapeProblem(sphere_block(FORCED_PATH, obstacle=sphere, objective=objective))
    alpha = 0.002 * np.sin(np.arange(pr.model.n_design)) + 0.001
    rep = check_gradient(pr, alpha, seed=1, n_directions=3)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


# ---------------------------------------------------------------- [[constraints]] along a path
BOTTOM = {"box": [[0.0, 2.0], [0.0, 1.0], [0.0, 0.3]]}       # the elements next to the contact face
PATH_CONSTRAINTS = [{"type": "peak_stress", "max": 1.0, "region": BOTTOM},
                    {"type": "frictional_dissipation", "max": 1.0},
                    {"type": "peak_stress", "max": 1.0, "aggregate": "ks", "rho": 20.0, "steps": "last"},
                    {"type": "frictional_dissipation", "max": 1.0, "steps": ["press"]}]


def with_constraints(cfg, constraints):
    return load_config({**cfg.data, "constraints": constraints})


def test_a_constraint_on_a_path_holds_at_the_steps_it_names():
    """The responses against a direct computation from the solves' states: the peak stress (the
    largest σ_vM of the region's quadrature points) at the worst step's end by default, at the
    last with steps = "last" (KS); the friction work Σ τ^k·(u_t^k − u_t^(k−1)) over the solves up
    to the step's end. The steps' objective values are not touched by the constraints."""
    from contactopt.fem.stress import von_mises_points
    from contactopt.sensitivity.objectives import aggregate, region_cells
    pr = ShapeProblem(with_constraints(block(PATH3), PATH_CONSTRAINTS))
    assert [c.steps.kind for c in pr.constraints] == ["max", "max", "last", "list"]
    alpha = wavy(pr)
    theta = pr.evaluate_value(alpha)
    objective_at_ends = pr.step_values()
    values = pr.constraint_values(alpha)
    assert pr.step_values() == objective_at_ends and pr.evaluate_value(alpha) == theta
    solves = pr.step_results()
    ends = [j for j, s in enumerate(pr.steps[0]) if s.end]
    cells = region_cells(pr.model, BOTTOM, "region")
    vm = [von_mises_points(pr.model.assembler, st.coords, st.u, cells).ravel() for _, _, st in solves]
    work, previous = [], np.zeros((pr.model.n_contact, 2))
    for _, _, st in solves:
        work.append(float(np.sum(st.tau * (st.u_c[:, :2] - previous))))
        previous = st.u_c[:, :2]
    work = np.cumsum(work)
    assert min(work[1:] - work[:-1]) > -1e-15 and work[1] > 1.5 * work[0]      # the shear slides
    peaks = [vm[j].max() for j in ends]
    assert np.argmax(peaks) != len(ends) - 1          # the worst moment is not the last step's end
    assert values[0] == pytest.approx(max(peaks), rel=1e-13)
    assert values[1] == pytest.approx(work[ends[-1]], rel=1e-12)
    st = solves[-1][2]                                # KS over the whole body, at the last step's end
    whole = von_mises_points(pr.model.assembler, st.coords, st.u, np.arange(pr.model.assembler.elements.shape[0]))
    assert values[2] == pytest.approx(aggregate(whole.ravel(), "ks", 20.0, 8.0)[0], rel=1e-13)
    assert values[3] == pytest.approx(work[ends[0]], rel=1e-12)


def _path_constraint_cases():
    for body in ("hex", "tet"):
        for path in ("condensation", "delassus", "fullspace"):
            for n in (2, 3):
                fast = path == "condensation" and (body, n) != ("tet", 2)
                yield pytest.param(body, path, n, marks=() if fast else (pytest.mark.slow,), id=f"{body}-{path}-{n}")


@pytest.mark.parametrize("body,path,n", list(_path_constraint_cases()))
def test_constraints_along_a_path_match_central_differences(body, path, n, tmp_path):
    """Each constraint's subgradient through the steps (the peak stress at the worst step, the
    friction work of the solves up to a step) on 2- and 3-step paths that slide. On the full-space
    path the differences are of Θ solved on the condensation path (the same function): its Newton
    stops at 1e-10, which a difference quotient divides by h (1e-6 off on the tetrahedra)."""
    if path == "delassus":
        from contactopt.fem.linsolve import pardiso_available
        if not pardiso_available():
            pytest.skip("the Delassus path needs MKL PARDISO")
    if body == "hex":
        cfg = with_constraints(block(PATH3[:n], linear_solver={"path": path}), PATH_CONSTRAINTS)
        h = 1e-6
    else:
        steps = [{"name": "press", "body_force": [0.0, 0.0, -1.0]},
                 {"name": "shear", "body_force": [0.0, 0.0, -1.0], "side": 0.05},
                 {"name": "ease", "body_force": [0.0, 0.0, -1.0], "side": 0.02}][:n]
        cfg = with_constraints(tet_box(steps, tmp_path, "").with_updates({"linear_solver": {"path": path}}),
                               [{**c, "region": {"box": [[0.0, 1.0], [0.0, 0.5], [0.0, 0.15]]}}
                                if "region" in c else c for c in PATH_CONSTRAINTS])
        h = 1e-7
    pr = ShapeProblem(cfg)
    twin = ShapeProblem(cfg.with_updates({"linear_solver": {"path": "condensation"}})) if path == "fullspace" else pr
    alpha = wavy(pr) if body == "hex" else pr.model.initial_design() + 0.001 * np.cos(np.arange(pr.model.n_design))
    for j, _ in enumerate(pr.constraints):
        rng = np.random.default_rng(11 + j)
        directions = [rng.standard_normal(alpha.size) for _ in range(2)]
        res = pr.for_constraint(j).subgradient(alpha)
        fd = central_differences(twin.for_constraint(j), alpha, directions, h=h)
        assert res.n_degenerate == 0
        g = np.array([res.gradient @ d for d in directions])
        assert np.abs(g - fd).max() <= 1e-6 * np.abs(fd).max(), (j, g, fd)
    pr.solve_states(alpha)
    assert any(st.counts["M1"] for _, _, st in pr.step_results())


def test_state_writes_the_objective_and_the_constraints_of_every_step(tmp_path, capsys):
    """contactopt state on a load path: each step's state.json has the objective (and its terms)
    and every constraint's response at the step's end; steps.json Θ over the steps as
    objective.steps says and the constraints as their own steps say. Checked against problems
    whose steps key names the one step."""
    import json
    terms = [{"type": "target_normal_force", "target": {"kind": "constant", "value": 0.001}},
             {"type": "frictional_dissipation", "weight": 10.0}]
    steps = [{"name": "press", "top_traction": TOP},
             {"name": "shear", "top_traction": TOP, "right_traction": SIDE, "substeps": 2}]
    cons = PATH_CONSTRAINTS[:2]
    cfg = with_constraints(block(steps, objective={"type": "sum", "terms": terms, "steps": "sum"}), cons)
    toml = tmp_path / "p.toml"
    toml.write_text(cfg.to_toml())
    out = tmp_path / "out"
    assert main(["state", str(toml), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.count("constraint frictional_dissipation") == 2
    listing = json.loads((out / "steps.json").read_text())
    pr = ShapeProblem(load_config(toml))
    alpha = pr.model.initial_design()
    assert listing["objective"]["value"] == pytest.approx(pr.evaluate_value(alpha), rel=1e-12)
    assert listing["objective"]["steps"] == "sum"
    for c, v in zip(listing["constraints"].values(), pr.constraint_values(alpha)):
        assert c["steps"] == "max" and c["value"] == pytest.approx(v, rel=1e-12)
        assert c["margin"] == pytest.approx(1.0 - v, rel=1e-12)
    for n, step in enumerate(("press", "shear")):
        doc = json.loads((out / f"step-{step}" / "state.json").read_text())
        at = [dict(c, steps=[step]) for c in cons]
        one = ShapeProblem(with_constraints(block(steps, objective={"type": "sum", "terms": terms, "steps": [step]}), at))
        ref = one.objective_report(alpha)
        assert doc["objective"]["value"] == pytest.approx(ref["value"], rel=1e-12)
        assert listing["steps"][n]["objective"] == doc["objective"]["value"]
        for t in ("target_normal_force", "frictional_dissipation"):
            assert doc["objective"]["terms"][t]["value"] == pytest.approx(ref["terms"][t]["value"], rel=1e-12)
        for c, v in zip(doc["constraints"].values(), one.constraint_values(alpha)):
            assert c["value"] == pytest.approx(v, rel=1e-12) and c["limit"] == 1.0
    press, shear = (json.loads((out / f"step-{s}" / "state.json").read_text()) for s in ("press", "shear"))
    work = [d["constraints"]["frictional_dissipation"]["value"] for d in (press, shear)]
    assert 0 < work[0] < work[1]              # the work accumulates along the path
    for t, term in listing["objective"]["terms"].items():     # Θ's terms: summed over the steps as Θ is
        assert term["value"] == pytest.approx(press["objective"]["terms"][t]["value"]
                                              + shear["objective"]["terms"][t]["value"], rel=1e-12)


@pytest.mark.slow
def test_a_path_run_meets_a_friction_work_limit_that_the_unconstrained_optimum_breaks(tmp_path):
    """preload_shear on an 8×4×3 mesh: the target's optimum triples the friction work of press,
    then shear; a limit between the two is met and active at the constrained optimum."""
    from contactopt.runner import run_optimization
    base = load_config(ROOT / "examples" / "preload_shear.toml").with_updates(SMALL)
    limit = 5e-5
    cfg = with_constraints(base, [{"type": "frictional_dissipation", "max": limit}])
    free = run_optimization(base, tmp_path / "free").summary
    con = run_optimization(cfg, tmp_path / "con").summary
    work_free = ShapeProblem(cfg).constraint_values(np.asarray(free["alpha"]).ravel())[0]
    resp = con["constraints"]["responses"]["frictional_dissipation"]
    assert work_free > 1.4 * limit > 2.0 * resp["initial"]["value"]
    assert resp["satisfied"] and abs(resp["margin"]) <= 1e-4 * limit          # met, and active
    assert free["J"] < con["J"] < 0.01 * con["J0"]


def test_a_state_without_warm_start_does_not_depend_on_what_was_solved_before():
    """A run's final figures are solved without warm start, also when the optimizer's last
    evaluation (warm-started: under force control Brent's solves start from each other) was at
    the same design, so that a resumed finished run repeats the uninterrupted one bit for bit."""
    cfg = sphere_block(None, obstacle=FORCED_SPHERE)
    fresh = ShapeProblem(cfg)
    alpha = fresh.model.initial_design()
    cold = fresh.evaluate_cases(alpha, warm_start=False).value
    after = ShapeProblem(cfg)
    after.evaluate(alpha)
    assert after.evaluate_cases(alpha, warm_start=False).value == cold
