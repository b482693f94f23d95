"""Bodies held only by contact (clamps that leave rigid motions free): the kernel of A(α), the
state against a clamped body, subgradients against central differences, and loads that no
admissible contact force balances refused with exit 2 and nothing written.

A block 2 × 1 × 1 without clamps, pressed onto the plane x3 = 0 by a top pressure 0.1 (normal
resultant N = 0.2) with a side traction on its right face (1 × 1), friction F = 0.3.
"""

import meshio
import numpy as np
import pytest

from contactopt.config import load_config, validate
from contactopt.errors import ConfigError
from contactopt.mesh.block import block_mesh
from contactopt.mesh.rigid import free_modes
from contactopt.mesh.tetsplit import hex_to_tets
from contactopt.paths.rigid import kernel_on_free
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient


def free_block(side=0.02, top=-0.1, friction=0.3, clamped=(), n=4, **updates):
    cfg = {"friction": {"coefficient": friction}, "linear_solver": {"path": "condensation"},
           "state": {"method": "newton", "tol": 1e-12},
           "loads": {"top_traction": [0.0, 0.0, top], "right_traction": [side, 0.0, 0.0]},
           "design": {"degree": [3, 2], "initial": 0.0, "C2": 0.0},
           "geometry": {"a": 2.0, "b": 1.0, "c": 1.0}, "mesh": {"nx": 2 * n, "ny": n, "nz": 3},
           "body": {"clamped": list(clamped)}}
    cfg.update(updates)
    return load_config("example1").with_updates(cfg)


def tet_free_block(tmp_path, shear=0.02, obstacle=None):
    """The block 2 × 1 × 1 as linear tetrahedra (mesh 8 × 4 × 3, six per cube), no clamp, a top
    traction (shear, 0, −0.1)."""
    hexes = block_mesh(2.0, 1.0, 1.0, 8, 4, 3)
    path = tmp_path / "tets.vtu"
    meshio.write(path, meshio.Mesh(hexes.points, [("tetra", hex_to_tets(hexes.cells))]))
    data = {k: v for k, v in free_block().data.items() if k not in ("geometry", "mesh")}
    data["body"] = {**data["body"], "mesh": str(path), "clamped": [], "contact": {"x3": 0.0}}
    data["loads"] = {"traction": [{"on": {"x3": 1.0}, "value": [shear, 0.0, -0.1]}]}
    if obstacle is not None:
        data["obstacle"] = obstacle
    return validate(data, "tets")


def design(problem):
    return 0.002 * np.sin(np.arange(problem.model.n_design)) + 0.001


# ------------------------------------------------------------------ the kernel
def test_the_clamps_leave_the_rigid_motions_they_do_not_fix_and_those_are_the_kernel_of_A():
    pts = block_mesh(2.0, 1.0, 1.0, 4, 2, 2).points
    fixed = np.zeros((pts.shape[0], 3), bool)
    m = free_modes(pts, fixed)
    assert m.count == 6 and np.array_equal(m.coefficients, np.eye(6))
    assert m.names()[0] == "the translation along x1" and m.names()[5].startswith("the rotation about x3")
    fixed[pts[:, 0] == 0.0, 0] = True            # u1 = 0 on the face x1 = 0: u2, u3 and the turn about x1 left
    m = free_modes(pts, fixed)
    assert m.count == 3
    assert m.names() == ["the translation along x2", "the translation along x3",
                         "the rotation about x1 through the centroid (1, 0.5, 0.5)"]
    fixed[:] = False
    fixed[(pts[:, 0] == 0.0) & (pts[:, 2] == 0.0), 0] = True     # u1 = 0 on one edge: also a turn about x2
    m = free_modes(pts, fixed)
    assert m.count == 4 and m.names()[3] == "the rotation about x2 through (1, 0.5, 0)"
    assert np.abs(m.vectors(pts)[fixed]).max() <= 1e-15
    problem = ShapeProblem(free_block())
    alpha = design(problem)
    asm = problem.model.assemble(alpha)
    R = kernel_on_free(problem.model, problem.model.body.rigid, asm.coords)
    assert R.shape[1] == 6
    assert np.abs(asm.A @ R).max() <= 1e-12 * abs(asm.A).max() * np.abs(R).max()


# ------------------------------------------------------------------ the state
def test_a_free_block_equals_the_block_clamped_at_three_still_nodes_whose_clamps_carry_only_their_contact_force():
    problem = ShapeProblem(free_block())
    alpha = np.zeros(problem.model.n_design)
    st = problem.solve_state(alpha)
    m = problem.model
    assert st.info["rigid_residual"] <= 1e-12 and st.counts["M1"] > 0 and st.counts["M3+"] > 0
    # equilibrium on every rigid motion: Rᵀ(f + Bᵀr) = 0 (force and moment about the centroid)
    asm = m.assemble(alpha)
    pts = asm.coords
    f = m.assembler.to_full(asm.L).reshape(-1, 3)
    r = np.zeros_like(f)
    r[m.contact_nodes] = np.c_[-st.tau, st.lam]
    scale = st.lam.sum()
    assert np.abs((f + r).sum(axis=0)).max() <= 1e-12 * scale
    assert np.abs(np.cross(pts - pts.mean(axis=0), f + r).sum(axis=0)).max() <= 1e-12 * scale
    # the nodes that stick in contact (gap 0) do not move: clamp three of them, not on one line
    u = st.u.reshape(-1, 3)
    stick = m.contact_nodes[st.class_names == "M3+"]
    xy = pts[stick, :2]
    b = int(np.argmax(np.linalg.norm(xy - xy[0], axis=1)))
    d, e = xy[b] - xy[0], xy - xy[0]
    c = int(np.argmax(np.abs(d[0] * e[:, 1] - d[1] * e[:, 0])))
    still = [stick[0], stick[b], stick[c]]
    assert np.abs(u[still]).max() <= 1e-12 * np.abs(u).max()
    assert abs(np.linalg.det(np.c_[pts[still][:, :2], np.ones(3)])) > 0.1
    box = [{"box": [[x - 1e-3, x + 1e-3], [y - 1e-3, y + 1e-3], [-1e-3, 1e-3]]} for x, y, _ in pts[still]]
    clamped = ShapeProblem(free_block(clamped=box))
    assert clamped.model.body.rigid is None                  # an ordinary clamped body, no rigid motion
    sc = clamped.solve_state(alpha)
    assert np.abs(sc.u - st.u).max() <= 1e-10 * np.abs(st.u).max()
    keep = ~np.isin(m.contact_nodes, still)
    assert np.array_equal(sc.classes, st.classes[keep])
    assert np.abs(sc.lam - st.lam[keep]).max() <= 1e-10 * st.lam.max()
    assert np.abs(sc.tau - st.tau[keep]).max() <= 1e-10 * st.lam.max()
    # the clamps' reactions (A u − L of the unclamped stiffness there) are the free body's contact
    # forces at those nodes: the clamps carry no force the contact did not
    reaction = m.assembler.to_full(asm.A @ sc.u[m.assembler.free] - asm.L).reshape(-1, 3)[still]
    assert np.abs(reaction - r[still]).max() <= 1e-10 * st.lam.max()


def one_node_clamp(problem, alpha, node, components, **updates):
    """(the state of the block clamped in ``components`` at ``node`` only, the clamp's force there):
    A u − L of the unclamped stiffness at the node less the clamped body's own contact force."""
    m = problem.model
    x, y, z = m.body.reference.points[node]
    box = {"box": [[x - 1e-3, x + 1e-3], [y - 1e-3, y + 1e-3], [z - 1e-3, z + 1e-3]]}
    clamped = ShapeProblem(free_block(clamped=[{"on": box, "components": components}], **updates))
    sc = clamped.solve_state(alpha)
    asm = m.assemble(alpha)
    force = m.assembler.to_full(asm.A @ sc.u[m.assembler.free] - asm.L).reshape(-1, 3)
    force[clamped.model.contact_nodes] -= np.c_[-sc.tau, sc.lam]
    return clamped, sc, force[node]


def test_a_free_block_equals_the_block_clamped_at_one_node_whose_clamp_carries_no_force():
    """One clamped node carries no force where the free body's displacement and force vanish in the
    clamped components: u2 on the symmetry plane x2 = 1/2 under the side traction (the other five
    motions held by contact); u1, u2 at the centre of the contact face under the top pressure alone
    (double symmetry: u_t = 0 and τ = 0 there). Under the side traction no node has τ1 = 0 (it changes
    sign between nodes), so a clamp of u1 at a sticking node carries that node's friction force,
    inside its cone: the same state, the clamp doing what friction did."""
    tight = {"state": {"method": "newton", "tol": 1e-14}}
    for side, components in ((0.02, [2]), (0.02, [1, 2]), (0.0, [1, 2])):
        problem = ShapeProblem(free_block(side=side, **tight))
        alpha = np.zeros(problem.model.n_design)
        st = problem.solve_state(alpha)
        m = problem.model
        pts = m.body.reference.points
        centre = int(np.flatnonzero(np.all(np.abs(pts - [1.0, 0.5, 0.0]) < 1e-12, axis=1))[0])
        k = int(np.searchsorted(m.contact_nodes, centre))
        assert st.class_names[k] == "M3+" and np.abs(st.u.reshape(-1, 3)[centre]).max() <= 1e-10 * np.abs(st.u).max()
        clamped, sc, force = one_node_clamp(problem, alpha, centre, components, side=side, **tight)
        assert clamped.model.body.rigid.count == {1: 5, 2: 4}[len(components)]     # u2: 5 motions; u1, u2: 4
        assert np.abs(sc.u - st.u).max() <= 1e-10 * np.abs(st.u).max()
        assert np.array_equal(sc.classes, st.classes)
        assert np.abs(sc.lam - st.lam).max() <= 1e-10 * st.lam.max()
        free_force = np.r_[-st.tau[k], st.lam[k]]
        if side and 1 in components:        # the node's friction force, carried by the clamp instead
            assert abs(force[0] - free_force[0]) <= 1e-10 * st.lam.max()
            assert abs(force[0]) > 1e-2 * st.lam.max() and abs(force[0]) < 0.3 * st.lam[k]
            assert np.abs(force[1:]).max() <= 1e-12 * st.lam.max()
        else:
            assert np.abs(force).max() <= 1e-12 * st.lam.max()
    # the subgradient with one clamp of u2 and five motions held by contact, on a design with gaps (the
    # clamp on the top, which the design does not move: the motions left free stay A(α)'s kernel)
    top = {"box": [[0.999, 1.001], [0.499, 0.501], [0.999, 1.001]]}
    clamped = ShapeProblem(free_block(clamped=[{"on": top, "components": [2]}]))
    assert clamped.model.body.rigid.count == 5
    rep = check_gradient(clamped, design(clamped), seed=1, n_directions=3, state_method="newton", state_tol=1e-13)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_clamps_that_fix_some_components_leave_the_others_to_contact():
    # u1 = 0 on the face x1 = 0: the contact holds u2, u3 and the rotation about x1
    part = ShapeProblem(free_block(clamped=[{"on": {"x1": 0.0}, "components": [1]}]))
    assert part.model.body.rigid.count == 3
    st = part.solve_state(design(part))
    assert st.info["rigid_residual"] <= 1e-12 and st.counts["M3+"] > 0
    # u1, u2 = 0 on the top, no friction: the normal contact holds u3 and the two tilts
    tilt = ShapeProblem(free_block(side=0.0, friction=0.0, clamped=[{"on": {"x3": 1.0}, "components": [1, 2]}]))
    assert tilt.model.body.rigid.names() == ["the translation along x3", "the rotation about x1 through (1, 0.5, 1)",
                                             "the rotation about x2 through (1, 0.5, 1)"]
    alpha = design(tilt)
    st = tilt.solve_state(alpha)
    assert st.info["rigid_residual"] <= 1e-12 and st.counts["M1"] == st.lam.size
    rep = check_gradient(tilt, alpha, seed=1, n_directions=3, state_method="newton", state_tol=1e-13)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


# ------------------------------------------------------------------ subgradients
@pytest.mark.parametrize("cells", ["hexahedron", "tetra"])
def test_the_subgradient_of_a_free_block_matches_central_differences(tmp_path, cells):
    problem = ShapeProblem(free_block() if cells == "hexahedron" else tet_free_block(tmp_path))
    assert problem.model.body.rigid.count == 6 and problem.model.body.reference.cell_type == cells
    alpha = design(problem)
    st = problem.solve_state(alpha)
    assert st.counts["M1"] > 0 and st.counts["M3+"] > 0
    rep = check_gradient(problem, alpha, seed=1, n_directions=3, state_method="newton", state_tol=1e-13)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


def test_a_free_block_on_a_sphere_is_held_by_friction_and_its_subgradient_matches_central_differences(tmp_path):
    sphere = {"shape": "sphere", "center": [1.0, 0.5, -5.0], "radius": 5.0}
    problem = ShapeProblem(tet_free_block(tmp_path, shear=0.01, obstacle=sphere))
    alpha = design(problem)
    st = problem.solve_state(alpha)
    assert st.info["rigid_residual"] <= 1e-12 and st.counts["M3+"] > 0 and st.counts["L"] > 0
    rep = check_gradient(problem, alpha, seed=2, n_directions=3, state_method="newton", state_tol=1e-13)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


# ------------------------------------------------------------------ refused
def test_a_side_traction_beyond_friction_is_refused_naming_the_translation(tmp_path, capsys, state_refused):
    ShapeProblem(free_block(side=0.059))                     # 0.059 < 0.3 × 0.2: held
    state_refused(free_block(side=0.07), "loads: the translation along x1 is not held: the tangential "
             "load 0.07 exceeds F × the normal load 0.3 × 0.2 = 0.06")


def test_loads_that_pull_away_tip_over_or_meet_no_friction_are_refused():
    with pytest.raises(ConfigError, match="the translation along x3 is not held: the load pulls the body away"):
        ShapeProblem(free_block(side=0.0, top=0.1))
    # F = 5 holds the side traction 0.5 = 2.5 N, but its moment about the edge x1 = 2 tips the block
    with pytest.raises(ConfigError, match=r"the rotation about x2 through \(2, 0.5, .*\) is not held"):
        ShapeProblem(free_block(side=0.5, friction=5.0))
    ShapeProblem(free_block(side=0.3, friction=5.0))
    with pytest.raises(ConfigError, match="the translation along x1 and the translation along x2 and the rotation "
                                          "about x3 through the centroid .* are not held: without friction"):
        ShapeProblem(free_block(side=0.0, friction=0.0))


def test_the_other_paths_refuse_a_body_held_only_by_contact():
    """The Delassus path refuses it by name; the full space takes it on both backends (anchored
    on one cell, tests/test_fullspace_held_face.py, tests/test_petsc_bodies.py), and "auto" takes
    the full space from the crossover on."""
    with pytest.raises(ConfigError, match="a body held only by contact is solved on the 'condensation', 'fullspace' "
                                          "and 'petsc' paths only"):
        ShapeProblem(free_block(linear_solver={"path": "delassus"}))
    assert ShapeProblem(free_block(linear_solver={"path": "fullspace"})).path.name == "fullspace"
    assert ShapeProblem(free_block(linear_solver={"path": "auto", "crossover": 10})).path.name == "fullspace"
    assert ShapeProblem(free_block(linear_solver={"path": "auto"})).path.name == "condensation"


def test_a_body_held_only_by_contact_rests_on_an_elastic_foundation():
    """The free block on a foundation block 3 × 2 × 1 (mortar partners): the contact forces balance
    the loads, N = 0.2 and the side load 0.02 along x1."""
    pb = ShapeProblem(free_block(foundation={"block": {"size": [3.0, 2.0, 1.0], "cells": [3, 2, 1],
                                                       "origin": [-0.5, -0.5]}}))
    assert pb.path.name == "condensation" and pb.model.body.rigid is not None
    st = pb.solve_state(pb.model.initial_design())
    assert st.converged and st.rigid is not None
    assert abs(st.lam.sum() - 0.2) <= 1e-10 and np.abs(np.abs(st.tau.sum(axis=0)) - [0.02, 0.0]).max() <= 1e-10


@pytest.mark.slow
def test_a_force_controlled_sphere_presses_a_body_free_in_x1_x2_and_the_subgradient_matches_central_differences():
    # clamped in u3 on its top only: friction under the punch holds u1, u2 and the turn about x3;
    # the punch's force has a tangential part 0.005 < F × 0.05
    sphere = {"shape": "sphere", "center": [1.0, 0.5, -5.0], "radius": 5.0, "control": "force",
              "force": [0.005, 0.0, 0.05]}
    problem = ShapeProblem(free_block(side=0.0, top=0.0, clamped=[{"on": {"x3": 1.0}, "components": [3]}],
                                      obstacle=sphere))
    assert problem.model.body.rigid.count == 3
    alpha = design(problem)
    st = problem.solve_state(alpha)
    assert st.info["obstacle_resultant"] == pytest.approx(np.linalg.norm(sphere["force"]), rel=1e-12)
    assert st.info["rigid_residual"] <= 1e-12 and st.counts["M3+"] > 0
    rep = check_gradient(problem, alpha, seed=1, n_directions=3, state_method="newton", state_tol=1e-13)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
