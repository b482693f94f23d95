"""A counterpart body shared by several contact pairs (fem/counterparts.py): condensed once onto the
union of its pairs' supports, each pair's partners on its own part. Checked against one pair on
the union of the faces, against a monolithic model built here, and against the same pairs on two
separate copies of the body (the coupling through the shared body matters).

Conventions: per contact node (t1, t2, ν) in the node's frame, ν from the counterpart to the face
body; r the contact force on the face body, λ = r_ν ≥ 0, τ = −r_t; w = u_face − u_partner.
"""

from pathlib import Path

import meshio
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from contactopt.config import load_config
from contactopt.contact.local import solve_local
from contactopt.contact.state import FROM_FCLIB, TO_FCLIB
from contactopt.errors import ConfigError
from contactopt.fem.elasticity import ElasticityAssembler
from contactopt.mesh.foundation import foundation_block
from contactopt.problem import ShapeProblem

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

# a block (8 × 4 × 4 cells, 2 × 1 × 1) on a base whose top nodes match its face's; the base's top
# split at x1 = 1.1 into the parts top_left and top_right (and whole as top)
BLOCK = """
name = "shared"
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
{bases}
{contacts}
[[designs]]
face = "block.contact"
degree = [3, 2]
C0 = 0.2
C1 = 0.5
C2 = 0.01
initial = 0.01
[state]
tol = 1.0e-14
max_iter = 200
"""

BASE = """[bodies.{name}]
mesh = "base.msh"
clamped = "bottom"
material = {{ E = 3.0, nu = 0.3 }}
"""

PAIR = """[[contacts]]
name = "{name}"
face = {{ body = "block", x3 = 0.0, box = [[{lo}, {hi}], [0.0, 1.0], [-1.0, 1.0]] }}
counterpart = "{counterpart}"
friction = {friction}
"""


def _base_file(path):
    """The base: a box 3 × 2 × 1 (12 × 8 × 2 cells) under the block, its top x3 = 0, with the
    parts top, top_left (x1 < 1.1), top_right, bottom."""
    ref = foundation_block([3.0, 2.0, 1.0], [12, 8, 2], [-0.5, -0.5])
    top = ref.parts["top"].faces
    left = ref.points[top].mean(axis=1)[:, 0] < 1.1
    groups = {"top": top, "top_left": top[left], "top_right": top[~left], "bottom": ref.parts["bottom"].faces}
    blocks = [("quad", f) for f in groups.values()] + [(ref.cell_type, ref.cells)]
    phys = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {n: np.array([t, 2]) for t, n in enumerate(groups, start=1)} | {"base": np.array([len(blocks), 3])}
    meshio.write(path, meshio.Mesh(ref.points, blocks, cell_data={"gmsh:physical": phys}, field_data=fd),
                 file_format="gmsh22", binary=False)


def _problem(tmp_path, layout, friction=(0.3, 0.3)):
    """The block on the base: ``layout`` 'shared' (two pairs, the base's top_left and top_right),
    'union' (one pair, the whole faces) or 'copies' (two pairs, each on its own copy of the base)."""
    _base_file(tmp_path / "base.msh")
    if layout == "union":
        bases = BASE.format(name="base")
        contacts = (PAIR.format(name="all", lo=0.0, hi=2.0, counterpart="base.top", friction=friction[0])
                    .replace('{ body = "block", x3 = 0.0, box = [[0.0, 2.0], [0.0, 1.0], [-1.0, 1.0]] }', '"block.contact"'))
    else:
        names = ("base", "base") if layout == "shared" else ("base", "copy")
        bases = "".join(BASE.format(name=n) for n in dict.fromkeys(names))
        contacts = (PAIR.format(name="left", lo=0.0, hi=1.1, counterpart=f"{names[0]}.top_left", friction=friction[0])
                    + PAIR.format(name="right", lo=1.1, hi=2.0, counterpart=f"{names[1]}.top_right",
                                  friction=friction[1]))
    path = tmp_path / f"{layout}.toml"
    path.write_text(BLOCK.format(bases=bases, contacts=contacts))
    return ShapeProblem(load_config(path))


def _designs(pb):
    a = pb.model.initial_design()
    return a, a + 0.004 * np.random.default_rng(2).standard_normal(a.size)


def test_two_pairs_on_one_body_agree_with_one_pair_on_the_union(tmp_path):
    """The base under both halves of the block's face as two pairs (one body, condensed once) and as
    one pair on the whole face: λ, τ, w to 1e-12 at the reference shape and a designed one; the
    shared body is one foundation whose compliance couples the two pairs' nodes."""
    shared, union = _problem(tmp_path, "shared"), _problem(tmp_path, "union")
    f = shared.model.foundation
    assert len(f.parts) == 1 and f.pairs == [[0, 1]] and f.parts[0].partner == "point"
    pair = shared.model.body.pair_of
    assert np.array_equal(f.rows[0], np.r_[np.flatnonzero(pair == 0), np.flatnonzero(pair == 1)])
    d0, d1 = ((3 * np.flatnonzero(pair == k)[:, None] + np.arange(3)).ravel() for k in range(2))
    off = np.abs(f.C[np.ix_(d0, d1)]).max()
    assert off > 0.05 * np.abs(f.C).max()          # the halves talk through the base
    assert np.array_equal(shared.model.contact_nodes, union.model.contact_nodes)
    for alpha in _designs(shared):
        a, b = shared.solve_state(alpha), union.solve_state(alpha)
        scale = b.lam.max()
        assert np.abs(a.lam - b.lam).max() <= 1e-12 * scale
        assert np.abs(a.tau - b.tau).max() <= 1e-12 * scale
        assert np.abs(a.u_c - b.u_c).max() <= 1e-12 * np.abs(b.u_c).max()
        assert np.array_equal(a.classes, b.classes)
    for k in range(2):
        assert a.lam[pair == k].sum() > 0.05 * a.lam.sum()


def _monolithic_state(pb, alpha):
    """λ, τ and w of the block on the base, built without contactopt's counterpart code: both
    stiffnesses in one block matrix, the Delassus operator W = B K⁻¹ Bᵀ of the relative
    displacements at the coinciding nodes by sparse solves, the same local solver."""
    model = pb.model
    asm = model.assemble(alpha)
    nb = model.body.reference.n_nodes
    mat = pb.config.material
    ref = meshio.read(Path(pb.config.source).parent / "base.msh")
    pts, hexes = ref.points, ref.cells_dict["hexahedron"]
    blocks = [ElasticityAssembler(model.body.reference.cells, nb, np.zeros(0, int), mat.E, mat.nu)
              .full_stiffness(asm.coords),
              ElasticityAssembler(hexes, pts.shape[0], np.zeros(0, int), 3.0, 0.3).full_stiffness(pts)]
    bottom = np.flatnonzero(np.isclose(pts[:, 2], pts[:, 2].min()))
    fixed = np.r_[model.body.fixed_dofs, 3 * nb + (3 * bottom[:, None] + np.arange(3)).ravel()]
    K, L = sp.block_diag(blocks).tocsr(), np.r_[asm.L_full, np.zeros(3 * pts.shape[0])]
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)
    index = np.full(K.shape[0], -1)
    index[free] = np.arange(free.size)
    x = model.body.reference.points[model.contact_nodes]
    d = np.linalg.norm(pts[None] - x[:, None], axis=2)
    assert np.allclose(d.min(axis=1), 0.0)
    partner = nb + np.argmin(d, axis=1)
    p = model.n_contact
    a_dofs = (3 * model.contact_nodes[:, None] + np.arange(3)).ravel()
    b_dofs = (3 * partner[:, None] + np.arange(3)).ravel()
    rows = np.arange(3 * p)
    B = sp.csr_matrix((np.r_[np.ones(3 * p), -np.ones(3 * p)], (np.r_[rows, rows], np.r_[index[a_dofs],
                                                                                            index[b_dofs]])),
                      shape=(3 * p, free.size))
    lu = sla.splu(K[free][:, free].tocsc())
    W = B @ lu.solve(B.T.toarray())
    W = 0.5 * (W + W.T)
    w0 = B @ lu.solve(L[free])
    perm = (3 * np.arange(p)[:, None] + TO_FCLIB).ravel()
    q = w0[perm]
    q[0::3] += asm.gap
    res = solve_local(W[np.ix_(perm, perm)], q, pb.friction, tol=1e-14, max_iter=200)
    r = res.r.reshape(p, 3)[:, FROM_FCLIB]
    w = (w0 + W @ r.ravel()).reshape(p, 3)
    return r[:, 2], -r[:, :2], w


@pytest.mark.parametrize("left", [0.3, 0.0])
def test_two_pairs_on_one_body_agree_with_a_monolithic_model(left, tmp_path):
    """The left pair with friction 0.3 or none, the right one 0.3: λ, τ, w to 1e-10 of the two
    bodies in one matrix (its local solver given the same coefficient per node)."""
    pb = _problem(tmp_path, "shared", friction=(left, 0.3))
    for alpha in _designs(pb):
        st = pb.solve_state(alpha)
        lam, tau, w = _monolithic_state(pb, alpha)
        scale = lam.max()
        assert np.abs(st.lam - lam).max() <= 1e-10 * scale
        assert np.abs(st.tau - tau).max() <= 1e-10 * scale
        assert np.abs(st.u_c - w).max() <= 1e-10 * np.abs(w).max()
    if left == 0.0:
        assert np.all(st.tau[pb.model.body.pair_of == 0] == 0.0)


def test_two_pairs_on_one_body_differ_from_two_copies_of_it(tmp_path):
    """The same two pairs, each on its own copy of the base: two bodies, no coupling between the
    halves, a stiffer support; the contact forces differ by more than 5 % of the peak, and the
    shared body's state is not the copies' (the off-diagonal blocks of C matter)."""
    shared, copies = _problem(tmp_path, "shared"), _problem(tmp_path, "copies")
    assert len(copies.model.foundation.parts) == 2 and copies.model.foundation.pairs == [[0], [1]]
    alpha = _designs(shared)[1]
    a, b = shared.solve_state(alpha), copies.solve_state(alpha)
    assert np.abs(a.lam - b.lam).max() > 0.05 * a.lam.max()
    assert np.abs(a.u_c - b.u_c).max() > 0.05 * np.abs(a.u_c).max()


def test_one_part_as_the_counterpart_of_two_pairs_is_refused(tmp_path):
    _base_file(tmp_path / "base.msh")
    contacts = (PAIR.format(name="left", lo=0.0, hi=1.1, counterpart="base.top", friction=0.3)
                + PAIR.format(name="right", lo=1.1, hi=2.0, counterpart="base.top", friction=0.3))
    path = tmp_path / "twice.toml"
    path.write_text(BLOCK.format(bases=BASE.format(name="base"), contacts=contacts))
    with pytest.raises(ConfigError, match=r"contacts\[1\].counterpart = 'base.top': is already the counterpart of "
                                          r"contacts\[0\]; two pairs on one body meet it on two parts"):
        load_config(path)


def test_a_shared_body_held_by_its_contacts_alone_is_named_with_its_pairs(tmp_path):
    """The base held only in x3 at its bottom, both pairs frictionless: its translations along x1
    and x2 are refused by name, with both its pairs."""
    _base_file(tmp_path / "base.msh")
    text = BLOCK.format(bases=BASE.format(name="base").replace(
        'clamped = "bottom"', 'clamped = [ { on = "bottom", components = [3] } ]'),
        contacts=PAIR.format(name="left", lo=0.0, hi=1.1, counterpart="base.top_left", friction=0.0)
        + PAIR.format(name="right", lo=1.1, hi=2.0, counterpart="base.top_right", friction=0.0))
    path = tmp_path / "floating.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=r"bodies.base: the translation along x1 is not held: the body is held only "
                                          r"by its contacts, and no contact force of contacts\[0\] and contacts\[1\] "
                                          r"acts along it \(it moves no contact node along its normal, and its pairs "
                                          r"have no friction\)"):
        ShapeProblem(load_config(path))


def test_a_run_writes_one_file_per_body_and_reports_each_pair(tmp_path):
    """bodies.pvd holds the block and the shared base once, the base's file its mesh with both
    pairs' contact forces; summary.json reports each pair."""
    import json

    from contactopt.cli import main
    pb = _problem(tmp_path, "shared")
    out = tmp_path / "run"
    assert main(["run", str(tmp_path / "shared.toml"), "--out", str(out), "--max-iter", "1"]) == 0
    pvd = (out / "bodies.pvd").read_text()
    assert 'part="1" file="optimal_base.vtu"' in pvd and 'part="2"' not in pvd, pvd
    mesh = meshio.read(out / "optimal_base.vtu")
    assert mesh.points.shape[0] == pb.model.foundation.parts[0].n_nodes
    force = mesh.point_data["contact_force"]
    top_left = mesh.points[:, 2] > -1e-9
    assert (np.abs(force[top_left & (mesh.points[:, 0] < 1.1), 2]).max() > 0
            and np.abs(force[top_left & (mesh.points[:, 0] > 1.1), 2]).max() > 0)
    summary = json.loads((out / "summary.json").read_text())
    assert [c["name"] for c in summary["contacts"]["optimal"]] == ["left", "right"]
    assert sum(c["nodes"] for c in summary["contacts"]["optimal"]) == pb.model.n_contact


def test_the_dovetail_flanks_carry_mirror_forces():
    """examples/dovetail.toml at its reference shape: the blade held by both flanks against the one
    slot body; by the mirror symmetry of the meshes the flanks' normal forces agree to 1e-10 (and
    their tangential ones up to the sign along the slope), and λ at mirror nodes to 1e-10; both
    flanks' resultants together hold the body force."""
    from scipy.spatial import cKDTree
    pb = ShapeProblem(load_config(EXAMPLES / "dovetail.toml"))
    m = pb.model
    assert m.foundation.pairs == [[0, 1]] and m.body.rigid is not None
    st = pb.solve_state(m.initial_design())
    left, right = (m.body.pair_of == k for k in range(2))
    assert st.lam[left].sum() == pytest.approx(st.lam[right].sum(), rel=1e-10)
    assert st.tau[left].sum(axis=0)[1] == pytest.approx(-st.tau[right].sum(axis=0)[1], rel=1e-10)
    x = m.body.reference.points[m.contact_nodes]
    mirror = cKDTree(x).query(x * [-1.0, 1.0, 1.0])[1]
    assert np.abs(st.lam - st.lam[mirror]).max() <= 1e-10 * st.lam.max()
    r = np.column_stack([-st.tau, st.lam])                       # the contact forces in the nodes' frames
    lift = np.einsum("pij,pj->i", m.frames, r)                    # their resultant on the blade
    assert lift[2] == pytest.approx(-0.002 * 0.625, rel=1e-9)    # the body force times the blade's volume
    assert abs(lift[0]) <= 1e-12


def test_the_face_body_s_body_force_is_read_without_a_loads_table(tmp_path):
    """bodies.<face body>.body_force in a model without [loads] is the body's load (it was dropped)."""
    _base_file(tmp_path / "base.msh")
    text = BLOCK.format(bases=BASE.format(name="base"),
                        contacts=PAIR.format(name="left", lo=0.0, hi=1.1, counterpart="base.top_left", friction=0.3)
                        + PAIR.format(name="right", lo=1.1, hi=2.0, counterpart="copy.top_right", friction=0.3))
    text = text.replace("[[contacts]]", BASE.format(name="copy") + "[[contacts]]", 1)
    start = text.index("[loads]")
    text = text[:start] + text[text.index("[bodies.block]"):]
    text = text.replace('clamped = "clamped"\n', 'clamped = "clamped"\nbody_force = [0.0, 0.0, -0.5]\n', 1)
    path = tmp_path / "weight.toml"
    path.write_text(text)
    assert load_config(path).loads.body_force == [0.0, 0.0, -0.5]
