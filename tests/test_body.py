"""Own bodies: mesh files with named parts, the morph, and bad input (issue: your own body).

The paper's block written as an unstructured mesh file (permuted numbering, named groups, faces
in arbitrary orientation) must give the built-in block's state and subgradient; the morph must
be affine in α with 0 ≤ w ≤ 1; every kind of bad input must end with exit 2 and nothing written.
"""

import json
import math
from pathlib import Path

import meshio
import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.errors import ConfigError, MeshError
from contactopt.fem.model import ElasticModel
from contactopt.mesh.block import block_mesh
from contactopt.mesh.reader import read_mesh
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient

DATA = Path(__file__).parent / "data"

BLOCK_LOADS = """
[[loads.traction]]
on = "top"
value = [0.0, 0.0, -8.0e-2]

[[loads.traction]]
on = "right"
value = [5.0e-2, 0.0, 0.0]
"""


def write_block_msh(path, nx, ny, nz, *, seed=0, fmt="gmsh22", parts=("clamped", "top", "right", "contact"),
                    cell_type="hexahedron", flip=False, round_to=None):
    """The block [0,2]×[0,1]×[0,1] as a mesh file: permuted nodes and cells, named face groups with
    faces in random orientation. Returns the permutation (new index of old node i = perm[i])."""
    ref = block_mesh(2.0, 1.0, 1.0, nx, ny, nz)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(ref.n_nodes)
    pts = np.empty_like(ref.points)
    pts[perm] = ref.points
    if round_to is not None:
        pts = np.round(pts, round_to) + rng.uniform(-0.4, 0.4, pts.shape) * 10.0 ** -round_to
    cells = perm[ref.cells][rng.permutation(ref.n_cells)]
    if flip:
        cells = cells[:, [0, 3, 2, 1, 4, 7, 6, 5]]          # every hexahedron inside out
    blocks, phys, geo, fd = [], [], [], {}
    for tag, name in enumerate(parts, start=1):
        f = perm[ref.parts[name].faces]
        f = np.array([np.roll(r, rng.integers(4))[::rng.choice([1, -1])] for r in f])
        blocks.append(("quad", f))
        phys.append(np.full(len(f), tag))
        geo.append(np.full(len(f), tag))
        fd[name] = np.array([tag, 2])
    blocks.append((cell_type, cells))
    phys.append(np.full(len(cells), 99))
    geo.append(np.full(len(cells), 1))
    fd["body"] = np.array([99, 3])
    m = meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": phys, "gmsh:geometrical": geo}, field_data=fd)
    meshio.write(path, m, file_format=fmt, binary=False)
    return perm


def block_file_config(tmp_path, nx, ny, nz, name="blockfile", extra="", **kw):
    write_block_msh(tmp_path / "block.msh", nx, ny, nz, **kw)
    toml = tmp_path / f"{name}.toml"
    base = load_config("example1").data
    toml.write_text(f'name = "{name}"\n[body]\nmesh = "block.msh"\nclamped = "clamped"\ncontact = "contact"\n'
                    f'[objective]\ntype = "target_normal_force"\n'
                    f'target = {_inline(base["objective"]["target"])}\n' + BLOCK_LOADS + extra)
    return toml


def _inline(d):
    import tomli_w
    return tomli_w.dumps({"t": d}).split("=", 1)[1].strip() if not isinstance(d, dict) else \
        "{ " + ", ".join(f"{k} = {_inline_value(v)}" for k, v in d.items()) + " }"


def _inline_value(v):
    if isinstance(v, dict):
        return _inline(v)
    if isinstance(v, list):
        return "[" + ", ".join(_inline_value(x) for x in v) + "]"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)


# ------------------------------------------------------------------ the block from a file
def test_block_from_file_gives_the_built_in_state_and_subgradient(tmp_path):
    toml = block_file_config(tmp_path, 32, 15, 9)
    built_in, from_file = ShapeProblem(load_config("example1")), ShapeProblem(load_config(toml))
    mb, mf = built_in.model, from_file.model
    assert mf.n_contact == mb.n_contact == 512
    assert mf.surface == mb.surface
    # contact nodes are ordered by node number: match them by position
    order = np.lexsort(mb.mesh.contact_points().T)
    order_f = np.lexsort(mf.mesh.contact_points().T)
    rng = np.random.default_rng(7)
    a0 = mb.initial_design()
    a1 = a0 + 0.004 * (rng.random(a0.size) - 0.5)
    a1 += (a0.sum() - a1.sum()) / a1.size
    assert mb.admissible.is_feasible(a1)
    for alpha in (a0, a1):
        rb, rf = subgradient(built_in, alpha), subgradient(from_file, alpha)
        lb, lf = rb.state.lam[order], rf.state.lam[order_f]
        assert np.max(np.abs(lb - lf)) <= 1e-10 * np.max(np.abs(lb))
        assert abs(rb.value - rf.value) <= 1e-10 * abs(rb.value)
        assert np.max(np.abs(rb.gradient - rf.gradient)) <= 1e-10 * np.max(np.abs(rb.gradient))
        assert np.array_equal(rb.state.classes[order], rf.state.classes[order_f])


def test_gmsh22_groups_rounded_coordinates_and_face_orientation(tmp_path):
    perm = write_block_msh(tmp_path / "b.msh", 4, 2, 3, fmt="gmsh22", round_to=9)
    ref = read_mesh(tmp_path / "b.msh")
    assert sorted(ref.parts) == ["body", "clamped", "contact", "right", "top"]
    blk = block_mesh(2.0, 1.0, 1.0, 4, 2, 3)
    for name in ("clamped", "contact", "right", "top"):
        assert np.array_equal(np.sort(ref.parts[name].nodes), np.sort(perm[blk.parts[name].nodes]))
        # faces come back oriented outward whatever their order in the file
        f = ref.parts[name].faces
        X = ref.points[f]
        n = np.cross(X[:, 1] - X[:, 0], X[:, 3] - X[:, 0])
        out = {"clamped": [-1, 0, 0], "contact": [0, 0, -1], "right": [1, 0, 0], "top": [0, 0, 1]}[name]
        assert np.all(n @ np.array(out, float) > 0), name
    # predicate parts on rounded coordinates use a tolerance, never ==
    from contactopt.mesh.reference import select_part
    p = select_part(ref, {"x1": 0.0}, 1e-6)
    assert np.array_equal(p.nodes, np.sort(perm[blk.parts["clamped"].nodes]))
    box = select_part(ref, {"box": [[1.0, 2.0], [0.0, 1.0], [0.0, 0.0]]}, 1e-6)
    assert box.nodes.size == 3 * 3 and box.faces.shape == (2 * 2, 4)


def test_gmsh41_cell_sets_and_a_face_in_two_groups():
    # made by Gmsh from tests/data/two_groups.geo: the bottom face is in the groups bottom and base
    path = DATA / "two_groups.msh"
    raw = meshio.read(path)
    assert "gmsh:bounding_entities" in raw.cell_sets          # meshio's own set, to be ignored
    r = read_mesh(path)
    assert sorted(r.parts) == ["base", "bottom", "solid", "top"]
    assert r.cell_type == "tetra"
    assert np.array_equal(r.parts["bottom"].faces, r.parts["base"].faces)
    assert r.parts["bottom"].faces.shape == (110, 3) and r.parts["solid"].faces.shape == (0, 3)
    X = r.points[r.parts["bottom"].faces]
    assert np.all(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])[:, 2] < 0)      # outward: −x3
    assert np.all(np.abs(r.points[r.parts["bottom"].nodes, 2]) < 1e-12)


# ------------------------------------------------------------------ the morph
def test_morph_is_affine_and_moves_the_contact_face_by_theta(tmp_path):
    model = ElasticModel(load_config(block_file_config(tmp_path, 6, 3, 4)))
    mesh, ref = model.mesh, model.body.reference
    w = model.weight
    assert 0.0 <= w.min() and w.max() <= 1.0
    assert np.max(np.abs(w - (1.0 - ref.points[:, 2]))) <= 1e-12          # imported block: w = 1 − x3
    rng = np.random.default_rng(1)
    a, b = 0.05 * rng.random(model.n_design), 0.05 * rng.random(model.n_design)
    xa, xb, xm = mesh.coordinates(a), mesh.coordinates(b), mesh.coordinates(0.5 * (a + b))
    assert np.max(np.abs(xm - 0.5 * (xa + xb))) <= 1e-15
    still = w == 0.0
    assert still.any() and np.array_equal(xa[still], ref.points[still])
    assert np.array_equal(xa[:, :2], ref.points[:, :2])
    face = model.body.contact_face.nodes
    theta = model.surface.evaluate(a, ref.points[face, 0], ref.points[face, 1])
    assert np.array_equal(xa[face, 2], theta)
    assert np.allclose(model.gap_matrix @ a, theta[np.isin(face, model.contact_nodes)], rtol=0, atol=1e-15)


def test_design_derivative_on_an_imported_mesh_matches_central_differences(tmp_path):
    model = ElasticModel(load_config(block_file_config(tmp_path, 5, 3, 3, extra="[loads]\nbody_force = [0.0, 0.01, -0.02]\n")))
    rng = np.random.default_rng(4)
    check_design_contraction(model, 0.02 + 0.05 * rng.random(model.n_design), (0, 13, 31), rng, h=1e-5)


def check_design_contraction(model, alpha, ks, rng, h):
    """vᵀ(∂A/∂α_k u − ∂L/∂α_k) against central differences of the assembled A and L (1e-6)."""
    asm = model.assembler
    u = asm.to_full(rng.standard_normal(asm.n_free))
    v = asm.to_full(rng.standard_normal(asm.n_free))
    pred = model.design_contraction(model.mesh.coordinates(alpha), u, v)
    for k in ks:
        e = np.zeros(model.n_design)
        e[k] = h
        p, m = model.assemble(alpha + e), model.assemble(alpha - e)
        fd = (v[asm.free] @ ((p.A - m.A) @ u[asm.free]) - v @ (p.L_full - m.L_full)) / (2 * h)
        assert abs(pred[k] - fd) <= 1e-6 * abs(fd), k


# ------------------------------------------------------------------ element quality
def test_largest_safe_lift_of_the_block_is_exact(tmp_path):
    model = ElasticModel(load_config(block_file_config(tmp_path, 4, 2, 3)))
    thr = model.config["body"]["min_jacobian_ratio"]
    # on the block the Jacobian ratio is 1 − ϑ_α/c: the box bound is exact
    assert math.isclose(model.safe_C0, 1.0 - thr, rel_tol=1e-12)
    r = model.mesh.ratio.ratios(np.full(model.n_design, 0.3))
    assert np.allclose(r, 0.7, rtol=0, atol=1e-12)


def test_a_design_that_would_invert_an_element_is_caught_before_assembly(tmp_path):
    model = ElasticModel(load_config(block_file_config(tmp_path, 4, 2, 3)))
    alpha = np.full(model.n_design, 0.01)
    alpha[:4] = 1.2                                  # the edge x1 = 0 rises above the top
    with pytest.raises(MeshError, match=r"element \d+ at \(.*top face"):
        model.assemble(alpha)


# ------------------------------------------------------------------ bad input: exit 2, nothing written
def _bad(tmp_path, case):
    good = block_file_config(tmp_path, 4, 2, 3)
    text = good.read_text()
    if case == "missing mesh":
        text = text.replace('mesh = "block.msh"', 'mesh = "nope.msh"')
    elif case == "unreadable mesh":
        (tmp_path / "junk.msh").write_text("$MeshFormat\nthis is not gmsh\n")
        text = text.replace('mesh = "block.msh"', 'mesh = "junk.msh"')
    elif case == "unsupported cell":
        _wedge_mesh(tmp_path / "w.vtu")
        text = text.replace('mesh = "block.msh"', 'mesh = "w.vtu"')
    elif case == "unknown group":
        text = text.replace('contact = "contact"', 'contact = "bottom"')
    elif case == "not on x3 = 0":
        text = text.replace('contact = "contact"', 'contact = "right"')
    elif case == "not a graph":
        _two_unmerged_blocks(tmp_path / "block.msh")
    elif case == "all contact clamped":
        text = text.replace('clamped = "clamped"', 'clamped = ["clamped", "contact"]')
    elif case == "rigid modes free":      # left free, without friction nothing holds u2
        text = text.replace('clamped = "clamped"', 'clamped = { on = "clamped", components = [1] }')
        text += "\n[friction]\ncoefficient = 0.0\n"
    elif case == "inverted as given":
        write_block_msh(tmp_path / "block.msh", 4, 2, 3, flip=True)
    elif case == "C0 inverts":
        text += "\n[design]\nC0 = 0.95\n"
    good.write_text(text)
    return good


def _wedge_mesh(path):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]], float)
    meshio.write(path, meshio.Mesh(pts, [("wedge", np.array([[0, 1, 2, 3, 4, 5]]))]))


def _two_unmerged_blocks(path):
    """Two blocks side by side whose nodes on the common face x1 = 1 were never merged: the
    bottom face then has two nodes at each (1, x2) — not a graph over (x1, x2)."""
    parts = [block_mesh(1.0, 1.0, 1.0, 2, 2, 2) for _ in range(2)]
    pts = np.vstack([parts[0].points, parts[1].points + [1.0, 0.0, 0.0]])
    n = parts[0].n_nodes
    cells = np.vstack([parts[0].cells, parts[1].cells + n])
    groups = {name: np.vstack([parts[0].parts[name].faces, parts[1].parts[name].faces + n])
              for name in ("clamped", "top", "right", "contact")}
    blocks = [("quad", f) for f in groups.values()] + [("hexahedron", cells)]
    tags = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {name: np.array([t, 2]) for t, name in enumerate(groups, start=1)}
    fd["body"] = np.array([len(blocks), 3])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data=fd), file_format="gmsh22", binary=False)


BAD = {
    "missing mesh": "no such file",
    "unreadable mesh": "cannot be read",
    "unsupported cell": "wedge are not supported (supported: hexahedron, tetra, tetra10)",
    "unknown group": "no part named 'bottom' (the mesh has: body, clamped, contact, right, top)",
    "not on x3 = 0": "do not lie on the foundation plane x3 = 0",
    "not a graph": "is not a graph over (x1, x2)",
    "all contact clamped": "every node of the contact face is clamped",
    "rigid modes free": "the translation along x2 is not held: without friction",
    "inverted as given": "inverted as given",
    "C0 inverts": "largest safe C0",
}


# a C0 that lets admissible designs invert an element refuses a run; a state needs no U (below)
@pytest.mark.parametrize("case, command", [(case, command) for case in BAD for command in ("state", "run")
                                           if (case, command) != ("C0 inverts", "state")])
def test_bad_body_input_exits_2_and_writes_nothing(tmp_path, capsys, case, command):
    cfg = _bad(tmp_path, case)
    out = tmp_path / "out"
    code = main([command, str(cfg), "--out", str(out)] + (["--max-iter", "1"] if command == "run" else []))
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("contactopt: error:")
    assert BAD[case] in err, err
    assert not out.exists()


def _bracket_with_design_defaults(tmp_path):
    """examples/bracket.toml without its C0: [design] C0 = 0.75 lets admissible designs invert the
    foot's elements (the largest safe C0 is 0.1445); its initial design 0.002 leaves the mesh valid."""
    example = Path(__file__).resolve().parents[1] / "examples" / "bracket.toml"
    text = example.read_text().replace("C0 = 0.1\n", "").replace('"bracket/bracket.msh"',
                                                                  json.dumps(str(example.parent / "bracket" / "bracket.msh")))
    toml = tmp_path / "bracket.toml"
    toml.write_text(text)
    assert load_config(toml).design.C0 == 0.75
    return toml


def test_a_state_is_solved_where_the_design_space_would_refuse_a_run(tmp_path, capsys):
    """The admissible set U matters to an optimization, not to one state: `contactopt state` solves
    the bracket with [design] defaults; `contactopt run` is refused, naming design.C0 and the largest
    safe C0, and writes nothing."""
    toml = _bracket_with_design_defaults(tmp_path)
    assert main(["state", str(toml), "--out", str(tmp_path / "state")]) == 0, capsys.readouterr().err
    doc = json.loads((tmp_path / "state" / "state.json").read_text())
    assert doc["warnings"] == []                              # α0 = 0.002 lies in U
    assert doc["summary"]["total_normal_force"] == pytest.approx(0.0056029, rel=1e-4)
    capsys.readouterr()
    out = tmp_path / "run"
    assert main(["run", str(toml), "--out", str(out), "--max-iter", "1"]) == 2
    err = capsys.readouterr().err
    assert "design.C0 = 0.75 lets admissible designs invert element" in err, err
    assert "the largest safe C0 for this mesh and morph is 0.1445" in err, err
    assert not out.exists()


def test_the_python_problem_checks_the_design_space_only_when_asked(tmp_path):
    """ShapeProblem solves states on any configuration; ``optimizing=True`` (a run's set-up) refuses
    the U that lets designs invert an element, as the model's check_design_space does."""
    cfg = load_config(_bracket_with_design_defaults(tmp_path))
    problem = ShapeProblem(cfg)
    model = problem.model
    assert model.safe_C0 == pytest.approx(0.1445, abs=1e-4)
    problems = model.design_space_problems()
    assert len(problems) == 1 and "design.C0 = 0.75 lets admissible designs invert" in problems[0]
    state = problem.solve_state(model.initial_design())
    assert state.lam.sum() == pytest.approx(0.0056029, rel=1e-4)
    with pytest.raises(ConfigError, match=r"design\.C0 = 0\.75 lets admissible designs invert element \d+"):
        ShapeProblem(cfg, optimizing=True)
    with pytest.raises(ConfigError, match="largest safe C0"):
        model.check_design_space()
    safe = ShapeProblem(cfg.with_updates({"design": {"C0": 0.14}}), optimizing=True).model   # below 0.1445
    assert safe.design_space_problems() == []


def test_block_loads_on_a_body_from_a_file_are_refused(tmp_path):
    toml = block_file_config(tmp_path, 2, 2, 2)
    toml.write_text(toml.read_text() + "\n[loads]\ntop_traction = [0.0, 0.0, -1.0]\n")
    with pytest.raises(ConfigError, match="built-in block"):
        load_config(toml)


# ------------------------------------------------------------------ tetrahedra from a file
def tet_box_config(tmp_path, extra=""):
    toml = tmp_path / "box.toml"
    toml.write_text(f'name = "box"\n[body]\nmesh = "{DATA / "two_groups.msh"}"\nclamped = "top"\ncontact = "bottom"\n'
                    '[loads]\nbody_force = [0.0, 0.0, -1.0]\n[[loads.pressure]]\non = { x1 = 1.0 }\nvalue = 0.05\n'
                    '[design]\ndegree = [3, 2]\nC0 = 0.05\nC2 = 0.002\ninitial = 0.002\n' + extra)
    return toml


def test_design_derivative_on_an_imported_tetrahedral_mesh_matches_central_differences(tmp_path):
    model = ElasticModel(load_config(tet_box_config(tmp_path)))
    assert model.mesh.cell_type == "tetra" and model.loads.pressures
    rng = np.random.default_rng(8)
    check_design_contraction(model, 0.002 + 0.01 * rng.random(model.n_design), range(model.n_design), rng, h=1e-6)


def test_subgradient_on_an_imported_tetrahedral_mesh_matches_central_differences(tmp_path):
    problem = ShapeProblem(load_config(tet_box_config(tmp_path, '[objective]\ntarget = { kind = "constant", value = 0.001 }\n')))
    alpha = problem.model.initial_design()
    res = subgradient(problem, alpha)
    assert res.n_degenerate == 0
    d = np.random.default_rng(9).standard_normal(alpha.size)
    d -= d.mean()
    h = 1e-6
    fd = (problem.evaluate_value(alpha + h * d) - problem.evaluate_value(alpha - h * d)) / (2 * h)
    assert abs(res.gradient @ d - fd) <= 1e-6 * abs(fd)


def test_thin_linear_tetrahedra_and_poor_cells_are_warned_about(tmp_path, caplog):
    from contactopt.mesh.body import _poor_cells, _thin_tetrahedra
    from contactopt.mesh.reference import ReferenceMesh
    from contactopt.mesh.tetsplit import hex_to_tets
    slab = block_mesh(2.0, 2.0, 0.05, 8, 8, 1)                  # one tetrahedron layer
    thin = ReferenceMesh(slab.points, hex_to_tets(slab.cells), "tetra")
    assert "too stiff in bending" in _thin_tetrahedra(thin)[0]
    thick = block_mesh(1.0, 1.0, 1.0, 4, 4, 4)
    assert _thin_tetrahedra(ReferenceMesh(thick.points, hex_to_tets(thick.cells), "tetra")) == []
    squashed = block_mesh(1.0, 1.0, 1.0, 2, 2, 2)
    squashed.points[13] += [0.46, 0.46, 0.46]                   # the centre node almost at a corner
    assert "shape quality below" in _poor_cells(squashed)[0]
    assert _poor_cells(thick) == []
