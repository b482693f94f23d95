"""A counterpart held only by its contacts on the full-space path (contactopt.paths.floating): the
right slab of tests/test_assembly_pairs.py's two slabs clamped along x3 only, friction holding
its translations along x1, x2 and its rotation about x3, against the condensation path (which
anchors the same motions on the contact DOFs, contactopt.paths.rigid), its balance and central
differences.

Conventions: per contact node (t1, t2, ν) (here x1, x2, x3), r the contact force on the block,
λ = r_ν ≥ 0, τ = −r_t; the slab carries −r at its partners; w = u_block − u_partner the state's u_c.
"""

import tomllib
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.paths import fullspace
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from test_assembly_pairs import DESIGN, TWO_SLABS

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
HELD_IN_X3 = 'clamped = { on = "bottom", components = [3] }\nmaterial = { E = 6.0, nu = 0.35 }'
SLAB_LOAD = "\nbody_force = [0.002, -0.001, -0.01]"     # the slab's own load, 1.875 in volume


def _text(load: bool = False) -> str:
    text = TWO_SLABS.replace('clamped = "bottom"\nmaterial = { E = 6.0, nu = 0.35 }', HELD_IN_X3 + (SLAB_LOAD if load else ""))
    assert text != TWO_SLABS
    return text + DESIGN


def _problem(path: str, load: bool = False) -> ShapeProblem:
    cfg = load_config(tomllib.loads(_text(load))).with_updates({"linear_solver": {"path": path}, "state": {"tol": 1e-12}})
    pb = ShapeProblem(cfg)
    assert pb.path.name == path
    return pb


def _design(model, seed=1, amp=0.003):
    a = model.initial_design()
    d = np.random.default_rng(seed).standard_normal(a.size)
    return a + amp * (d - d.mean())


def _rel(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / np.abs(np.asarray(b)).max())


def _both(load: bool = False):
    out = {}
    for path in ("condensation", "fullspace"):
        pb = _problem(path, load)
        a = _design(pb.model)
        theta, xi = pb.evaluate(a)
        out[path] = theta, xi, pb.solve_state(a), pb
    return out["condensation"], out["fullspace"]


def _agreement(cond, full):
    (t0, x0, s0, _), (t1, x1, s1, _) = cond, full
    assert np.array_equal(s1.classes, s0.classes)
    return {"Theta": abs(t1 - t0) / abs(t0), "xi": _rel(x1, x0), "lambda": _rel(s1.lam, s0.lam),
            "w": _rel(s1.u_c, s0.u_c), "slab": _rel(s1.foundation.displacement, s0.foundation.displacement)}


def test_a_counterpart_held_only_by_its_contacts_agrees_on_both_paths():
    """Θ, ξ, λ, w, the node classes and the slabs' displacements of one evaluation (measured
    ≤ 1.2e-12), with sticking and sliding nodes on the floating slab's pair; the slab moves along
    its free motions (its bottom, clamped along x3 only, slides along x1)."""
    cond, full = _both()
    d = _agreement(cond, full)
    assert max(d.values()) <= 1e-9, d
    s1, pb = full[2], full[3]
    assert s1.rigid is not None and s1.rigid.residual <= 1e-10
    right = pb.model.foundation.rows[1]
    cls = s1.classes[right]
    assert np.sum(cls == CLASS_CODES["M3+"]) > 0 and np.sum(cls == CLASS_CODES["M1"]) > 0
    slab = s1.foundation.displacement[-3 * pb.model.foundation.parts[1].mesh.reference.n_nodes:].reshape(-1, 3)
    ref = pb.model.foundation.parts[1].mesh.reference
    bottom = ref.points[:, 2] == ref.points[:, 2].min()
    assert np.abs(slab[bottom, 0]).min() > 1e-3 * np.abs(s1.u_c).max()


def test_a_floating_counterpart_s_pair_balances_its_load():
    """The slab with its own body force (0.002, −0.001, −0.01): its pair's tangential forces sum to
    its load's resultant and the moment about x3 of its contact forces to its load's, to 1e-8
    (measured 1e-13); the state as the condensation path's."""
    cond, full = _both(load=True)
    d = _agreement(cond, full)
    assert max(d.values()) <= 1e-9, d
    st, pb = full[2], full[3]
    f = pb.model.foundation
    slab = f.parts[1]
    r = np.column_stack((-st.tau, st.lam))
    F = slab.load_resultant
    assert np.abs(F[:2]).min() > 0
    assert np.abs(r[f.rows[1]].sum(axis=0)[:2] - F[:2]).max() <= 1e-8 * np.abs(F[:2]).max()
    # R_fᵀ(f_f − Π_locᵀ r) = 0 on every free motion (translations x1, x2, the rotation about x3)
    R_r, names = f.kernel()                                     # −Π R_f on the contact DOFs
    R_f = slab.rigid.vectors(slab.mesh.reference.points).reshape(-1, slab.rigid.count)[slab.assembler.free]
    assert len(names) == 3
    assert np.abs(R_f.T @ slab.f_f + R_r.T @ r.ravel()).max() <= 1e-8 * np.abs(F[:2]).max()


def test_the_anchor_s_iteration_alone_reaches_the_same_state(monkeypatch):
    """Without the unanchored Newton steps after the first anchored solve, the iteration
    β ← Nᵀu of contactopt.paths.floating to its end: the same state (measured 1.2e-10, the
    anchor's force at the Newton method's 1e-10)."""
    monkeypatch.setattr(fullspace, "FREE_NEWTON_STEPS", 0)
    cond, full = _both()
    d = _agreement(cond, full)
    assert max(d.values()) <= 1e-9, d
    assert full[2].rigid.iterations > 2


def test_the_subgradient_matches_central_differences_with_a_floating_counterpart():
    """ξ·d against central differences on the full space, sliding and sticking nodes; h =
    1e-2·max|α| as the other full-space checks (the Newton method stops at 1e-10; measured 4e-10,
    2e-9, 6e-10)."""
    pb = _problem("fullspace")
    gc = check_gradient(pb, _design(pb.model), n_directions=3, seed=0, h=1e-2)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0


def test_the_block_on_two_slabs_at_its_flat_initial_design_agrees_on_both_paths():
    """examples/block_two_slabs.toml, its right slab clamped along x3 only, at α0 (a flat face,
    where the contact nodes' 3 × 3 blocks of the Newton system hold exact zeros that the anchored
    matrix keeps in its pattern for the Robin blocks): the condensation's state (measured 3e-13)."""
    text = (EXAMPLES / "block_two_slabs.toml").read_text()
    text = text.replace('clamped = "bottom"\nmaterial = { E = 6.0, nu = 0.35 }', HELD_IN_X3)
    out = {}
    for path in ("condensation", "fullspace"):
        pb = ShapeProblem(load_config(tomllib.loads(text)).with_updates(
            {"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
        assert pb.model.foundation.parts[1].rigid is not None
        a = pb.model.initial_design()
        theta, xi = pb.evaluate(a)
        out[path] = theta, xi, pb.solve_state(a), pb
    d = _agreement(out["condensation"], out["fullspace"])
    assert max(d.values()) <= 1e-9, d
