"""Dual-weighted gaps on rigid obstacles (``[obstacle] weighting = "mortar"``): the weights'
identities on irregular faces, the gaps they give, subgradients against central differences on
every path that takes an obstacle, and the faces that are refused.

The block and obstacles of tests/test_obstacles.py (a block 2 × 2 × 1 clamped at its top, its contact
face on x3 = 0, pushed onto the obstacle); hexahedra (quadrilateral faces) and the same grid split
into linear tetrahedra (triangular faces).
"""

import meshio
import numpy as np
import pytest

from contactopt.config import validate
from contactopt.errors import ConfigError
from contactopt.fem.mortar import dual_weighted
from contactopt.mesh.block import block_mesh
from contactopt.mesh.tetsplit import hex_to_tets, tet4_to_tet10
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from test_obstacles import CYLINDER, FORCED, SPHERE, block, tet_block


def irregular_face(seed=0, n=6):
    """A flat triangulated square [0, 1]² with its interior nodes moved at random by 30 % of h."""
    rng = np.random.default_rng(seed)
    g = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(g, g)
    pts = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    inner = (X.ravel() > 0) & (X.ravel() < 1) & (Y.ravel() > 0) & (Y.ravel() < 1)
    pts[inner, :2] += 0.3 / n * rng.uniform(-1, 1, (inner.sum(), 2))
    k = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, 1:].ravel(), k[1:, :-1].ravel()
    return pts, np.r_[np.c_[a, b, c], np.c_[a, c, d]]


def test_dual_weights_keep_linear_fields_and_the_integral_of_any_field():
    pts, tri = irregular_face()
    nodes = np.arange(pts.shape[0])

    def fields(x):
        return np.c_[2.0 - 3.0 * x[:, 0] + 0.5 * x[:, 1], np.exp(x[:, 0]) * np.cos(2 * x[:, 1])]

    D, v = dual_weighted("triangle", tri, pts, nodes, fields, degree=12)
    exact = fields(pts)
    # biorthogonality: a field linear on every face keeps its nodal values
    assert np.abs(v[:, 0] - exact[:, 0]).max() <= 1e-13
    # Σ_j Φ_j = 1: Σ_j D_jj v_j = ∫ f dA for every field; a curved field is not read at the node
    area_int = (np.exp(1.0) - 1.0) * np.sin(2.0) / 2.0
    assert abs(D @ v[:, 1] - area_int) <= 1e-9
    assert D.sum() == pytest.approx(1.0, abs=1e-13) and np.all(D > 0)
    assert np.abs(v[:, 1] - exact[:, 1]).max() > 1e-4


@pytest.mark.parametrize("cells", ["hexahedron", "tetra"])
def test_the_weighted_gap_on_a_sphere_is_the_nodal_gap_to_second_order(tmp_path, cells):
    # g̃_j − g_j = D_jj⁻¹ ∫ Φ_j (g − I g): the interpolation error of the curved gap, O(h²/R)
    obstacle = SPHERE
    cfg = block(obstacle) if cells == "hexahedron" else tet_block(tmp_path, obstacle)
    node = ShapeProblem(cfg)
    mortar = ShapeProblem(cfg.with_updates({"obstacle": {**obstacle, "weighting": "mortar"}}))
    h = 0.25
    d = mortar.model.gap0 - node.model.gap0
    assert 0 < np.abs(d).max() <= h * h / SPHERE["radius"]
    alpha = 0.002 * np.sin(np.arange(node.model.n_design)) + 0.001
    g_node = node.model.gap_matrix @ alpha + node.model.gap0
    g_mortar = mortar.model.gap_matrix @ alpha + mortar.model.gap0
    assert np.abs(g_mortar - g_node).max() <= h * h / SPHERE["radius"] + h * h * np.abs(alpha).max()


def test_node_weighting_is_the_default_bit_for_bit():
    alpha = 0.002 * np.sin(np.arange(12)) + 0.001
    a = ShapeProblem(block(SPHERE))
    b = ShapeProblem(block({**SPHERE, "weighting": "node"}))
    va, ga = a.evaluate(alpha)
    vb, gb = b.evaluate(alpha)
    assert va == vb and np.array_equal(ga, gb)


def test_mortar_weighting_on_the_plane_keeps_a_flat_face_and_weights_the_design():
    # on the plane the gap of a flat face is ϑ_α: the weighted gap of α = const is α itself; a
    # curved ϑ_α is weighted over the node's faces (Σ_j D_jj g̃_j = ∫ ϑ_α dA)
    plane = {"shape": "plane", "weighting": "mortar"}
    pr = ShapeProblem(block(plane))
    m = pr.model
    one = np.full(m.n_design, 0.003)
    assert np.abs(m.gap_matrix @ one + m.gap0 - 0.003).max() <= 1e-15
    node = ShapeProblem(block({"shape": "plane"})).model
    alpha = 0.002 * np.sin(np.arange(m.n_design)) + 0.001
    assert np.abs((m.gap_matrix - node.gap_matrix) @ alpha).max() > 1e-8


@pytest.mark.parametrize("shape", ["sphere", "cylinder", "plane"])
@pytest.mark.parametrize("cells", ["hexahedron", "tetra"])
def test_subgradient_with_weighted_gaps_matches_central_differences(tmp_path, shape, cells):
    obstacle = {"sphere": SPHERE, "cylinder": CYLINDER,
                "plane": {"shape": "plane", "control": "displacement", "displacement": [0.0, 0.0, 0.002]}}[shape]
    obstacle = {**obstacle, "weighting": "mortar"}
    cfg = block(obstacle) if cells == "hexahedron" else tet_block(tmp_path, obstacle)
    if shape == "plane":
        cfg = cfg.with_updates({"loads": {**cfg.data["loads"], "body_force": [0.0, 0.0, -0.02]}}) \
            if cells == "tetra" else cfg.with_updates({"loads": {"top_traction": [0.0, 0.0, 0.0],
                                                                 "right_traction": [0.01, 0.0, 0.0]}})
    problem = ShapeProblem(cfg)
    assert problem.model.body.reference.cell_type == cells
    alpha = 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001
    st = problem.solve_state(alpha)
    assert st.counts["M1"] > 0 and st.counts["M3+"] > 0          # slip and stick
    rep = check_gradient(problem, alpha, seed=1, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


@pytest.mark.parametrize("other", ["delassus", "fullspace"])
def test_the_other_paths_with_weighted_gaps_equal_the_condensation_and_match_central_differences(tmp_path, other):
    obstacle = {**SPHERE, "displacement": [0.003, 0.0, 0.05], "weighting": "mortar"}
    cond = ShapeProblem(tet_block(tmp_path, obstacle))
    prob = ShapeProblem(tet_block(tmp_path, obstacle).with_updates({"linear_solver": {"path": other}}))
    assert prob.path.name == other
    alpha = 0.002 * np.sin(np.arange(cond.model.n_design)) + 0.001
    sc, so = cond.solve_state(alpha), prob.solve_state(alpha)
    assert np.array_equal(sc.classes, so.classes) and so.counts["M1"] > 0 and so.counts["M3+"] > 0
    assert np.abs(sc.lam - so.lam).max() <= 1e-10 * sc.lam.max()
    rep = check_gradient(prob, alpha, seed=1, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_force_control_with_weighted_gaps_balances_the_force_and_matches_central_differences(tmp_path):
    obstacle = {**FORCED["sphere"], "weighting": "mortar"}
    problem = ShapeProblem(tet_block(tmp_path, obstacle))
    alpha = 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001
    st = problem.solve_state(alpha)
    assert st.info["obstacle_resultant"] == pytest.approx(np.linalg.norm(obstacle["force"]), rel=1e-12)
    assert st.counts["M1"] > 0 and st.counts["M3+"] > 0
    rep = check_gradient(problem, alpha, seed=2, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_quadratic_faces_and_unknown_weightings_are_refused(tmp_path):
    hexes = block_mesh(2.0, 2.0, 1.0, 4, 4, 2)
    pts, cells = tet4_to_tet10(hexes.points, hex_to_tets(hexes.cells))
    path = tmp_path / "tet10.vtu"
    meshio.write(path, meshio.Mesh(pts, [("tetra10", cells)]))
    cfg = tet_block(tmp_path, {**SPHERE, "weighting": "mortar"})
    data = {**cfg.data, "body": {**cfg.data["body"], "mesh": str(path)}}
    with pytest.raises(ConfigError, match="weighting = 'mortar' needs linear contact faces"):
        ShapeProblem(validate(data, "tet10"))
    with pytest.raises(ConfigError, match="obstacle.weighting"):
        validate({**cfg.data, "obstacle": {**SPHERE, "weighting": "dual"}}, "bad")
