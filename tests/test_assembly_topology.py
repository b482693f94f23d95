"""Pairs whose faces lie on several bodies (fem/faces.py): a four-body chain whose third pair has
its face on a counterpart body of the second, against the contact patch test, against the same
stack written with every face on one body, subgradients and bad input.

Conventions: per contact node (t1, t2, ν) in the node's frame, ν from the counterpart to the face,
r the contact force on the face's body, λ = r_ν ≥ 0, τ = −r_t; the law's rows are the face body's
contact nodes, then those of the faces on other bodies (``model.pair_of`` names each row's pair).
"""

from pathlib import Path

import meshio
import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.errors import ConfigError
from contactopt.mesh.foundation import foundation_block
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

P = 0.01          # the pressure on the top of the stack


def _box(path, cells, lift):
    """A unit box (parts top, bottom, left, right, front, back) over [0, 1]² lifted to
    x3 ∈ [lift − 1, lift], as a Gmsh file."""
    ref = foundation_block([1.0, 1.0, 1.0], cells, [0.0, 0.0])
    names = ("top", "bottom", "left", "right", "front", "back")
    blocks = [("quad", ref.parts[n].faces) for n in names] + [(ref.cell_type, ref.cells)]
    phys = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {n: np.array([t, 2]) for t, n in enumerate(names, start=1)} | {"box": np.array([len(blocks), 3])}
    meshio.write(path, meshio.Mesh(ref.points + [0.0, 0.0, lift], blocks, cell_data={"gmsh:physical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)


def _rollers(sides=True, extra=""):
    """Symmetry rollers as a TOML list: u2 = 0 on front and back, and u1 = 0 on left and right
    (``sides``; the built-in block calls its left face "clamped")."""
    x1 = '{ on = "left", components = [1] }, { on = "right", components = [1] }, ' if sides else ""
    return f'[ {extra}{x1}{{ on = "front", components = [2] }}, {{ on = "back", components = [2] }} ]'


def _chain_text(tmp_path, friction=(0.0, 0.0, 0.0), sides=True, extra="") -> str:
    """Four unit blocks stacked in x3, each its own grid (5 × 4, 7 × 6, 4 × 5 and 3 × 4 cells across,
    their nodes offset): lower (held at its bottom), middle (the face body, the built-in block),
    upper and top (held in x3 only by their contacts); rollers on the sides; a pressure P on the top.
    contacts[0] middle/lower, contacts[1] middle/upper, contacts[2] upper/top: its face on upper, the
    counterpart of contacts[1]. Mortar partners."""
    _box(tmp_path / "upper.msh", [4, 5, 2], 2.0)
    _box(tmp_path / "top.msh", [3, 4, 2], 3.0)
    f1, f2, f3 = friction
    clamped = _rollers(sides).replace('"left"', '"clamped"')
    return f"""
name = "chain"
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
clamped = {clamped}
[bodies.lower]
block = {{ size = [1.0, 1.0, 1.0], cells = [5, 4, 3], origin = [0.0, 0.0] }}
clamped = {_rollers(sides, '{ on = "bottom", components = [1, 2, 3] }, ')}
material = {{ E = 2.0, nu = 0.25 }}
[bodies.upper]
mesh = "upper.msh"
clamped = {_rollers(sides)}
material = {{ E = 0.5, nu = 0.35 }}
[bodies.top]
mesh = "top.msh"
clamped = {_rollers(sides)}
material = {{ E = 0.8, nu = 0.3 }}
[[loads.pressure]]
on = "top.top"
value = {P}
[[contacts]]
face = "middle.contact"
counterpart = "lower.top"
friction = {f1}
partner = "mortar"
[[contacts]]
face = "middle.top"
counterpart = "upper.bottom"
friction = {f2}
partner = "mortar"
[[contacts]]
face = "upper.top"
counterpart = "top.bottom"
friction = {f3}
partner = "mortar"
[state]
tol = 1.0e-14
max_iter = 200
{extra}"""


def _write(tmp_path, text, name="model.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _chain(tmp_path, **kw) -> ShapeProblem:
    return ShapeProblem(load_config(_write(tmp_path, _chain_text(tmp_path, **kw))))


# ------------------------------------------------------------------ the contact patch test across a chain
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_the_contact_patch_test_passes_across_a_chain_of_four_bodies(friction, tmp_path):
    """Uniform pressure P on all three interfaces to 1e-8 relative and ‖τ‖ ≤ 1e-8 λ at every node,
    non-matching offset grids, the third pair's face on upper (the counterpart of the second), the
    middle, upper and top blocks held in x3 only by their contacts."""
    pb = _chain(tmp_path, friction=(friction,) * 3)
    m = pb.model
    p_a = m.contact_nodes.size
    assert m.n_contact == p_a + 30                                  # upper.top's 5 × 6 nodes follow
    assert np.all(m.pair_of[p_a:] == 2) and not np.any(m.pair_of[:p_a] == 2)
    assert m.body.rigid is not None and m.foundation.kernel()[1] == [
        "the translation along x3 of the counterpart of contacts[1]",
        "the translation along x3 of the counterpart of contacts[2]"]
    st = pb.solve_state(m.initial_design())
    p = st.lam / m.contact_areas()
    for k in range(3):
        mine = m.pair_of == k
        assert np.abs(p[mine] / P - 1).max() <= 1e-8, (k, p[mine])
        assert st.lam[mine].sum() == pytest.approx(P, rel=1e-10)
    assert np.all(np.linalg.norm(st.tau, axis=1) <= 1e-8 * st.lam)


# ------------------------------------------------------------------ against the stack written with one face body
def _three(tmp_path, written: str, friction: float, q: float, moved=None) -> ShapeProblem:
    """Three unit blocks with matching 4 × 3 grids stacked in x3 (lower held at its bottom, middle
    and upper held in x3 and, with friction, x1 by their contacts alone; u2 = 0 on front and back,
    without friction u1 = 0 on left and right), P on the top of
    upper and a traction q along x1 on its right face. ``written = "star"``: both faces on middle;
    ``"chain"``: the face body lower, the second pair's face on middle (the counterpart of the first).
    ``moved``: upper's top moved by that translation (``control = "displacement"``) in place of P."""
    for name, lift in (("lower", 0.0), ("middle", 1.0), ("upper", 2.0)):
        _box(tmp_path / f"{name}.msh", [4, 3, 2], lift)
    sides = friction == 0.0                     # without friction rollers hold x1 too
    held = _rollers(sides, '{ on = "bottom", components = [1, 2, 3] }, ')
    lower = f'mesh = "lower.msh"\nclamped = {held}\nmaterial = {{ E = 2.0, nu = 0.25 }}\n'
    bodies = {"lower": lower, "middle": f'mesh = "middle.msh"\nclamped = {_rollers(sides)}\n',
              "upper": f'mesh = "upper.msh"\nclamped = {_rollers(sides)}\nmaterial = {{ E = 0.5, nu = 0.35 }}\n'}
    if moved is not None:
        bodies["upper"] += f'control = "displacement"\nloaded = "top"\ndisplacement = {list(moved)}\n'
    first = "middle" if written == "star" else "lower"
    pair = 'face = "middle.bottom"\ncounterpart = "lower.top"' if written == "star" else \
        'face = "lower.top"\ncounterpart = "middle.bottom"'
    text = 'name = "three"\n[material]\nE = 1.0\nnu = 0.3\n'
    for b in [first] + [b for b in bodies if b != first]:
        text += f"[bodies.{b}]\n{bodies[b]}"
    if moved is None:
        text += f'[[loads.pressure]]\non = "upper.top"\nvalue = {P}\n'
    text += (f'[[loads.traction]]\non = "upper.right"\n'
             f'value = [{q}, 0.0, 0.0]\n[[contacts]]\n{pair}\nfriction = {friction}\n[[contacts]]\n'
             f'face = "middle.top"\ncounterpart = "upper.bottom"\nfriction = {friction}\n'
             f'[state]\ntol = {1e-14 if moved is None else 1e-12}\nmax_iter = 200\n')
    return ShapeProblem(load_config(_write(tmp_path, text, f"{written}.toml")))


def _rows(pb, st):
    """Per pair: the rows' reference (x1, x2), their contact forces on the face's body in global
    components and λ, ordered by (x1, x2)."""
    m = pb.model
    p_a = m.contact_nodes.size
    x = m.body.reference.points[m.contact_nodes]
    if m.n_contact > p_a:
        x, R = np.vstack([x, m.foundation.off_points]), m.foundation.frames
    else:
        R = np.broadcast_to(np.eye(3), (p_a, 3, 3)) if m.frames is None else m.frames
    r = np.einsum("mij,mj->mi", R, np.column_stack([-st.tau, st.lam]))
    out = []
    for k in range(2):
        mine = np.flatnonzero(m.pair_of == k)
        o = mine[np.lexsort((x[mine, 1], x[mine, 0]))]
        out.append((x[o, :2], r[o], st.lam[o], m.contact_areas()[o]))
    return out


@pytest.mark.parametrize("friction, q", [(0.0, 0.0), (0.3, 0.002)])
def test_a_chain_agrees_with_the_stack_written_with_every_face_on_one_body(friction, q, tmp_path):
    """Matching meshes, point partners (node to node: which side is the face does not change the
    discrete problem): the chain (the second pair's face on middle, a counterpart of the first)
    gives the contact forces of the same stack with both faces on middle to 1e-10, each pair's
    forces balance the loads above it to 1e-10, and without friction the pressure is P exactly."""
    star, chain = _three(tmp_path, "star", friction, q), _three(tmp_path, "chain", friction, q)
    assert chain.model.n_contact > chain.model.contact_nodes.size     # the second pair's rows follow
    a = _rows(star, star.solve_state(star.model.initial_design()))
    b = _rows(chain, chain.solve_state(chain.model.initial_design()))
    load = np.array([q, 0.0, -P])                  # on upper: what the second pair carries, and the first
    for k, sign in ((0, -1.0), (1, 1.0)):          # the first pair's face is on lower in the chain
        (xa, ra, la, _), (xb, rb, lb, area) = a[k], b[k]
        assert np.abs(xa - xb).max() <= 1e-12
        assert np.abs(la - lb).max() <= 1e-10 * la.max()
        assert np.abs(ra - sign * rb).max() <= 1e-10 * np.abs(ra).max()
        assert np.abs(sign * rb.sum(axis=0) - (load if k else -load)).max() <= 1e-10 * P
        if friction == 0.0:
            assert np.abs(lb / area / P - 1).max() <= 1e-10


@pytest.mark.parametrize("friction, moved", [(0.0, (0.0, 0.0, -0.01)), (0.3, (0.002, 0.0, -0.01))])
def test_a_chain_pressed_by_a_moved_counterpart_agrees_with_the_stack_with_one_face_body(friction, moved,
                                                                                        tmp_path):
    """Upper, the counterpart of the face on middle, moved down (and along x1) by its top: its
    translation enters the rows of that face; the chain gives the contact forces of the stack
    written with both faces on middle to 1e-10, and middle's two pairs balance each other."""
    star = _three(tmp_path, "star", friction, 0.0, moved)
    chain = _three(tmp_path, "chain", friction, 0.0, moved)
    held = chain.model.foundation.kernel()[1]            # middle, held only by its contacts
    assert "the translation along x3 of the counterpart of contacts[0]" in held and len(held) == (
        1 if friction == 0.0 else 3)
    a = _rows(star, star.solve_state(star.model.initial_design()))
    b = _rows(chain, chain.solve_state(chain.model.initial_design()))
    assert a[1][2].sum() > 1e-3                    # pressed
    for k, sign in ((0, -1.0), (1, 1.0)):
        (_, ra, la, _), (_, rb, lb, _) = a[k], b[k]
        assert np.abs(la - lb).max() <= 1e-10 * la.max()
        assert np.abs(ra - sign * rb).max() <= 1e-10 * np.abs(ra).max()
    assert np.abs(b[0][1].sum(axis=0) - b[1][1].sum(axis=0)).max() <= 1e-10 * a[1][2].sum()


# ------------------------------------------------------------------ subgradients
DESIGN = """
[[designs]]
face = "middle.contact"
degree = [2, 2]
C0 = 0.2
C1 = 0.5
C2 = 0.01
initial = 0.0
"""


def test_subgradients_with_a_design_and_sliding_nodes_on_a_face_off_the_face_body(tmp_path):
    """A design on the face body's contact face, a traction along x1 on the top block (every block
    held in x1 by friction alone) that slides nodes of the pair whose face lies on upper: ξ against
    central differences to 1e-6."""
    extra = DESIGN + '[[loads.traction]]\non = "top.right"\nvalue = [0.001, 0.0, 0.0]\n'
    pb = _chain(tmp_path, friction=(0.3, 0.3, 0.15), sides=False, extra=extra)
    m = pb.model
    alpha = m.initial_design() + 0.003 * np.random.default_rng(3).standard_normal(m.n_design)
    st = pb.solve_state(alpha)
    assert np.sum(st.classes[m.pair_of == 2] == CLASS_CODES["M1"]) >= 5
    gc = check_gradient(pb, alpha, n_directions=2, seed=1)
    assert gc.passed and max(gc.rel_errors) <= 1e-6, gc.rel_errors


# ------------------------------------------------------------------ outputs
def test_the_cli_writes_the_state_of_a_chain(tmp_path, capsys):
    """contactopt state on the chain: exit 0, state.json with each pair's normal force P and every
    row of the law named by its node and body."""
    import json
    path = _write(tmp_path, _chain_text(tmp_path))
    out = tmp_path / "out"
    assert main(["state", str(path), "--out", str(out)]) == 0
    report = json.loads((out / "state.json").read_text())
    assert [c["face"] for c in report["contacts"]] == ["middle.contact", "middle.top", "upper.top"]
    assert [c["nodes"] for c in report["contacts"]][2] == 30
    for c in report["contacts"]:
        assert c["total_normal_force"] == pytest.approx(P, rel=1e-10)
    rows = report["contact"]                      # every row, the face body's first, each on its body
    assert len(rows["node"]) == len(rows["x1"]) == len(rows["lam"]) == report["n_contact"] == 142
    assert rows["body"][:112] == ["middle"] * 112 and rows["body"][112:] == ["upper"] * 30
    assert (out / "foundation.vtu").exists() and (out / "body.vtu").exists()


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize("change, needle", [
    (('face = "upper.top"\ncounterpart = "top.bottom"', 'face = "top.bottom"\ncounterpart = "upper.top"'),
     "contacts[2].face = 'top.bottom': with several pairs contactopt takes the faces of every pair on one body so "
     "far ('middle', the face of contacts[0]), or a face on a counterpart body of another pair against a third, "
     "elastic body (paths: condensation, fullspace, petsc); 'top' is the counterpart of no pair"),
    (('face = "upper.top"\ncounterpart = "top.bottom"', 'face = "upper.top"\ncounterpart = "middle.top"'),
     "contacts[2].face = 'upper.top': with several pairs contactopt takes the faces of every pair on one body so "
     "far ('middle', the face of contacts[0]), or a face on a counterpart body of another pair against a third, "
     "elastic body (paths: condensation, fullspace, petsc); its counterpart lies on the face body 'middle'"),
    (('[state]', '[[contacts]]\nface = "top.front"\ncounterpart = "upper.front"\n[state]'),
     "contacts[3].face = 'top.front': with several pairs contactopt takes the faces of every pair on one body so "
     "far ('middle', the face of contacts[0]), or a face on a counterpart body of another pair against a third, "
     "elastic body (paths: condensation, fullspace, petsc); the bodies top → upper → top carry each other's faces in a cycle"),
    (('face = "upper.top"\ncounterpart = "top.bottom"', 'face = "upper.top"\ncounterpart = { shape = "plane" }'),
     "this face meets a rigid counterpart: make 'upper' the face body"),
    (('[bodies.upper]\n', '[bodies.upper]\ncontrol = "displacement"\nloaded = "top"\ndisplacement = [0.0, 0.0, 0.0]\n'),
     "body 'upper', which carries it, is moved by control = 'displacement'"),
    (('[bodies.lower]\n', '[bodies.lower]\ncontrol = "force"\nloaded = "bottom"\nforce = [0.0, 0.0, 0.01]\n'),
     "bodies.lower (contacts[0]): a counterpart pressed by control = 'force' in a model whose faces lie on several "
     "bodies (contacts[2]) is not taken so far"),
    (('[state]', '[[designs]]\nface = "upper.top"\n[state]'),
     "designs[0].face = 'upper.top': body 'upper' carries the face of a pair (off the face body)"),
])
def test_what_faces_on_several_bodies_cannot_take_is_refused_by_name(change, needle, tmp_path):
    text = _chain_text(tmp_path)
    assert change[0] in text
    with pytest.raises(ConfigError) as exc:
        load_config(_write(tmp_path, text.replace(*change)))
    assert needle in str(exc.value), str(exc.value)


def test_a_face_on_the_nodes_of_another_pairs_partners_is_refused_by_the_cli(tmp_path, capsys):
    """The third pair's face on upper.bottom, where the partners of contacts[1] lie: exit 2 naming
    the pair, nothing written."""
    text = _chain_text(tmp_path).replace('face = "upper.top"\ncounterpart = "top.bottom"',
                                         'face = "upper.bottom"\ncounterpart = "top.bottom"')
    out = tmp_path / "out"
    assert main(["state", str(_write(tmp_path, text)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "contacts[2].face: 30 of its node(s) carry partners of another pair on the same body" in err, err
    assert not out.exists()


@pytest.mark.parametrize("path", ["delassus"])
def test_the_other_paths_refuse_a_face_off_the_face_body_by_name(path, tmp_path):
    extra = f'[linear_solver]\npath = "{path}"\n'
    with pytest.raises(ConfigError) as exc:
        _chain(tmp_path, extra=extra)
    assert (f"linear_solver.path = '{path}': contacts[2].face lies on body 'upper'; a pair whose face lies on a "
            "counterpart body of another pair is solved on the 'condensation', 'fullspace' and 'petsc' paths only "
            "so far; use path 'condensation', 'fullspace', 'petsc' or 'auto'") in str(exc.value)


def test_an_objective_of_the_whole_displacement_is_refused_with_faces_on_several_bodies(tmp_path):
    with pytest.raises(ConfigError, match=r"objective 'frictional_dissipation': an objective of the whole "
                                          r"displacement in a model whose faces lie on several bodies "
                                          r"\(contacts\[2\]\) is not taken so far"):
        _chain(tmp_path, extra='[objective]\ntype = "frictional_dissipation"\n')


# ------------------------------------------------------------------ load paths
def _without_top(text: str) -> str:
    """The chain's configuration without its top block and third pair: the pressure P on upper's
    top, every face on the face body (middle)."""
    top = text[text.index("[bodies.top]"):text.index("[[loads.pressure]]")]
    third = text[text.index('[[contacts]]\nface = "upper.top"'):text.index("[state]")]
    return text.replace(top, "").replace(third, "").replace('on = "top.top"', 'on = "upper.top"')


@pytest.mark.parametrize("case, q, slide", [("chain", 0.002, 0), ("chain, top sheared", -0.0005, 2),
                                            ("chain, full space", 0.002, 0), ("every face on middle", 0.002, 0)])
def test_a_load_path_on_a_chain_matches_central_differences(case, q, slide, tmp_path):
    """Pressed, then a traction q along x1 on the face body's right side in a second step, every
    block held in x1 by friction alone and at front and back by rollers u2 = 0 (contact nodes
    there have the clamped u2 as their frame's t1), a design on the face body's contact face: ξ
    against central differences to 1e-6 with rows sliding (``slide`` the pair) in the shear step.
    "chain": the face body slides on its pairs; "chain, top sheared": a traction on the top block
    (in every step) slides the rows of the face on upper, the step pulls the face body back;
    "chain, full space": the first on the full-space path; "every face on middle": the stack without
    its top block and third pair. Measured 7e-11 to 2.5e-9; 5e-6 to 2e-3 where the carry between
    the steps was zeroed on the clamped component's global index (u2, the frames' t2) rather than
    on its column of the frame (t1)."""
    steps = ('[[load_steps]]\nname = "press"\n[[load_steps]]\nname = "shear"\n'
             f'traction = [{{ on = "middle.right", value = [{q}, 0.0, 0.0] }}]\n'
             '[objective]\ntype = "target_normal_force"\n')
    if case == "chain, top sheared":
        steps += '[[loads.traction]]\non = "top.right"\nvalue = [0.001, 0.0, 0.0]\n'
    text = _chain_text(tmp_path, friction=(0.3, 0.3, 0.15), sides=False, extra=DESIGN + steps)
    if case == "every face on middle":
        text = _without_top(text)
    if case == "chain, full space":
        text = text.replace("[state]", '[linear_solver]\npath = "fullspace"\n[state]')
    pb = ShapeProblem(load_config(_write(tmp_path, text)))
    m = pb.model
    assert pb.path.name == ("fullspace" if case == "chain, full space" else "condensation")
    assert (m.n_contact > m.contact_nodes.size) == case.startswith("chain")
    held = m.contact_pinned[:m.contact_nodes.size]           # the face body's rows: u2 is t1
    assert np.any(held[:, 0]) and not np.any(held[:, 1:])
    alpha = m.initial_design() + 0.003 * np.random.default_rng(3).standard_normal(m.n_design)
    shear = pb.solve_states(alpha)[0]
    assert shear.step == "shear" and np.sum(shear.classes[m.pair_of == slide] == CLASS_CODES["M1"]) >= 8
    gc = check_gradient(pb, alpha, n_directions=2, seed=1)
    assert gc.n_degenerate == 0 and gc.passed and max(gc.rel_errors) <= 1e-6, gc.rel_errors


def test_two_load_cases_on_a_chain_match_central_differences(tmp_path):
    """Two load cases (each a single step) on the chain held by friction alone, a design on the face
    body, the worst case's maximum: ξ against central differences to 1e-6 (measured 1e-8, 2.5e-8)."""
    cases = ('[[load_cases]]\nname = "a"\ntraction = [{ on = "middle.right", value = [0.001, 0.0, 0.0] }]\n'
             '[[load_cases]]\nname = "b"\ntraction = [{ on = "middle.right", value = [0.002, 0.001, 0.0] }]\n'
             '[objective]\ntype = "target_normal_force"\ncombine = "max"\n')
    pb = _chain(tmp_path, friction=(0.3, 0.3, 0.15), sides=False, extra=DESIGN + cases)
    m = pb.model
    alpha = m.initial_design() + 0.003 * np.random.default_rng(3).standard_normal(m.n_design)
    states = pb.solve_states(alpha)
    assert len(states) == 2 and all(np.sum(st.classes == CLASS_CODES["M1"]) > 0 for st in states)
    gc = check_gradient(pb, alpha, n_directions=2, seed=1)
    assert gc.passed and max(gc.rel_errors) <= 1e-6, gc.rel_errors
