"""Assemblies of several contact pairs on one face body (fem/counterparts.py): a monolithic model
of three bodies built here, a floating roller between two plates against Hertz, subgradients and
bad input.

Conventions: per contact node (t1, t2, ν) in the node's frame, ν from the counterpart to the face
body; r the contact force on the face body, λ = r_ν ≥ 0, τ = −r_t; each counterpart carries −r at
its partners; w = u_face − u_partner. Pairs in [[contacts]] order.
"""

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.contact.local import solve_local
from contactopt.contact.state import FROM_FCLIB, TO_FCLIB, classify_nodes
from contactopt.fem.elasticity import ElasticityAssembler
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

# a block (Example 1's, 8 × 4 × 4) on two slabs side by side whose top nodes match its face's
TWO_SLABS = """
name = "two_slabs"
[geometry]
a = 2.0
b = 1.0
c = 1.0
[mesh]
nx = 8
ny = 4
nz = 4
[material]
E = 21.19
nu = 0.277
[loads]
top_traction = [0.0, 0.0, -8.0e-2]
right_traction = [4.0e-2, 0.01, 0.0]
[bodies.block]
clamped = "clamped"
[bodies.left]
block = { size = [1.5, 2.0, 1.0], cells = [6, 8, 2], origin = [-0.5, -0.5] }
clamped = "bottom"
material = { E = 2.119 }
[bodies.right]
block = { size = [1.25, 2.0, 0.75], cells = [5, 8, 3], origin = [1.25, -0.5] }
clamped = "bottom"
material = { E = 6.0, nu = 0.35 }
[[contacts]]
name = "left"
face = { body = "block", x3 = 0.0, box = [[0.0, 1.1], [0.0, 1.0], [-1.0, 1.0]] }
counterpart = "left.top"
friction = 0.3
[[contacts]]
name = "right"
face = { body = "block", x3 = 0.0, box = [[1.1, 2.0], [0.0, 1.0], [-1.0, 1.0]] }
counterpart = "right.top"
friction = 0.3
[state]
tol = 1.0e-14
max_iter = 200
"""

DESIGN = """
[[designs]]
face = "block.contact"
degree = [3, 2]
C0 = 0.2
C1 = 0.5
C2 = 0.01
initial = 0.01
"""


def _write(tmp_path, text, name="model.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _monolithic_state(pb, alpha):
    """λ, τ, w and classes of the block on its two slabs, built without contactopt's counterpart
    code and in the other form: the three stiffnesses in one block matrix (each slab with its own
    material), the Delassus operator W = B K⁻¹ Bᵀ of the relative displacements w = u_block − u_slab
    at the coinciding nodes by sparse solves, the same local solver with the same coefficient."""
    model = pb.model
    asm_b = model.assemble(alpha)
    nb = model.body.reference.n_nodes
    blocks, loads, fixed, offset = [], [asm_b.L_full], [model.body.fixed_dofs], 3 * nb
    mat = pb.config.material
    blocks.append(ElasticityAssembler(model.body.reference.cells, nb, np.zeros(0, int), mat.E, mat.nu)
                  .full_stiffness(asm_b.coords))
    partner = np.full(model.n_contact, -1)
    x_b = model.body.reference.points[model.contact_nodes]
    for k, spec in enumerate(pb.config.pairs):
        ref = model.foundation.parts[k].mesh.reference
        f = spec.foundation
        blocks.append(ElasticityAssembler(ref.cells, ref.n_nodes, np.zeros(0, int), f.material.E, f.material.nu)
                      .full_stiffness(ref.points))
        loads.append(np.zeros(3 * ref.n_nodes))
        bottom = np.flatnonzero(np.isclose(ref.points[:, 2], ref.points[:, 2].min()))
        fixed.append(offset + (3 * bottom[:, None] + np.arange(3)).ravel())
        rows = np.flatnonzero(model.body.pair_of == k)
        d = np.linalg.norm(ref.points[None, :, :] - x_b[rows, None, :], axis=2)
        assert np.allclose(d.min(axis=1), 0.0)           # matching meshes: a node under every contact node
        partner[rows] = offset // 3 + np.argmin(d, axis=1)
        offset += 3 * ref.n_nodes
    K, L = sp.block_diag(blocks).tocsr(), np.concatenate(loads)
    free = np.setdiff1d(np.arange(K.shape[0]), np.concatenate(fixed))
    index = np.full(K.shape[0], -1)
    index[free] = np.arange(free.size)
    # the compliance form: w = B u with B = (the block's DOF − its partner's DOF) per contact DOF,
    # W = B K⁻¹ Bᵀ and the relative displacement without contact forces w0 = B K⁻¹ L
    p = model.n_contact
    pb_dofs = (3 * model.contact_nodes[:, None] + np.arange(3)).ravel()
    pf_dofs = (3 * partner[:, None] + np.arange(3)).ravel()
    rows = np.arange(3 * p)
    B = sp.csr_matrix((np.r_[np.ones(3 * p), -np.ones(3 * p)], (np.r_[rows, rows], np.r_[index[pb_dofs],
                                                                                            index[pf_dofs]])),
                      shape=(3 * p, free.size))
    lu = sla.splu(K[free][:, free].tocsc())
    W = B @ lu.solve(B.T.toarray())
    W = 0.5 * (W + W.T)
    w0 = B @ lu.solve(L[free])
    perm = (3 * np.arange(p)[:, None] + TO_FCLIB).ravel()        # (t1, t2, ν) → (ν, t1, t2)
    q = w0[perm]
    q[0::3] += asm_b.gap
    res = solve_local(W[np.ix_(perm, perm)], q, pb.friction, tol=1e-14, max_iter=200)
    r = res.r.reshape(p, 3)[:, FROM_FCLIB]
    w = (w0 + W @ r.ravel()).reshape(p, 3)
    lam, tau = r[:, 2], -r[:, :2]
    return lam, tau, w, classify_nodes(w, lam, tau, asm_b.gap, pb.friction)


@pytest.mark.parametrize("left", [0.3, 0.0])
def test_two_pairs_agree_with_a_monolithic_model_of_three_bodies(left, tmp_path):
    """A block on two slabs of other materials, the right pair with friction 0.3 and the left one
    with 0.3 or none, at the reference shape and a designed one: λ, τ and w to 1e-10 of a
    monolithic model of the three bodies (its local solver given the same coefficient per node);
    slip, stick and separation all present; no tangential force on a frictionless pair."""
    text = TWO_SLABS.replace("friction = 0.3", f"friction = {left}", 1)
    pb = ShapeProblem(load_config(_write(tmp_path, text + DESIGN)))
    pair = pb.model.body.pair_of
    assert np.array_equal(np.atleast_1d(pb.friction) * np.ones(pair.size), np.where(pair == 0, left, 0.3))
    assert [f.partner for f in pb.model.foundation.parts] == ["point", "point"]
    rng = np.random.default_rng(2)
    for alpha in (pb.model.initial_design(), pb.model.initial_design() + 0.004 * rng.standard_normal(pb.model.n_design)):
        st = pb.solve_state(alpha)
        lam, tau, w, classes = _monolithic_state(pb, alpha)
        scale = lam.max()
        assert np.abs(st.lam - lam).max() <= 1e-10 * scale
        assert np.abs(st.tau - tau).max() <= 1e-10 * scale
        assert np.abs(st.u_c - w).max() <= 1e-10 * np.abs(w).max()
        assert np.array_equal(st.classes, classes)
    for k in range(2):                       # both pairs carry load
        assert lam[pair == k].sum() > 0.03 * lam.sum()
    if left == 0.0:
        assert np.all(st.tau[pair == 0] == 0.0) and np.abs(st.tau[pair == 1]).max() > 0.1 * scale


def test_subgradient_with_two_pairs_matches_central_differences(tmp_path):
    """ξ·d of a design on the block's face against Richardson central differences to 1e-6, with
    sliding, sticking and free nodes on both pairs."""
    pb = ShapeProblem(load_config(_write(tmp_path, TWO_SLABS + DESIGN)))
    a = pb.model.initial_design()
    alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    gc = check_gradient(pb, alpha, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0


def _hertz(pb, st):
    """Per pair (P′, b, p0, b_Hertz, p0_Hertz) of the half model one element long (LEN) in plane
    strain: P′ = 2Σλ n3 / LEN, (b, p0) fitted to p² = p0²(1 − x1²/b²) (verification.hertz.fit)."""
    from contactopt.verification.hertz import fit
    m = pb.model
    x = m.body.reference.points[m.contact_nodes]
    p = st.lam / m.contact_areas()
    n3 = np.abs(m.frames[:, 2, 2])
    length = np.ptp(m.body.reference.points[:, 1])
    E, nu = pb.config.material.E, pb.config.material.nu
    E_star = E / (2 * (1 - nu ** 2))                 # two bodies of one material
    radius = m.body.chart.radius
    out = []
    for k in range(2):
        s = m.body.pair_of == k
        P1 = 2 * float(st.lam[s] @ n3[s]) / length
        b, p0 = fit(np.abs(x[s, 0]), p[s])
        bH = math.sqrt(4 * P1 * radius / (math.pi * E_star))
        out.append((P1, b, p0, bH, 2 * P1 / (math.pi * bH)))
    return out


def test_a_floating_roller_between_two_plates_is_hertzian_on_both_sides():
    """The roller held only by its two contacts (examples/roller_plates.toml): the two pairs' forces
    equal to 1e-8 (the roller's balance), the half-width and peak pressure on both sides against
    Hertz's b = √(4P′R/(πE*)), p0 = 2P′/(πb) (measured: b −0.8 %, p0 +2.0 %; docs/assemblies.md)."""
    pb = ShapeProblem(load_config(EXAMPLES / "roller_plates.toml"))
    assert pb.model.body.rigid is not None and pb.model.body.rigid.names() == ["the translation along x3"]
    st = pb.solve_state(pb.model.initial_design())
    (P0, b0, p00, bH0, pH0), (P1, b1, p01, bH1, pH1) = _hertz(pb, st)
    assert abs(P0 - P1) <= 1e-8 * P0
    for b, p0, bH, pH in ((b0, p00, bH0, pH0), (b1, p01, bH1, pH1)):
        assert abs(b / bH - 1) < 0.015 and abs(p0 / pH - 1) < 0.03
    assert (st.lam > 0).sum() >= 30


def test_a_node_claimed_by_two_pairs_is_refused(tmp_path, capsys):
    text = TWO_SLABS.replace("box = [[1.1, 2.0]", "box = [[0.9, 2.0]")
    out = tmp_path / "out"
    assert main(["state", str(_write(tmp_path, text)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "contacts[1].face and contacts[0].face: 5 node(s) are claimed by both pairs" in err, err
    assert not out.exists()


def test_several_pairs_are_refused_by_the_paths_that_do_not_take_them(tmp_path):
    from contactopt.errors import ConfigError
    text = TWO_SLABS + '[linear_solver]\npath = "delassus"\n'
    with pytest.raises(ConfigError, match="2 contact pairs against elastic bodies"):
        ShapeProblem(load_config(_write(tmp_path, text)))


# ------------------------------------------------------------------ the contact patch test across two interfaces
def _box_file(path, size, cells, origin, lift):
    """A generated box ([foundation] block's, parts top, bottom, left, right, front, back) lifted by
    ``lift`` along x3, as a Gmsh file: a body above another."""
    import meshio

    from contactopt.mesh.foundation import foundation_block
    ref = foundation_block(size, cells, origin)
    names = ("top", "bottom", "left", "right", "front", "back")
    blocks = [("quad", ref.parts[n].faces) for n in names] + [(ref.cell_type, ref.cells)]
    phys = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {n: np.array([t, 2]) for t, n in enumerate(names, start=1)} | {"box": np.array([len(blocks), 3])}
    meshio.write(path, meshio.Mesh(ref.points + [0.0, 0.0, lift], blocks, cell_data={"gmsh:physical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)
    return path


def _rollers(left="left", extra=""):
    """u1 = 0 on the faces x1 = 0, 1 and u2 = 0 on x2 = 0, 1 (symmetry rollers), as a TOML list."""
    return (f'[ {extra}{{ on = "{left}", components = [1] }}, {{ on = "right", components = [1] }}, '
            '{ on = "front", components = [2] }, { on = "back", components = [2] } ]')


def _stack(tmp_path, friction):
    """Three unit blocks stacked, each its own grid (5 × 4, 7 × 6 and 4 × 5 cells across, their nodes
    offset): the lower held at its bottom, the middle and the upper held in x3 only by their
    contacts, rollers on every side; a pressure p = 0.01 on the top. Mortar partners."""
    _box_file(tmp_path / "upper.msh", [1.0, 1.0, 1.0], [4, 5, 2], [0.0, 0.0], 2.0)
    text = f"""
name = "stack"
[geometry]
a = 1.0
b = 1.0
c = 1.0
[mesh]
nx = 7
ny = 6
nz = 3
[material]
E = 1.0
nu = 0.3
[bodies.middle]
clamped = {_rollers("clamped")}
[bodies.lower]
block = {{ size = [1.0, 1.0, 1.0], cells = [5, 4, 3], origin = [0.0, 0.0] }}
clamped = {_rollers(extra='{ on = "bottom", components = [1, 2, 3] }, ')}
material = {{ E = 2.0, nu = 0.25 }}
[bodies.upper]
mesh = "upper.msh"
clamped = {_rollers()}
material = {{ E = 0.5, nu = 0.35 }}
[[loads.pressure]]
on = "upper.top"
value = 0.01
[[contacts]]
face = "middle.contact"
counterpart = "lower.top"
friction = {friction}
partner = "mortar"
[[contacts]]
face = "middle.top"
counterpart = "upper.bottom"
friction = {friction}
partner = "mortar"
[state]
tol = 1.0e-14
max_iter = 200
"""
    return ShapeProblem(load_config(_write(tmp_path, text)))


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_the_contact_patch_test_passes_across_two_interfaces(friction, tmp_path):
    """Uniform pressure p on both interfaces to 1e-8 relative and ‖τ‖ ≤ 1e-8 λ at every node, with
    non-matching and offset grids, the middle and upper blocks held in x3 only by their contacts."""
    pb = _stack(tmp_path, friction)
    m = pb.model
    assert m.body.rigid is not None and m.foundation.kernel()[1] == [
        "the translation along x3 of the counterpart of contacts[1]"]
    assert [f.partner for f in m.foundation.parts] == ["mortar", "mortar"]
    st = pb.solve_state(m.initial_design())
    p = st.lam / m.contact_areas()
    for k in range(2):
        mine = m.body.pair_of == k
        assert np.abs(p[mine] / 0.01 - 1).max() <= 1e-8, (k, p[mine])
        assert st.lam[mine].sum() == pytest.approx(0.01, rel=1e-10)
    assert np.all(np.linalg.norm(st.tau, axis=1) <= 1e-8 * st.lam)


def test_a_pressure_objective_of_one_pair_reads_its_nodes_alone(tmp_path):
    """max_pressure (KS) over the pair "left" alone: its value that of the pair's nodes, the
    subgradient against central differences; an unknown pair is refused by name."""
    obj = '[objective]\ntype = "max_pressure"\naggregate = "ks"\nrho = 200.0\ncontacts = ["left"]\n'
    pb = ShapeProblem(load_config(_write(tmp_path, TWO_SLABS + DESIGN + obj)))
    alpha = pb.model.initial_design()
    st = pb.solve_state(alpha)
    p = st.lam / pb.model.contact_areas()
    left, right = p[pb.model.body.pair_of == 0], p[pb.model.body.pair_of == 1]
    assert right.max() > 10 * left.max()             # the objective is not the peak of all pairs
    value = pb.evaluate_value(alpha)
    assert left.max() < value <= left.max() + np.log(left.size) / 200.0
    gc = check_gradient(pb, alpha + 0.002 * np.random.default_rng(3).standard_normal(alpha.size),
                        n_directions=2, seed=1)
    assert gc.passed, gc.rel_errors
    bad = obj.replace('["left"]', '["left", "middle", 7]')
    with pytest.raises(Exception, match=r"objective.contacts: 'middle', 7 is no contact pair of the model \(pairs: "
                                        r"0 'left', 1 'right'\)"):
        ShapeProblem(load_config(_write(tmp_path, TWO_SLABS + DESIGN + bad)))


def test_a_floating_body_whose_motion_nothing_holds_is_refused_by_name(tmp_path, capsys):
    """The right slab held only in x3 at its bottom, both pairs without friction: exit 2 naming the
    body and each motion no contact force holds, nothing written."""
    text = TWO_SLABS.replace("friction = 0.3", "friction = 0.0")
    text = text.replace('[bodies.right]\nblock = { size = [1.25, 2.0, 0.75], cells = [5, 8, 3], origin = [1.25, -0.5] }\n'
                        'clamped = "bottom"', '[bodies.right]\nblock = { size = [1.25, 2.0, 0.75], cells = [5, 8, 3], '
                        'origin = [1.25, -0.5] }\nclamped = [ { on = "bottom", components = [3] } ]')
    out = tmp_path / "out"
    assert main(["state", str(_write(tmp_path, text)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    for motion in ("the translation along x1", "the translation along x2"):
        assert f"bodies.right: {motion} is not held: the body is held only by its contacts, and no contact force " \
               "of contacts[1] acts along it" in err, err
    assert "bodies.left" not in err
    assert not out.exists()


# ------------------------------------------------------------------ a joint slips as a whole at Q = F·N
def _joint(q_ratio, cells, friction=0.2, p=0.01):
    """A plate (1 × 1 × 0.25) on a slab, held in x1 and x3 only by its contact (u2 = 0 on its front
    and back faces and the slab's), pressed by p on its top, then sheared along x1 by a traction
    on its end face whose resultant is q_ratio·F·N (N = p, the plate's area 1): a load path of two
    steps. Returns the state of its end, or the error that says the plate is not held."""
    from contactopt.errors import ContactOptError
    n, nz = cells
    shear = q_ratio * friction * p / 0.25
    text = f"""
name = "joint"
[geometry]
a = 1.0
b = 1.0
c = 0.25
[mesh]
nx = {n}
ny = {n}
nz = {nz}
[material]
E = 1.0
nu = 0.3
[bodies.plate]
clamped = [ {{ on = "front", components = [2] }}, {{ on = "back", components = [2] }} ]
[bodies.base]
block = {{ size = [1.2, 1.0, 0.5], cells = [{n + 1}, {n}, {nz}], origin = [-0.1, 0.0] }}
clamped = [ {{ on = "bottom", components = [1, 2, 3] }}, {{ on = "front", components = [2] }},
            {{ on = "back", components = [2] }} ]
[[contacts]]
face = "plate.contact"
counterpart = "base.top"
friction = {friction}
partner = "mortar"
[[load_steps]]
name = "press"
top_traction = [0.0, 0.0, {-p}]
[[load_steps]]
name = "shear"
top_traction = [0.0, 0.0, {-p}]
right_traction = [{shear}, 0.0, 0.0]
[state]
tol = 1.0e-12
max_iter = 400
"""
    text = text.replace(",\n            {", ", {")
    try:
        pb = ShapeProblem(load_config(_write_text(text)))
        return pb.solve_states(pb.model.initial_design())[-1], pb
    except ContactOptError as exc:
        return exc, None


def _write_text(text):
    import tempfile
    path = Path(tempfile.mkdtemp()) / "joint.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("cells", [(6, 2), (10, 3)])
def test_a_clamped_joint_slips_as_a_whole_at_the_coulomb_load(cells):
    """Below Q = F·N the plate is held, and nodes stick; the shear at which it is no longer held
    (bisection on Q/FN to 2e-3) lies within 1 % of F·N, the sliding nodes' share rising on the way
    and, at the last shear held, every node carrying nearly its whole Coulomb limit. (Whether Q =
    F·N itself is held, with every node sliding, is decided by round-off: under some BLAS kernels
    the last shear held is 0.998 F·N, with 91 % of the nodes sliding and the others at ≥ 96 % of
    their limit.)"""
    lo, hi = 0.9, 1.1
    st, pb = _joint(lo, cells)
    assert pb is not None, st
    share = [np.mean(st.class_names[st.lam > 0] == "M1")]
    assert share[0] < 1.0
    bad, _ = _joint(hi, cells)
    assert "not held" in str(bad), bad
    while hi - lo > 2e-3:
        mid = 0.5 * (lo + hi)
        st, pb = _joint(mid, cells)
        if pb is None:
            assert "not held" in str(st), st
            hi = mid
        else:
            lo = mid
            touching = st.lam > 0
            share.append(np.mean(st.class_names[touching] == "M1"))
            mobilized = np.linalg.norm(st.tau, axis=1)[touching] / (0.2 * st.lam[touching])
            assert np.sum(st.lam) == pytest.approx(0.01, rel=1e-9)      # N, the pressure's resultant
    assert abs(0.5 * (lo + hi) - 1.0) < 0.01, (lo, hi)
    assert share[-1] >= 0.9 and share[-1] > share[0] and mobilized.min() >= 0.95, (share, mobilized.min())


def test_a_run_writes_a_file_per_body_and_maps_per_pair(tmp_path):
    """bodies.pvd holds the face body and each counterpart body as its own part, each counterpart's
    file its own mesh; summary.json reports each pair."""
    import json

    import meshio
    cfg = _write(tmp_path, TWO_SLABS + DESIGN)
    out = tmp_path / "run"
    assert main(["run", str(cfg), "--out", str(out), "--max-iter", "1"]) == 0
    pvd = (out / "bodies.pvd").read_text()
    for name, part in (("initial.vtu", 0), ("initial_left.vtu", 1), ("optimal_right.vtu", 2)):
        assert f'part="{part}" file="{name}"' in pvd, pvd
    pb = ShapeProblem(load_config(cfg))
    for k, name in enumerate(("left", "right")):
        mesh = meshio.read(out / f"optimal_{name}.vtu")
        assert mesh.points.shape[0] == pb.model.foundation.parts[k].n_nodes
        assert "pair" not in mesh.point_data and "displacement" in mesh.point_data
    summary = json.loads((out / "summary.json").read_text())
    assert [c["name"] for c in summary["contacts"]["optimal"]] == ["left", "right"]
    assert sum(c["nodes"] for c in summary["contacts"]["optimal"]) == pb.model.n_contact


def test_subgradient_with_two_pairs_along_a_load_path_matches_central_differences(tmp_path):
    """Pressed, then sheared: each step's body displacement comes from that step's load (the
    pairs' counterparts condensed on their support), ξ·d against central differences to 1e-6."""
    import tomllib
    text = TWO_SLABS + DESIGN + (
        '[[load_steps]]\nname = "press"\ntop_traction = [0.0, 0.0, -8.0e-2]\n'
        '[[load_steps]]\nname = "shear"\ntop_traction = [0.0, 0.0, -8.0e-2]\nright_traction = [4.0e-2, 0.01, 0.0]\n'
        '[objective]\ntype = "pressure_uniformity"\n')
    data = tomllib.loads(text)
    data["loads"] = {}
    pb = ShapeProblem(load_config(data))
    a = pb.model.initial_design()
    alpha = a + 0.002 * np.random.default_rng(0).standard_normal(a.size)
    gc = check_gradient(pb, alpha, n_directions=2, seed=0)
    assert gc.n_degenerate == 0 and gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0


@pytest.mark.parametrize("objective", ["compliance", "frictional_dissipation"])
def test_whole_displacement_objectives_of_the_lap_joint_match_central_differences(objective):
    """The lap joint (examples/lap_joint.toml): a floating plate between the bolt head above it and
    the lower plate below it (their nodes' frames opposite), the design on the plate's underside
    only, along the load path: ξ·d of the compliance and of the friction work against central
    differences to 1e-6 (both take the frames' rotation of the contact vectors they place on the
    body's DOFs)."""
    data = load_config(EXAMPLES / "lap_joint.toml").to_dict()
    data["objective"] = {"type": objective, "scale": 1.0e8}
    pb = ShapeProblem(load_config(data))
    rng = np.random.default_rng(0)
    a = pb.model.initial_design()
    alpha = a + 0.0002 * rng.standard_normal(a.size)
    _, xi = pb.evaluate(alpha)
    for _ in range(2):
        d = rng.standard_normal(a.size)
        d /= np.linalg.norm(d)
        h = 1e-6                                # Richardson's central differences at h and 2h
        f1 = (pb.evaluate_value(alpha + h * d) - pb.evaluate_value(alpha - h * d)) / (2 * h)
        f2 = (pb.evaluate_value(alpha + 2 * h * d) - pb.evaluate_value(alpha - 2 * h * d)) / (4 * h)
        fd = (4 * f1 - f2) / 3
        assert abs(xi @ d - fd) <= 1e-6 * max(abs(fd), np.abs(xi).max() * 1e-3), (xi @ d, fd)


def test_the_peak_stress_region_names_its_body(tmp_path):
    """region = "block.right" is the block's part "right", "block" the whole block; a counterpart body's
    part is that body's (tests/test_assembly_rigid.py), its stress none of the block's."""
    def value(region):
        obj = f'[objective]\ntype = "peak_stress"\nregion = "{region}"\n'
        pb = ShapeProblem(load_config(_write(tmp_path, TWO_SLABS + DESIGN + obj)))
        return pb.evaluate_value(pb.model.initial_design())
    assert value("block.right") == value("right") < value("block") == value("")
    assert 0 < value("left.top") not in (value("block"), value("right"))
