"""Rigid obstacles of any shape ([obstacle], contactopt.mesh.obstacle): frames, gaps, states and
subgradients; bad input refused with exit 2 and nothing written.

A block 2 × 2 × 1 clamped at its top, its contact face on x3 = 0, pushed onto the obstacle by a
prescribed rigid translation of the obstacle (control = "displacement").
"""

import meshio
import numpy as np
import pytest
import tomli_w

from contactopt.cli import main
from contactopt.config import load_config, validate
from contactopt.errors import ConfigError
from contactopt.mesh.block import block_mesh
from contactopt.mesh.obstacle import Cylinder, Sphere, closest_on_triangles, read_surface, tangent_frames
from contactopt.mesh.tetsplit import hex_to_tets
from contactopt.paths import select_path
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

R = 5.0
SPHERE = {"shape": "sphere", "center": [1.0, 1.0, -R], "radius": R, "control": "displacement",
          "displacement": [0.0, 0.0, 0.05]}
CYLINDER = {"shape": "cylinder", "point": [1.0, 0.0, -R], "axis": [0.0, 1.0, 0.0], "radius": R,
            "control": "displacement", "displacement": [0.0, 0.0, 0.02]}


def block(obstacle=None, friction=0.3, n=4, path="condensation", **updates):
    """The block (mesh 2n × 2n × 3) with ``obstacle`` ([obstacle] table, or None for none)."""
    common = {"friction": {"coefficient": friction}, "linear_solver": {"path": path},
              "material": {"nu": 0.3}, "state": {"method": "newton", "tol": 1e-12},
              "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
              "design": {"degree": [3, 2], "initial": 0.0, "C2": 0.0},
              "geometry": {"a": 2.0, "b": 2.0, "c": 1.0}, "mesh": {"nx": 2 * n, "ny": 2 * n, "nz": 3},
              "body": {"clamped": "top"}}
    if obstacle is not None:
        common["obstacle"] = obstacle
    common.update(updates)
    return load_config("example1").with_updates(common)


def prism(path, polygon, y0, y1):
    """A closed STL: the star-shaped ``polygon`` [(x1, x3), …] (counter-clockwise about its
    centroid) extruded along x2 from y0 to y1, its caps fanned from the centroid."""
    poly = np.asarray(polygon, float)
    k = len(poly)
    c = poly.mean(axis=0)
    pts = [(u, y0, v) for u, v in poly] + [(u, y1, v) for u, v in poly] + [(c[0], y0, c[1]), (c[0], y1, c[1])]
    tri = []
    for i in range(k):
        j = (i + 1) % k
        tri += [(i, j, k + j), (i, k + j, k + i), (2 * k, j, i), (2 * k + 1, k + i, k + j)]
    meshio.write(path, meshio.Mesh(np.asarray(pts), [("triangle", np.asarray(tri))]), file_format="stl", binary=True)
    return str(path)


def polygonal_cylinder(path, sides=48):
    """A closed STL of the cylinder CYLINDER (its axis along x2), a prism of ``sides`` sides with a
    vertex at the top, longer than the block."""
    t = 0.5 * np.pi + 2 * np.pi * np.arange(sides) / sides
    return prism(path, np.c_[1.0 + R * np.cos(t), -R + R * np.sin(t)], -1.0, 3.0)


# ------------------------------------------------------------------ geometry
def test_closest_points_on_triangles_against_a_dense_sampling():
    rng = np.random.default_rng(3)
    P = rng.standard_normal((5, 3, 3))
    x = 2 * rng.standard_normal((40, 3))
    got = closest_on_triangles(x, P)
    s, t = np.meshgrid(np.linspace(0, 1, 401), np.linspace(0, 1, 401))
    keep = s + t <= 1
    bary = np.c_[1 - s[keep] - t[keep], s[keep], t[keep]]
    for k in range(5):
        samples = bary @ P[k]
        d = np.linalg.norm(samples[None] - x[:, None], axis=2).min(axis=1)
        dist = np.linalg.norm(got[:, k] - x, axis=1)
        assert np.all(dist <= d + 1e-12) and np.all(dist >= d - 5e-3)


def test_frames_are_right_handed_and_the_plane_gets_the_axes():
    n = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [1.0, 0.0, 0.0], [0.0, -0.6, 0.8]])
    R_ = tangent_frames(n)
    assert np.array_equal(R_[0], np.eye(3))
    assert np.allclose(np.einsum("kij,kil->kjl", R_, R_), np.eye(3), atol=1e-15)
    assert np.allclose(np.linalg.det(R_), 1.0)
    x = np.array([[1.0, 1.0, 0.0], [3.0, 1.0, 0.0]])
    fr = Sphere([1.0, 1.0, -R], R).frames(x)
    assert np.allclose(fr.distance, [0.0, np.hypot(2.0, R) - R])
    fc = Cylinder([1.0, 0.0, -R], [0.0, 3.0, 0.0], R).frames(x)
    assert np.allclose(fc.distance, fr.distance) and np.allclose(fc.normal, fr.normal)


def test_a_polygonal_cylinder_from_stl_gives_distances_of_its_facets(tmp_path):
    surf = read_surface(polygonal_cylinder(tmp_path / "c.stl"))
    x = np.array([[1.0, 0.5, 0.1], [1.4, 1.5, 0.3], [1.0, 1.0, -R]])
    d = surf.frames(x).distance
    exact = Cylinder([1.0, 0.0, -R], [0, 1, 0], R).frames(x).distance
    inscribed = R * (1 - np.cos(np.pi / 48))            # the facets lie inside the circle
    assert np.allclose(d[:2], exact[:2], atol=inscribed + 1e-12) and d[0] == pytest.approx(0.1)
    assert d[2] == pytest.approx(-2.0)          # on the axis, inside: nearest the end cap at x2 = 3


# ------------------------------------------------------------------ the plane is the default
def test_the_plane_obstacle_is_the_default_bit_for_bit():
    alpha = 0.002 + 0.003 * np.sin(np.arange(12))
    cfg = block(friction=0.3, loads={"top_traction": [0.0, 0.0, -0.05], "right_traction": [0.02, 0.0, 0.0]})
    a = ShapeProblem(cfg)
    b = ShapeProblem(cfg.with_updates({"obstacle": {"shape": "plane"}}))
    assert b.model.frames is None
    va, ga = a.evaluate(alpha)
    vb, gb = b.evaluate(alpha)
    sa, sb = a.solve_state(alpha), b.solve_state(alpha)
    assert va == vb and np.array_equal(ga, gb)
    assert np.array_equal(sa.u, sb.u) and np.array_equal(sa.lam, sb.lam) and np.array_equal(sa.tau, sb.tau)


def test_a_closed_box_from_stl_under_the_face_is_the_plane(tmp_path):
    # frames (e1, e2, e3) and distance x3 from the facets of a box: the plane's state to round-off
    box = prism(tmp_path / "box.stl", [(-1.0, -1.0), (3.0, -1.0), (3.0, 0.0), (-1.0, 0.0)], -1.0, 3.0)
    d = {"control": "displacement", "displacement": [0.0, 0.0, 0.01]}
    plane = ShapeProblem(block({"shape": "plane", **d}, loads={"right_traction": [0.01, 0.0, 0.0]}))
    stl = ShapeProblem(block({"shape": "surface", "mesh": box, **d}, loads={"right_traction": [0.01, 0.0, 0.0]}))
    assert stl.model.frames is not None and np.allclose(stl.model.frames, np.eye(3), atol=0)
    alpha = 0.004 * np.cos(np.arange(12))
    sp, ss = plane.solve_state(alpha), stl.solve_state(alpha)
    assert np.array_equal(sp.classes, ss.classes) and sp.counts["M1"] > 0 and sp.counts["M3+"] > 0
    assert np.abs(sp.lam - ss.lam).max() <= 1e-10 * sp.lam.max()
    assert np.abs(sp.u - ss.u).max() <= 1e-10 * np.abs(sp.u).max()


# ------------------------------------------------------------------ subgradients
def tet_block(tmp_path, obstacle, friction=0.3):
    """The block as a file of linear tetrahedra (each hexahedron split into six), mesh 8 × 8 × 3."""
    hexes = block_mesh(2.0, 2.0, 1.0, 8, 8, 3)
    path = tmp_path / "tets.vtu"
    meshio.write(path, meshio.Mesh(hexes.points, [("tetra", hex_to_tets(hexes.cells))]))
    cfg = block(obstacle, friction)
    data = {k: v for k, v in cfg.data.items() if k not in ("geometry", "mesh")}
    data["body"] = {**data["body"], "mesh": str(path), "clamped": {"x3": 1.0}, "contact": {"x3": 0.0}}
    data["loads"] = {"body_force": [0.0, 0.0, 0.0]}
    return validate(data, "tets")


@pytest.mark.parametrize("shape", ["sphere", "cylinder", "surface"])
@pytest.mark.parametrize("cells", ["hexahedron", "tetra"])
def test_subgradient_on_an_obstacle_matches_central_differences(tmp_path, shape, cells):
    obstacle = {"sphere": SPHERE, "cylinder": CYLINDER,
                "surface": {**CYLINDER, "shape": "surface", "mesh": polygonal_cylinder(tmp_path / "c.stl")}}[shape]
    cfg = block(obstacle) if cells == "hexahedron" else tet_block(tmp_path, obstacle)
    problem = ShapeProblem(cfg)
    assert problem.model.frames is not None and problem.model.body.reference.cell_type == cells
    alpha = 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001
    st = problem.solve_state(alpha)
    assert st.counts["M1"] > 0 and st.counts["M3+"] > 0          # slip and stick: friction acts in the frames
    rep = check_gradient(problem, alpha, seed=1, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


def equal_to_condensation(cond, prob, alpha, tol, seed):
    """Asserts that ``prob``'s state at ``alpha`` equals the condensation path's (the same classes,
    some sliding and some sticking; λ and u to ``tol`` relative), ξ to 1e-8, and that its ξ
    matches central differences to 1e-6; returns both states and the check's report."""
    sc, so = cond.solve_state(alpha), prob.solve_state(alpha)
    assert np.array_equal(sc.classes, so.classes) and so.counts["M1"] > 0 and so.counts["M3+"] > 0
    assert np.abs(sc.lam - so.lam).max() <= tol * sc.lam.max()
    assert np.abs(sc.u - so.u).max() <= tol * np.abs(sc.u).max()
    xc, xo = cond.evaluate(alpha)[1], prob.evaluate(alpha)[1]
    assert np.abs(xo - xc).max() <= 1e-8 * np.abs(xc).max()
    rep = check_gradient(prob, alpha, seed=seed, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    return sc, so, rep


@pytest.mark.parametrize("shape", ["sphere", "cylinder", "surface"])
@pytest.mark.parametrize("cells", ["hexahedron", "tetra"])
@pytest.mark.parametrize("other", ["delassus", "fullspace"])
def test_the_delassus_and_fullspace_paths_on_an_obstacle_equal_the_condensation_and_match_central_differences(
        tmp_path, other, shape, cells):
    # the Delassus operator and the full-space Newton system in the nodes' frames, against the
    # rotated condensed system
    obstacle = {"sphere": {**SPHERE, "displacement": [0.003, 0.0, 0.05]}, "cylinder": CYLINDER,
                "surface": {**CYLINDER, "shape": "surface", "mesh": polygonal_cylinder(tmp_path / "c.stl")}}[shape]
    problems = []
    for path in ("condensation", other):
        cfg = block(obstacle, path=path) if cells == "hexahedron" else tet_block(tmp_path, obstacle)
        if cells != "hexahedron":
            cfg = cfg.with_updates({"linear_solver": {"path": path}})
        problems.append(ShapeProblem(cfg))
    cond, dela = problems
    assert dela.path.name == other
    alpha = 0.002 * np.sin(np.arange(cond.model.n_design)) + 0.001
    _, _, rep = equal_to_condensation(cond, dela, alpha, 1e-10, seed=1)
    # (the full-space Newton stops at 1e-10, the floor of its Taylor remainders at the smallest steps)
    assert other == "fullspace" or rep.taylor_rate >= 1.9


FORCED = {"sphere": {**SPHERE, "control": "force", "force": [0.0, 0.0, 1.2]},
          "cylinder": {**CYLINDER, "control": "force", "force": [0.3, 0.0, 1.0]}}


@pytest.mark.parametrize("shape,cells", [("sphere", "hexahedron"),
                                         pytest.param("sphere", "tetra", marks=pytest.mark.slow),
                                         pytest.param("cylinder", "hexahedron", marks=pytest.mark.slow),
                                         pytest.param("cylinder", "tetra", marks=pytest.mark.slow),
                                         pytest.param("surface", "hexahedron", marks=pytest.mark.slow),
                                         pytest.param("surface", "tetra", marks=pytest.mark.slow)])
def test_force_control_balances_the_force_and_its_subgradient_matches_central_differences(tmp_path, shape, cells):
    obstacle = FORCED.get(shape) or {**FORCED["cylinder"], "shape": "surface",
                                     "mesh": polygonal_cylinder(tmp_path / "c.stl")}
    cfg = block(obstacle) if cells == "hexahedron" else tet_block(tmp_path, obstacle)
    problem = ShapeProblem(cfg)
    alpha = 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001
    st = problem.solve_state(alpha)
    f = np.asarray(obstacle["force"])
    assert st.info["obstacle_resultant"] == pytest.approx(np.linalg.norm(f), rel=1e-12)
    assert st.counts["M1"] > 0 and st.counts["M3+"] > 0
    # the same obstacle moved by the translation found gives the same state (displacement control)
    s = st.info["obstacle_translation"]
    moved = {**obstacle, "control": "displacement", "displacement": (s * f / np.linalg.norm(f)).tolist()}
    cfg2 = block(moved) if cells == "hexahedron" else tet_block(tmp_path, moved)
    st2 = ShapeProblem(cfg2).solve_state(alpha)
    assert np.abs(st2.lam - st.lam).max() <= 1e-10 * st.lam.max()
    rep = check_gradient(problem, alpha, seed=2, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


def test_a_tangential_translation_drags_the_face_and_its_subgradient_matches_central_differences():
    # the contact law sees the slip relative to the moved obstacle: the friction force follows
    # the translation's tangential part; the state's u_c is that relative displacement
    moved = {**SPHERE, "displacement": [0.004, 0.002, 0.05]}
    problem = ShapeProblem(block(moved))
    alpha = 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001
    st, st0 = problem.solve_state(alpha), ShapeProblem(block(SPHERE)).solve_state(alpha)
    m = problem.model
    force = np.einsum("mij,mj->i", m.frames, np.c_[-st.tau, st.lam])
    force0 = np.einsum("mij,mj->i", m.frames, np.c_[-st0.tau, st0.lam])
    drag = force - force0
    assert drag[0] > 100 * abs(force0[0]) and drag[1] > 100 * abs(force0[1])
    slid = st.class_names == "M1"
    u_body = st.u.reshape(-1, 3)[m.contact_nodes]
    w = np.einsum("mij,mi->mj", m.frames, u_body) - m.slip_shift          # relative, per node frame
    assert np.abs(w - st.u_c).max() <= 1e-12 * np.abs(u_body).max() and slid.any()
    rep = check_gradient(problem, alpha, seed=3, n_directions=3)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_the_obstacle_gap_and_its_design_derivative():
    # g_m = d_m + n3 ϑ_α − d·n_m at the contact nodes (mesh.obstacle)
    problem = ShapeProblem(block(SPHERE))
    m = problem.model
    x = m.body.reference.points[m.contact_nodes]
    fr = Sphere(SPHERE["center"], R).frames(x)
    alpha = 0.01 * np.cos(np.arange(m.n_design))
    theta = m.surface.basis_matrix(x[:, 0], x[:, 1]) @ alpha
    expect = fr.distance + fr.normal[:, 2] * theta - fr.normal @ SPHERE["displacement"]
    assert np.allclose(m.assemble(alpha).gap, expect, atol=1e-15)


# ------------------------------------------------------------------ bad input
def write(tmp_path, cfg, name="c.toml"):
    path = tmp_path / name
    path.write_text(tomli_w.dumps(cfg.data if hasattr(cfg, "data") else cfg))
    return path


def test_a_body_node_inside_the_obstacle_exits_2_and_writes_nothing(tmp_path, capsys, state_refused):
    deep = {**SPHERE, "center": [1.0, 1.0, -R + 0.05]}
    state_refused(write(tmp_path, block(deep)), "node(s) of the body lie inside the sphere",
             "depth 0.05")


def test_unknown_obstacle_keys_and_missing_radius_exit_2(tmp_path, capsys, state_refused):
    data = block().data
    data["obstacle"] = {"shape": "sphere", "center": [1.0, 1.0, -5.0], "raduis": 5.0}
    state_refused(write(tmp_path, data), "obstacle.raduis: unknown key", "obstacle.radius: required")


def test_an_stl_that_is_not_closed_exits_2(tmp_path, capsys, state_refused):
    good = polygonal_cylinder(tmp_path / "c.stl", sides=12)
    m = meshio.read(good)
    meshio.write(tmp_path / "open.stl", meshio.Mesh(m.points, [("triangle", m.cells[0].data[1:])]), file_format="stl", binary=True)
    obstacle = {**CYLINDER, "shape": "surface", "mesh": str(tmp_path / "open.stl")}
    state_refused(write(tmp_path, block(obstacle)), "is not closed", "not shared by exactly two")


def test_a_contact_node_whose_closest_point_is_not_unique_exits_2(tmp_path, capsys, state_refused):
    # a V groove along x2 under x1 = 1: the nodes above its bottom line are as close to both flanks
    groove = prism(tmp_path / "v.stl", [(-1.0, -1.0), (3.0, -1.0), (3.0, -0.1), (1.0, -0.3), (-1.0, -0.1)],
                   -1.0, 3.0)
    state_refused(write(tmp_path, block({"shape": "surface", "mesh": groove})),
             "closest point on the surface is not unique for 9 node(s)", "node 4 at (1, 0, 0)")


@pytest.mark.parametrize("shape,cells", [("sphere", "hexahedron"), ("sphere", "tetra"),
                                         pytest.param("cylinder", "hexahedron", marks=pytest.mark.slow),
                                         pytest.param("cylinder", "tetra", marks=pytest.mark.slow),
                                         pytest.param("surface", "hexahedron", marks=pytest.mark.slow),
                                         pytest.param("surface", "tetra", marks=pytest.mark.slow)])
@pytest.mark.parametrize("other", ["delassus", "fullspace"])
def test_force_control_on_the_delassus_and_fullspace_paths_equals_the_condensation(tmp_path, other, shape, cells):
    # one Brent iteration and one subgradient (paths/force.py) on three ways to solve a state: the
    # translation, the state and ξ agree, and ξ matches central differences
    obstacle = FORCED.get(shape) or {**FORCED["cylinder"], "shape": "surface",
                                     "mesh": polygonal_cylinder(tmp_path / "c.stl")}
    problems = []
    for path in ("condensation", other):
        cfg = block(obstacle, path=path) if cells == "hexahedron" else tet_block(tmp_path, obstacle)
        problems.append(ShapeProblem(cfg.with_updates({"linear_solver": {"path": path}})))
    cond, prob = problems
    assert prob.path.name == other
    alpha = 0.002 * np.sin(np.arange(cond.model.n_design)) + 0.001
    sc, so, _ = equal_to_condensation(cond, prob, alpha, 1e-8, seed=2)
    s = sc.info["obstacle_translation"]
    assert abs(so.info["obstacle_translation"] - s) <= 1e-8 * abs(s)
    assert so.info["obstacle_resultant"] == pytest.approx(np.linalg.norm(obstacle["force"]), rel=1e-9)


@pytest.mark.parametrize("path", ["condensation", pytest.param("delassus", marks=pytest.mark.slow),
                                  pytest.param("fullspace", marks=pytest.mark.slow)])
def test_an_objective_of_the_whole_displacement_under_force_control_matches_central_differences(path):
    # the body's displacement u_c = w + s e moves with the translation also at fixed law displacement w:
    # a force with a tangential part in the nodes' frames (e ≠ 0)
    problem = ShapeProblem(block(FORCED["cylinder"], path=path, objective={"type": "peak_stress"}))
    alpha = 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001
    assert np.abs(problem.model.force_b[:, :2]).max() > 0.1
    rep = check_gradient(problem, alpha, seed=2, n_directions=3)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_the_plane_moved_tangentially_on_the_delassus_and_fullspace_paths_equals_the_condensation():
    # the translation's tangential part is the law's reference on every path, the plane's frames the axes
    obstacle = {"shape": "plane", "control": "displacement", "displacement": [0.003, 0.001, 0.02]}
    states = [ShapeProblem(block(obstacle, path=path)).solve_state(np.full(12, 0.001))
              for path in ("condensation", "delassus", "fullspace")]
    sc = states[0]
    assert sc.counts["M1"] > 0 and sc.counts["M3+"] > 0
    for st in states[1:]:
        assert np.array_equal(st.classes, sc.classes)
        assert np.abs(st.lam - sc.lam).max() <= 1e-10 * sc.lam.max()
        assert np.abs(st.u - sc.u).max() <= 1e-10 * np.abs(sc.u).max()


def test_a_zero_force_a_foundation_and_the_other_paths_are_refused(tmp_path, capsys, state_refused):
    state_refused(write(tmp_path, {**block().data, "obstacle": {**SPHERE, "control": "force"}}),
             "obstacle.force = [0, 0, 0]", "no component along any free direction")
    with pytest.raises(ConfigError, match="no contact node's normal has a component along the force"):
        ShapeProblem(block({**SPHERE, "control": "force", "force": [0.0, 0.0, -1.0]}))
    with pytest.raises(ConfigError, match=r"\[obstacle\] and \[foundation\] exclude each other"):
        block(SPHERE, foundation={"block": {"size": [3.0, 3.0, 1.0], "cells": [3, 3, 1]}})
    # force control on the paths that take obstacles (the PETSc path's: tests/test_petsc_bodies.py)
    for path in ("delassus", "fullspace"):
        assert select_path(block(FORCED["sphere"], path=path), 1000)[0] == path
        assert select_path(block({"shape": "plane", "control": "force", "force": [0.0, 0.0, 1.0]}, path=path),
                           10)[0] == path
    assert select_path(block(FORCED["sphere"], path="auto"), 10 ** 7)[0] == "condensation"
    for path in ("delassus", "fullspace"):
        assert select_path(block(SPHERE, path=path), 1000)[0] == path
    assert select_path(block(SPHERE, path="auto"), 10 ** 7)[0] == "condensation"
    # the plane takes every path, with a translation too
    assert select_path(block({"shape": "plane", "control": "displacement"}, path="fullspace"), 10)[0] == "fullspace"


# ------------------------------------------------------------------ Hertz (coarse; benchmarks/hertz.py refines)
def test_hertz_contact_of_a_sphere_and_a_cylinder_on_coarse_meshes():
    from contactopt.verification.hertz import A_TARGET, measure_cylinder, measure_sphere
    s = measure_sphere(A_TARGET / 3)
    assert s["counts"]["M1"] > 10 and s["counts"]["M2"] == 0
    assert abs(s["a"] / s["a_H"] - 1) < 0.01 and abs(s["p0"] / s["p0_H"] - 1) < 0.01
    assert abs(s["delta_corr"] / s["delta_H"] - 1) < 0.01
    c = [measure_cylinder(A_TARGET / k) for k in (3, 6)]
    err = [abs(q["p0"] / q["p0_H"] - 1) for q in c]
    assert err[1] < err[0] < 0.01
    assert abs(c[1]["a"] / c[1]["a_H"] - 1) < 0.005


@pytest.mark.slow
def test_monotonic_indentation_with_friction_changes_the_hertz_pressure_by_a_few_percent():
    """Goodman's coupling under monotonic loading (docs/obstacles.md, "Friction"): the sphere's force
    raised in 8 load steps with F = 0.3 (ν = 0.3, β = 0.29, h = a/3) against the frictionless run and
    the static (one-step) problem. Measured (benchmarks/goodman.py --steps): the centre pressure
    +5.7 % (static +6.0 %), the fitted contact radius −1.2 %, the approach −0.7 %; the last
    increment's stick zone c/a = 0.89 (static 0.59). Bounds: a few percent and below the static
    problem's change (sticking from the unloaded state resists more than sticking from capture)."""
    from contactopt.verification.hertz import A_TARGET, P_SPHERE, fit, pressure, sphere_problem

    def measure(friction, steps=0):
        pr = sphere_problem(A_TARGET / 3, friction, steps=steps)
        st = pr.solve_state(np.zeros(pr.model.n_design))
        r, p, _, _ = pressure(pr, st)
        A = pr.model.contact_areas()
        stick = (st.class_names == "M3+") & (st.lam > 0)
        out = {"p0": float(p[np.argmin(r)]), "a": fit(r, p)[0], "delta": st.obstacle.translation,
               "c": float(np.sqrt(A[stick].sum() / A[st.lam > 0].sum()))}
        if steps:
            out["forces"] = [s.obstacle.resultant for _, _, s in pr.step_results()]
        return out

    free, static, monotonic = measure(0.0), measure(0.3), measure(0.3, steps=8)
    assert monotonic["forces"] == pytest.approx(P_SPHERE / 4 * np.arange(1, 9) / 8, rel=1e-12)
    rise = {k: q["p0"] / free["p0"] - 1 for k, q in (("static", static), ("monotonic", monotonic))}
    assert 0.03 < rise["monotonic"] < rise["static"] < 0.08, rise
    assert -0.02 < monotonic["a"] / free["a"] - 1 < 0
    assert -0.01 < monotonic["delta"] / free["delta"] - 1 < 0
    assert monotonic["c"] > static["c"] + 0.2


@pytest.mark.slow
def test_the_stick_zone_of_monotonic_indentation_is_the_frictional_flat_punchs():
    """The sphere's force in 4 load steps, F = 0.3, ν = 0.3, h = a/6: the stick–slip boundary of the
    last increment lies between the last sticking and the first slipping node (0.87 a and 0.92 a,
    a fitted), and Spence's ratio from the punch's integral equations, c/a = 0.898–0.902, lies
    between them: two independent computations agree to the mesh's ring spacing."""
    from contactopt.verification.hertz import A_TARGET, fit, pressure, sphere_problem
    from contactopt.verification.spence import punch_system, stick_ratio
    pr = sphere_problem(A_TARGET / 6, 0.3, steps=4)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    r, p, _, _ = pressure(pr, st)
    a = fit(r, p)[0]
    names = st.class_names
    stick = r[(names == "M3+") & (st.lam > 0)].max() / a
    slip = r[(names == "M1") & (st.lam > 0)].min() / a
    lo, hi = stick_ratio(punch_system(0.3, 200), 0.3)
    assert stick < lo < hi < slip, (stick, lo, hi, slip)
    assert slip - stick < 0.06                     # one ring of nodes: the comparison is that sharp


def test_the_frictional_flat_punch_from_the_half_space_integral_equations():
    """The reference stick ratio of the monotonic frictional Hertz indentation (verification/spence.py):
    its collocation reproduces the frictionless punch (P = 2aE*δ) and the fully bonded one
    (Mossakovskii's ln(3 − 4ν)/(2β)) to 2e-5, and gives c/a = 0.90 at β/F = 0.95 (ν = 0.3, F = 0.3;
    0.897–0.903 on 120 rings, 0.898–0.901 on 200), the slip annulus vanishing as F grows."""
    import math

    from contactopt.verification.spence import load_ratio, punch_system, stick_ratio
    system = punch_system(0.3, 120)
    assert load_ratio(system, bonded=False) == pytest.approx(1.0, abs=2e-5)
    assert load_ratio(system, bonded=True) == pytest.approx(math.log(3 - 4 * 0.3) / (2 * system.beta), rel=2e-5)
    lo, hi = stick_ratio(system, 0.3)
    assert 0.89 < lo < hi < 0.91
    assert stick_ratio(system, 0.6)[0] > hi and stick_ratio(system, 1.0)[0] > 0.999


def test_the_state_command_on_a_force_controlled_sphere_writes_the_frames(tmp_path):
    out = tmp_path / "st"
    assert main(["state", str(write(tmp_path, block(FORCED["sphere"]))), "--out", str(out)]) == 0
    vtu = meshio.read(next(out.rglob("*.vtu")))
    n, f = vtu.point_data["obstacle_normal"], vtu.point_data["contact_force"]
    on = vtu.point_data["contact_node"] == 1
    assert np.allclose(np.linalg.norm(n[on], axis=1), 1.0)
    assert f[:, 2].sum() == pytest.approx(1.2, rel=1e-12)      # the force control's resultant


def test_the_saddle_example_rests_on_its_pipe_with_the_pressure_peaking_in_the_middle():
    from pathlib import Path
    problem = ShapeProblem(str(Path(__file__).parents[1] / "examples" / "saddle.toml"))
    m = problem.model
    assert np.abs(m.gap0).max() < 1e-12            # the underside conforms to the pipe
    st = problem.solve_state(m.initial_design())
    p = st.lam / m.contact_areas()
    x1 = m.body.reference.points[m.contact_nodes, 0]
    assert st.info["obstacle_resultant"] == pytest.approx(0.2, rel=1e-12)
    assert p[np.abs(x1 - 1.0) < 1e-9].min() > 2 * p[np.abs(x1 - 0.25) < 1e-9].max()


# ------------------------------------------------------------------ symmetry planes through the contact face
def punch_stl(path, radius, centre=(1.0, 1.0), sides=48):
    """A closed STL of a flat punch: the ``sides``-gon of circumradius ``radius`` about the vertical
    through ``centre`` (vertices on the x1 and x2 directions), its top on x3 = 0."""
    t = 2 * np.pi * np.arange(sides) / sides
    ring = np.c_[centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)]
    pts = np.r_[np.c_[ring, np.zeros(sides)], np.c_[ring, np.full(sides, -2.0)], [[*centre, 0.0], [*centre, -2.0]]]
    tri = []
    for i in range(sides):
        j = (i + 1) % sides
        tri += [(i, sides + i, sides + j), (i, sides + j, j), (2 * sides, i, j), (2 * sides + 1, sides + j, sides + i)]
    meshio.write(path, meshio.Mesh(pts, [("triangle", np.asarray(tri))]), file_format="stl", binary=True)
    return str(path)


@pytest.mark.parametrize("shape", ["sphere", "punch"])
def test_a_quarter_model_on_an_obstacle_equals_the_full_model(tmp_path, shape):
    # the full block 2 × 2 × 1 (8 × 8 × 3) and its quarter [0, 1]² with u1 = 0 on x1 = 1 and u2 = 0
    # on x2 = 1, pressed by the obstacle centred on (1, 1); on the punch the nodes of x2 = 1 outside
    # its rim have the normal ±e1 and take t2 = e2 (the clamped direction) in the quarter
    obstacle = SPHERE if shape == "sphere" else \
        {"shape": "surface", "mesh": punch_stl(tmp_path / "p.stl", 0.6), "control": "displacement",
         "displacement": [0.0, 0.0, 0.01]}
    design = {"degree": [2, 2], "initial": 0.0, "C2": 0.0, "domain": [[0.0, 2.0], [0.0, 2.0]]}
    full = ShapeProblem(block(obstacle, design=design))
    quarter = ShapeProblem(block(obstacle, design=design, geometry={"a": 1.0, "b": 1.0, "c": 1.0},
                                 mesh={"nx": 4, "ny": 4, "nz": 3},
                                 body={"clamped": ["top", {"on": {"x1": 1.0}, "components": [1]},
                                                   {"on": {"x2": 1.0}, "components": [2]}]}))
    alpha = np.zeros(9)
    sf, sq = full.solve_state(alpha), quarter.solve_state(alpha)
    xf = full.model.body.reference.points[full.model.contact_nodes]
    xq = quarter.model.body.reference.points[quarter.model.contact_nodes]
    idx = np.array([np.flatnonzero(np.all(np.abs(xf - x) < 1e-12, axis=1))[0] for x in xq])
    share = np.where(np.abs(xq[:, 0] - 1) < 1e-9, 0.5, 1.0) * np.where(np.abs(xq[:, 1] - 1) < 1e-9, 0.5, 1.0)
    assert np.sum(sq.lam > 0) >= 4 and (sq.counts["M1"] > 0 or shape == "punch")
    assert np.abs(sf.lam[idx] * share - sq.lam).max() <= 1e-9 * sf.lam.max()
    uf = sf.u.reshape(-1, 3)[full.model.contact_nodes][idx]
    uq = sq.u.reshape(-1, 3)[quarter.model.contact_nodes]
    assert np.abs(uf - uq).max() <= 1e-9 * np.abs(uf).max()
    assert np.array_equal(sf.classes[idx], sq.classes)


@pytest.mark.slow
def test_a_resumed_run_on_a_force_controlled_obstacle_is_bit_identical(tmp_path):
    from pathlib import Path
    saddle = str(Path(__file__).parents[1] / "examples" / "saddle.toml")
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["run", saddle, "--out", str(a), "--max-iter", "14"]) == 0
    assert main(["run", saddle, "--out", str(b), "--max-iter", "7"]) == 0
    assert main(["run", saddle, "--out", str(b), "--resume", "--max-iter", "14"]) == 0
    assert (a / "alpha.json").read_bytes() == (b / "alpha.json").read_bytes()


def test_an_objective_of_the_whole_displacement_on_a_sphere_matches_central_differences():
    # ∂J/∂u on every DOF enters the adjoint in global components, rotated into the nodes' frames
    problem = ShapeProblem(block(SPHERE, objective={"type": "peak_stress"}))
    alpha = 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001
    rep = check_gradient(problem, alpha, seed=1, n_directions=3)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    with pytest.raises(ConfigError, match="frictional_dissipation.*fixed plane only"):
        block(SPHERE, objective={"type": "frictional_dissipation"})
