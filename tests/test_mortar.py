"""Mortar coupling: the segmentation, the dual basis, Π = D⁻¹M, the contact patch test on an
elastic foundation, and subgradients with mortar partners.

Conventions: per contact node (t1, t2, ν) = (x1, x2, x3); r the contact force on the body,
λ = r_ν ≥ 0, τ = −r_t; the foundation carries −Πᵀr; w = u_body − Π u_f.
"""

import numpy as np
import pytest

from contactopt.config import load_config, validate
from contactopt.fem.elements import face_type
from contactopt.fem.mortar import dual_coefficients, mortar_matrices
from contactopt.mesh.segmentation import clip_convex, segment, signed_area
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from contactopt.verification.patch import H_BODY, node_areas, patch_config, patch_errors
from test_foundation import _design

E, NU = 21.19, 0.277


def grid(xs, ys, tri=False):
    """Nodes (n, 2) and faces (quadrilaterals, or each split in two triangles) of a tensor grid."""
    X, Y = np.meshgrid(xs, ys, indexing="xy")
    P = np.column_stack([X.ravel(), Y.ravel()])
    n = len(xs)
    F = np.array([[j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i]
                  for j in range(len(ys) - 1) for i in range(n - 1)])
    return P, (np.vstack([F[:, [0, 1, 2]], F[:, [0, 2, 3]]]) if tri else F)


def jittered(P, h, amp, seed):
    r = np.random.default_rng(seed)
    lo, hi = P.min(axis=0), P.max(axis=0)
    inner = np.all((P > lo + 1e-12) & (P < hi - 1e-12), axis=1)
    P = P.copy()
    P[inner] += amp * h * r.uniform(-1, 1, (int(inner.sum()), 2))
    return P


# ------------------------------------------------------------------ segmentation
def test_clipping_two_squares_gives_their_intersection():
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    around = np.array([[0.5, -0.5], [1.5, 0.5], [0.5, 1.5], [-0.5, 0.5]])           # the square inscribed
    assert np.isclose(signed_area(clip_convex(sq, around)), 1.0, atol=1e-15)
    diamond = np.array([[1.0, 0.0], [2.0, 1.0], [1.0, 2.0], [0.0, 1.0]])            # x1 + x2 ≥ 1 in the square
    assert np.isclose(signed_area(clip_convex(sq, diamond)), 0.5, atol=1e-15)
    assert np.isclose(signed_area(clip_convex(sq, sq + [0.25, 0.5])), 0.375, atol=1e-15)
    assert clip_convex(sq, sq + [2.0, 0.0]).shape[0] == 0
    tri = np.array([[0, 0], [2, 0], [0, 2]], float)
    assert np.isclose(signed_area(clip_convex(sq, tri)), 1.0, atol=1e-15)


@pytest.mark.parametrize("tri_s,tri_m", [(False, False), (True, False), (False, True), (True, True)])
def test_segmentation_covers_each_face_once(tri_s, tri_m):
    Ps, Fs = grid(np.linspace(0, 1, 8), np.linspace(0, 1, 8), tri_s)
    Ps = jittered(Ps, 1 / 7, 0.2, 0)
    Pm, Fm = grid(np.linspace(-0.05, 1.05, 11), np.linspace(-0.05, 1.05, 11), tri_m)
    Pm = jittered(Pm, 0.11, 0.2, 1)
    nc = 3 if tri_s else 4
    seg = segment(Ps[Fs[:, :nc]], Pm[Fm])
    # a face's area is the sum of its clipped pieces' areas (up to a dozen polygons, each a fan of
    # cross products): round-off of some hundred ulps, which the BLAS kernel moves (1.1e-13 seen)
    assert np.allclose(seg.covered, seg.slave_area, rtol=1e-12, atol=0)
    _, w = seg.quadrature((np.array([[1 / 3, 1 / 3]]), np.array([0.5])))
    assert np.isclose(w.sum(), 1.0, rtol=1e-13)


# ------------------------------------------------------------------ dual basis and Π = D⁻¹M
@pytest.mark.parametrize("name,X", [
    ("quad", np.array([[[0.0, 0.0], [1.2, 0.1], [1.0, 0.9], [-0.1, 1.1]]])),
    ("triangle", np.array([[[0.0, 0.0], [1.2, 0.1], [0.3, 0.9]]]))])
def test_dual_basis_is_biorthogonal(name, X):
    """∫ Φ_j N_k = δ_jk ∫ N_j on a distorted face (a Gauss rule of the reference face)."""
    ft = face_type(name)
    A = dual_coefficients(ft, X)[0]
    from contactopt.fem.mortar import _mass_rule
    q, w = _mass_rule(ft)
    N, dN = ft.shape(q)
    dA = np.abs(np.linalg.det(np.einsum("qaj,ai->qij", dN, X[0]))) * w
    Phi = N @ A.T
    B = np.einsum("q,qj,qk->jk", dA, Phi, N)
    assert np.allclose(B, np.diag(np.einsum("q,qj->j", dA, N)), atol=1e-14)


CASES = {"7x7 on 10x10": ((8, 8), (11, 11), False, False),
         "10x10 on 7x7": ((11, 11), (8, 8), False, False),
         "triangles on quadrilaterals": ((8, 8), (11, 11), True, False),
         "quadrilaterals on triangles": ((11, 11), (8, 8), False, True),
         "triangles on triangles": ((6, 9), (8, 5), True, True)}


@pytest.mark.parametrize("case", CASES)
def test_projection_reproduces_linear_fields_on_non_matching_faces(case):
    """Π = D⁻¹M: rows sum to 1, and a field linear in the plane passes exactly (the reason for
    the patch test); averaged shape functions in place of Φ would not reproduce it at the edge."""
    (ns, ms), (nm, mm), tri_s, tri_m = CASES[case]
    Ps, Fs = grid(np.linspace(0, 1, ns), np.linspace(0, 1, ms), tri_s)
    Pm, Fm = grid(np.linspace(0, 1, nm) ** 1.3, np.linspace(0, 1, mm), tri_m)    # graded, offset lines
    D, M, _ = mortar_matrices("triangle" if tri_s else "quad", Fs, Ps, "triangle" if tri_m else "quad", Fm, Pm)
    Pi = M.multiply(1.0 / D[:, None]).tocsr()
    assert np.abs(np.asarray(Pi.sum(axis=1)).ravel() - 1.0).max() < 1e-13
    for lin in (lambda P: P[:, 0], lambda P: P[:, 1], lambda P: 2.0 * P[:, 0] - 3.0 * P[:, 1] + 0.5):
        assert np.abs(Pi @ lin(Pm) - lin(Ps)).max() < 1e-13
    assert np.isclose(D.sum(), 1.0, rtol=1e-13)                  # Σ_j D_jj = the face's area
    assert D.min() > 0


def tri6_grid(nx, ny):
    """Six-node triangles on the unit square (nx × ny squares, each cut into two), the mid-side nodes
    at the edges' mid-points."""
    P, F = grid(np.linspace(0, 1, nx + 1), np.linspace(0, 1, ny + 1), True)
    P, edges, faces = list(map(tuple, P)), {}, []
    for f in F:
        mids = []
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            key = (min(a, b), max(a, b))
            if key not in edges:
                edges[key] = len(P)
                P.append(tuple((np.array(P[a]) + np.array(P[b])) / 2))
            mids.append(edges[key])
        faces.append([*f, *mids])
    return np.array(P), np.array(faces)


def test_the_transformed_dual_basis_of_six_node_triangles():
    """N̂ = T N (α = 1/5): T's columns sum to one (Σ N̂ = 1), the dual basis on N̂ is biorthogonal
    to it, D_jj = ∫ N̂_j > 0 at corners and mid-side nodes alike, and Π = D⁻¹M maps a linear field
    of the counterpart to the transformed nodal values T⁻ᵀ f of the body's."""
    from contactopt.fem.mortar import _mass_rule, face_transform, transformed_basis
    Ps, Fs = tri6_grid(3, 4)
    T = transformed_basis("triangle6", Fs, Ps.shape[0])
    assert np.allclose(np.asarray(T.sum(axis=0)).ravel(), 1.0, rtol=0, atol=1e-15)
    ft = face_type("triangle6")
    X = Ps[Fs[:1]]
    A = dual_coefficients(ft, X)[0]
    q, w = _mass_rule(ft)
    N, dN = ft.shape(q)
    Nh = N @ face_transform(ft).T
    dA = np.abs(np.linalg.det(np.einsum("qaj,ai->qij", dN, X[0]))) * w
    B = np.einsum("q,qj,qk->jk", dA, Nh @ A.T, Nh)
    assert np.allclose(B, np.diag(np.einsum("q,qj->j", dA, Nh)), atol=1e-14)
    Pm, Fm = grid(np.linspace(0, 1, 6) ** 1.3, np.linspace(0, 1, 5), False)
    D, M, _ = mortar_matrices("triangle6", Fs, Ps, "quad", Fm, Pm)
    assert D.min() > 0 and np.isclose(D.sum(), 1.0, rtol=1e-13)
    Pi = M.multiply(1.0 / D[:, None]).tocsr()
    assert np.abs(np.asarray(Pi.sum(axis=1)).ravel() - 1.0).max() < 1e-13
    Tt = T.toarray().T
    for lin in (lambda P: P[:, 0], lambda P: 2.0 * P[:, 0] - 3.0 * P[:, 1] + 0.5):
        assert np.abs(Pi @ lin(Pm) - np.linalg.solve(Tt, lin(Ps))).max() < 1e-13


# ------------------------------------------------------------------ the contact patch test
PATCH = {"7x7 on 7x7 (matching)": (7, 7, "hexahedron", "hexahedron", "point"),
         "7x7 on 10x10": (7, 10, "hexahedron", "hexahedron", "mortar"),
         "10x10 on 7x7": (10, 7, "hexahedron", "hexahedron", "mortar"),
         "8x8 on an offset 8x8": (8, 8, "hexahedron", "offset", "mortar"),
         "hexahedra on tetrahedra": (7, 10, "hexahedron", "tetra", "mortar"),
         "tetrahedra on hexahedra": (7, 10, "tetra", "hexahedron", "mortar"),
         "tetrahedra on tetrahedra": (10, 7, "tetra", "tetra", "mortar"),
         "hexahedra on tet10": (7, 5, "hexahedron", "tetra10", "mortar"),
         "tet10 on hexahedra": (4, 5, "tetra10", "hexahedron", "mortar"),
         "tet10 on tetrahedra": (5, 4, "tetra10", "tetra", "mortar"),
         "tet10 on tet10": (4, 3, "tetra10", "tetra10", "mortar")}


@pytest.mark.parametrize("friction", [0.0, 0.3])
@pytest.mark.parametrize("case", PATCH)
def test_contact_patch_test_on_an_elastic_foundation(case, friction, tmp_path):
    """The overlap loading (:mod:`contactopt.verification.patch`): uniform pressure to 1e-8 relative, ‖τ‖ ≤ 1e-8 a p ('auto' partners:
    point on matching meshes, mortar on the others)."""
    nb, nf, body, found, partner = PATCH[case]
    pb = ShapeProblem(patch_config(nb, nf, friction, tmp_path, body=body, foundation=found))
    assert pb.model.foundation.partner == partner
    st = pb.solve_state(pb.model.initial_design())
    assert st.converged
    err = patch_errors(pb, st)
    assert err["max"] <= 1e-8 and err["shear"] <= 1e-8, err


def test_averaged_partners_fail_the_patch_test_with_friction(tmp_path):
    """What the mortar partners cure: averaged partners on matching meshes with friction carry a
    false shear at the face's edge (and a pressure error)."""
    pb = ShapeProblem(patch_config(7, 7, 0.3, tmp_path, partner="average"))
    err = patch_errors(pb, pb.solve_state(pb.model.initial_design()))
    assert err["shear"] > 0.05 and err["max"] > 1e-3, err


def test_quadratic_body_faces_take_the_transformed_dual_basis(tmp_path):
    """Six-node triangles with mortar partners: T keeps the resultant (its columns sum to one), every
    node of the face is in contact under the patch test's pressure (the corners too, which carry no
    force in the standard basis), and the pressure output is the uniform p at every node."""
    from contactopt.io.pressure import contact_pressure
    from contactopt.verification.patch import exact_pressure
    pb = ShapeProblem(patch_config(4, 5, 0.3, tmp_path, body="tetra10", partner="mortar"))
    T = pb.model.foundation.basis
    assert T is not None and np.allclose(np.asarray(T.sum(axis=0)).ravel(), 1.0, rtol=0, atol=1e-15)
    st = pb.solve_state(pb.model.initial_design())
    assert st.counts["L"] == 0 and st.counts["M3+"] == pb.model.contact_nodes.size
    p = contact_pressure(pb.model, st.lam, st.coords)
    assert np.abs(p / exact_pressure(st.coords, pb.model.contact_nodes) - 1.0).max() <= 1e-8
    assert np.all(pb.model.contact_areas() > 0)


# ------------------------------------------------------------------ subgradients
COARSE = {"mesh": {"nx": 12, "ny": 6, "nz": 4}}


@pytest.mark.parametrize("element", ["hexahedron", "tetra"])
def test_subgradient_with_mortar_partners_matches_central_differences(element):
    """Example 1's body (F = 0.3: sliding, sticking and free nodes) on a coarser, wider, non-matching
    foundation with mortar partners: ξ·d against central differences to 1e-6."""
    f = {"block": {"size": [3.0, 2.0, 1.0], "cells": [9, 5, 3], "origin": [-0.5, -0.5], "element": element},
         "material": {"E": E / 10}}
    pb = ShapeProblem(load_config("example1").with_updates({**COARSE, "foundation": f}))
    assert pb.model.foundation.partner == "mortar"
    gc = check_gradient(pb, _design(pb.model), n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0


def test_subgradient_on_a_tetrahedral_body_with_mortar_partners(tmp_path):
    """A tetrahedral body 6×6 on hexahedra 8×8 (the patch test's blocks), a crowned design and a
    sideways pull on the top: free, sliding and sticking nodes; ξ·d against central differences."""
    cfg = patch_config(6, 8, 0.3, tmp_path, body="tetra").with_updates(
        {"design": {"degree": [2, 2], "initial": 0.0},
         "loads": {"traction": [{"on": {"x3": H_BODY}, "value": [0.02, 0.01, 0.0]}]}})
    pb = ShapeProblem(cfg)
    assert pb.model.foundation.partner == "mortar"
    a = pb.model.initial_design() + 0.004 * np.random.default_rng(0).standard_normal(9) - 0.003
    gc = check_gradient(pb, a, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0


def test_subgradient_on_a_tet10_body_with_mortar_partners(tmp_path):
    """The transformed dual basis: a tet10 body 4×4 on hexahedra 5×5, a crowned design and a sideways
    pull: free, sliding and sticking nodes; ξ·d of the compliance against central differences."""
    cfg = patch_config(4, 5, 0.3, tmp_path, body="tetra10").with_updates(
        {"design": {"degree": [2, 2], "initial": 0.0},
         "loads": {"traction": [{"on": {"x3": H_BODY}, "value": [0.02, 0.01, 0.0]}]}})
    pb = ShapeProblem(cfg)
    assert pb.model.foundation.partner == "mortar" and pb.model.foundation.basis is not None
    a = pb.model.initial_design() + 0.004 * np.random.default_rng(0).standard_normal(9) - 0.003
    gc = check_gradient(pb, a, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_patch_test_with_symmetry_planes_through_both_bodies(friction, tmp_path):
    """The overlap loading with rollers u1 = 0 on x1 = 0 and u2 = 0 on x2 = 0 through the contact face
    of the body and the foundation alike, 7×7 on 10×10 with mortar partners: still exact."""
    raw = patch_config(7, 10, friction, tmp_path).to_dict()
    raw["body"]["clamped"] = [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]},
                              {"on": {"x3": H_BODY}, "components": [3]}]
    pb = ShapeProblem(load_config(raw))
    assert pb.model.foundation.partner == "mortar" and pb.model.body.pinned_dofs.size > 0
    err = patch_errors(pb, pb.solve_state(pb.model.initial_design()))
    assert err["max"] <= 1e-8 and err["shear"] <= 1e-8, err


def test_the_segmentation_is_built_once_per_run_not_per_evaluation(monkeypatch, tmp_path):
    """Π = D⁻¹M does not depend on α (design moves are normal to the common plane): evaluations of
    new designs never segment again."""
    import contactopt.fem.mortar as mortar
    pb = ShapeProblem(patch_config(7, 10, 0.3, tmp_path))
    calls = []
    monkeypatch.setattr(mortar, "segment", lambda *a, **k: calls.append(1))
    a = pb.model.initial_design()
    for k in range(2):
        pb.evaluate(a - 0.001 * k)
    assert not calls


def lame_shaft(tmp_path, k, nt_shaft, partner="auto", **kw):
    """Lamé's shrink fit: the quarter hub (4k × 8k × 1) on an elastic quarter shaft with ``nt_shaft``
    cells along its arc (:mod:`contactopt.verification.lame`)."""
    from contactopt.verification import lame
    h = lame.quarter_hub_mesh(tmp_path / "hub.msh", 4 * k, 8 * k, 1)
    s = lame.quarter_shaft_mesh(tmp_path / "shaft.msh", 3 * k, nt_shaft, 1, radius=lame.B + lame.DELTA)
    data = lame.shaft_config(h, s, **kw)
    data["foundation"]["partner"] = partner
    return data


def test_mortar_partners_on_a_cylindrical_face_follow_lame_on_non_matching_meshes(tmp_path):
    """The hub's bore on a shaft meshed independently (the shaft's arc divided into 3/4 or 3/2 of
    the hub's cells), segmented on the bore's chart (ρθ, x3): the nodal pressure within 0.5 % rms of
    Lamé's at the hub 8 × 16, where point partners scatter by 5–15 %; 'auto' takes mortar partners
    there and point partners on matching meshes."""
    from contactopt.verification import lame
    p = lame.pressure_equal_materials()
    for nt_shaft in (12, 24):
        pb = ShapeProblem(validate(lame_shaft(tmp_path, 2, nt_shaft), "lame"))
        assert pb.model.foundation.partner == "mortar"
        rms, worst = lame.pressure_errors(pb, p)
        assert rms <= 0.005 and worst <= 0.005, (nt_shaft, rms, worst)
    assert ShapeProblem(validate(lame_shaft(tmp_path, 2, 16), "lame")).model.foundation.partner == "point"


def test_the_subgradient_with_mortar_partners_on_a_cylindrical_face_matches_central_differences(tmp_path):
    data = lame_shaft(tmp_path, 1, 6, friction=0.3, objective={"type": "pressure_uniformity"})
    problem = ShapeProblem(validate(data, "lame"))
    assert problem.model.foundation.partner == "mortar" and problem.model.frames is not None
    alpha = 1e-4 * (1.0 + np.sin(np.arange(problem.model.n_design)))
    rep = check_gradient(problem, alpha, seed=5, n_directions=3)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_averaged_partners_on_a_curved_face_are_refused(tmp_path, state_refused):
    """Averaged partners integrate on the plane x3 = 0 only; a face on a cylinder is refused by name,
    exit 2."""
    state_refused(lame_shaft(tmp_path, 1, 6, partner="average"),
                  "foundation.partner = 'average' takes a contact face on x3 = 0")


def classic_config(nb, nf, friction, tmp_path, body="hexahedron", foundation="hexahedron"):
    """The classic loading: the patch test's blocks at the design 0, a pressure 0.1 on the body's
    top, the body held in x3 by the contact alone (rollers in x1, x2 away from the contact face)."""
    raw = patch_config(nb, nf, friction, tmp_path, body=body, foundation=foundation).to_dict()
    raw["body"]["clamped"] = raw["body"]["clamped"][:2]
    raw["design"]["initial"] = 0.0
    raw["loads"] = {"traction": [{"on": {"x3": H_BODY}, "value": [0.0, 0.0, -0.1]}]}
    if body not in ("tetra", "tetra10"):
        raw["loads"].update(top_traction=[0.0, 0.0, 0.0], right_traction=[0.0, 0.0, 0.0])
    return load_config(raw)


@pytest.mark.parametrize("friction", [0.0, 0.3])
@pytest.mark.parametrize("case", PATCH)
def test_classic_patch_test_a_body_held_only_by_contact_on_the_foundation(case, friction, tmp_path):
    """A pressure p = 0.1 on the body's top, the body held in x3 only by the contact on the elastic
    foundation: λ_m = p a_m to 1e-8 and ‖τ‖ ≤ 1e-8 a p."""
    nb, nf, body, found, partner = PATCH[case]
    pb = ShapeProblem(classic_config(nb, nf, friction, tmp_path, body=body, foundation=found))
    assert pb.model.foundation.partner == partner and pb.model.body.rigid is not None
    st = pb.solve_state(pb.model.initial_design())
    assert st.converged and st.rigid is not None
    area = node_areas(pb)
    assert np.abs(st.lam / area / 0.1 - 1.0).max() <= 1e-8
    assert np.linalg.norm(st.tau, axis=1).max() <= 1e-8 * 0.1 * area.max()


@pytest.mark.parametrize("body, nb", [("tetra", 6), ("tetra10", 4)])
def test_subgradient_of_a_body_held_only_by_contact_on_the_foundation(body, nb, tmp_path):
    """Tetrahedra 6×6 (or tet10 4×4) on hexahedra 8×8, held in x3 by the contact alone, a crowned
    design and a sideways pull: sliding and sticking nodes; ξ·d against central differences."""
    raw = classic_config(nb, 8, 0.3, tmp_path, body=body).to_dict()
    raw["design"]["degree"] = [2, 2]
    raw["loads"] = {"traction": [{"on": {"x3": H_BODY}, "value": [0.01, 0.005, -0.1]}]}
    pb = ShapeProblem(load_config(raw))
    a = pb.model.initial_design() + 0.004 * np.random.default_rng(0).standard_normal(9)
    a -= a.min()
    gc = check_gradient(pb, a, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0


@pytest.mark.parametrize("friction", [0.0, 0.3])
@pytest.mark.parametrize("case", ["7x7 on 10x10", "8x8 on an offset 8x8", "tetrahedra on hexahedra",
                                  "tet10 on hexahedra"])
def test_classic_patch_test_with_symmetry_planes_through_both_bodies(case, friction, tmp_path):
    """The textbook form: a pressure on the body's top, symmetry rollers through the contact face of
    both bodies, the body held in x3 by the contact alone; mortar partners."""
    nb, nf, body, found, partner = PATCH[case]
    raw = classic_config(nb, nf, friction, tmp_path, body=body, foundation=found).to_dict()
    raw["body"]["clamped"] = [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]
    pb = ShapeProblem(load_config(raw))
    assert pb.model.foundation.partner == partner and pb.model.body.rigid is not None
    st = pb.solve_state(pb.model.initial_design())
    area = node_areas(pb)
    assert np.abs(st.lam / area / 0.1 - 1.0).max() <= 1e-8
    assert np.linalg.norm(st.tau, axis=1).max() <= 1e-8 * 0.1 * area.max()
