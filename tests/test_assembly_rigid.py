"""Rigid counterparts in a model of several pairs (fem/counterparts.py ``RigidCounterpart``): a pair
whose counterpart is a table of [obstacle] beside pairs against elastic bodies, against a very stiff
elastic body in its place, a monolithic model, a floating roller on a rigid plane under an elastic
plate, and central differences.

Conventions: per contact node (t1, t2, ν) in the node's frame, ν from the counterpart to the face
body; r the contact force on the face body, λ = r_ν ≥ 0, τ = −r_t; w = u_face − u_partner (a rigid
counterpart's partner moves by its prescribed translation alone). Pairs in [[contacts]] order.
"""

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from test_assembly_pairs import DESIGN, TWO_SLABS

from contactopt.config import load_config
from contactopt.contact.local import solve_local
from contactopt.contact.state import FROM_FCLIB, TO_FCLIB, classify_nodes
from contactopt.errors import ConfigError
from contactopt.fem.elasticity import ElasticityAssembler
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
LEFT = """[bodies.left]
block = { size = [1.5, 2.0, 1.0], cells = [6, 8, 2], origin = [-0.5, -0.5] }
clamped = "bottom"
material = { E = 2.119 }
"""
assert LEFT in TWO_SLABS


def _rigid(counterpart='{ shape = "plane" }', friction=0.3) -> str:
    """The block on two slabs with the left slab replaced by a rigid counterpart."""
    text = TWO_SLABS.replace(LEFT, "").replace('counterpart = "left.top"', f"counterpart = {counterpart}")
    return text.replace("friction = 0.3", f"friction = {friction}", 1)


def _write(tmp_path, text, name="model.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _problem(tmp_path, text, name="model.toml") -> ShapeProblem:
    return ShapeProblem(load_config(_write(tmp_path, text, name)))


def _monolithic_state(pb, alpha, shift=(0.0, 0.0, 0.0)):
    """λ, τ, w and classes of the block on the right slab and the rigid plane, without contactopt's
    counterpart code: the block and the slab in one matrix, w = B u − (the plane's translation
    ``shift`` at the left pair's nodes) with B = (the block's DOF − its partner's DOF) on the right
    pair and the block's DOF alone on the left one, W = B K⁻¹ Bᵀ by sparse solves, the same local
    solver with the same coefficient per node."""
    model = pb.model
    asm_b = model.assemble(alpha)
    nb = model.body.reference.n_nodes
    mat = pb.config.material
    blocks = [ElasticityAssembler(model.body.reference.cells, nb, np.zeros(0, int), mat.E, mat.nu)
              .full_stiffness(asm_b.coords)]
    loads, fixed, offset = [asm_b.L_full], [model.body.fixed_dofs], 3 * nb
    partner = np.full(model.n_contact, -1)
    x_b = model.body.reference.points[model.contact_nodes]
    for k, spec in enumerate(pb.config.pairs):
        if spec.rigid:
            continue
        ref = model.foundation.parts[k].mesh.reference
        f = spec.foundation
        blocks.append(ElasticityAssembler(ref.cells, ref.n_nodes, np.zeros(0, int), f.material.E, f.material.nu)
                      .full_stiffness(ref.points))
        loads.append(np.zeros(3 * ref.n_nodes))
        bottom = np.flatnonzero(np.isclose(ref.points[:, 2], ref.points[:, 2].min()))
        fixed.append(offset + (3 * bottom[:, None] + np.arange(3)).ravel())
        rows = np.flatnonzero(model.body.pair_of == k)
        d = np.linalg.norm(ref.points[None, :, :] - x_b[rows, None, :], axis=2)
        assert np.allclose(d.min(axis=1), 0.0)
        partner[rows] = offset // 3 + np.argmin(d, axis=1)
        offset += 3 * ref.n_nodes
    K, L = sp.block_diag(blocks).tocsr(), np.concatenate(loads)
    free = np.setdiff1d(np.arange(K.shape[0]), np.concatenate(fixed))
    index = np.full(K.shape[0], -1)
    index[free] = np.arange(free.size)
    p = model.n_contact
    on_body = (3 * model.contact_nodes[:, None] + np.arange(3)).ravel()
    elastic = np.repeat(partner >= 0, 3)
    on_partner = (3 * partner[partner >= 0][:, None] + np.arange(3)).ravel()
    rows = np.arange(3 * p)
    B = sp.csr_matrix((np.r_[np.ones(3 * p), -np.ones(on_partner.size)],
                       (np.r_[rows, rows[elastic]], np.r_[index[on_body], index[on_partner]])), shape=(3 * p, free.size))
    lu = sla.splu(K[free][:, free].tocsc())
    W = B @ lu.solve(B.T.toarray())
    W = 0.5 * (W + W.T)
    w0 = B @ lu.solve(L[free])
    w0[~elastic] -= np.tile(shift, p)[~elastic]
    perm = (3 * np.arange(p)[:, None] + TO_FCLIB).ravel()        # (t1, t2, ν) → (ν, t1, t2)
    q = w0[perm]
    gap = asm_b.coords[model.contact_nodes, 2]          # the face's height over the plane and the slab
    q[0::3] += gap
    res = solve_local(W[np.ix_(perm, perm)], q, pb.friction, tol=1e-14, max_iter=200)
    r = res.r.reshape(p, 3)[:, FROM_FCLIB]
    w = (w0 + W @ r.ravel()).reshape(p, 3)
    lam, tau = r[:, 2], -r[:, :2]
    return lam, tau, w, classify_nodes(w, lam, tau, gap, pb.friction)


@pytest.mark.parametrize("left", [0.3, 0.0])
def test_a_rigid_plane_beside_an_elastic_slab_agrees_with_a_monolithic_model(left, tmp_path):
    """The block on the right slab and, for its left pair, the rigid plane x3 = 0 (fixed, or moved by
    a translation with tangential parts): λ, τ and w to 1e-10 of the monolithic model at the reference
    shape and a designed one; slip, stick and separation present, the rigid pair carrying load."""
    rng = np.random.default_rng(3)
    for shift in ((0.0, 0.0, 0.0), (0.003, -0.001, 0.0005)):
        plane = '{ shape = "plane" }' if not any(shift) else \
            f'{{ shape = "plane", control = "displacement", displacement = {list(shift)} }}'
        pb = _problem(tmp_path, _rigid(plane, left) + DESIGN)
        assert [f.partner for f in pb.model.foundation.parts] == ["rigid", "point"]
        pair = pb.model.body.pair_of
        a = pb.model.initial_design()
        for alpha in (a, a + 0.004 * rng.standard_normal(a.size)):
            st = pb.solve_state(alpha)
            lam, tau, w, classes = _monolithic_state(pb, alpha, shift)
            scale = lam.max()
            assert np.abs(st.lam - lam).max() <= 1e-10 * scale
            assert np.abs(st.tau - tau).max() <= 1e-10 * scale
            assert np.abs(st.u_c - w).max() <= 1e-10 * np.abs(w).max()
            assert np.array_equal(st.classes, classes)
            assert set(np.unique(classes)) >= {0, 1, 3} if left else True
        for k in range(2):
            assert lam[pair == k].sum() > 0.03 * lam.sum()
        if left == 0.0:
            assert np.all(st.tau[pair == 0] == 0.0) and np.abs(st.tau[pair == 1]).max() > 0.1 * scale


def test_a_rigid_plane_is_the_limit_of_a_stiff_slab(tmp_path):
    """The rigid plane in place of the left slab against that slab with E × 1e6 and E × 1e7 (point
    partners, its top nodes matching the face's): Θ, λ and τ within 2e-5 of the largest force, the
    difference falling tenfold with the compliance (measured: λ 1.2e-5, then 1.2e-6)."""
    pb = _problem(tmp_path, _rigid() + DESIGN, "rigid.toml")
    a = pb.model.initial_design()
    st, J = pb.solve_state(a), pb.evaluate_value(a)
    diffs = []
    for scale in ("e6", "e7"):
        stiff = _problem(tmp_path, TWO_SLABS.replace("E = 2.119 }", f"E = 2.119{scale} }}") + DESIGN, f"{scale}.toml")
        s1, J1 = stiff.solve_state(a), stiff.evaluate_value(a)
        top = s1.lam.max()
        diffs.append((abs(J - J1) / abs(J1), np.abs(st.lam - s1.lam).max() / top, np.abs(st.tau - s1.tau).max() / top))
    assert max(diffs[0]) < 2e-5 and min(diffs[0]) > 1e-7
    for d6, d7 in zip(*diffs):
        assert 8 < d6 / d7 < 12


def test_subgradient_with_a_rigid_pair_matches_central_differences(tmp_path):
    """ξ·d of a design on the block's face over the rigid plane and the slab, friction on both
    pairs, against Richardson central differences to 1e-6 (sliding, sticking and free nodes)."""
    pb = _problem(tmp_path, _rigid('{ shape = "plane", control = "displacement", displacement = [0.002, 0.0, 0.0] }')
                  + DESIGN)
    a = pb.model.initial_design()
    alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    gc = check_gradient(pb, alpha, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0
