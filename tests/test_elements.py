"""Element types: exact patch tests, convergence rates, shape derivatives, pressure loads.

Tetrahedral meshes come from the block's structured grid split into six tetrahedra per cube
(contactopt.mesh.tetsplit), P2 by adding the edge midpoints.
"""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from contactopt.fem.elasticity import ElasticityAssembler, element_geometry, lame
from contactopt.fem.elements import HEX8, TET4, TET10, element_type
from contactopt.fem.loads import (body_load, body_load_shape_contraction, face_areas_nodal, pressure_load,
                                  pressure_load_shape_contraction, surface_load, surface_load_shape_contraction)
from contactopt.mesh.block import block_mesh
from contactopt.mesh.reference import ReferenceMesh
from contactopt.mesh.tetsplit import hex_to_tets, tet4_to_tet10

E, NU = 21.19, 0.277


def cube_mesh(n, kind, distort=0.0, seed=0):
    """Unit cube, n³ cells, as (points, cells, element); interior vertices moved by ``distort``·h."""
    ref = block_mesh(1.0, 1.0, 1.0, n, n, n)
    pts, cells = ref.points.copy(), ref.cells
    if distort:
        inner = np.all((pts > 1e-12) & (pts < 1 - 1e-12), axis=1)
        pts[inner] += distort / n * np.random.default_rng(seed).uniform(-1, 1, (inner.sum(), 3))
    if kind == "hexahedron":
        return pts, cells, HEX8
    tets = hex_to_tets(cells, pts)
    if kind == "tetra":
        return pts, tets, TET4
    p10, c10 = tet4_to_tet10(pts, tets)      # straight edges: midpoints of the (distorted) edges
    return p10, c10, TET10


def on_boundary(pts):
    return np.any((pts < 1e-12) | (pts > 1 - 1e-12), axis=1)


def solve_dirichlet(asm, X, fixed_nodes, u_fixed, f_full):
    A = asm.full_stiffness(X).tocsr()
    fixed = np.repeat(fixed_nodes, 3)
    u = np.zeros(A.shape[0])
    u[fixed] = u_fixed.ravel()[fixed]
    free = ~fixed
    rhs = f_full[free] - A[free][:, fixed] @ u[fixed]
    u[free] = spla.spsolve(A[free][:, free].tocsc(), rhs)
    return u


# ------------------------------------------------------------------ patch tests
@pytest.mark.parametrize("kind", ["tetra", "tetra10", "hexahedron"])
def test_patch_test_is_exact_on_distorted_meshes(kind):
    pts, cells, el = cube_mesh(3, kind, distort=0.3, seed=1)
    asm = ElasticityAssembler(cells, len(pts), [], E, NU, element=el)
    rng = np.random.default_rng(2)
    B, c = rng.standard_normal((3, 3)), rng.standard_normal(3)
    u_ex = pts @ B.T + c
    u = solve_dirichlet(asm, pts, on_boundary(pts), u_ex, np.zeros(3 * len(pts)))
    assert np.max(np.abs(u.reshape(-1, 3) - u_ex)) <= 1e-10 * np.abs(u_ex).max()


def test_patch_test_on_a_morphed_tetrahedral_block():
    """P1 tetrahedra of the block lifted by a Bézier surface (the morph of an optimization)."""
    from contactopt.design.bezier import BezierSurface
    ref = block_mesh(2.0, 1.0, 1.0, 6, 3, 3)
    tets = hex_to_tets(ref.cells)
    surf = BezierSurface(3, 2, 2.0, 1.0)
    alpha = 0.05 + 0.25 * np.random.default_rng(0).random(surf.size)
    X = ref.points.copy()
    X[:, 2] += surf.evaluate(alpha, X[:, 0], X[:, 1]) * (1.0 - X[:, 2])
    asm = ElasticityAssembler(tets, len(X), [], E, NU, element=TET4)
    assert np.all(asm.jacobian_determinants(X) > 0)
    B = np.random.default_rng(3).standard_normal((3, 3))
    u_ex = X @ B.T
    bnd = ReferenceMesh(ref.points, tets, "tetra").boundary_faces()
    fixed = np.zeros(len(X), bool)
    fixed[bnd] = True
    u = solve_dirichlet(asm, X, fixed, u_ex, np.zeros(3 * len(X)))
    assert np.max(np.abs(u.reshape(-1, 3) - u_ex)) <= 1e-10 * np.abs(u_ex).max()


# ------------------------------------------------------------------ convergence rates
def _tet_rule_high():
    """Collapsed Gauss rule on the reference tetrahedron (27 points, exact to degree 3 and more)."""
    x, w = np.polynomial.legendre.leggauss(3)
    x, w = 0.5 * (x + 1), 0.5 * w
    U, V, W = np.meshgrid(x, x, x, indexing="ij")
    WU, WV, WW = np.meshgrid(w, w, w, indexing="ij")
    q = np.column_stack([U.ravel(), (V * (1 - U)).ravel(), (W * (1 - U) * (1 - V)).ravel()])
    wq = (WU * WV * WW * (1 - U) ** 2 * (1 - V)).ravel()
    return q, wq


def _exact(x):
    s = np.sin(np.pi * x)
    return np.column_stack([s[:, 0] * s[:, 1] * s[:, 2], x[:, 0] * s[:, 1] * s[:, 2],
                            s[:, 0] * x[:, 1] * x[:, 2] * (1 - x[:, 2])])


def _exact_grad(x, h=1e-5):
    g = np.empty((x.shape[0], 3, 3))
    for m in range(3):
        e = np.zeros(3)
        e[m] = h
        g[:, :, m] = (_exact(x + e) - _exact(x - e)) / (2 * h)
    return g


def _body_force(x, lam, mu, h=1e-4):
    """f = −div σ(u) by central differences of the exact stress (smooth, accurate to ~1e-8)."""
    def sigma(y):
        g = _exact_grad(y)
        eps = 0.5 * (g + g.transpose(0, 2, 1))
        return lam * np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(3) + 2 * mu * eps
    f = np.zeros((x.shape[0], 3))
    for m in range(3):
        e = np.zeros(3)
        e[m] = h
        f -= (sigma(x + e)[:, :, m] - sigma(x - e)[:, :, m]) / (2 * h)
    return f


def _errors(kind, n):
    pts, cells, el = cube_mesh(n, kind)
    shape = {"tetra": "tet4_shape", "tetra10": "tet10_shape"}[kind]
    from contactopt.fem import elements
    q, wq = _tet_rule_high()
    N, dN = getattr(elements, shape)(q)
    lam, mu = lame(E, NU)
    X = pts[cells]
    G, det = element_geometry(X, dN)
    xq = np.einsum("qa,eam->eqm", N, X)
    f = _body_force(xq.reshape(-1, 3), lam, mu).reshape(xq.shape)
    fe = np.einsum("q,qa,eqm,eq->eam", wq, N, f, det)
    F = np.zeros((len(pts), 3))
    for m in range(3):
        F[:, m] = np.bincount(cells.ravel(), weights=fe[..., m].ravel(), minlength=len(pts))
    asm = ElasticityAssembler(cells, len(pts), [], E, NU, element=el)
    u = solve_dirichlet(asm, pts, on_boundary(pts), _exact(pts), F.ravel()).reshape(-1, 3)
    ue = u[cells]
    uh = np.einsum("qa,eam->eqm", N, ue)
    gh = np.einsum("eam,eqan->eqmn", ue, G)
    ex = _exact(xq.reshape(-1, 3)).reshape(xq.shape)
    gx = _exact_grad(xq.reshape(-1, 3)).reshape(*xq.shape, 3)
    l2 = np.sqrt(np.einsum("q,eq,eqm->", wq, det, (uh - ex) ** 2))
    eps = 0.5 * ((gh - gx) + (gh - gx).swapaxes(2, 3))
    en = np.einsum("q,eq,eqmn->", wq, det, 2 * mu * eps ** 2) + np.einsum(
        "q,eq,eq->", wq, det, lam * np.trace(eps, axis1=2, axis2=3) ** 2)
    return l2, np.sqrt(en)


@pytest.mark.parametrize("kind, ns, rates", [("tetra", (4, 8, 16), (2.0, 1.0)),
                                             ("tetra10", (2, 4, 8), (3.0, 2.0))])
def test_convergence_rates_on_a_manufactured_solution(kind, ns, rates):
    errs = np.array([_errors(kind, n) for n in ns])
    hs = 1.0 / np.array(ns)
    r_l2 = np.polyfit(np.log(hs), np.log(errs[:, 0]), 1)[0]
    r_en = np.polyfit(np.log(hs), np.log(errs[:, 1]), 1)[0]
    assert abs(r_l2 - rates[0]) < 0.2, (r_l2, errs)
    assert abs(r_en - rates[1]) < 0.2, (r_en, errs)


# ------------------------------------------------------------------ shape derivatives
@pytest.mark.parametrize("kind", ["tetra", "tetra10", "hexahedron"])
def test_shape_derivatives_match_central_differences(kind):
    pts, cells, el = cube_mesh(2, kind, distort=0.2, seed=5)
    asm = ElasticityAssembler(cells, len(pts), [], E, NU, element=el)
    ref = ReferenceMesh(pts, cells, kind)
    faces = ref.boundary_faces()
    top = faces[np.all(pts[faces[:, :3], 2] > 1 - 1e-12, axis=1)]
    rng = np.random.default_rng(6)
    u, v = rng.standard_normal(3 * len(pts)), rng.standard_normal(3 * len(pts))
    t, p, f = np.array([0.3, -0.2, 0.5]), 0.7, np.array([0.1, 0.4, -0.3])
    a = asm.stiffness_shape_contraction(pts, u, v)
    b = surface_load_shape_contraction(pts, top, t, v, face=el.face)
    c = pressure_load_shape_contraction(pts, top, p, v, face=el.face)
    d = body_load_shape_contraction(pts, cells, el.N, el.dN, el.w, f, v)
    h = 1e-6
    for node, m in ((int(top[0, 0]), 2), (int(top[1, 1]), 0), (len(pts) // 2, 1)):
        Xp, Xm = pts.copy(), pts.copy()
        Xp[node, m] += h
        Xm[node, m] -= h
        fd = [(v @ (asm.full_stiffness(Xp) @ u) - v @ (asm.full_stiffness(Xm) @ u)) / (2 * h),
              v @ (surface_load(Xp, top, t, face=el.face) - surface_load(Xm, top, t, face=el.face)) / (2 * h),
              v @ (pressure_load(Xp, top, p, face=el.face) - pressure_load(Xm, top, p, face=el.face)) / (2 * h),
              v @ (body_load(Xp, cells, el.N, el.dN, el.w, f) - body_load(Xm, cells, el.N, el.dN, el.w, f)) / (2 * h)]
        for pred, ref_ in zip((a[node, m], b[node, m], c[node, m], d[node, m]), fd):
            assert abs(pred - ref_) <= 1e-6 * max(abs(ref_), 1e-3 * np.abs(fd).max()), (kind, node, m, pred, ref_)


# ------------------------------------------------------------------ pressure
@pytest.mark.parametrize("kind", ["tetra", "tetra10", "hexahedron"])
def test_pressure_on_a_closed_surface_sums_to_zero_and_on_a_flat_face_to_p_area(kind):
    pts, cells, el = cube_mesh(3, kind, distort=0.25, seed=7)
    X = pts.copy()
    X[:, 2] += 0.1 * np.sin(2 * X[:, 0]) * X[:, 2]           # a curved, closed body
    ref = ReferenceMesh(X, cells, kind)
    L = pressure_load(X, ref.boundary_faces(), 2.5, face=el.face).reshape(-1, 3)
    assert np.abs(L.sum(axis=0)).max() <= 1e-12
    bottom = ref.boundary_faces()
    bottom = bottom[np.all(pts[bottom[:, :3], 2] < 1e-12, axis=1)]
    Lb = pressure_load(pts, bottom, 2.5, face=el.face).reshape(-1, 3).sum(axis=0)
    assert np.allclose(Lb, [0.0, 0.0, 2.5], rtol=0, atol=1e-12)     # −p·area·n, n = −e3, area 1
    assert abs(face_areas_nodal(pts, bottom, face=el.face).sum() - 1.0) <= 1e-12


def test_element_type_lookup_names_the_supported_types():
    from contactopt.errors import MeshError
    assert element_type("tetra10") is TET10
    with pytest.raises(MeshError, match="'wedge'.*hexahedron, tetra, tetra10"):
        element_type("wedge")
