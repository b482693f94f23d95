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

from contactopt.config import load_config
from contactopt.contact.local import solve_local
from contactopt.contact.state import FROM_FCLIB, TO_FCLIB, classify_nodes
from contactopt.errors import ConfigError
from contactopt.fem.elasticity import ElasticityAssembler
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from test_assembly_pairs import DESIGN, TWO_SLABS

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
    u = np.zeros(K.shape[0])                     # every body's displacement: K u = L + Bᵀ r
    u[free] = lu.solve(L[free] + B.T @ r.ravel())
    _monolithic_state.u = u[3 * nb:]             # the slab's (the bodies after the block, in pair order)
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


@pytest.mark.parametrize("counterpart", [
    '{ shape = "plane", control = "displacement", displacement = [0.002, 0.0, 0.0] }',
    '{ shape = "sphere", center = [0.5, 0.5, -20.0], radius = 20.0, control = "displacement", '
    'displacement = [0.001, 0.0, 0.004] }'], ids=["plane", "sphere"])
def test_subgradient_with_a_rigid_pair_matches_central_differences(counterpart, tmp_path):
    """ξ·d of a design on the block's face over a rigid counterpart (the plane moved along x1, or a
    sphere, whose frames are not the axes) and the slab, friction on both pairs, against Richardson
    central differences to 1e-6 (sliding, sticking and free nodes)."""
    pb = _problem(tmp_path, _rigid(counterpart) + DESIGN)
    a = pb.model.initial_design()
    alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    gc = check_gradient(pb, alpha, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0


FULL_SPACE_CASES = {
    "plane": '{ shape = "plane" }',
    "plane moved": '{ shape = "plane", control = "displacement", displacement = [0.002, 0.0, 0.0] }',
    "sphere moved": '{ shape = "sphere", center = [0.5, 0.5, -20.0], radius = 20.0, control = "displacement", '
                    'displacement = [0.001, 0.0, 0.004] }'}


def _on_path(text, path, tol=1e-12) -> ShapeProblem:
    import tomllib
    cfg = load_config(tomllib.loads(text)).with_updates({"linear_solver": {"path": path}, "state": {"tol": tol}})
    return ShapeProblem(cfg)


@pytest.mark.parametrize("case", sorted(FULL_SPACE_CASES))
def test_the_full_space_agrees_with_the_condensation_beside_a_rigid_counterpart(case):
    """The block on the rigid counterpart (the plane, fixed or moved, or a sphere, whose frames are not
    the axes) and the elastic slab: the slab's DOFs in the full-space Newton system, none for the
    rigid pair (its rows of Π zero, its gap and translation from its geometry): Θ, ξ, λ, w and the
    slab's displacement against the condensation path to 1e-10 (measured 1e-13 to 7e-13)."""
    from test_foundation_fullspace import _agree
    d = _agree(lambda path: _on_path(_rigid(FULL_SPACE_CASES[case]) + DESIGN, path))
    assert max(d.values()) <= 1e-10, d


@pytest.mark.parametrize("case", ["plane moved", "sphere moved"])
def test_subgradient_beside_a_rigid_counterpart_on_the_full_space_matches_central_differences(case):
    """ξ·d on the full-space path against central differences; its Newton method stops at 1e-10 (its
    Krylov floor), so the step is h = 1e-2 max|α| (tests/test_foundation_fullspace.py; measured
    5e-11)."""
    pb = _on_path(_rigid(FULL_SPACE_CASES[case]) + DESIGN, "fullspace", tol=1e-14)
    assert pb.path.name == "fullspace"
    a = pb.model.initial_design()
    alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    gc = check_gradient(pb, alpha, n_directions=3, seed=0, h=1e-2)
    assert gc.n_degenerate == 0 and gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_the_patch_test_passes_on_a_rigid_plane_under_a_floating_stack(friction, tmp_path):
    """The stack of tests/test_assembly_pairs.py with its lower block replaced by the rigid plane:
    the middle block (the face body) and the upper one held in x3 only by their contacts, a pressure
    p on the top: the pressure on both interfaces is p to 1e-8, τ = 0 (the floating counterpart
    beside the rigid pair, its rigid motion in the anchored problem)."""
    from test_assembly_pairs import _stack
    _stack(tmp_path, friction)                      # writes upper.msh and model.toml
    src = (tmp_path / "model.toml").read_text()
    start = src.index("[bodies.lower]")
    src = src[:start] + src[src.index("[bodies.upper]"):]
    src = src.replace('counterpart = "lower.top"\nfriction', 'counterpart = { shape = "plane" }\nfriction')
    src = src.replace('partner = "mortar"\n', "", 1)
    pb = _problem(tmp_path, src, "rigid.toml")
    m = pb.model
    assert [f.partner for f in m.foundation.parts] == ["rigid", "mortar"]
    assert m.body.rigid is not None and m.foundation.kernel()[1] == [
        "the translation along x3 of the counterpart of contacts[1]"]
    st = pb.solve_state(m.initial_design())
    p = st.lam / m.contact_areas()
    for k in range(2):
        mine = m.body.pair_of == k
        assert np.abs(p[mine] / 0.01 - 1).max() <= 1e-8, (k, p[mine])
    assert np.all(np.linalg.norm(st.tau, axis=1) <= 1e-8 * st.lam)


def _roller_on_a_plane(tmp_path, friction=0.2) -> ShapeProblem:
    """examples/roller_plates.toml with the lower plate replaced by the rigid plane x3 = 0: the roller
    held only by its contacts, the plane below (pair "bottom") and the elastic upper plate pressed
    down by a displacement (pair "top"), friction on both."""
    text = (EXAMPLES / "roller_plates.toml").read_text().replace('mesh = "roller_plates/',
                                                                 f'mesh = "{EXAMPLES}/roller_plates/')
    start = text.index("[bodies.lower]")
    text = text[:start] + text[text.index("[bodies.upper]"):]
    text = text.replace('counterpart = "lower.top"\npartner = "mortar"', 'counterpart = { shape = "plane" }')
    return _problem(tmp_path, text.replace("coefficient = 0.0", f"coefficient = {friction}"))


def test_a_floating_roller_on_a_rigid_plane_under_an_elastic_plate(tmp_path):
    """The roller on the rigid plane under the elastic plate, friction 0.2: the vertical resultants of
    the two pairs (λ and τ in global components) balance to 1e-8; on each side the half-width and peak
    pressure against Hertz's b = √(4P′R/(πE*)), p0 = 2P′/(πb) with that side's E*: E/(1 − ν²) on the
    rigid plane, E/(2(1 − ν²)) against the plate (measured: b −0.7 % and −0.6 %, p0 +5.8 % on 7 nodes
    across the half-width on the plane and +1.8 %)."""
    from contactopt.verification.hertz import fit
    pb = _roller_on_a_plane(tmp_path)
    m = pb.model
    assert [f.partner for f in m.foundation.parts] == ["rigid", "mortar"]
    bottom = m.body.pair_of == 0
    assert np.abs(m.frames[bottom, :, 2] - [0.0, 0.0, 1.0]).max() == 0.0      # the plane's normal e3
    st = pb.solve_state(m.initial_design())
    g = np.einsum("mij,mj->mi", m.frames, np.c_[-st.tau, st.lam])      # the forces on the roller, global
    F0, F1 = g[bottom].sum(axis=0), g[~bottom].sum(axis=0)
    assert abs(F0[2] + F1[2]) <= 1e-8 * F0[2] and F0[2] > 0
    assert np.abs(st.tau[bottom]).max() > 0.05 * st.lam.max()       # friction acts on the plane
    x = m.body.reference.points[m.contact_nodes]
    p = st.lam / m.contact_areas()
    length = np.ptp(m.body.reference.points[:, 1])
    E, nu = pb.config.material.E, pb.config.material.nu
    for k, E_star in ((0, E / (1 - nu ** 2)), (1, E / (2 * (1 - nu ** 2)))):
        s = m.body.pair_of == k
        P1 = 2 * float(st.lam[s] @ np.abs(m.frames[s, 2, 2])) / length
        b, p0 = fit(np.abs(x[s, 0]), p[s])
        bH = math.sqrt(4 * P1 * m.body.chart.radius / (math.pi * E_star))
        assert abs(b / bH - 1) < 0.015 and abs(p0 / (2 * P1 / (math.pi * bH)) - 1) < 0.07, (k, b / bH, p0)


@pytest.mark.parametrize("change, needle", [
    ('counterpart = { shape = "plane", weighting = "mortar" }',
     "contacts[0].counterpart.weighting = 'mortar': the mortar-weighted gap of a rigid counterpart takes a model of "
     "one pair so far"),
    ('counterpart = { shape = "plane" }\npartner = "mortar"', "contacts[0].partner: a rigid counterpart has no partners"),
    ('counterpart = { shape = "sphere", center = [0.5, 0.5, -20.0] }', "contacts[0].counterpart.radius: required"),
])
def test_what_a_rigid_pair_does_not_take_is_refused_by_name(change, needle, tmp_path):
    text = _rigid().replace('counterpart = { shape = "plane" }', change)
    with pytest.raises(ConfigError) as exc:
        load_config(_write(tmp_path, text + DESIGN))
    assert needle in str(exc.value)


def _all_rigid(counterpart='{ shape = "plane" }') -> str:
    """The block on two slabs with both slabs replaced by the rigid ``counterpart``: two pairs, no
    counterpart body."""
    text = _rigid(counterpart).replace('counterpart = "right.top"', f"counterpart = {counterpart}")
    return text[:text.index("[bodies.right]")] + text[text.index("[[contacts]]"):]


def _one_pair(counterpart) -> str:
    """The same block on one pair, its whole contact face against ``counterpart`` (the one-body model)."""
    text = _all_rigid(counterpart)
    start, stop = text.index("[[contacts]]"), text.index("[state]")
    return text[:start] + f'[[contacts]]\nface = "block.contact"\ncounterpart = {counterpart}\nfriction = 0.3\n' + text[stop:]


def test_a_model_whose_counterparts_are_all_rigid_is_taken(tmp_path):
    """Two pairs, each against the rigid plane: no counterpart body, Π without columns, C = 0."""
    pb = _problem(tmp_path, _all_rigid() + DESIGN)
    f = pb.model.foundation
    assert pb.config.assembly.bodies == ("block",)
    assert [p.partner for p in f.parts] == ["rigid", "rigid"] and f.P.shape == (3 * pb.model.n_contact, 0)
    assert not np.any(f.C)


ONE_PAIR_CASES = {
    "plane": '{ shape = "plane" }',
    "plane moved": '{ shape = "plane", control = "displacement", displacement = [0.002, -0.001, 0.0005] }',
    "sphere moved": '{ shape = "sphere", center = [1.0, 0.5, -20.0], radius = 20.0, control = "displacement", '
                    'displacement = [0.001, 0.0, 0.004] }'}


@pytest.mark.parametrize("path", ["condensation", "fullspace"])
@pytest.mark.parametrize("case", sorted(ONE_PAIR_CASES))
def test_two_pairs_on_one_rigid_counterpart_are_the_one_pair_model(case, path):
    """The block's face split into two pairs, each against the same rigid counterpart (the plane,
    fixed or moved with tangential parts, or a sphere), against the one-body model of one pair on
    that counterpart: Θ, ξ, λ and the classes at a designed shape to 1e-10 on the condensation
    path (measured 1e-14) and 1e-9 on the full space (two Newton runs at 1e-12, measured 6e-11);
    the pairs' w is relative to the counterpart's translation R_mᵀ d per node, the one pair's u_c
    to its tangential parts only (its normal part is in the gap)."""
    out = []
    for text in (_all_rigid(ONE_PAIR_CASES[case]), _one_pair(ONE_PAIR_CASES[case])):
        pb = _on_path(text + DESIGN, path)
        assert pb.path.name == path
        a = pb.model.initial_design()
        alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
        theta, xi = pb.evaluate(alpha)
        out.append((pb, theta, xi, pb.solve_state(alpha)))
    (pb2, t2, x2, s2), (pb1, t1, x1, s1) = out
    assert pb1.model.foundation is None and pb2.model.foundation.P.shape[1] == 0
    assert np.array_equal(pb1.model.contact_nodes, pb2.model.contact_nodes)
    bound = 1e-10 if path == "condensation" else 1e-9
    assert abs(t2 - t1) <= bound * abs(t1)
    assert np.abs(x2 - x1).max() <= bound * np.abs(x1).max()
    assert np.abs(s2.lam - s1.lam).max() <= bound * s1.lam.max()
    assert np.array_equal(s2.classes, s1.classes) and s1.counts["M1"] > 0 and s1.counts["L"] > 0
    w = s1.u_c - pb2.model.foundation.q_f.reshape(-1, 3) * [0.0, 0.0, 1.0]
    assert np.abs(s2.u_c - w).max() <= bound * np.abs(w).max()


@pytest.mark.parametrize("path", ["condensation", "fullspace"])
def test_subgradient_with_every_counterpart_rigid_matches_central_differences(path):
    """ξ·d of the block on two rigid counterparts (the plane moved along x1 under the left pair, a
    sphere under the right one, friction 0.3 and 0.1) against central differences to 1e-6."""
    sphere = ('{ shape = "sphere", center = [1.5, 0.5, -20.0], radius = 20.0, control = "displacement", '
              'displacement = [0.0, 0.001, 0.003] }')
    text = _all_rigid('{ shape = "plane", control = "displacement", displacement = [0.002, 0.0, 0.0] }')
    start = text.index('name = "right"')
    text = text[:start] + text[start:].replace(text[start:].split("counterpart = ", 1)[1].split("\n", 1)[0], sphere, 1)
    text = text[:start] + text[start:].replace("friction = 0.3", "friction = 0.1", 1)
    pb = _on_path(text + DESIGN, path, tol=1e-14 if path == "condensation" else 1e-12)
    assert [p.obstacle.shape for p in pb.config.pairs] == ["plane", "sphere"]
    a = pb.model.initial_design()
    alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    gc = check_gradient(pb, alpha, n_directions=3, seed=0, **({} if path == "condensation" else {"h": 1e-2}))
    assert gc.n_degenerate == 0 and gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["L"] > 0


PEAK = '[objective]\ntype = "peak_stress"\nregion = "{region}"\naggregate = "{aggregate}"\n'


@pytest.mark.parametrize("region", ["right.", "right.top"])
def test_the_peak_stress_of_a_counterpart_body_is_that_of_a_monolithic_model(region, tmp_path):
    """The peak von Mises stress of the right slab (all of it, or its elements on its top face)
    beside the rigid plane, at a designed shape, against the stress fem/stress.py computes from the
    slab's displacement in the monolithic model: to 1e-9."""
    from contactopt.fem.stress import von_mises_points
    from contactopt.sensitivity.objectives import counterpart_region
    pb = _problem(tmp_path, _rigid() + DESIGN + PEAK.format(region=region, aggregate="max"))
    a = pb.model.initial_design()
    alpha = a + 0.004 * np.random.default_rng(5).standard_normal(a.size)
    _monolithic_state(pb, alpha)
    slab = pb.model.foundation.parts[1]
    b, cells = counterpart_region(pb.model, region, "objective.region")
    assert b == 1 and 0 < cells.size <= slab.assembler.elements.shape[0]
    assert (cells.size == slab.assembler.elements.shape[0]) == (region == "right.")
    peak = von_mises_points(slab.assembler, slab.mesh.reference.points, _monolithic_state.u, cells).max()
    assert abs(pb.evaluate_value(alpha) - peak) <= 1e-9 * peak


@pytest.mark.parametrize("text, region, aggregate", [(None, "right.", "max"), (None, "right.top", "ks"),
                                                     (TWO_SLABS, "left.", "ks")],
                         ids=["beside-plane", "beside-plane-top", "two-slabs"])
def test_subgradient_of_a_counterpart_peak_stress_matches_central_differences(text, region, aggregate, tmp_path):
    """ξ·d of the peak stress of a counterpart body (beside the rigid plane, or of the left slab of
    the two), through its recovery from the contact forces, against central differences to 1e-6."""
    pb = _problem(tmp_path, (text or _rigid()) + DESIGN + PEAK.format(region=region, aggregate=aggregate))
    a = pb.model.initial_design()
    alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    gc = check_gradient(pb, alpha, n_directions=3, seed=0)
    assert gc.n_degenerate == 0 and gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6


def test_the_peak_stress_of_a_floating_counterpart_is_refused_by_name(tmp_path):
    """A counterpart held only by its contacts: its displacement is not one of the contact forces alone."""
    from test_assembly_pairs import _stack
    _stack(tmp_path, 0.0)
    text = (tmp_path / "model.toml").read_text() + PEAK.format(region="upper.", aggregate="max")
    with pytest.raises(ConfigError, match="objective.region = 'upper.': body 'upper' is held only by its contacts"):
        _problem(tmp_path, text, "peak.toml").evaluate_value(np.zeros(1))


def test_the_peak_stress_of_the_one_pair_foundation_is_refused_by_name():
    """The slab of examples/block_on_slab.toml (one pair): not taken so far, and said so."""
    text = (EXAMPLES / "block_on_slab.toml").read_text()
    text = text[:text.index("[objective]")] + PEAK.format(region="slab.top", aggregate="ks") + text[text.index("[state]"):]
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        with pytest.raises(ConfigError, match="the peak stress of a counterpart body takes a model of several pairs"):
            ShapeProblem(load_config(_write(Path(tmp), text))).evaluate_value(np.zeros(1))


def _squeezed(tmp_path, lid: str, friction: float = 0.0) -> ShapeProblem:
    """A unit block (7 × 6 × 3 cells, E = 1, ν = 0.3, rollers on its sides, held along x3 only by its
    contacts, no load of its own) between the rigid plane x3 = 0 under its face (pair 0) and a rigid
    lid over its top (pair 1): the box x3 ∈ [1, 2] as a closed STL surface, its face on the block's
    top, pressed by ``lid`` (the keys of its control)."""
    from test_assembly_pairs import _rollers
    from test_obstacles import prism
    box = prism(tmp_path / "lid.stl", [(-1.0, 1.0), (2.0, 1.0), (2.0, 2.0), (-1.0, 2.0)], -1.0, 2.0)
    return _problem(tmp_path, f"""
name = "squeezed"
[geometry]
a = 1.0
b = 1.0
c = 1.0
[mesh]
nx = 7
ny = 6
nz = 3
[loads]
top_traction = [0.0, 0.0, 0.0]
right_traction = [0.0, 0.0, 0.0]
[material]
E = 1.0
nu = 0.3
[bodies.middle]
clamped = {_rollers("clamped")}
[[contacts]]
face = "middle.contact"
counterpart = {{ shape = "plane" }}
friction = {friction}
[[contacts]]
face = "middle.top"
counterpart = {{ shape = "surface", mesh = "{box}", {lid} }}
friction = {friction}
[state]
tol = 1.0e-12
max_iter = 200
""", "squeezed.toml")


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_a_block_squeezed_between_two_rigid_counterparts_has_the_uniform_pressure(friction, tmp_path):
    """The lid moved down by δ = 0.01 onto the block held only by its contacts: uniaxial strain δ/h
    under the rollers, so the pressure on both faces is p = E(1 − ν)/((1 + ν)(1 − 2ν)) δ to 1e-10
    (measured 2e-13), τ = 0, the block's translation along x3 the anchor's."""
    pb = _squeezed(tmp_path, 'control = "displacement", displacement = [0.0, 0.0, -0.01]', friction)
    m = pb.model
    assert m.body.rigid.names() == ["the translation along x3"]
    assert [f.partner for f in m.foundation.parts] == ["rigid", "rigid"]
    assert np.abs(m.frames[m.body.pair_of == 1, :, 2] - [0.0, 0.0, -1.0]).max() <= 1e-12   # the lid's normal
    st = pb.solve_state(m.initial_design())
    p = st.lam / m.contact_areas()
    nu = 0.3
    expected = (1 - nu) / ((1 + nu) * (1 - 2 * nu)) * 0.01
    for k in range(2):
        mine = m.body.pair_of == k
        assert mine.sum() == 56 and np.abs(p[mine] / expected - 1).max() <= 1e-10, (k, p[mine])
    assert np.abs(st.tau).max() <= 1e-10 * st.lam.max()


def test_the_state_of_a_model_of_rigid_counterparts_only_is_written_without_a_foundation(tmp_path):
    """``contactopt state`` on the block between the plane and the lid: no counterpart body, so no
    foundation.vtu or foundation.png (there is no mesh to write)."""
    from contactopt.cli import main
    _squeezed(tmp_path, 'control = "displacement", displacement = [0.0, 0.0, -0.01]')
    assert main(["state", str(tmp_path / "squeezed.toml"), "--out", str(tmp_path / "out")]) in (0, None)
    written = {p.name for p in (tmp_path / "out").iterdir()}
    assert {"state.json", "body.vtu", "pressure.png"} <= written and not written & {"foundation.vtu", "foundation.png"}
