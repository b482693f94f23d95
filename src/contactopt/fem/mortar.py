"""Dual mortar coupling of the body's contact face with a counterpart's face (Popp, Gee & Wall).

The contact constraints are integrated over the body's face Γ (the "slave" side, carrying the
multipliers) against the counterpart's face (the "master" side) on their common segmentation
(:mod:`contactopt.mesh.segmentation`). The multipliers are interpolated with the dual basis Φ_j,
biorthogonal to the body's face shape functions N_k on every face e:

    ∫_e Φ_j N_k dΓ = δ_jk ∫_e N_j dΓ,   Φ = A_e N,   A_e = D_e M_e⁻¹,

D_e = diag(∫_e N_j), M_e = (∫_e N_j N_k) (Wohlmuth). The mortar matrices

    D_jj = ∫_Γ Φ_j N_j dΓ   (diagonal, > 0),     M_jk = ∫_Γ Φ_j N̄_k dΓ

(N̄_k the counterpart's shape functions) give the weighted relative displacement of body node j
and the counterpart, divided by D_jj:

    w_j = u_j − Σ_k (D⁻¹M)_jk ū_k = D_jj⁻¹ ∫_Γ Φ_j (u − ū) dΓ,

so Π = D⁻¹M takes the place of point partners: one cone per node, as in node-wise contact, and
the force r_j on body node j puts −Πᵀ r on the counterpart's nodes (work-conjugate). Each row
of Π sums to one where the counterpart covers the body's face, and Π reproduces every field
linear on the face: a uniform pressure and a uniform strain pass across non-matching meshes
exactly (the contact patch test), where averaged partners (standard shape functions in place of
Φ) do not.

Sign and ordering convention: per contact node (t1, t2, ν) = (x1, x2, x3) — the common plane is
the counterpart's face x3 = 0 (or the chart of a curved face, whose frames rotate the coupling
afterwards) and ν its normal, pointing into the body; w_ν = u_ν − (Πū)_ν
opens the gap, the normal force λ = r_ν ≥ 0 pushes the body away from the counterpart, and the
weighted slip increment is the tangential part of the increment of w.

The design moves the body's face along ν: its projection on the common plane, hence the
segmentation, Φ, D and M, do not depend on α, and Π is computed once per run.

Six-node triangles (the faces of ten-node tetrahedra) take the transformed dual basis of Popp,
Gee & Wall. Their standard shape functions integrate to zero at the corners, so a dual basis
built on them would give the corners D_jj = 0. The face's basis is first changed so that every
function has a positive integral: each corner takes a share α of the two mid-side functions of
its edges, and each mid-side function keeps the rest,

    N̂_c = N_c + α (N_m + N_m'),   N̂_m = (1 − 2α) N_m,   α = 1/5,

(m, m' the mid-side nodes next to corner c), i.e. N̂ = T N with T the same on both faces of an
edge, so that it is one matrix on the contact face's nodes; Σ N̂ = Σ N = 1, ∫ N̂_c = 2A/15 and
∫ N̂_m = A/5 on a face of area A. The dual basis is then built on N̂ (Φ = A_e N̂, biorthogonal
to N̂), and D, M with N̂ on the body's side. The displacement u_h = Σ N_k u_k = Σ N̂_j û_j has
the transformed nodal values û = T⁻ᵀ u (a corner keeps its value, a mid-side node takes
(u_m − α(u_a + u_b))/(1 − 2α) with a, b its edge's corners), and the forces conjugate to û are
r̂ = T r: the cones act per node on (û − Π ū, r̂). T keeps the resultant and the moment of the
forces on faces with straight edges. Linear faces use T = I.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..mesh.segmentation import Segmentation, is_affine, reference_coordinates, segment
from .elements import face_type, tri_rule

__all__ = ["MortarCoupling", "dual_coefficients", "dual_weighted", "mortar_coupling", "mortar_matrices",
           "transformed_basis"]

QUAD_EXTRA = 6    # degree added on quadrilaterals that are not parallelograms (Φ, N not polynomial in the plane)
ALPHA = 0.2       # the share of a mid-side function a corner of a six-node triangle takes (module docstring)
TRI6_MIDS = np.array([[3, 5], [3, 4], [4, 5]])     # the mid-side nodes next to corners 0, 1, 2
TRI6_EDGE_CORNERS = np.array([[0, 1], [1, 2], [2, 0]])   # the corners of mid-side nodes 3, 4, 5


def face_transform(ftype, alpha: float = ALPHA) -> np.ndarray:
    """T_e (n, n) of one face, N̂ = T_e N (module docstring): the identity on linear faces."""
    ft = face_type(ftype)
    T = np.eye(ft.n_nodes)
    if ft.degree == 2:
        if ft.n_nodes != 6:
            raise ValueError(f"the transformed dual basis is built for six-node triangles, not {ft.name}")
        for c in range(3):
            T[c, TRI6_MIDS[c]] = alpha
        T[3:, 3:] *= 1.0 - 2.0 * alpha
    return T


def transformed_basis(ftype, faces: np.ndarray, n: int, alpha: float = ALPHA) -> sp.csr_matrix:
    """T (n × n, sparse) on the nodes of a face of ``faces`` (F, 6) of six-node triangles: row c
    of a corner has 1 at c and α at its edges' mid-side nodes, row m of a mid-side node 1 − 2α
    (module docstring); the identity on linear faces and on nodes off the face."""
    ft = face_type(ftype)
    faces = np.asarray(faces)
    rows, cols, vals = [np.arange(n)], [np.arange(n)], [np.ones(n)]
    if ft.degree == 2:
        face_transform(ft, alpha)                       # the check of the face type
        mids = faces[:, 3:].ravel()
        corners = faces[:, TRI6_EDGE_CORNERS].reshape(-1, 2)
        edge = np.unique(np.c_[mids, np.sort(corners, axis=1)], axis=0)        # one row per edge
        vals[0][np.unique(edge[:, 0])] = 1.0 - 2.0 * alpha
        rows += [edge[:, 1], edge[:, 2]]
        cols += [edge[:, 0], edge[:, 0]]
        vals += [np.full(edge.shape[0], alpha)] * 2
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))


_G3 = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_W3 = np.array([5.0, 8.0, 5.0]) / 9.0


def _mass_rule(ftype):
    """A rule of the reference face exact for N_j N_k det J (the face mass matrix)."""
    if ftype.name == "quad":
        q = np.array([(a, b) for b in _G3 for a in _G3])
        return q, np.outer(_W3, _W3).ravel()
    return tri_rule(2 * ftype.degree + 2)


def dual_coefficients(ftype, X: np.ndarray) -> np.ndarray:
    """A (F, n, n) with Φ = A N̂ on every face (module docstring): A_e = D_e M_e⁻¹ for the faces
    of type ``ftype`` with nodes at X (F, n, 2) in the common plane, D_e = diag(∫ N̂_j),
    M_e = (∫ N̂_j N̂_k); N̂ = N on linear faces, the transformed basis on six-node triangles."""
    ft = face_type(ftype)
    q, w = _mass_rule(ft)
    N, dN = ft.shape(q)
    N = N @ face_transform(ft).T                                  # N̂ = T_e N at every point
    J = np.einsum("qaj,fai->fqij", dN, X)
    dA = np.abs(np.linalg.det(J)) * w                             # (F, Q)
    Me = np.einsum("fq,qa,qb->fab", dA, N, N)
    De = Me.sum(axis=2)                                           # ∫ N_j (Σ_k N_k = 1)
    return De[:, :, None] * np.linalg.inv(Me)                     # D_e M_e⁻¹ (M_e symmetric)


def _face_rule(ft, degree: int):
    """Points and weights of the reference face exact to ``degree`` (a Gauss product on the square)."""
    if ft.name == "quad":
        g, w = np.polynomial.legendre.leggauss(degree // 2 + 1)
        return np.array([(a, b) for b in g for a in g]), np.outer(w, w).ravel()
    return tri_rule(degree)


def dual_weighted(ftype, faces: np.ndarray, points: np.ndarray, nodes: np.ndarray, values, degree: int = 8):
    """Dual-weighted nodal values of fields given at points of the body's face (a rigid counterpart:
    the gap to an obstacle, the design's lift): for every node j of ``nodes``

        D_jj = ∫_Γ Φ_j N_j dA,   v_j = D_jj⁻¹ ∫_Γ Φ_j f dA,

    Φ_j the dual basis of the faces (module docstring) on their own geometry (``points`` (n, 3), the
    flat facets of the face ``faces`` (F, k) of type ``ftype``), integrated with a rule exact to
    ``degree`` on each face. ``values(x)`` gives the fields f at points x (K, 3): (K, c). Returns
    (D (len(nodes),), v (len(nodes), c)). Biorthogonality makes v_j = f(x_j) for every f linear on
    each face (∫ Φ_j N_k = δ_jk D_jj): node-wise values are kept where the field is the face's own
    interpolant, and a field curved within a face is weighted by its integral over the node's
    faces instead of read at the node. Linear faces only.

    Sign convention: v has the sign of f (a gap g ≥ 0 open, < 0 overlapping), D_jj > 0; the order of
    the rows is the order of ``nodes``."""
    ft = face_type(ftype)
    if ft.degree != 1:
        raise ValueError(f"dual-weighted values are built for linear faces only, not {ft.name}")
    faces = np.asarray(faces, np.int64)
    q, w = _face_rule(ft, degree)
    N, dN = ft.shape(q)
    X = np.asarray(points, float)[faces]                                   # (F, k, 3)
    T1, T2 = np.einsum("fam,qa->fqm", X, dN[:, :, 0]), np.einsum("fam,qa->fqm", X, dN[:, :, 1])
    dA = np.linalg.norm(np.cross(T1, T2), axis=2) * w                      # (F, Q)
    Me = np.einsum("fq,qa,qb->fab", dA, N, N)
    A = Me.sum(axis=2)[:, :, None] * np.linalg.inv(Me)                     # D_e M_e⁻¹
    Phi = np.einsum("fab,qb->fqa", A, N) * dA[:, :, None]                  # Φ_j dA  (F, Q, k)
    xq = np.einsum("qa,fam->fqm", N, X).reshape(-1, 3)
    f = np.asarray(values(xq), float).reshape(faces.shape[0], q.shape[0], -1)
    n_all = int(max(faces.max(initial=-1), np.max(nodes, initial=-1))) + 1
    D = np.bincount(faces.ravel(), weights=np.einsum("fqa,qa->fa", Phi, N).ravel(), minlength=n_all)
    Wf = np.einsum("fqa,fqc->fac", Phi, f)
    V = np.stack([np.bincount(faces.ravel(), weights=Wf[:, :, c].ravel(), minlength=n_all)
                  for c in range(f.shape[2])], axis=1)
    nodes = np.asarray(nodes, np.int64)
    return D[nodes], V[nodes] / D[nodes, None]


def mortar_matrices(s_type, s_faces: np.ndarray, s_xy: np.ndarray, m_type, m_faces: np.ndarray,
                    m_xy: np.ndarray, seg: Segmentation | None = None, n_slave: int | None = None,
                    n_master: int | None = None):
    """(D (n_slave,), M (n_slave × n_master, CSR), seg): the mortar matrices (module docstring)
    of the body's faces ``s_faces`` (F_s, n_s) of type ``s_type`` against the counterpart's
    ``m_faces`` (F_m, n_m), with node coordinates ``s_xy``, ``m_xy`` (·, 2) in the common plane.
    ``seg`` is computed from the faces' corner polygons unless given."""
    st, mt = face_type(s_type), face_type(m_type)
    ncs, ncm = (4 if st.name == "quad" else 3), (4 if mt.name == "quad" else 3)
    Xs, Xm = s_xy[s_faces], m_xy[m_faces]
    if seg is None:
        seg = segment(Xs[:, :ncs], Xm[:, :ncm])
    n_slave = int(s_xy.shape[0]) if n_slave is None else n_slave
    n_master = int(m_xy.shape[0]) if n_master is None else n_master
    A = dual_coefficients(st, Xs)
    affine = is_affine(Xs[:, :ncs]) and is_affine(Xm[:, :ncm])
    degree = 2 * (st.degree + mt.degree) + (0 if affine else QUAD_EXTRA)
    x, dA = seg.quadrature(tri_rule(degree))                      # (T, Q, 2), (T, Q)
    T, Q = dA.shape
    s_of, m_of = np.repeat(seg.slave, Q), np.repeat(seg.master, Q)
    xs = x.reshape(-1, 2)
    Ns, _ = st.shape(reference_coordinates(Xs[s_of, :ncs], xs))   # (TQ, n_s)
    Ns = Ns @ face_transform(st).T                                  # N̂ on six-node triangles
    Nm, _ = mt.shape(reference_coordinates(Xm[m_of, :ncm], xs))   # (TQ, n_m)
    Phi = np.einsum("kab,kb->ka", A[s_of], Ns) * dA.reshape(-1)[:, None]      # Φ_j dA
    D = np.bincount(s_faces[s_of].ravel(), weights=(Phi * Ns).ravel(), minlength=n_slave)
    rows = np.repeat(s_faces[s_of], Nm.shape[1], axis=1).ravel()
    cols = np.repeat(m_faces[m_of][:, None, :], Ns.shape[1], axis=1).ravel()
    vals = (Phi[:, :, None] * Nm[:, None, :]).ravel()
    M = sp.csr_matrix((vals, (rows, cols)), shape=(n_slave, n_master))
    M.sum_duplicates()
    return D, M, seg


class MortarCoupling:
    """Π = D⁻¹M on the rows of the body's contact nodes (module docstring), with the segmentation,
    D and M it comes from. ``uncovered`` lists the body faces the counterpart does not cover
    (relative area ``cover_tol``)."""

    def __init__(self, D, M, seg: Segmentation, rows: np.ndarray, cover_tol: float = 1e-9):
        self.D, self.M, self.segmentation = D, M, seg
        self.rows = np.asarray(rows)
        self.uncovered = np.flatnonzero(np.abs(seg.covered - seg.slave_area) > cover_tol * np.abs(seg.slave_area))
        Dr = D[self.rows]
        self.Pi = sp.diags(1.0 / Dr) @ M[self.rows]
        self.Pi = sp.csr_matrix(self.Pi)
        self.Pi.eliminate_zeros()

    def weighted_gap(self, g_body: np.ndarray, g_counterpart: np.ndarray) -> np.ndarray:
        """g̃_j / D_jj = g_j − (Π ḡ)_j on the contact nodes: a nodal field of the body and one of
        the counterpart (any trailing components, e.g. (t1, t2, ν)) to the weighted relative
        field, the quantity the node's cone acts on."""
        return g_body[self.rows] - self.Pi @ g_counterpart


def mortar_coupling(s_type, s_faces, s_xy, m_type, m_faces, m_xy, rows) -> MortarCoupling:
    """The :class:`MortarCoupling` of the body's faces against the counterpart's (arguments of
    :func:`mortar_matrices`), on the body nodes ``rows`` (its contact nodes)."""
    D, M, seg = mortar_matrices(s_type, s_faces, s_xy, m_type, m_faces, m_xy)
    return MortarCoupling(D, M, seg, rows)

