"""Element types (HEX8, TET4, TET10 with QUAD4, TRI3, TRI6 faces) in the one assembly layer:
reference data, patch tests, convergence rates, loads, design derivatives, the tetrahedral split."""

from math import factorial

import numpy as np
import pytest

from contactopt.errors import ContactOptError, MeshError
from contactopt.fem import loads as L
from contactopt.fem.elasticity import ElasticityAssembler, element_geometry, lame
from contactopt.fem.elements import (
    HEX8,
    QUAD4,
    TET4,
    TET10,
    TRI6,
    element_type,
    face_type,
    gauss_hex,
    tet_rule,
    tri_rule,
)
from contactopt.fem.linsolve import factorize
from contactopt.mesh.block import block_mesh
from contactopt.mesh.reference import CELL_FACES
from contactopt.mesh.tetsplit import hex_to_tets, quads_to_triangles, tet4_to_tet10, tet_boundary_faces

E, NU = 21.19, 0.277
ELEMENTS = {"HEX8": HEX8, "TET4": TET4, "TET10": TET10}


# ---------------------------------------------------------------------- meshes
def smooth_map(x, amp=0.06):
    """A smooth map of the unit cube onto itself (boundary faces stay on their planes)."""
    s = np.prod(np.sin(np.pi * x), axis=1)
    d = np.array([1.0, -0.7, 0.8])
    y = x + amp * s[:, None] * d
    y[:, 0] += 0.5 * amp * np.sin(np.pi * x[:, 0]) * x[:, 1] * (1 - x[:, 1])
    return y


def cube_mesh(kind, n, amp=0.06, jitter=0.0, seed=0):
    """Unit cube, n³ cubes: (points, cells, boundary faces, boundary-node mask) for an element type.

    Hexahedra or the Kuhn split; P2 midside nodes at the reference edge midpoints; then every node
    goes through ``smooth_map`` (curved P2 elements) and interior vertices are jittered by
    ``jitter``·h (straight P2 edges stay straight only where amp = 0)."""
    ref = block_mesh(1.0, 1.0, 1.0, n, n, n)
    pts, cells = ref.points, ref.cells
    if kind == "HEX8":
        faces = ref.boundary_faces()
    else:
        cells = hex_to_tets(cells)
        faces = tet_boundary_faces(cells)
        if kind == "TET10":
            pts, cells, faces = tet4_to_tet10(pts, cells, faces)
    bnd = np.zeros(len(pts), bool)
    bnd[faces.ravel()] = True
    pts = pts.copy()
    if jitter:
        rng = np.random.default_rng(seed)
        inner = np.flatnonzero(~bnd)[: len(ref.points)]
        inner = inner[inner < len(ref.points)]
        pts[inner] += jitter / n * rng.uniform(-1, 1, (inner.size, 3))
        if kind == "TET10":                       # midside nodes follow the vertices: straight edges
            from contactopt.mesh.tetsplit import TET10_EDGES
            e = cells[:, 4:].ravel()
            v = cells[:, TET10_EDGES].reshape(-1, 2)
            pts[e] = 0.5 * (pts[v[:, 0]] + pts[v[:, 1]])
    return smooth_map(pts, amp), cells, faces, bnd


def solve_dirichlet(asm, X, bnd, g, f_full):
    """A u = f with u = g on the nodes ``bnd`` (all components)."""
    A = asm.full_stiffness(X).tocsr()
    fixed = np.repeat(bnd, 3)
    u = np.zeros(A.shape[0])
    u[fixed] = g.ravel()[fixed]
    free = ~fixed
    rhs = f_full[free] - A[free][:, fixed] @ u[fixed]
    with factorize(A[free][:, free].tocsr()) as fac:
        u[free] = fac.solve(rhs)
    return u


# ---------------------------------------------------------------------- reference data
@pytest.mark.parametrize("name", ["HEX8", "TET4", "TET10"])
def test_reference_element_data(name):
    el = ELEMENTS[name]
    assert element_type(el.meshio_name) is el and element_type(name) is el
    N, dN = el.shape(el.points)
    assert np.allclose(N, np.eye(el.n_nodes), atol=1e-14)          # nodal basis
    for NN, dd in ((el.N, el.dN), (el.load_N, el.load_dN)):
        assert np.allclose(NN.sum(axis=1), 1) and np.allclose(dd.sum(axis=1), 0)
    # gradients against central differences of the shape functions
    q = np.array([[0.11, 0.23, 0.31]]) if name != "HEX8" else np.array([[0.3, -0.5, 0.2]])
    h = 1e-6
    fd = np.stack([(el.shape(q + h * e)[0] - el.shape(q - h * e)[0]) / (2 * h) for e in np.eye(3)], axis=2)
    assert np.abs(fd - el.shape(q)[1]).max() < 1e-8
    # faces: as the reference mesh lists them, and outward on the reference element
    assert el.face.meshio_name == CELL_FACES[el.meshio_name][0]
    assert np.array_equal(el.faces, CELL_FACES[el.meshio_name][1])
    centre = el.points[: el.n_vertices].mean(axis=0)
    for f in el.faces:
        Xf = el.points[f]
        T1 = np.einsum("am,qa->qm", Xf, el.face.dN[:, :, 0])
        T2 = np.einsum("am,qa->qm", Xf, el.face.dN[:, :, 1])
        out = Xf.mean(axis=0) - centre
        assert np.all(np.cross(T1, T2) @ out > 0)
        assert np.allclose(el.face.shape(el.face.points)[0], np.eye(el.face.n_nodes), atol=1e-14)


def test_quadrature_rules_are_exact_to_their_degree():
    for d in range(1, 8):
        q, w = tet_rule(d)
        q2, w2 = tri_rule(d)
        assert np.all(w > 0) and np.all(w2 > 0)
        for a in range(d + 1):
            for b in range(d + 1 - a):
                c = d - a - b
                exact = factorial(a) * factorial(b) * factorial(c) / factorial(d + 3)
                assert abs(w @ (q[:, 0] ** a * q[:, 1] ** b * q[:, 2] ** c) - exact) < 1e-15
            exact = factorial(a) * factorial(d - a) / factorial(d + 2)
            assert abs(w2 @ (q2[:, 0] ** a * q2[:, 1] ** (d - a)) - exact) < 1e-15
    assert TET4.w.size == 1 and TET10.w.size == 4 and HEX8.w.size == 8 and TRI6.w.size == 6


def test_unsupported_types_are_named_with_the_supported_ones():
    with pytest.raises(MeshError, match=r"'wedge'.*hexahedron, tetra, tetra10") as exc:
        element_type("wedge")
    assert isinstance(exc.value, ContactOptError)
    with pytest.raises(MeshError, match=r"'quad8'.*quad, triangle, triangle6"):
        face_type("quad8")
    assert face_type("triangle6") is TRI6 and face_type("quad") is QUAD4
    with pytest.raises(MeshError, match="TET10|tetra10"):
        ElasticityAssembler(np.zeros((3, 4), int), 10, [], E, NU, element=TET10)


# ---------------------------------------------------------------------- patch tests
@pytest.mark.parametrize("name", ["HEX8", "TET4", "TET10"])
def test_patch_test_affine_field_is_reproduced_on_distorted_mesh(name):
    # distorted elements (straight-sided for TET10: the 4-point rule is exact for them)
    X, cells, faces, bnd = cube_mesh(name, 4, amp=0.08 if name != "TET10" else 0.0, jitter=0.25, seed=2)
    asm = ElasticityAssembler(cells, len(X), [], E, NU, element=ELEMENTS[name])
    assert asm.jacobian_determinants(X).min() > 0
    rng = np.random.default_rng(1)
    M, c = rng.standard_normal((3, 3)), rng.standard_normal(3)
    exact = X @ M.T + c
    u = solve_dirichlet(asm, X, bnd, exact, np.zeros(X.size))
    assert not np.all(bnd)
    assert np.abs(u.reshape(-1, 3) - exact).max() < 1e-10 * np.abs(exact).max()
    # K u_affine is the consistent load of the constant traction σ n on the boundary
    lam, mu = lame(E, NU)
    eps = 0.5 * (M + M.T)
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    f = asm.full_stiffness(X) @ exact.ravel()
    # t = σ n: three "pressures" by columns: ∫ N_a σ n dS = −Σ_j σ[:, j] (pressure_load of p = −1)_j
    Ln = L.pressure_load(X, faces, -1.0).reshape(-1, 3)          # ∫ N_a n dS
    assert np.abs(f.reshape(-1, 3) - Ln @ sigma.T).max() < 1e-10 * np.abs(f).max()


def test_curved_p2_patch_test_error_is_the_quadrature_error():
    # curved P2 tetrahedra with the 4-point rule: not exact, but small and falling under refinement
    errs = []
    for n in (2, 4):
        X, cells, _, bnd = cube_mesh("TET10", n, amp=0.08)
        asm = ElasticityAssembler(cells, len(X), [], E, NU, element=TET10)
        M = np.array([[0.3, -0.2, 0.5], [0.1, 0.4, -0.3], [0.2, 0.1, 0.6]])
        exact = X @ M.T
        u = solve_dirichlet(asm, X, bnd, exact, np.zeros(X.size))
        errs.append(np.abs(u.reshape(-1, 3) - exact).max() / np.abs(exact).max())
    assert 1e-12 < errs[1] < errs[0] < 1e-2


@pytest.mark.parametrize("name", ["TET4", "TET10"])
def test_patch_test_on_a_morphed_tetrahedral_block(name):
    # the block lifted by a Bézier surface with the weight 1 − x3 (the morph of an optimization).
    # P2 midside nodes move with the morph: curved elements. Still exact with the 4-point rule:
    # only x3 moves, J = J_ref + e3 ⊗ ∇_ξ h, so every cofactor of J is of degree ≤ 1 and
    # ∫ adj(J)ᵀ ∇_ξ N_a (the patch test's integrand) has degree 2
    from contactopt.design.bezier import BezierSurface
    ref = block_mesh(2.0, 1.0, 1.0, 4, 2, 2)
    tets = hex_to_tets(ref.cells)
    pts, cells, faces = ref.points, tets, tet_boundary_faces(tets)
    if name == "TET10":
        pts, cells, faces = tet4_to_tet10(pts, tets, faces)
    surf = BezierSurface(3, 2, 2.0, 1.0)
    alpha = 0.05 + 0.25 * np.random.default_rng(0).random(surf.size)
    X = pts.copy()
    X[:, 2] += surf.evaluate(alpha, X[:, 0], X[:, 1]) * (1.0 - X[:, 2])
    asm = ElasticityAssembler(cells, len(X), [], E, NU, element=ELEMENTS[name])
    assert np.all(asm.jacobian_determinants(X) > 0)
    B = np.random.default_rng(3).standard_normal((3, 3))
    exact = X @ B.T
    bnd = np.zeros(len(X), bool)
    bnd[faces.ravel()] = True
    u = solve_dirichlet(asm, X, bnd, exact, np.zeros(X.size))
    err = np.abs(u.reshape(-1, 3) - exact).max() / np.abs(exact).max()
    assert err < 1e-10, err


# ---------------------------------------------------------------------- convergence rates
KM = np.array([[0.9, 1.3, 0.7], [1.1, 0.6, 1.4], [0.5, 1.2, 1.0]])
PHI = np.array([[0.3, 0.2, 0.5], [0.1, 0.4, 0.25], [0.6, 0.35, 0.15]])


def u_exact(x):
    return np.stack([np.prod(np.sin(KM[i] * x + PHI[i]), axis=-1) for i in range(3)], axis=-1)


def _factors(x):
    a = KM[None] * x[:, None, :] + PHI[None]
    return np.sin(a), np.cos(a)


def grad_exact(x):
    s, c = _factors(x)
    H = np.empty(x.shape[:1] + (3, 3))
    for j in range(3):
        f = s.copy()
        f[:, :, j] = KM[None, :, j] * c[:, :, j]
        H[:, :, j] = np.prod(f, axis=2)
    return H


def body_force(x):
    s, c = _factors(x)
    T = np.empty(x.shape[:1] + (3, 3, 3))
    for j in range(3):
        for k in range(3):
            f = s.copy()
            if j == k:
                f[:, :, j] = -KM[None, :, j] ** 2 * s[:, :, j]
            else:
                f[:, :, j] = KM[None, :, j] * c[:, :, j]
                f[:, :, k] = KM[None, :, k] * c[:, :, k]
            T[:, :, j, k] = np.prod(f, axis=2)
    lam, mu = lame(E, NU)
    div_grad = np.einsum("nkki->ni", T)
    return -(lam * div_grad + mu * (np.einsum("nijj->ni", T) + div_grad))


def fine_rule(el):
    """A rule of degree 2p + 1 for loads and errors of an element of degree p."""
    if el is HEX8:
        q, w = gauss_hex(3)
    else:
        q, w = tet_rule(2 * el.degree + 1)
    N, dN = el.shape(q)
    return N, dN, w


@pytest.mark.parametrize("name, sizes, rates", [("TET4", (4, 8, 16), (2, 1)), ("TET10", (2, 4, 8), (3, 2)),
                                                ("HEX8", (3, 6, 12), (2, 1))])
def test_convergence_rates_manufactured_solution(name, sizes, rates):
    el = ELEMENTS[name]
    lam, mu = lame(E, NU)
    N, dN, w = fine_rule(el)
    hs, l2, en = [], [], []
    for n in sizes:
        X, cells, _, bnd = cube_mesh(name, n)
        asm = ElasticityAssembler(cells, len(X), [], E, NU, element=el)
        Xe = X[cells]
        G, det = element_geometry(Xe, dN)
        xq = np.einsum("qa,eam->eqm", N, Xe).reshape(-1, 3)
        fq = body_force(xq).reshape(len(cells), -1, 3)
        fe = np.einsum("q,qa,eq,eqm->eam", w, N, det, fq)
        f = np.stack([np.bincount(cells.ravel(), fe[:, :, m].ravel(), minlength=len(X)) for m in range(3)], axis=1)
        u = solve_dirichlet(asm, X, bnd, u_exact(X), f.ravel())
        ue = u.reshape(-1, 3)[cells]
        err = np.einsum("qa,eam->eqm", N, ue) - u_exact(xq).reshape(fq.shape)
        l2.append(np.sqrt(np.einsum("q,eq,eqm->", w, det, err ** 2)))
        He = np.einsum("eai,eqaj->eqij", ue, G) - grad_exact(xq).reshape(len(cells), -1, 3, 3)
        eps = 0.5 * (He + np.swapaxes(He, -1, -2))
        energy = 2 * mu * np.einsum("eqij,eqij->eq", eps, eps) + lam * np.einsum("eqii->eq", eps) ** 2
        en.append(np.sqrt(np.einsum("q,eq,eq->", w, det, energy)))
        hs.append(1.0 / n)
    rate_l2 = np.polyfit(np.log(hs), np.log(l2), 1)[0]
    rate_en = np.polyfit(np.log(hs), np.log(en), 1)[0]
    assert abs(rate_l2 - rates[0]) < 0.2, (rate_l2, l2)
    assert abs(rate_en - rates[1]) < 0.2, (rate_en, en)


# ---------------------------------------------------------------------- loads
@pytest.mark.parametrize("name", ["HEX8", "TET4", "TET10"])
def test_pressure_on_closed_surface_has_no_resultant_and_areas_add_up(name):
    X, cells, faces, _ = cube_mesh(name, 3, amp=0.1)
    X = X @ np.array([[1.0, 0.2, 0.0], [0.0, 0.9, 0.3], [0.1, 0.0, 1.2]]).T + [0.3, -1.0, 2.0]
    P = L.pressure_load(X, faces, 2.5, face=ELEMENTS[name].face).reshape(-1, 3)
    scale = 2.5 * L.face_areas_nodal(X, faces).sum()
    assert np.abs(P.sum(axis=0)).max() < 1e-13 * scale
    # moment of a uniform pressure on a closed surface is zero too
    assert np.abs(np.cross(X, P).sum(axis=0)).max() < 1e-12 * scale
    # ∫ x·n dS = 3 V: the pressure's virtual work on x equals −3 p V
    # (exact for every type: x·(T1 × T2) has degree ≤ 4 on a TRI6 face, det J of a curved TET10
    # degree 3, integrated by its body-load rule)
    el = ELEMENTS[name]
    V = np.einsum("eq,q->", element_geometry(X[cells], el.load_dN)[1], el.load_w)
    assert abs(np.sum(P * X) + 3 * 2.5 * V) < 1e-12 * 2.5 * V


@pytest.mark.parametrize("name", ["HEX8", "TET4", "TET10"])
def test_pressure_on_flat_face_is_minus_p_area_n(name):
    ref = block_mesh(2.0, 1.0, 1.0, 3, 2, 2)
    cells, faces = ref.cells, ref.parts["right"].faces
    pts = ref.points
    if name != "HEX8":
        cells = hex_to_tets(cells)
        faces = quads_to_triangles(faces, cells)
        if name == "TET10":
            pts, cells, faces = tet4_to_tet10(pts, cells, faces)
    # rotate and shift the body; the face x1 = 2 (area 1) keeps its outward normal R e1
    th = 0.4
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    X = pts @ R.T + [1.0, 2.0, 3.0]
    p = 3.7
    P = L.pressure_load(X, faces, p).reshape(-1, 3)
    assert np.allclose(P.sum(axis=0), -p * 1.0 * R[:, 0], atol=1e-13)
    A = L.face_areas_nodal(X, faces)
    assert abs(A.sum() - 1.0) < 1e-13
    Al = L.face_areas_nodal(X, faces, lumped=True)
    assert abs(Al.sum() - 1.0) < 1e-13 and np.all(Al[np.unique(faces)] > 0)
    if name == "TET10":                       # consistent corner weights of flat P2 faces: 0
        assert np.abs(A[np.unique(faces[:, :3])]).max() < 1e-15
    else:                                     # parallelograms and triangles: lumped = consistent
        assert np.allclose(Al, A, rtol=0, atol=1e-15)
    on = np.unique(faces)
    assert np.all(A[np.setdiff1d(np.arange(len(X)), on)] == 0)
    # traction and pressure are the same vector field here
    T = L.surface_load(X, faces, -p * R[:, 0]).reshape(-1, 3)
    assert np.allclose(T, P, atol=1e-14)


# ---------------------------------------------------------------------- design derivatives
def _direction(X, seed):
    return np.random.default_rng(seed).standard_normal(X.shape) * 0.3


@pytest.mark.parametrize("name", ["HEX8", "TET4", "TET10"])
def test_shape_contractions_match_central_differences(name):
    X, cells, faces, bnd = cube_mesh(name, 2, amp=0.1, jitter=0.2, seed=4)
    el = ELEMENTS[name]
    fixed = (3 * np.flatnonzero(X[:, 0] < 1e-12)[:, None] + np.arange(3)).ravel()
    asm = ElasticityAssembler(cells, len(X), fixed, E, NU, element=el)
    rng = np.random.default_rng(7)
    u = asm.to_full(rng.standard_normal(asm.n_free))
    v = asm.to_full(rng.standard_normal(asm.n_free))
    V = _direction(X, 3)
    h = 1e-6
    Xp, Xm = X + h * V, X - h * V

    def check(pred, fp, fm):
        fd = (fp - fm) / (2 * h)
        assert abs(fd) > 1e-3
        assert abs(np.sum(pred * V) - fd) <= 1e-6 * abs(fd), (np.sum(pred * V), fd)

    def vAu(Y):
        return v[asm.free] @ (asm.stiffness(Y) @ u[asm.free])
    check(asm.stiffness_shape_contraction(X, u, v), vAu(Xp), vAu(Xm))
    t = np.array([0.3, -1.2, 0.7])
    check(L.surface_load_shape_contraction(X, faces, t, v),
          v @ L.surface_load(Xp, faces, t), v @ L.surface_load(Xm, faces, t))
    check(L.pressure_load_shape_contraction(X, faces, 1.7, v, face=el.face),
          v @ L.pressure_load(Xp, faces, 1.7), v @ L.pressure_load(Xm, faces, 1.7))
    f = np.array([0.2, 0.5, -1.0])
    check(L.body_load_shape_contraction(X, cells, f, v, element=el),
          v @ L.body_load(Xp, cells, f, element=el), v @ L.body_load(Xm, cells, f, element=el))
    # the old call with an explicit rule gives the same vector for the element's own rule
    Nl, dNl, wl = el.reference(load=True)
    assert np.array_equal(L.body_load(X, cells, Nl, dNl, wl, f), L.body_load(X, cells, f))
    # the body load integrates exactly: Σ_a L_a = f·|Ω|
    vol = np.einsum("eq,q->", asm.jacobian_determinants(X), asm.w)
    assert np.allclose(L.body_load(X, cells, f).reshape(-1, 3).sum(axis=0), f * vol, rtol=1e-12)


# ---------------------------------------------------------------------- assembler
@pytest.mark.parametrize("name", ["TET4", "TET10", "HEX8"])
def test_stiffness_rigid_modes_symmetry_pair_assembly_and_inverted_element(name):
    X, cells, _, _ = cube_mesh(name, 2, amp=0.1, jitter=0.2)
    el = ELEMENTS[name]
    asm = ElasticityAssembler(cells, len(X), [], E, NU, element=el)
    Ke = asm.element_matrices(X[cells])
    assert Ke.shape == (len(cells), 3 * el.n_nodes, 3 * el.n_nodes)
    for e in (0, len(cells) // 2, len(cells) - 1):
        ev = np.linalg.eigvalsh(Ke[e])
        assert np.sum(np.abs(ev) < 1e-10 * ev.max()) == 6 and ev[6] > 1e-6 * ev.max()
    fixed = (3 * np.flatnonzero(X[:, 2] < 1e-12)[:, None] + np.arange(3)).ravel()
    asm2 = ElasticityAssembler(cells, len(X), fixed, E, NU, element=el)
    A = asm2.stiffness(X)                 # per node pair, against element matrices scattered
    Af = asm.full_stiffness(X).tocsr()[asm2.free][:, asm2.free]
    assert A.nnz == Af.nnz and abs(A - Af).max() < 1e-14 * abs(Af).max()
    assert np.array_equal(A.indices, Af.tocsr().sorted_indices().indices)
    assert abs(A - A.T).max() < 1e-13 * abs(A).max()
    # Laplacian: constants in the kernel, ∫|∇g·x|² = |g|²|Ω| for a linear function
    K = asm.scalar_laplacian(X)
    g = np.array([0.3, -0.4, 1.1])
    assert np.abs(K @ np.ones(len(X))).max() < 1e-12
    vol = np.einsum("eq,q->", asm.jacobian_determinants(X), asm.w)
    assert abs((X @ g) @ K @ (X @ g) - g @ g * vol) < 1e-12 * g @ g * vol     # isoparametric: ∇(g·x) = g
    # element e listed with two vertices (and the midside nodes that go with them) swapped
    e = len(cells) - 2
    swap = {"TET4": [1, 0, 2, 3], "TET10": [1, 0, 2, 3, 4, 6, 5, 8, 7, 9],
            "HEX8": [4, 5, 6, 7, 0, 1, 2, 3]}[name]                # HEX8: top and bottom swapped
    bad = cells.copy()
    bad[e] = cells[e, swap]
    asm3 = ElasticityAssembler(bad, len(X), fixed, E, NU, element=el)
    with pytest.raises(MeshError, match=r"inverted") as exc:
        asm3.stiffness(X)
    assert str(exc.value).startswith("1 element(s)") and str(exc.value).endswith(f"[{e}]")
    det = asm3.jacobian_determinants(X)
    assert np.all(det[e] < 0) and np.all(np.delete(det, e, axis=0) > 0)


# ---------------------------------------------------------------------- tetrahedral split
def test_kuhn_split_is_conforming_positive_and_fills_the_block():
    ref = block_mesh(2.0, 1.0, 1.5, 4, 3, 2)
    tets = hex_to_tets(ref.cells)
    X = ref.points[tets]
    det = np.linalg.det(X[:, 1:] - X[:, :1])
    assert det.min() > 0 and abs(det.sum() / 6 - 3.0) < 1e-12
    bnd = tet_boundary_faces(tets)
    assert len(bnd) == 2 * len(ref.boundary_faces())                # conforming: no hanging faces
    for name in ("clamped", "top", "right", "front", "back", "contact"):
        quads = ref.parts[name].faces
        tri = quads_to_triangles(quads, tets)
        assert tri.shape == (2 * len(quads), 3)
        P = ref.points
        n = np.cross(P[tri[:, 1]] - P[tri[:, 0]], P[tri[:, 2]] - P[tri[:, 0]])
        nq = np.cross(P[quads[:, 1]] - P[quads[:, 0]], P[quads[:, 3]] - P[quads[:, 0]])
        assert np.all(np.einsum("fm,fm->f", n, np.repeat(nq, 2, axis=0)) > 0)   # same orientation
    p10, c10, f6 = tet4_to_tet10(ref.points, tets, bnd)
    nv = len(ref.points)
    n_edges = len(p10) - nv
    # Euler for the tetrahedral complex of a ball: V − E + F − T = 1
    tri = np.unique(np.sort(tets[:, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]].reshape(-1, 3), axis=1), axis=0)
    assert nv - n_edges + len(tri) - len(tets) == 1
    from contactopt.mesh.tetsplit import TET10_EDGES, TRI6_EDGES
    assert np.allclose(p10[c10[:, 4:]], p10[c10[:, TET10_EDGES]].mean(axis=2))
    assert np.allclose(p10[f6[:, 3:]], p10[f6[:, TRI6_EDGES]].mean(axis=2))
