"""Contact faces on a chart ([design] chart, motion; contactopt.design.chart): the fitted plane and
cylinder, designs moved along the face's normal, interference fits on a rigid counterpart, and bad
input refused with exit 2 and nothing written.

The set-up is Lamé's shrink fit (contactopt.verification.lame): a quarter hub whose bore (a
cylinder around x3) overlaps a rigid shaft by δ, plane strain, symmetry planes through the bore.
"""

import numpy as np
import pytest

from contactopt.config import load_config, validate
from contactopt.design.chart import fit_cylinder, fit_plane
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from contactopt.verification import lame


def hub(tmp_path, nr=4, nt=8, nz=2, angle=0.5 * np.pi, length=0.25, **kw):
    mesh = lame.quarter_hub_mesh(tmp_path / "hub.msh", nr, nt, nz, angle=angle, length=length)
    return lame.shrink_fit_config(mesh, length=length, **kw)


# ------------------------------------------------------------------ fits
def test_the_fitted_plane_and_cylinder_recover_the_geometry():
    rng = np.random.default_rng(2)
    n = np.array([1.0, -2.0, 2.0]) / 3.0
    e = np.linalg.svd(n[None])[2][1:]
    x = rng.random((50, 2)) @ e + [0.3, 0.1, -0.2]
    plane, res = fit_plane(x, np.tile(n, (50, 1)))
    assert res < 1e-12 and np.allclose(plane.normal, n)
    a = np.array([2.0, 1.0, -2.0]) / 3.0
    u = np.cross(a, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    t, s = rng.uniform(-1.0, 1.0, 60), rng.uniform(0.0, 3.0, 60)
    radial = np.cos(t)[:, None] * u + np.sin(t)[:, None] * v
    origin = np.array([1.0, -1.0, 0.5])
    x = origin + 2.5 * radial + s[:, None] * a
    cyl, res = fit_cylinder(x, radial)
    assert res < 1e-9 and abs(cyl.radius - 2.5) < 1e-9 and abs(abs(cyl.axis @ a) - 1) < 1e-12
    xi = cyl.parameters(x)
    # arc length on the fitted cylinder along its first coordinate, the axial position along the second
    assert np.allclose(np.diff(xi[:2, 0]) / 2.5, np.diff(t[:2]), atol=1e-9)


# ------------------------------------------------------------------ Lamé
def test_the_shrink_fit_pressure_converges_to_lames_at_second_order(tmp_path):
    p = lame.pressure_rigid_shaft()
    errors = []
    for nr, nt in ((4, 8), (8, 16)):
        problem = ShapeProblem(validate(hub(tmp_path, nr, nt, 1), "lame"))
        assert problem.model.body.chart.kind == "cylinder"
        errors.append(lame.pressure_errors(problem, p))
    assert errors[1][1] < 0.003 and errors[0][1] < 0.01
    rate = np.log2(errors[0][0] / errors[1][0])
    assert rate > 1.8, errors


@pytest.mark.parametrize("degree", [(2, 1), (0, 2)])
def test_the_subgradient_with_normal_motion_on_a_cylinder_matches_central_differences(tmp_path, degree):
    cfg = validate(hub(tmp_path, degree=degree, friction=0.3,
                       objective={"type": "pressure_uniformity"}), "lame")
    problem = ShapeProblem(cfg)
    model = problem.model
    assert model.mesh.directions is not None and model.n_design == (degree[0] + 1) * (degree[1] + 1)
    alpha = 1e-4 * (1.0 + np.sin(np.arange(model.n_design)))
    st = problem.solve_state(alpha)
    assert st.counts["M3+"] + st.counts["M1"] > 0.8 * st.lam.size
    rep = check_gradient(problem, alpha, seed=3, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_a_design_along_the_normal_removes_the_interference_it_moves(tmp_path):
    # a constant ϑ = δ/2 along the bore's inward normal (outwards, radially) halves the interference:
    # the pressure stays uniform and halves (to O(δ): the bore's radius grows by δ/2 too; the
    # faceted bore's nodes move radially by exactly ϑ)
    problem = ShapeProblem(validate(hub(tmp_path, 8, 16, 1, degree=(1, 1)), "lame"))
    half = np.full(problem.model.n_design, 0.5 * lame.DELTA)
    _, p0, _ = lame.contact_pressure(problem)
    _, p1, _ = lame.contact_pressure(problem, half)
    assert np.ptp(p1) <= 1e-9 * p1.max() and np.ptp(p0) <= 1e-9 * p0.max()
    assert abs(p1[0] / p0[0] - 0.5) < 2 * lame.DELTA
    coords = problem.model.assemble(half).coords
    r = np.hypot(*coords[problem.model.contact_nodes, :2].T)
    assert np.allclose(r, lame.B + 0.5 * lame.DELTA, atol=1e-12)


# ------------------------------------------------------------------ bad input
def test_a_face_neither_plane_nor_cylinder_is_refused(state_refused):
    cfg = load_config("example1").with_updates({
        "mesh": {"nx": 4, "ny": 2, "nz": 2},
        "body": {"contact": {"box": [[-1.0, 3.0], [-1.0, 2.0], [-1.0, 2.0]]}, "clamped": "clamped"},
        "obstacle": {"shape": "sphere", "center": [1.0, 0.5, -5.0], "radius": 4.0}})
    state_refused(cfg, "design.chart = 'auto'", "is neither a plane nor a circular cylinder")


def test_an_overlap_without_interference_is_refused_naming_the_nodes(tmp_path, state_refused):
    data = hub(tmp_path)
    data["body"]["interference"] = False
    state_refused(data, "node(s) of the body lie inside the cylinder", "node 0 at (1, 0, 0)",
                  "body.interference = true")


def test_a_chart_axis_that_is_not_a_unit_vector_is_refused(tmp_path, state_refused):
    data = hub(tmp_path, design={"chart": "cylinder", "axis": [0.0, 0.0, 2.0]})
    state_refused(data, "design.axis", "unit vector")


def test_normal_motion_on_a_face_whose_normals_flip_is_refused(tmp_path, state_refused):
    # 0.6 of a bore seen as a plane: its normals near the two ends turn away from the best-fit plane's
    data = hub(tmp_path, nt=12, angle=1.2 * np.pi, length=2.5, design={"chart": "plane", "motion": "normal"})
    data["body"]["clamped"] = data["body"]["clamped"][2:] + [{"on": {"x1": 0.0}, "components": [1, 2]}]
    state_refused(data, "normals of the contact face bore flip", "graph over its chart")


@pytest.mark.parametrize("other", ["delassus", "fullspace"])
def test_the_delassus_and_fullspace_paths_on_a_cylindrical_chart_equal_the_condensation(tmp_path, other):
    # interference, normal motion and symmetry planes whose clamped u3 is a tangent of the bore
    # (E = 1e4; the test below takes the press fit at E = 1)
    problems = [ShapeProblem(validate(hub(tmp_path, friction=0.3, path=path, material={"E": 1e4},
                                          objective={"type": "pressure_uniformity"}), "lame"))
                for path in ("condensation", other)]
    cond, prob = problems
    assert prob.path.name == other
    alpha = 1e-4 * (1.0 + np.sin(np.arange(cond.model.n_design)))
    sc, so = cond.solve_state(alpha), prob.solve_state(alpha)
    assert np.array_equal(sc.classes, so.classes)
    assert np.abs(sc.lam - so.lam).max() <= 1e-9 * sc.lam.max()
    xc, xo = cond.evaluate(alpha)[1], prob.evaluate(alpha)[1]
    assert np.abs(xo - xc).max() <= 1e-7 * np.abs(xc).max()
    if other == "delassus":     # (the full-space ξ equals the condensation's, checked against differences above)
        rep = check_gradient(prob, alpha, seed=4, n_directions=2)
        assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_a_press_fit_without_load_on_the_fullspace_path_equals_the_condensation(tmp_path, friction):
    # L = 0: the full-space Newton measures its residuals against the overlap's forces, not against
    # 1 (the fit's forces are ~1e-4 here), so it converges to the condensation's state
    problems = [ShapeProblem(validate(hub(tmp_path, friction=friction, path=path), "lame"))
                for path in ("condensation", "fullspace")]
    cond, full = problems
    assert full.path.name == "fullspace" and not np.any(full.model.assemble(full.model.initial_design()).L)
    for alpha in (cond.model.initial_design(), 1e-4 * (1.0 + np.sin(np.arange(cond.model.n_design)))):
        sc, sf = cond.solve_state(alpha), full.solve_state(alpha)
        assert sf.converged and np.array_equal(sc.classes, sf.classes)
        assert np.abs(sf.lam - sc.lam).max() <= 1e-8 * sc.lam.max()
        assert np.abs(sf.tau - sc.tau).max() <= 1e-8 * sc.lam.max()
        assert np.abs(sf.u - sc.u).max() <= 1e-8 * np.abs(sc.u).max()


# ------------------------------------------------------------------ an elastic curved counterpart
def shaft(tmp_path, nt=8, nt_shaft=None, k=1, **kw):
    h = lame.quarter_hub_mesh(tmp_path / "hub.msh", 4 * k, nt * k, 1)
    s = lame.quarter_shaft_mesh(tmp_path / "shaft.msh", 3 * k, (nt_shaft or nt) * k, 1, radius=lame.B + lame.DELTA)
    return lame.shaft_config(h, s, **kw)


def test_the_shrink_fit_on_a_shaft_of_the_same_material_converges_to_lames_pressure(tmp_path):
    p = lame.pressure_equal_materials()
    errors = [lame.pressure_errors(ShapeProblem(validate(shaft(tmp_path, k=k), "lame")), p) for k in (1, 2)]
    assert errors[0][1] < 0.006 and errors[1][1] < 0.0015, errors
    assert np.log2(errors[0][0] / errors[1][0]) > 1.9, errors


def test_the_subgradient_on_an_elastic_curved_counterpart_matches_central_differences(tmp_path):
    cfg = validate(shaft(tmp_path, friction=0.3, objective={"type": "pressure_uniformity"}), "lame")
    problem = ShapeProblem(cfg)
    assert problem.model.foundation is not None and problem.model.frames is not None
    alpha = 1e-4 * (1.0 + np.sin(np.arange(problem.model.n_design)))
    st = problem.solve_state(alpha)
    assert st.counts["L"] == 0
    rep = check_gradient(problem, alpha, seed=5, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_the_hub_pushed_along_its_shaft_slides_as_a_whole_at_the_push_out_force(tmp_path):
    # friction 0.3, the fit, then the hub's end faces moved along x3 (displacement control): the force
    # grows while part of the interface sticks and stays at μΣλ once every node slides; against
    # 2πbLμp/4 within 2 %: the discretisation (-1.37 % here, -0.59 % and -0.32 % at 2× and 3× the
    # refinement, docs/charts.md), mostly the contact face's end rings free along x3
    h = lame.quarter_hub_mesh(tmp_path / "hub.msh", 4, 8, 2, ends=True)
    s = lame.quarter_shaft_mesh(tmp_path / "shaft.msh", 3, 8, 2, radius=lame.B + lame.DELTA, ends=True)
    pushes = [2e-4 * k for k in range(1, 9)]
    pr = ShapeProblem(validate(lame.push_out_config(h, s, len(pushes)), "push-out"))
    rows = lame.push_out(pr, pushes)
    force = np.array([r["force"] for r in rows])
    assert abs(force[0]) <= 1e-12 * force[-1]                  # the fit alone: no axial force
    assert rows[1]["stick"] > 0 and rows[-1]["slide"] == 1.0
    assert np.all(np.diff(force) >= -1e-9 * force[-1])
    assert force[-1] == pytest.approx(0.3 * rows[-1]["normal"], rel=1e-9)
    assert force[-1] == pytest.approx(2 * np.pi * lame.B * 0.25 * 0.3 * lame.pressure_equal_materials() / 4, rel=0.02)


def test_an_overlap_with_the_foundation_without_interference_is_refused(tmp_path, state_refused):
    data = shaft(tmp_path)
    data["body"]["interference"] = False
    state_refused(data, "contact node(s) of the body lie inside the foundation", "depth 0.001",
                  "body.interference = true")


def test_a_symmetry_plane_through_the_body_only_is_refused_on_a_foundation(tmp_path, state_refused):
    data = shaft(tmp_path)
    # the shaft's plane x1 = 0 clamped away from its surface only
    data["foundation"]["clamped"][0]["on"] = {"box": [[-0.1, 0.1], [-0.1, 0.5], [-0.1, 1.0]]}
    state_refused(data, "free at their partners on the foundation", "foundation.clamped")


@pytest.mark.parametrize("concave", [False, True])
def test_a_spherical_pad_on_a_spherical_seat_follows_hertz(tmp_path, concave):
    from contactopt.verification import two_spheres
    cfg = validate(two_spheres.two_spheres_config(tmp_path, 0.25, concave=concave), "hertz")
    problem = ShapeProblem(cfg)
    assert problem.model.body.chart.kind == "plane" and problem.model.foundation is not None
    r = two_spheres.measure(problem, concave)
    # coarse (h = a/2): within 2 %; docs/charts.md refines to h = a/8 (within 0.3 %)
    assert abs(r["a"] / r["a_H"] - 1) < 0.02 and abs(r["p0"] / r["p0_H"] - 1) < 0.02, r


def test_non_matching_meshes_of_the_shaft_carry_lames_mean_pressure(tmp_path):
    # the shaft's faceted surface sags between its nodes by more than the interference; the gaps are
    # measured to the cylinder its nodes lie on (surface smoothing), so the mean pressure converges
    p = lame.pressure_equal_materials()
    means = []
    for k in (1, 2):
        problem = ShapeProblem(validate(shaft(tmp_path, nt=8, nt_shaft=6, k=k), "lame"))
        st = problem.solve_state(problem.model.initial_design())
        means.append(st.lam.sum() / problem.model.contact_areas().sum() / p - 1)
    assert abs(means[1]) < 0.002 and abs(means[1]) < 0.3 * abs(means[0]), means


def test_the_roller_example_peaks_at_its_end_and_its_subgradient_matches_central_differences():
    from pathlib import Path
    problem = ShapeProblem(str(Path(__file__).parents[1] / "examples" / "roller_crowning.toml"))
    m = problem.model
    alpha = m.initial_design()
    st = problem.solve_state(alpha)
    x = m.body.reference.points[m.contact_nodes]
    p = st.lam / m.contact_areas()
    line = np.abs(x[:, 1]) < 1e-9
    mid, end = p[line & (x[:, 0] < 1e-9)][0], p[line & (x[:, 0] > 2 - 1e-9)][0]
    assert end > 1.5 * mid and p.max() == end          # the free end's edge peak
    rep = check_gradient(problem, alpha, seed=2, n_directions=2)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_the_exported_body_with_its_designed_bore_has_the_designs_state(tmp_path):
    from contactopt.io.export import export_design
    problem = ShapeProblem(validate(hub(tmp_path, friction=0.3), "lame"))
    alpha = 1e-4 * (1.0 + np.sin(np.arange(problem.model.n_design)))
    st = problem.solve_state(alpha)
    export_design(problem.model, alpha, tmp_path / "export", formats=["mesh"])
    again = ShapeProblem(load_config(tmp_path / "export" / "optimal_body.toml"))
    assert again.model.body.chart.kind == "cylinder"
    st2 = again.solve_state(again.model.initial_design())
    assert np.array_equal(st.classes, st2.classes)
    assert np.abs(st.lam - st2.lam).max() <= 1e-9 * st.lam.max()
