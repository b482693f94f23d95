"""The design space beyond the paper's U, and the graded block.

A crowned contact face (the paraboloid r²/2R, whose Bézier net of degree 2 has a negative control
point) solved through ``contactopt state --alpha`` must equal the same paraboloid built into a mesh
file (``initial_gap = "mesh"``); with ``design.lower < 0`` the bundle method must keep ϑ_α ≥ 0 at
every node of the contact face in every iterate; a graded block must equal the same grid read
from a file; bad input ends with exit 2 and writes nothing.
"""

import json
import logging
from pathlib import Path

import meshio
import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.design.admissible import AdmissibleSet
from contactopt.design.bezier import BezierSurface
from contactopt.fem.model import ElasticModel
from contactopt.mesh.block import block_mesh
from contactopt.optimize import minimize_bundle
from contactopt.problem import ShapeProblem

A, B, C = 2.0, 1.0, 1.0
NX, NY, NZ = 8, 4, 3
R = 4.0                                   # radius of curvature of the paraboloid
LOADS = [{"on": "top", "value": [0.0, 0.0, -8e-2]}, {"on": "right", "value": [5e-2, 0.0, 0.0]}]


def paraboloid(x1, x2):
    """The gap r²/2R of a paraboloid touching the plane at the centre of the face."""
    return ((x1 - A / 2) ** 2 + (x2 - B / 2) ** 2) / (2 * R)


def paraboloid_net():
    """Its control points of degree (2, 2): α_ij = f_i + g_j with the Bernstein coefficients
    (1/4, −1/4, 1/4)·L²/2R of (x − L/2)²/2R on [0, L] (Σ_j β_j = 1 adds the two parts)."""
    f = np.array([0.25, -0.25, 0.25]) * A ** 2 / (2 * R)
    g = np.array([0.25, -0.25, 0.25]) * B ** 2 / (2 * R)
    return f[:, None] + g[None, :]


def write_msh(path, points, ref, names=("clamped", "top", "right", "contact")):
    """The block's cells at ``points`` as a binary Gmsh 2.2 file with the block's face groups."""
    blocks = [("quad", ref.parts[n].faces) for n in names] + [("hexahedron", ref.cells)]
    tags = [np.full(len(cells), k) for k, (_, cells) in enumerate(blocks, start=1)]
    fd = {n: np.array([k, 2]) for k, n in enumerate(names, start=1)} | {"body": np.array([len(names) + 1, 3])}
    meshio.write(path, meshio.Mesh(points, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data=fd), file_format="gmsh22", binary=True)


def crowned_configs(tmp_path, config_file):
    """The block with the crown as a design, and the block with the crown in its mesh file."""
    base = {"name": "crown_design", "geometry": {"a": A, "b": B, "c": C}, "mesh": {"nx": NX, "ny": NY, "nz": NZ},
            "loads": {"traction": LOADS}, "design": {"degree": [2, 2], "C0": 0.5}}
    design = config_file(name="design", config=base)
    ref = block_mesh(A, B, C, NX, NY, NZ)
    pts = ref.points.copy()
    pts[:, 2] += paraboloid(pts[:, 0], pts[:, 1]) * (1.0 - pts[:, 2] / C)     # the block's morph weight
    write_msh(tmp_path / "crowned.msh", pts, ref)
    mesh = config_file(name="mesh", config={
        "name": "crown_mesh", "body": {"mesh": "crowned.msh", "clamped": "clamped", "contact": "contact",
                                       "initial_gap": "mesh"},
        "loads": {"traction": LOADS}, "design": {"degree": [2, 2], "C0": 0.5, "C2": 0.0, "initial": 0.0}})
    return design, mesh


def test_degree_two_net_is_the_paraboloid_and_dips_below_zero():
    net = paraboloid_net()
    assert net[1, 1] < 0 and net.min() == net[1, 1]
    x1, x2 = np.random.default_rng(0).uniform([0, 0], [A, B], (1000, 2)).T
    assert np.abs(BezierSurface(2, 2, A, B).evaluate(net, x1, x2) - paraboloid(x1, x2)).max() < 1e-15


def test_crowned_design_through_state_equals_the_crown_in_the_mesh(tmp_path, capsys, config_file):
    design, mesh = crowned_configs(tmp_path, config_file)
    alpha = tmp_path / "crown.json"
    alpha.write_text(json.dumps({"alpha": paraboloid_net().tolist()}))
    assert main(["state", str(design), "--alpha", str(alpha), "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert main(["state", str(mesh), "--out", str(tmp_path / "b")]) == 0
    a = json.loads((tmp_path / "a" / "state.json").read_text())
    b = json.loads((tmp_path / "b" / "state.json").read_text())
    # outside the paper's U (α ≥ 0, mean value C2) but ϑ ≥ 0 on the face: solved, with warnings
    assert "outside the admissible set U" in err and "bound: α[1,1]" in err and "volume" in err
    assert any(w.startswith("bound: α[1,1] = ") for w in a["warnings"])
    assert any(w.startswith("volume") for w in a["warnings"]) and not any("gap" in w for w in a["warnings"])
    assert b["warnings"] == []
    ca, cb = a["contact"], b["contact"]
    assert ca["node"] == cb["node"] and a["summary"]["converged"] and b["summary"]["converged"]
    assert np.allclose(ca["gap"], cb["gap"], rtol=0, atol=1e-15)
    lam_a = np.array(ca["lam"])
    assert 3 <= np.count_nonzero(lam_a > 0) < lam_a.size     # a contact patch, not the whole face
    for key in ("lam", "u_c", "tau"):
        x, y = np.array(ca[key]), np.array(cb[key])
        assert np.abs(x - y).max() <= 1e-10 * np.abs(y).max(), key
    assert ca["class"] == cb["class"]


def test_a_design_that_inverts_the_mesh_is_refused(tmp_path, capsys, config_file):
    design, _ = crowned_configs(tmp_path, config_file)
    alpha = tmp_path / "high.json"
    alpha.write_text(json.dumps({"alpha": np.full((3, 3), 1.2).tolist()}))    # above the top face c = 1
    out = tmp_path / "out"
    assert main(["state", str(design), "--alpha", str(alpha), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--alpha {alpha}: the design would leave" in err and "inverted" in err and not out.exists()


def test_a_face_below_the_plane_is_named(tmp_path, capsys, config_file):
    design, _ = crowned_configs(tmp_path, config_file)
    alpha = tmp_path / "low.json"
    alpha.write_text(json.dumps({"alpha": (paraboloid_net() - 0.01).tolist()}))
    assert main(["state", str(design), "--alpha", str(alpha), "--out", str(tmp_path / "s")]) == 0
    warn = json.loads((tmp_path / "s" / "state.json").read_text())["warnings"]
    gap = [w for w in warn if w.startswith("gap:")]
    # the paraboloid lowered by 0.01 dips below the plane where r² < 2R·0.01 = 0.08: 5 nodes
    assert len(gap) == 1 and "broken at 5 of 45 nodes" in gap[0] and "-0.01 at node 22 (1, 0.5)" in gap[0]


# ---------------------------------------------------------------------- the admissible set
def test_gap_rows_only_where_they_can_be_active():
    surf = BezierSurface(7, 3, 2.0, 1.0)
    g1, g2 = np.meshgrid(np.linspace(0, 2, 33), np.linspace(0, 1, 16))
    Bm = surf.basis_matrix(g1.ravel(), g2.ravel())
    paper = AdmissibleSet(7, 3, 2.0, 1.0, 0.75, 0.5, 0.01)
    same = AdmissibleSet(7, 3, 2.0, 1.0, 0.75, 0.5, 0.01, gap_basis=Bm)
    for k in ("lb", "ub", "A_ub", "b_ub", "A_eq", "b_eq"):          # lower = 0: the paper's U, row for row
        assert np.array_equal(getattr(paper, k), getattr(same, k)), k
    crowned = AdmissibleSet(7, 3, 2.0, 1.0, 0.75, 0.5, 0.01, lower=-0.1, gap_basis=Bm)
    assert crowned.gap_rows.size == Bm.shape[0] and np.all(crowned.lb == -0.1)
    # a face high above the plane (g0 = 0.2 > 0.1 = −lower) needs no row
    high = AdmissibleSet(7, 3, 2.0, 1.0, 0.75, 0.5, 0.01, lower=-0.1, gap_basis=Bm, gap_offset=np.full(len(Bm), 0.2))
    assert high.gap_rows.size == 0
    # slopes of at most C1 = 0.02 keep every control point near the mean 0.01: a face high enough
    # above the plane cannot reach it, and its rows go (each one dropped cannot be active)
    g0 = np.linspace(0.0, 0.1, len(Bm))
    tight = AdmissibleSet(7, 3, 2.0, 1.0, 0.75, 0.02, 0.01, lower=-0.5, gap_basis=Bm, gap_offset=g0)
    assert 0 < tight.gap_rows.size < len(Bm) and tight.A_ub.shape[0] == 104 + tight.gap_rows.size
    from scipy.optimize import linprog
    for m in np.setdiff1d(np.arange(len(Bm)), tight.gap_rows)[::20]:
        least = linprog(Bm[m], A_ub=tight.A_ub[:104], b_ub=tight.b_ub[:104], A_eq=tight.A_eq, b_eq=tight.b_eq,
                        bounds=list(zip(tight.lb, tight.ub))).fun
        assert least + g0[m] >= 0
    # and the first row kept is active at some design of U
    m = tight.gap_rows[0]
    least = linprog(Bm[m], A_ub=tight.A_ub[:104], b_ub=tight.b_ub[:104], A_eq=tight.A_eq, b_eq=tight.b_eq,
                    bounds=list(zip(tight.lb, tight.ub))).fun
    assert least + g0[m] < 0


def test_lower_above_C0_and_graded_coordinates_not_increasing_exit_2(tmp_path, capsys, config_file):
    base = load_config("example1").with_updates({"mesh": {"nx": 4, "ny": 2, "nz": 2}}).data
    for name, upd, needle in (
            ("lower", {"design": {**base["design"], "lower": 0.8}}, "design.lower = 0.8: must be ≤ design.C0 = 0.75"),
            ("graded", {"mesh": {"x1": [0.0, 1.0, 0.5, 2.0], "ny": 2, "nz": 2}},
             "mesh.x1 = [0.0, 1.0, 0.5, 2.0]: must be strictly increasing (x1[2] = 0.5 ≤ x1[1] = 1"),
            ("mixed", {"mesh": {"x3": [0.0, 0.2, 1.0], "nx": 4, "ny": 2, "nz": 2}},
             "mesh.x3 and mesh.nz: give the node coordinates or the number of elements in x3, not both"),
            ("start", {"mesh": {"x2": [0.1, 1.0], "nx": 4, "nz": 2}}, "mesh.x2 = [0.1, 1.0]: must start at 0"),
            ("end", {"mesh": {"x1": [0.0, 1.0, 3.0], "ny": 2, "nz": 2}}, "mesh.x1 ends at 3, geometry.a = 2")):
        cfg = config_file(name=name, config={**base, **upd})
        for cmd in (["state", str(cfg), "--out", str(tmp_path / "s")], ["run", str(cfg), "--out", str(tmp_path / "r")]):
            assert main(cmd) == 2
            err = capsys.readouterr().err
            assert needle in err, (name, err)
            assert not (tmp_path / "s").exists() and not (tmp_path / "r").exists()


# ---------------------------------------------------------------------- the graded block
def test_graded_block_equals_the_same_grid_from_a_file(tmp_path, config_file):
    x1 = [0.0, 0.1, 0.3, 0.6, 1.0, 1.5, 2.0]
    x3 = [0.0, 0.05, 0.15, 0.4, 1.0]
    data = load_config("example1").data
    graded = load_config({**data, "mesh": {"x1": x1, "ny": 3, "x3": x3}, "name": "graded"})
    assert "nx" not in graded["mesh"] and "nz" not in graded["mesh"] and graded["mesh"]["ny"] == 3
    m = ElasticModel(graded)
    pts = m.body.reference.points
    assert np.array_equal(np.unique(pts[:, 0]), x1) and np.array_equal(np.unique(pts[:, 2]), x3)
    assert m.mesh.nx == 6 and m.mesh.nz == 4 and m.n_contact == 6 * 4
    # the weight is the block's 1 − x3/c also on a graded grid (linear functions are discretely harmonic)
    assert np.abs(m.weight - (1.0 - pts[:, 2])).max() < 1e-12
    # the resolved configuration reads back (a run directory's config.toml)
    assert load_config(config_file(name="back", config=graded.data))["mesh"] == graded["mesh"]
    # the same grid as a mesh file: the same state
    ref = m.body.reference
    write_msh(tmp_path / "graded.msh", ref.points, ref)
    data = {k: v for k, v in graded.data.items() if k not in ("geometry", "mesh")}
    data["body"] = {**data["body"], "mesh": str(tmp_path / "graded.msh")}
    data["loads"] = {"traction": LOADS}
    blk = ShapeProblem(graded)
    fil = ShapeProblem(load_config(data))
    alpha = np.full(32, 0.01)
    sa, sb = blk.solve_state(alpha), fil.solve_state(alpha)
    assert np.array_equal(blk.model.contact_nodes, fil.model.contact_nodes) and sa.lam.max() > 0
    for key in ("lam", "u_c", "tau"):
        x, y = getattr(sa, key), getattr(sb, key)
        assert np.abs(x - y).max() <= 1e-10 * np.abs(y).max(), key


# ---------------------------------------------------------------------- optimization with lower < 0
def run_recording(cfg, max_iter):
    """The bundle iterations of ``contactopt run`` (Θ/Θ(α0), the same options), recording every
    design the oracle is asked about; returns the problem, those designs and J at the last iterate."""
    problem = ShapeProblem(cfg)
    model, opt = problem.model, cfg["optimizer"]
    alpha0 = model.initial_design()
    scale = abs(problem.evaluate_value(alpha0))
    seen = []

    def oracle(x):
        seen.append(np.array(x))
        f, g = problem.evaluate(x)
        return f / scale, g / scale
    res = minimize_bundle(oracle, alpha0, **model.admissible.constraints(), eps=opt["eps"], max_iter=max_iter,
                          **{k: opt[k] for k in ("ftol", "ftol_window", "metric", "metric_memory")})
    return problem, np.array(seen), res.fun * scale


def face_heights(model, X):
    ref = model.body.reference
    nodes = model.body.contact_face.nodes
    return X @ model.surface.basis_matrix(ref.points[nodes, 0], ref.points[nodes, 1]).T


def test_a_run_with_negative_lower_bound_keeps_the_face_above_the_plane():
    """Example 1 (on a coarser mesh) with lower = −0.1: every design the bundle method evaluates has
    ϑ_α ≥ 0 at every node of the contact face, and the run uses the room (negative control points,
    the face touching the plane: rows of ϑ_α ≥ 0 active)."""
    crowned = load_config("example1").with_updates({"mesh": {"nx": 16, "ny": 8, "nz": 5}, "design": {"lower": -0.1}})
    problem, X, _ = run_recording(crowned, 12)
    assert problem.model.admissible.gap_rows.size == 17 * 9
    theta = face_heights(problem.model, X)
    assert theta.min() >= -1e-9
    assert X.min() < -0.02                                   # control points below the paper's bound 0
    assert np.min(theta.min(axis=1)) < 1e-6                  # the face has reached the plane: rows active


@pytest.mark.slow
def test_example1_with_negative_lower_bound_to_its_stop():
    """The full Example 1 with lower = −0.1 to the stop: ϑ_α ≥ 0 at every iterate, J below the paper's."""
    cfg = load_config("example1").with_updates({"design": {"lower": -0.1}})
    problem, X, J = run_recording(cfg, cfg["optimizer"]["max_iter"])
    assert face_heights(problem.model, X).min() >= -1e-9
    assert J < 8.4e-8                                  # the paper's U: J = 8.36e-8 (docs)


def test_a_design_outside_U_is_solved_with_a_warning_naming_the_constraint(tmp_path, capsys, config_file):
    """α = 0.02 everywhere breaks only the mean value C2 = 0.01 (refused before lower bounds and designs outside U were taken)."""
    cfg = config_file(name="small", config=load_config("example1").with_updates(
        {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "name": "small"}).data)
    alpha = tmp_path / "a.json"
    alpha.write_text(json.dumps({"alpha": np.full((8, 4), 0.02).tolist()}))
    assert main(["state", str(cfg), "--alpha", str(alpha), "--out", str(tmp_path / "s")]) == 0
    warn = json.loads((tmp_path / "s" / "state.json").read_text())["warnings"]
    assert len(warn) == 2 and "(1 constraint(s) broken)" in warn[0]
    assert warn[1] == "volume: Σα = 0.64 ≠ C2·(d1+1)(d2+1) = 0.32"
    assert "contactopt: warning: volume: Σα = 0.64" in capsys.readouterr().err
    assert main(["state", str(cfg), "--out", str(tmp_path / "t")]) == 0      # α0 ∈ U: no warning
    assert json.loads((tmp_path / "t" / "state.json").read_text())["warnings"] == []


def test_with_initial_gap_mesh_the_rows_hold_the_total_gap(tmp_path, config_file):
    """initial_gap = "mesh": the constraint is height + ϑ_α ≥ 0; rows only where lower + height < 0."""
    _, mesh = crowned_configs(tmp_path, config_file)
    cfg = load_config(mesh).with_updates({"design": {"lower": -0.1}})
    model = ElasticModel(cfg)
    U = model.admissible
    nodes = model.body.contact_face.nodes
    height = paraboloid(*model.body.reference.points[nodes, :2].T)
    assert np.min(np.abs(height - 0.1)) > 1e-3
    assert np.array_equal(U.gap_rows, np.flatnonzero(height < 0.1))       # ℓ_k = lower = −0.1 here
    assert np.allclose(U.b_ub[-U.gap_rows.size:], height[U.gap_rows], rtol=0, atol=1e-15)
    assert U.is_feasible(np.zeros(9)) and U.violations(np.full(9, 0.0)) == []
    low = U.violations(np.full(9, -0.05))                                  # the face lowered by 0.05
    assert low[0].startswith("volume") and low[1:] == [f"gap: height + ϑ ≥ 0 broken at {np.sum(height < 0.05)} of 45 nodes of the contact face "
                   "(the face below the foundation plane), the deepest -0.05 at node 22 (1, 0.5)"]


@pytest.mark.parametrize("seed", range(3))
def test_worst_jacobian_ratio_on_the_box_is_attained_at_a_vertex(seed):
    """min over lower ≤ α ≤ C0 of 1 + Rα (the C0 check with a negative lower bound) equals the
    minimum over the box's vertices, and safe_C0 is the C0 where it meets the threshold."""
    from contactopt.mesh.morph import JacobianRatio
    rng = np.random.default_rng(seed)
    grad3 = rng.standard_normal((6, 2, 4))
    dx3 = rng.standard_normal((10, 4)) * 0.3
    elements = rng.integers(0, 10, (6, 4))
    jr = JacobianRatio(elements, grad3, dx3, 0.1)
    C0, lower = 0.4, -0.2
    vertices = np.array(np.meshgrid(*[[lower, C0]] * 4)).reshape(4, -1).T
    brute = min(jr.ratios(v).min() for v in vertices)
    assert np.isclose(jr.worst_on_box(C0, lower)[0], brute, rtol=0, atol=1e-14)
    safe = jr.safe_C0(lower)
    if np.isfinite(safe) and safe > lower:
        assert np.isclose(jr.worst_on_box(safe, lower)[0], 0.1, rtol=0, atol=1e-12)


# ------------------------------------------------------------------ the overlap warning
def _overlap_warnings(caplog, config):
    """The warnings of building ``config``'s model and checking its design space for a run, as
    (at construction, at the check)."""
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="contactopt"):
        model = ElasticModel(config)
        built = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        caplog.clear()
        model.check_design_space()
        checked = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    return built, checked


def test_an_overlap_is_warned_about_in_the_counterparts_terms_and_not_where_it_is_intended(caplog, small_config):
    """design.lower < 0 without nonnegative_gap lets designs overlap the counterpart: a run is warned
    on the foundation plane (as before) and on an obstacle (naming it); a state is not (it solves one
    design); a shrink fit (body.interference, the roller pressed into its race) intends the overlap:
    no warning, and none speaks of a plane."""
    loose = {"lower": -0.01, "nonnegative_gap": False}
    built, checked = _overlap_warnings(caplog, small_config(design=loose))
    assert built == []
    assert len(checked) == 1 and ("design.lower = -0.01 < 0 with design.nonnegative_gap = false: admissible "
                                  "designs may put the contact face below the foundation plane (an initial "
                                  "penetration; body.interference = true where the overlap is intended)") in checked[0]
    sphere = {"shape": "sphere", "center": [1.0, 0.5, -5.0], "radius": 5.0}
    built, checked = _overlap_warnings(caplog, small_config(design=loose, obstacle=sphere))
    assert built == [] and len(checked) == 1 and "put the contact face into the obstacle's sphere" in checked[0]
    roller = load_config(Path(__file__).resolve().parents[1] / "examples" / "roller_crowning_interference.toml")
    assert roller.body.interference and roller.design.lower < 0 and not roller.design.nonnegative_gap
    built, checked = _overlap_warnings(caplog, roller)
    assert built == [] and checked == []


def test_a_gap_row_broken_on_an_obstacle_names_the_obstacle():
    """The gap rows of U on an obstacle are distance + ϑ ≥ 0; a design breaking them is reported as
    the face moved into the obstacle (on the plane: below the foundation plane, as before)."""
    basis = np.full((3, 4), 0.25)
    for counterpart, expect in (("the obstacle's cylinder", "distance + ϑ ≥ 0 broken at 3 of 3 nodes of the "
                                 "contact face (the face into the obstacle's cylinder), the deepest -0.1 at node 7"),
                                ("the foundation plane", "height + ϑ ≥ 0 broken at 3 of 3 nodes of the contact "
                                 "face (the face below the foundation plane), the deepest -0.1 at node 7")):
        U = AdmissibleSet(1, 1, 1.0, 1.0, 1.0, 10.0, 0.0, lower=-1.0, gap_basis=basis, gap_offset=np.full(3, 0.1),
                          gap_nodes=np.array([7, 8, 9]), counterpart=counterpart)
        assert U.gap_violations(np.full(4, -0.2)) == [f"gap: {expect}"]
