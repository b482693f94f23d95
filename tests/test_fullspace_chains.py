"""Pairs whose faces lie on several bodies (a chain, contactopt.fem.faces) on the full-space path:
the rows of a face on a counterpart body are that body's own DOFs in the one Newton system of all
bodies (contactopt.paths.coupled: T[c_b, c_b] = Q, T[c_b, partners] = Q Π_loc), a clamped
component of such a node an unknown of its own with a unit diagonal. Against the contact patch
test, against the condensation path (a different solver of the same discrete problem), against
central differences, and through the CLI.

Conventions: per contact node (t1, t2, ν) in the node's frame, ν from the counterpart to the face,
r the contact force on the face's body, λ = r_ν ≥ 0, τ = −r_t; the law's rows are the face body's
contact nodes, then those of the faces on other bodies (``model.pair_of``).
"""

import json
from pathlib import Path

import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from test_assembly_topology import DESIGN, P, _chain_text, _rows, _three, _write

ROOT = Path(__file__).resolve().parents[1]


def _rel(a, b):
    b = np.asarray(b)
    return float(np.abs(np.asarray(a) - b).max() / max(np.abs(b).max(), 1e-300))


def _on(tmp_path, text, path, name="model"):
    return ShapeProblem(load_config(_write(tmp_path, text + f'\n[linear_solver]\npath = "{path}"\n', f"{name}_{path}.toml")))


def _both(tmp_path, text, alpha=None):
    """(problem, Θ, ξ, state) on the condensation and the full-space path at ``alpha(model)``."""
    out = []
    for path in ("condensation", "fullspace"):
        pb = _on(tmp_path, text, path)
        assert pb.path.name == path
        a = pb.model.initial_design() if alpha is None else alpha(pb.model)
        theta, xi = pb.evaluate(a)
        out.append((pb, theta, xi, pb.solve_state(a)))
    return out


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_the_contact_patch_test_passes_across_a_chain_on_the_full_space(friction, tmp_path):
    """Four blocks on non-matching offset grids, mortar partners, the third pair's face on the
    counterpart of the second (its edge nodes' clamped components pinned rows), three blocks held
    in x3 only by contact: pressure P on every interface to 1e-8, τ = 0, and the condensation's
    contact forces and face displacements to 1e-9 (measured 1.5e-13, 7e-14)."""
    (_, _, _, s0), (pb, _, _, s1) = _both(tmp_path, _chain_text(tmp_path, friction=(friction,) * 3))
    m = pb.model
    assert m.n_contact == m.contact_nodes.size + 30 and pb.path.couple.n_pinned > 0
    p = s1.lam / m.contact_areas()
    for k in range(3):
        mine = m.pair_of == k
        assert np.abs(p[mine] / P - 1).max() <= 1e-8, (k, p[mine])
    assert np.all(np.linalg.norm(s1.tau, axis=1) <= 1e-8 * s1.lam)
    assert _rel(s1.lam, s0.lam) <= 1e-9
    assert _rel(s1.foundation.u_body_c, s0.foundation.u_body_c) <= 1e-9
    assert _rel(s1.foundation.displacement, s0.foundation.displacement) <= 1e-9


SLIDING = DESIGN + '[[loads.traction]]\non = "top.right"\nvalue = [0.001, 0.0, 0.0]\n'


def _alpha(m):
    return m.initial_design() + 0.003 * np.random.default_rng(3).standard_normal(m.n_design)


def test_a_sliding_chain_whose_face_body_floats_agrees_with_the_condensation(tmp_path):
    """The chain held in x1 by friction alone (the face body too: anchored on one of its cells on
    the full space), a design and a traction that slides rows of the face on upper: Θ, ξ, λ, w,
    every row's face displacement and the counterparts' displacement to 1e-9 (measured ≤ 9e-13),
    the same node classes."""
    text = _chain_text(tmp_path, friction=(0.3, 0.3, 0.15), sides=False, extra=SLIDING)
    (_, t0, x0, s0), (pb, t1, x1, s1) = _both(tmp_path, text, _alpha)
    m = pb.model
    assert m.body.rigid is not None and np.sum(s1.classes[m.pair_of == 2] == CLASS_CODES["M1"]) >= 5
    assert np.array_equal(s1.classes, s0.classes)
    assert abs(t1 - t0) <= 1e-9 * abs(t0)
    assert _rel(x1, x0) <= 1e-9
    for a, b in ((s1.lam, s0.lam), (s1.u_c, s0.u_c), (s1.u, s0.u), (s1.foundation.u_body_c, s0.foundation.u_body_c),
                 (s1.foundation.u_partner, s0.foundation.u_partner),
                 (s1.foundation.displacement, s0.foundation.displacement)):
        assert _rel(a, b) <= 1e-9


def test_subgradients_of_a_sliding_chain_on_the_full_space_match_central_differences(tmp_path):
    """ξ against central differences to 1e-6 (measured 7.5e-9, 1.9e-8) with rows of the face on
    upper sliding and the face body held only by contact."""
    pb = _on(tmp_path, _chain_text(tmp_path, friction=(0.3, 0.3, 0.15), sides=False, extra=SLIDING), "fullspace")
    gc = check_gradient(pb, _alpha(pb.model), n_directions=2, seed=1)
    assert gc.passed and max(gc.rel_errors) <= 1e-6, gc.rel_errors


@pytest.mark.parametrize("friction, moved", [(0.0, (0.0, 0.0, -0.01)), (0.3, (0.002, 0.0, -0.01))])
def test_a_chain_pressed_by_a_moved_counterpart_agrees_with_the_stack_on_the_full_space(friction, moved, tmp_path):
    """Three blocks, the face body lower, the second pair's face on middle (held only by its
    contacts), upper moved by its top: the full space gives the contact forces of the stack written
    with both faces on middle (condensation) to 1e-9, pair by pair."""
    star = _three(tmp_path, "star", friction, 0.0, moved)
    _three(tmp_path, "chain", friction, 0.0, moved)
    chain = ShapeProblem(load_config(tmp_path / "chain.toml").with_updates({"linear_solver": {"path": "fullspace"}}))
    assert chain.path.name == "fullspace"
    a = _rows(star, star.solve_state(star.model.initial_design()))
    b = _rows(chain, chain.solve_state(chain.model.initial_design()))
    assert a[1][2].sum() > 1e-3
    for k, sign in ((0, -1.0), (1, 1.0)):
        (_, ra, la, _), (_, rb, lb, _) = a[k], b[k]
        assert np.abs(la - lb).max() <= 1e-9 * la.max()
        assert np.abs(ra - sign * rb).max() <= 1e-9 * np.abs(ra).max()


def test_auto_takes_the_full_space_for_a_chain_from_the_crossover_and_the_cli_writes_its_state(tmp_path, capsys):
    """``path = "auto"`` with a crossover below the model's DOFs takes the full space; `contactopt
    state` writes every row, each pair carrying P (1e-10)."""
    text = _chain_text(tmp_path) + '\n[linear_solver]\npath = "auto"\ncrossover = 100\n'
    path = _write(tmp_path, text)
    assert ShapeProblem(load_config(path)).path.name == "fullspace"
    out = tmp_path / "out"
    assert main(["state", str(path), "--out", str(out)]) == 0
    report = json.loads((out / "state.json").read_text())
    for c in report["contacts"]:
        assert c["total_normal_force"] == pytest.approx(P, rel=1e-10)
    assert report["n_contact"] == 142 and report["contact"]["body"][112:] == ["upper"] * 30
    assert (out / "foundation.vtu").exists()


def test_the_bolted_stack_agrees_on_both_paths_and_its_head_carries_the_preload():
    """examples/bolted_stack.toml: a chain whose face body (the head, the paper's flat face, no chart)
    carries one pair and the plates the other two; the head, held by its contact alone, passes the
    preload 0.01 to the upper plate exactly (Σλ of its pair to 1e-10 on both paths: its faces are
    flat, normals ±e3); the full space gives the condensation's Θ, ξ and λ to 1e-9 (measured 5e-14,
    1.2e-11, 7.5e-13)."""
    out = []
    for path in ("condensation", "fullspace"):
        pb = ShapeProblem(load_config(ROOT / "examples" / "bolted_stack.toml").with_updates(
            {"linear_solver": {"path": path}}))
        a = pb.model.initial_design() + 0.001 * (1.0 + np.sin(np.arange(pb.model.n_design)))
        theta, xi = pb.evaluate(a)
        st = pb.solve_state(a)
        m = pb.model
        assert st.lam[m.pair_of == 0].sum() == pytest.approx(0.01, rel=1e-10)
        out.append((theta, xi, st))
    (t0, x0, s0), (t1, x1, s1) = out
    assert abs(t1 - t0) <= 1e-9 * abs(t0) and _rel(x1, x0) <= 1e-9 and _rel(s1.lam, s0.lam) <= 1e-9


def test_check_gradient_of_the_bolted_stack_with_newton_states_passes(capsys):
    """`contactopt check-gradient --state-method newton`: the states by Newton to 1e-13 (the default
    successive approximations contract slowly with the head held along the bolt by contact alone).
    Two directions, whose directional derivatives are 0.13 and 0.079 (measured within 3.7e-8 under
    the machine's, the Haswell and the Prescott OpenBLAS kernels; the third seeded direction's is
    3.3e-3, and its relative difference, 1.6e-7 to 9.6e-7 by kernel, is the central differences'
    floor over a small derivative)."""
    assert main(["check-gradient", str(ROOT / "examples" / "bolted_stack.toml"), "--directions", "2",
                 "--state-method", "newton"]) == 0
    out = capsys.readouterr().out
    assert "PASSED" in out, out


def test_a_run_of_the_bolted_stack_writes_every_output(tmp_path):
    """`contactopt run` of a chain to its figures: the comparison maps of λ and of the pressure show
    the face body's rows (before, the maps drew the face body's face with every row's values and the
    run failed at its outputs)."""
    out = tmp_path / "run"
    assert main(["run", str(ROOT / "examples" / "bolted_stack.toml"), "--out", str(out), "--max-iter", "2"]) == 0
    for name in ("summary.json", "stress.png", "pressure.png", "surface.png", "contact.png", "optimal_plate1.vtu"):
        assert (out / name).exists(), name
