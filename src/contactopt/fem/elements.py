"""Element and face types: reference shape functions, their gradients and quadrature rules.

One assembly layer (:mod:`contactopt.fem.elasticity`, :mod:`contactopt.fem.loads`) serves every
type; a type only gives its reference data. Node orders are meshio's (= VTK's):

* ``HEX8`` (``hexahedron``, Q1): vertices (0,0,0), (1,0,0), (1,1,0), (0,1,0), (0,0,1), (1,0,1),
  (1,1,1), (0,1,1) of [−1,1]³ (as 0 ↦ −1); 2×2×2 Gauss, exact for the stiffness of a
  parallelepiped.
* ``TET4`` (``tetra``, P1): vertices (0,0,0), (1,0,0), (0,1,0), (0,0,1); one point at the
  centroid (degree 1), exact for the (constant) stiffness and for ∫N_a, the body load.
* ``TET10`` (``tetra10``, P2): the four vertices, then the midpoints of the edges 01, 12, 02,
  03, 13, 23 (Gmsh lists the last two as 23, 13; meshio swaps them on reading, so files from
  Gmsh arrive in this order); the symmetric 4-point rule of degree 2, exact for the stiffness
  of a straight tetrahedron (isoparametric when curved), and an 8-point rule of degree 3 for the
  body load (exact for a straight one, and for det J of degree 1 in a curved one).

Every element type lists its boundary faces (``faces``, local node lists, the same as
:data:`contactopt.mesh.reference.CELL_FACES`) so that the normal T1 × T2 of the face
parametrisation (T_k = ∂x/∂η_k) points out of the element. Face types (reference coordinates
(η, ζ)):

* ``QUAD4`` (``quad``): (−1,−1), (1,−1), (1,1), (−1,1); 2×2 Gauss.
* ``TRI3`` (``triangle``): (0,0), (1,0), (0,1); 3-point rule of degree 2.
* ``TRI6`` (``triangle6``): the three vertices, then the midpoints of the edges 01, 12, 20;
  6-point rule of degree 4 (exact for N_a·|T1×T2| on a curved quadratic face up to degree 4).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.special import roots_jacobi

from ..errors import MeshError


@dataclass(frozen=True, eq=False)
class FaceType:
    """A boundary-face type: N (Q, n), dN/d(η, ζ) (Q, n, 2), weights w (Q,) of its rule.

    ``name`` is the meshio cell type (also ``meshio_name``), ``label`` the short name (``TRI6``),
    ``points`` the reference nodes (n, 2) and ``shape(q) → (N, dN)`` the shape functions at any
    reference points q (Q, 2).
    """

    name: str
    n_nodes: int
    N: np.ndarray = field(repr=False)
    dN: np.ndarray = field(repr=False)
    w: np.ndarray = field(repr=False)
    label: str = ""
    points: np.ndarray = field(default=None, repr=False)
    shape: Callable = field(default=None, repr=False)
    n_vertices: int = 0
    degree: int = 1

    @property
    def meshio_name(self) -> str:
        return self.name


@dataclass(frozen=True, eq=False)
class ElementType:
    """A volume-element type: N (Q, n), dN/dξ (Q, n, 3), weights w (Q,) of the stiffness rule.

    ``load_N``, ``load_dN``, ``load_w``: the (possibly finer) rule of the body load; ``faces``
    (n_faces, n_face_nodes): the element's boundary faces as local node lists, each oriented so
    that T1 × T2 points out of the element, of type ``face``. ``name`` is the meshio cell type
    (also ``meshio_name``), ``label`` the short name (``TET10``), ``points`` the reference nodes
    (n, 3), ``shape(q) → (N, dN)`` the shape functions at any reference points q (Q, 3).
    """

    name: str
    n_nodes: int
    N: np.ndarray = field(repr=False)
    dN: np.ndarray = field(repr=False)
    w: np.ndarray = field(repr=False)
    face: FaceType = field(repr=False)
    faces: np.ndarray = field(default=None, repr=False)
    load_N: np.ndarray = field(default=None, repr=False)
    load_dN: np.ndarray = field(default=None, repr=False)
    load_w: np.ndarray = field(default=None, repr=False)
    label: str = ""
    points: np.ndarray = field(default=None, repr=False)
    shape: Callable = field(default=None, repr=False)
    n_vertices: int = 0
    degree: int = 1

    @property
    def meshio_name(self) -> str:
        return self.name

    def reference(self, load: bool = False):
        """(N, dN, w) of the stiffness rule, or of the body-load rule with ``load=True``."""
        return (self.load_N, self.load_dN, self.load_w) if load else (self.N, self.dN, self.w)


# ---------------------------------------------------------------------- hexahedra
_HEX_SIGNS = 2.0 * np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                             (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)], float) - 1.0


def hex_shape(q: np.ndarray):
    """Q1 shape functions N (Q, 8) and gradients dN/dξ (Q, 8, 3) at points q (Q, 3) of [−1,1]³."""
    q = np.atleast_2d(np.asarray(q, float))
    lin = 1.0 + q[:, None, :] * _HEX_SIGNS[None, :, :]      # (Q, 8, 3) factors (1 ± ξ_m)
    N = np.prod(lin, axis=2) / 8.0
    dN = np.empty((q.shape[0], 8, 3))
    for m in range(3):
        others = np.prod(np.delete(lin, m, axis=2), axis=2)
        dN[:, :, m] = _HEX_SIGNS[None, :, m] * others / 8.0
    return N, dN


def gauss_hex(order: int = 2):
    """Tensor Gauss–Legendre rule on [−1,1]³: points (order³, 3) and weights, x fastest."""
    x, w = np.polynomial.legendre.leggauss(order)
    q = np.array([(a, b, c) for c in x for b in x for a in x])
    wq = np.array([wa * wb * wc for wc in w for wb in w for wa in w])
    return q, wq


_QSIGN = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], float)


def quad_shape(q: np.ndarray):
    """Bilinear N (Q, 4) and dN/d(η, ζ) (Q, 4, 2) at points q (Q, 2) of [−1,1]²."""
    lin = 1.0 + q[:, None, :] * _QSIGN[None]
    N = lin[:, :, 0] * lin[:, :, 1] / 4.0
    dN = np.stack([_QSIGN[None, :, 0] * lin[:, :, 1], _QSIGN[None, :, 1] * lin[:, :, 0]], axis=2) / 4.0
    return N, dN


# ---------------------------------------------------------------------- simplices
def _tet_bary(q):
    q = np.atleast_2d(np.asarray(q, float))
    return np.column_stack([1.0 - q.sum(axis=1), q])         # (Q, 4): L0..L3

# ∂L_i/∂ξ_m on the reference tetrahedron
_DL = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
TET10_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])


def tet4_shape(q):
    """P1 N (Q, 4) and dN/dξ (Q, 4, 3) on the reference tetrahedron."""
    L = _tet_bary(q)
    return L, np.broadcast_to(_DL, (L.shape[0], 4, 3)).copy()


def _quadratic(L, dL, edges):
    """P2 on a simplex from barycentric L (Q, v) with ∂L/∂ξ dL (v, d): N_i = L_i(2L_i − 1) at the
    vertices, N_ij = 4 L_i L_j at the edge midpoints (in the order of ``edges``)."""
    Q, v = L.shape
    n = v + len(edges)
    N = np.empty((Q, n))
    dN = np.empty((Q, n, dL.shape[1]))
    N[:, :v] = L * (2.0 * L - 1.0)
    dN[:, :v] = (4.0 * L - 1.0)[:, :, None] * dL[None]
    i, j = edges.T
    N[:, v:] = 4.0 * L[:, i] * L[:, j]
    dN[:, v:] = 4.0 * (L[:, i, None] * dL[None, j] + L[:, j, None] * dL[None, i])
    return N, dN


def tet10_shape(q):
    """P2 N (Q, 10) and dN/dξ (Q, 10, 3): N_i = L_i(2L_i − 1), N_ij = 4 L_i L_j (VTK edge order)."""
    return _quadratic(_tet_bary(q), _DL, TET10_EDGES)


def _tri_bary(q):
    q = np.atleast_2d(np.asarray(q, float))
    return np.column_stack([1.0 - q.sum(axis=1), q])         # (Q, 3)


_DT = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
TRI6_EDGES = np.array([[0, 1], [1, 2], [2, 0]])


def tri3_shape(q):
    L = _tri_bary(q)
    return L, np.broadcast_to(_DT, (L.shape[0], 3, 2)).copy()


def tri6_shape(q):
    return _quadratic(_tri_bary(q), _DT, TRI6_EDGES)


def _conical(degree: int, dim: int):
    """Stroud's conical product rule of the reference simplex (positive weights, exact to
    ``degree``): Gauss–Jacobi points collapsed from the cube, (⌈(degree+1)/2⌉)^dim points."""
    n = max(1, (degree + 2) // 2)
    axes = []
    for k in range(dim):                       # weight (1 − t)^(dim−1−k) on [0, 1]
        a = dim - 1 - k
        x, w = roots_jacobi(n, a, 0)
        axes.append(((x + 1) / 2, w / 2 ** (a + 1)))
    grids = np.meshgrid(*[t for t, _ in axes], indexing="ij")
    wts = np.meshgrid(*[w for _, w in axes], indexing="ij")
    t = [g.ravel() for g in grids]
    w = np.prod([g.ravel() for g in wts], axis=0)
    q = np.empty((w.size, dim))
    rest = np.ones(w.size)
    for k in range(dim):
        q[:, k] = t[k] * rest
        rest = rest * (1 - t[k])
    return q, w


def tet_rule(degree: int):
    """Points (Q, 3) and weights (Q,) on the reference tetrahedron (volume 1/6), exact to ``degree``:
    the centroid (1), the symmetric 4-point rule (2), else Stroud's conical product."""
    if degree <= 1:
        return np.array([[0.25, 0.25, 0.25]]), np.array([1.0 / 6.0])
    if degree == 2:
        a, b = 0.5854101966249685, 0.1381966011250105
        q = np.array([[b, b, b], [a, b, b], [b, a, b], [b, b, a]])
        return q, np.full(4, 1.0 / 24.0)
    return _conical(degree, 3)


def tri_rule(degree: int):
    """Points (Q, 2) and weights (Q,) on the reference triangle (area 1/2), exact to ``degree``:
    the symmetric 3-point rule (≤ 2), the 6-point rule of Dunavant (3, 4), else a conical product."""
    if degree <= 2:
        q = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])
        return q, np.full(3, 1.0 / 6.0)
    if degree <= 4:
        a, b = 0.44594849091596488632, 0.09157621350977074346
        wa, wb = 0.22338158967801146570 / 2.0, 0.10995174365532186764 / 2.0
        q = np.array([[a, a], [1 - 2 * a, a], [a, 1 - 2 * a], [b, b], [1 - 2 * b, b], [b, 1 - 2 * b]])
        return q, np.array([wa, wa, wa, wb, wb, wb])
    return _conical(degree, 2)


_tet_rule, _tri_rule = tet_rule, tri_rule


def _face(name, label, n, n_vertices, degree, shape, rule, points):
    q, w = rule
    N, dN = shape(q)
    return FaceType(name, n, N, dN, w, label=label, points=points, shape=shape, n_vertices=n_vertices,
                    degree=degree)


def _element(name, label, n, n_vertices, degree, shape, rule, load_rule, face, faces, points):
    q, w = rule
    N, dN = shape(q)
    ql, wl = load_rule
    Nl, dNl = shape(ql)
    return ElementType(name, n, N, dN, w, face, faces=faces, load_N=Nl, load_dN=dNl, load_w=wl,
                       label=label, points=points, shape=shape, n_vertices=n_vertices, degree=degree)


_G = 1.0 / np.sqrt(3.0)
GAUSS_1D = np.array([-_G, _G])
_TET_POINTS = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
_TRI_POINTS = np.array([[0.0, 0], [1, 0], [0, 1]])
QUAD4 = _face("quad", "QUAD4", 4, 4, 1, quad_shape,
              (np.array([(x, y) for y in GAUSS_1D for x in GAUSS_1D]), np.ones(4)), _QSIGN.copy())
TRI3 = _face("triangle", "TRI3", 3, 3, 1, tri3_shape, tri_rule(2), _TRI_POINTS)
TRI6 = _face("triangle6", "TRI6", 6, 3, 2, tri6_shape, tri_rule(4),
             np.vstack([_TRI_POINTS, _TRI_POINTS[TRI6_EDGES].mean(axis=1)]))
# local faces, outward by the right-hand rule (= contactopt.mesh.reference.CELL_FACES)
HEX8 = _element("hexahedron", "HEX8", 8, 8, 1, hex_shape, gauss_hex(2), gauss_hex(2), QUAD4,
                np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]),
                _HEX_SIGNS.copy())
TET4 = _element("tetra", "TET4", 4, 4, 1, tet4_shape, tet_rule(1), tet_rule(1), TRI3,
                np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]), _TET_POINTS)
TET10 = _element("tetra10", "TET10", 10, 4, 2, tet10_shape, tet_rule(2), tet_rule(3), TRI6,
                 np.array([[0, 2, 1, 6, 5, 4], [0, 1, 3, 4, 8, 7], [1, 2, 3, 5, 9, 8], [0, 3, 2, 7, 9, 6]]),
                 np.vstack([_TET_POINTS, _TET_POINTS[TET10_EDGES].mean(axis=1)]))

ELEMENTS = {e.name: e for e in (HEX8, TET4, TET10)}
FACES = {f.name: f for f in (QUAD4, TRI3, TRI6)}


def element_type(name) -> ElementType:
    """The element type of a meshio cell type name (or short label, or an ElementType itself);
    MeshError names the supported ones."""
    if isinstance(name, ElementType):
        return name
    for e in ELEMENTS.values():
        if name in (e.name, e.label):
            return e
    raise MeshError(f"volume cells of type {name!r} are not supported "
                    f"(supported: {', '.join(ELEMENTS)})")


def face_type(name) -> FaceType:
    """The face type of a meshio cell type name (or short label, or a FaceType itself)."""
    if isinstance(name, FaceType):
        return name
    for f in FACES.values():
        if name in (f.name, f.label):
            return f
    raise MeshError(f"boundary faces of type {name!r} are not supported "
                    f"(supported: {', '.join(FACES)})")


def element_for(cells: np.ndarray) -> ElementType:
    """The element type of cells (E, n) by their node count (8, 4, 10)."""
    n = np.shape(cells)[1] if np.ndim(cells) == 2 else -1
    for e in ELEMENTS.values():
        if e.n_nodes == n:
            return e
    raise MeshError(f"cells of {n} nodes are no supported element (supported: "
                    + ", ".join(f"{e.name} ({e.n_nodes})" for e in ELEMENTS.values()) + ")")


def face_for(faces: np.ndarray) -> FaceType:
    """The face type of faces (F, n) by their node count (4, 3, 6)."""
    n = np.shape(faces)[1] if np.ndim(faces) == 2 else -1
    for f in FACES.values():
        if f.n_nodes == n:
            return f
    raise MeshError(f"faces of {n} nodes are no supported face type (supported: "
                    + ", ".join(f"{f.name} ({f.n_nodes})" for f in FACES.values()) + ")")
