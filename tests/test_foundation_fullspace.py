"""Two bodies on the full-space path: an elastic foundation joined to the body's Newton system by
the change of unknowns of contactopt.paths.coupled, against the condensation path (which condenses
the foundation onto its support: a different computation of the same state), central differences
and a resumed run.

Conventions: per contact node (t1, t2, ν), r the contact force on the body, λ = r_ν ≥ 0,
τ = −r_t; w = u_body − u_partner the state's u_c on both paths.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.paths import select_path
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

ROOT = Path(__file__).resolve().parents[1]
E_BODY = 21.19
COARSE = {"mesh": {"nx": 12, "ny": 6, "nz": 4}}
SOFT = {"material": {"E": E_BODY / 10}}


def _block(cells=(9, 5, 3), size=(3.0, 2.0, 1.0), origin=(-0.5, -0.5)):
    return {"size": list(size), "cells": list(cells), "origin": list(origin), "element": "hexahedron"}


FOUNDATIONS = {
    "point partners": {"block": _block(), "partner": "point", **SOFT},
    "averaged partners, own loads": {"block": _block(), "partner": "average", **SOFT,
                                     "loads": {"body_force": [0.0, 0.0, -0.02],
                                               "pressure": [{"on": "top", "value": 0.005}]}},
    "mortar partners": {"block": _block(), "partner": "mortar", **SOFT},
    "prescribed translation": {"block": _block(), "partner": "point", **SOFT, "control": "displacement",
                               "loaded": "bottom", "displacement": [0.002, 0.0, 0.001]},
}


def _config(foundation, path, **updates):
    return load_config("example1").with_updates({**COARSE, "foundation": foundation, "state": {"tol": 1e-12},
                                                 "linear_solver": {"path": path}, **updates})


def _design(model, seed=1, amp=0.003):
    a = model.initial_design()
    d = np.random.default_rng(seed).standard_normal(a.size)
    a = a + amp * (d - d.mean())
    assert model.admissible.is_feasible(a)
    return a


def _rel(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / np.abs(np.asarray(b)).max())


@pytest.mark.parametrize("kind", sorted(FOUNDATIONS))
def test_the_full_space_and_the_condensation_agree(kind):
    """Θ, ξ, λ, w and the node classes of one evaluation, with sliding and sticking nodes: the
    foundation condensed onto its support against the foundation's DOFs in the Newton system
    (measured 1e-11; the issue's bound 1e-7)."""
    out = {}
    for path in ("condensation", "fullspace"):
        pb = ShapeProblem(_config(FOUNDATIONS[kind], path))
        assert pb.path.name == path
        assert (pb.model.foundation.C is None) == (path == "fullspace")      # nothing condensed in full space
        a = _design(pb.model)
        theta, xi = pb.evaluate(a)
        out[path] = theta, xi, pb.solve_state(a)
    (t0, x0, s0), (t1, x1, s1) = out["condensation"], out["fullspace"]
    assert abs(t1 - t0) <= 1e-9 * abs(t0)
    assert _rel(x1, x0) <= 1e-8
    assert _rel(s1.lam, s0.lam) <= 1e-9 and _rel(s1.u_c, s0.u_c) <= 1e-8
    assert np.array_equal(s1.classes, s0.classes)
    assert np.sum(s0.classes == CLASS_CODES["M1"]) > 0 and np.sum(s0.classes == CLASS_CODES["M3+"]) > 0
    # the foundation's own displacement and the partners', from its DOFs here and recovered there
    assert _rel(s1.foundation.displacement, s0.foundation.displacement) <= 1e-8
    assert _rel(s1.foundation.u_partner, s0.foundation.u_partner) <= 1e-8


@pytest.mark.parametrize("name", ["roller_crowning_interference", "round_pad_slab"])
def test_the_examples_on_a_curved_seat_and_a_tetrahedral_pad_agree(name):
    """A roller pressed into its cylindrical race by an interference (nodes' frames, gaps along
    the normals) and a tetrahedral pad on a slab with averaged partners."""
    out = {}
    for path in ("condensation", "fullspace"):
        pb = ShapeProblem(load_config(ROOT / "examples" / f"{name}.toml").with_updates(
            {"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
        a = pb.model.initial_design()
        out[path] = pb.evaluate(a), pb.solve_state(a)
    ((t0, x0), s0), ((t1, x1), s1) = out["condensation"], out["fullspace"]
    assert abs(t1 - t0) <= 1e-9 * abs(t0)
    assert _rel(x1, x0) <= 1e-8
    assert _rel(s1.lam, s0.lam) <= 1e-9 and np.array_equal(s1.classes, s0.classes)


def test_subgradient_matches_central_differences_on_the_full_space():
    """ξ·d against central differences, sliding and sticking nodes, the foundation's own loads.
    The full-space Newton method stops at 1e-10 (its Krylov floor), not at the 1e-14 of the
    check's default, so the step is h = 1e-2·max|α| (measured: 5e-9, 4e-9, 2e-8 there; 4e-7 at
    3e-3, where the states' error divided by h shows)."""
    pb = ShapeProblem(_config(FOUNDATIONS["averaged partners, own loads"], "fullspace"))
    gc = check_gradient(pb, _design(pb.model), n_directions=3, seed=0, h=1e-2)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0


def test_a_load_path_on_a_foundation_agrees_on_both_paths():
    """Press, then shear (the slip's reference per step): the last step's Θ and ξ agree."""
    steps = [{"name": "press", "top_traction": [0.0, 0.0, -8.0e-2]},
             {"name": "shear", "top_traction": [0.0, 0.0, -8.0e-2], "right_traction": [4.0e-2, 0.01, 0.0]}]
    out = {}
    for path in ("condensation", "fullspace"):
        pb = ShapeProblem(_config(FOUNDATIONS["point partners"], path, load_steps=steps,
                                  objective={"type": "frictional_dissipation"}))
        out[path] = pb.evaluate(_design(pb.model))
    (t0, x0), (t1, x1) = out["condensation"], out["fullspace"]
    assert abs(t1 - t0) <= 1e-9 * abs(t0) and t0 > 0
    assert _rel(x1, x0) <= 1e-7


def test_auto_takes_the_full_space_for_two_bodies_from_the_crossover_on():
    cfg = _config(FOUNDATIONS["point partners"], "auto")
    crossover = cfg.linear_solver.crossover
    assert select_path(cfg, crossover - 1)[0] == "condensation"
    assert select_path(cfg, crossover)[0] == "fullspace"


def _agree(make, seed=1, amp=0.003):
    """Θ, ξ, λ, w, the classes and the counterparts' displacements of one evaluation on both paths
    (``make(path)`` the problem): their relative differences."""
    out = {}
    for path in ("condensation", "fullspace"):
        pb = make(path)
        assert pb.path.name == path
        a = pb.model.initial_design()
        d = np.random.default_rng(seed).standard_normal(a.size)
        a = a + amp * (d - d.mean())
        theta, xi = pb.evaluate(a)
        out[path] = theta, xi, pb.solve_state(a)
    (t0, x0, s0), (t1, x1, s1) = out["condensation"], out["fullspace"]
    assert np.array_equal(s1.classes, s0.classes)
    return {"Theta": abs(t1 - t0) / abs(t0), "xi": _rel(x1, x0), "lambda": _rel(s1.lam, s0.lam),
            "w": _rel(s1.u_c, s0.u_c), "bodies": _rel(s1.foundation.displacement, s0.foundation.displacement)}


@pytest.mark.parametrize("objective", ["target_force", "frictional_dissipation"])
def test_several_pairs_on_two_slabs_agree(objective):
    """Example 1's block on two slabs (a pair each, friction 0.3 and 0.3, its face designed,
    tests/test_assembly_pairs.py): both slabs' DOFs in the Newton system."""
    import tomllib

    from test_assembly_pairs import DESIGN, TWO_SLABS

    def make(path):
        cfg = load_config(tomllib.loads(TWO_SLABS + DESIGN)).with_updates(
            {"linear_solver": {"path": path}, "state": {"tol": 1e-12}})
        if objective != "target_force":
            cfg = cfg.with_updates({"objective": {"type": objective}})
        return ShapeProblem(cfg)
    d = _agree(make)
    assert d["Theta"] <= 1e-9 and d["xi"] <= 1e-8 and d["lambda"] <= 1e-9 and d["w"] <= 1e-8 and d["bodies"] <= 1e-8, d


def test_a_body_under_two_pairs_agrees(tmp_path):
    """The block on one base through two pairs (the base's top_left and top_right,
    tests/test_assembly_shared.py): the base's compliance couples the pairs."""
    from test_assembly_shared import _problem

    def make(path):
        pb = _problem(tmp_path, "shared")
        return ShapeProblem(pb.config.with_updates({"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
    d = _agree(make)
    assert d["Theta"] <= 1e-9 and d["xi"] <= 1e-8 and d["lambda"] <= 1e-9 and d["w"] <= 1e-8 and d["bodies"] <= 1e-8, d


def test_what_the_full_space_does_not_take_yet_is_refused_by_name():
    """A counterpart held only by its contacts (the right slab clamped along x3 only, its
    tangential motions held by friction) is taken on the full space (anchored,
    tests/test_fullspace_floating.py) and by the PETSc backend, which shares the rules
    (tests/test_petsc_bodies.py)."""
    import tomllib

    from contactopt.paths.fullspace import refuse_counterparts
    from test_assembly_pairs import DESIGN, TWO_SLABS
    text = TWO_SLABS.replace('clamped = "bottom"\nmaterial = { E = 6.0',
                             'clamped = { on = "bottom", components = [3] }\nmaterial = { E = 6.0')
    assert text != TWO_SLABS
    cfg = load_config(tomllib.loads(text + DESIGN)).with_updates({"linear_solver": {"path": "fullspace"}})
    pb = ShapeProblem(cfg)
    assert pb.path.name == "fullspace"
    refuse_counterparts(pb.model, "petsc")          # (no refusal left but mortar partners on six-node triangles)


def test_a_resumed_full_space_run_on_a_foundation_repeats_the_uninterrupted_one(tmp_path):
    """The checkpoint holds both bodies' displacement (the Newton system's unknowns)."""
    from contactopt.runner import run_optimization
    cfg = load_config("example1").with_updates({
        "mesh": {"nx": 8, "ny": 4, "nz": 3}, "optimizer": {"ftol": 0.0, "eps": 1e-12},
        "linear_solver": {"path": "fullspace"},
        "foundation": {"block": _block(cells=(6, 4, 2)), "material": {"E": 2.0}}})
    full = run_optimization(cfg, tmp_path / "full", max_iter=6)
    run_optimization(cfg, tmp_path / "part", max_iter=3)
    resumed = run_optimization(cfg, tmp_path / "part", max_iter=6, resume=True)
    assert full.summary["iterations"] == resumed.summary["iterations"] == 6
    assert resumed.summary["J"] == full.summary["J"]
    assert (json.loads((tmp_path / "part" / "alpha.json").read_text())
            == json.loads((tmp_path / "full" / "alpha.json").read_text()))


@pytest.mark.parametrize("sideways", [0.0, 0.4])
def test_a_foundation_pressed_by_a_force_agrees_and_its_subgradient_matches(sideways):
    """The foundation pressed up by f = (f1, 0, 3) on its bottom face (the translation's search
    around the full-space solve; f1 ≠ 0 drags the partners tangentially): Θ, ξ, λ, the
    translation, both bodies' displacements against the condensation; ξ·d against central
    differences (measured 3e-8)."""
    f = {"block": _block(), "material": {"E": 2.0}, "control": "force", "force": [sideways, 0.0, 3.0]}
    out = {}
    for path in ("condensation", "fullspace"):
        pb = ShapeProblem(_config(f, path))
        a = _design(pb.model)
        theta, xi = pb.evaluate(a)
        out[path] = theta, xi, pb.solve_state(a)
    (t0, x0, s0), (t1, x1, s1) = out["condensation"], out["fullspace"]
    assert abs(t1 - t0) <= 1e-9 * abs(t0) and _rel(x1, x0) <= 1e-8
    assert _rel(s1.lam, s0.lam) <= 1e-9 and _rel(s1.u_c, s0.u_c) <= 1e-8
    assert abs(s1.obstacle.translation - s0.obstacle.translation) <= 1e-9 * abs(s0.obstacle.translation)
    assert _rel(s1.foundation.displacement, s0.foundation.displacement) <= 1e-8
    assert _rel(s1.foundation.u_partner, s0.foundation.u_partner) <= 1e-8
    gc = check_gradient(pb, a, n_directions=2, seed=0, h=1e-2)
    assert gc.n_degenerate == 0 and max(gc.rel_errors) <= 1e-6, gc.rel_errors


def test_a_rigid_counterpart_beside_an_elastic_one_is_taken_on_the_full_space():
    """The block on a rigid plane and an elastic slab (tests/test_assembly_rigid.py): the slab's DOFs
    in the Newton system, none for the plane (its agreement with the condensation is tested there)."""
    import tomllib

    from test_assembly_rigid import _rigid
    cfg = load_config(tomllib.loads(_rigid())).with_updates({"linear_solver": {"path": "fullspace"}})
    pb = ShapeProblem(cfg)
    couple = pb.path.couple
    slab = pb.model.foundation.parts[1]
    assert [f.partner for f in pb.model.foundation.parts] == ["rigid", "point"]
    assert couple.parts == [slab] and couple.n == pb.model.assembler.n_free + slab.assembler.n_free


def test_a_shrink_fit_on_meshes_that_do_not_match_is_lames_on_both_paths(tmp_path):
    """The quarter hub (32 × 64) on a quarter shaft (48 around) of its material, mortar partners,
    plane strain: the contact pressure within 5e-4 rms of Lamé's (measured 2.6e-4) and the same
    state on both paths. With the one body's forcing term the full-space Newton stalled here at
    an error of 3e-4 (paths/fullspace.py COUPLED_FORCING)."""
    from contactopt.config import validate
    from contactopt.verification import lame
    hub = lame.quarter_hub_mesh(tmp_path / "hub.msh", 32, 64, 1)
    shaft = lame.quarter_shaft_mesh(tmp_path / "shaft.msh", 24, 48, 1, radius=lame.B + lame.DELTA)
    out = {}
    for path in ("condensation", "fullspace"):
        cfg = lame.shaft_config(hub, shaft)
        cfg["foundation"]["partner"] = "mortar"
        cfg["linear_solver"] = {"path": path}
        pb = ShapeProblem(validate(cfg, "lame"))
        out[path] = lame.contact_pressure(pb)
    p = out["fullspace"][1]
    e = p / lame.pressure_equal_materials() - 1
    assert np.sqrt(np.mean(e ** 2)) <= 5e-4
    assert _rel(p, out["condensation"][1]) <= 1e-8


def test_the_hub_s_edge_relief_agrees_on_both_paths():
    """examples/hub_edge_relief.toml (a hub shorter than its shaft, the bore's axial profile, the
    KS peak pressure) at a relieved design: Θ and ξ."""
    cfg = load_config(ROOT / "examples" / "hub_edge_relief.toml")

    def make(path):
        return ShapeProblem(cfg.with_updates({"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
    out = {}
    for path in ("condensation", "fullspace"):
        pb = make(path)
        a = pb.model.initial_design() + 2e-4 * np.linspace(0.0, 1.0, pb.model.n_design)
        out[path] = pb.evaluate(a)
    (t0, x0), (t1, x1) = out["condensation"], out["fullspace"]
    assert abs(t1 - t0) <= 1e-9 * abs(t0) and _rel(x1, x0) <= 1e-8


# ------------------------------------------------------------------ the memory estimate of two bodies
# one evaluation of Example 1 on its slab (15,360 + 10,200 DOFs) on the full space, in a process of its own
# (its peak the high-water mark of its own memory map, VmHWM: ru_maxrss keeps that of the test
# process it was forked from across the exec)
PEAK_CHILD = """
import json, sys
from contactopt.config import load_config
from contactopt.problem import ShapeProblem
pb = ShapeProblem(load_config(sys.argv[1]).with_updates({"linear_solver": {"path": "fullspace"}}))
pb.evaluate(pb.model.initial_design())
est = pb.path.memory_estimate(pb.model)
with open("/proc/self/status") as f:
    peak = next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))
print(json.dumps({"peak": peak, "estimate": est.total, "parts": est.parts}))
"""


def test_the_full_space_estimate_counts_both_bodies_within_30_percent_of_the_peak():
    """The estimate of a two-body evaluation on the full space counts the slab's DOFs in the Newton
    system beside the body's (its part "foundation"), within ±30 % of the peak RSS of the evaluation
    measured in a child process (measured 0.45 GB estimated against 0.44 GB; the body's part alone
    0.30 GB)."""
    import os
    import subprocess
    import sys
    if not Path("/proc/self/status").exists():
        pytest.skip("the peak is read from /proc/self/status (Linux)")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", PEAK_CHILD, str(ROOT / "examples" / "example1_elastic.toml")],
                         capture_output=True, text=True, env=env, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["parts"]["foundation"] > 0.2 * got["estimate"]
    assert abs(got["estimate"] / got["peak"] - 1) <= 0.3, got


def test_the_full_space_estimate_at_scale_against_the_measured_peak():
    """Example 1 on its slab refined to 113,088 + 77,616 DOFs (docs/foundation.md, "At scale":
    2.49 GB peak on the full space): the estimate from the meshes alone within 15 % (2.19 GB)."""
    from contactopt.fem import memory
    from contactopt.mesh.body import build_body
    from contactopt.mesh.foundation import build_foundation_mesh
    from contactopt.paths import PATHS
    base = load_config(ROOT / "examples" / "example1_elastic.toml")
    fnd = base.to_dict()["foundation"]
    cfg = base.with_updates({"mesh": {"nx": 64, "ny": 30, "nz": 18},
                             "foundation": {**fnd, "block": {**fnd["block"], "cells": [48, 32, 16]}}})
    body = build_body(cfg)
    fm = build_foundation_mesh(cfg.foundation, body.reference.points[body.contact_nodes, :2], cfg.source)
    free = np.ones(3 * fm.reference.n_nodes, bool)
    free[fm.fixed_dofs] = False
    size = memory.CounterpartSize(int(free.sum()), memory.matrix_entries(fm.reference.cells, fm.reference.n_nodes,
                                                                          free.reshape(-1, 3).sum(axis=1)),
                                  0, 3 * body.contact_nodes.size)
    assert (memory.free_dofs(body), size.n_dofs) == (113088, 77616)
    est = PATHS["fullspace"].memory_estimate(body, counterparts=[size])
    assert abs(est.total_gb / 2.49 - 1) <= 0.15, est.describe()


def test_a_refusal_names_the_path_that_fits(monkeypatch):
    """Example 1 on its slab asked on the condensation path with memory for the full space's
    evaluation (0.45 GB) but not the condensation's (0.57 GB, the slab's factor and dense matrices):
    refused when the slab's mesh is read, before it is condensed, with the full space named."""
    from contactopt.fem import memory
    from contactopt.paths import PATHS
    cfg = load_config(ROOT / "examples" / "example1_elastic.toml")
    pb = ShapeProblem(cfg.with_updates({"linear_solver": {"path": "fullspace"}}))
    full = PATHS["fullspace"].memory_estimate(pb.model).total
    cond = PATHS["condensation"].memory_estimate(pb.model).total
    assert full < cond
    monkeypatch.setattr(memory, "available_memory", lambda: (full + cond) / 2 / 0.9)
    with pytest.raises(memory.InsufficientMemoryError) as err:
        ShapeProblem(cfg.with_updates({"linear_solver": {"path": "condensation"}}))
    text = str(err.value)
    assert "foundation" in text and f"The 'fullspace' path would fit (about {full / memory.GB:.1f} GB)" in text
    assert "path = 'fullspace'" in text
    ShapeProblem(cfg.with_updates({"linear_solver": {"path": "fullspace"}}))      # and it does
    monkeypatch.setattr(memory, "available_memory", lambda: 0.9 * full / 0.9)
    with pytest.raises(memory.InsufficientMemoryError, match=r"No other path that takes this model fits either "
                                                             r"\('condensation' \d\.\d GB"):
        ShapeProblem(cfg.with_updates({"linear_solver": {"path": "fullspace"}}))
