"""Consistent nodal loads (paper (2.9)) and their design-derivative contractions.

Surface tractions t (force per unit area, a fixed vector in the global frame) and pressures p
(the traction −p n̂, n̂ the outward unit normal of the current face: p > 0 pushes into the body)
act on boundary faces that may move with α (the block's right face does); a body force f (per
unit volume) acts in Ω(α). Every integral is taken on the current geometry with the face's or
element's rule (:mod:`contactopt.fem.elements`) and differentiated exactly with respect to the
node coordinates: each ``*_shape_contraction`` is the derivative of the assembled vector, not of
the continuous integral. A face's nodes are ordered so that n = T1 × T2 (T_k = ∂x/∂η_k) points
out of the body. Vectors are full-length (3·n_nodes, DOF 3n + m); contractions are (n_nodes, 3).

The face (element) type is the keyword ``face`` (``element``): a FaceType (ElementType), its
meshio name, or None for the type with the array's node count (4: quad, 3: triangle,
6: triangle6; 8: hexahedron, 4: tetra, 10: tetra10).
"""

from __future__ import annotations

import numpy as np

from .elasticity import element_geometry
from .elements import QUAD4, ElementType, FaceType, element_for, element_type, face_for, face_type

__all__ = ["surface_load", "surface_load_shape_contraction", "pressure_load", "pressure_load_shape_contraction",
           "face_areas_nodal", "body_load", "body_load_shape_contraction", "quad_reference"]


def quad_reference():
    """Bilinear N (4 gp, 4), dN/d(η,ζ) (4 gp, 4, 2), weights (4,) on [−1,1]²."""
    return QUAD4.N, QUAD4.dN, QUAD4.w


def _face(faces, face) -> FaceType:
    return face_for(faces) if face is None else face_type(face)


def _element(elements, element) -> ElementType:
    return element_for(elements) if element is None else element_type(element)


def _scatter(n_nodes: int, nodes: np.ndarray, vals: np.ndarray) -> np.ndarray:
    """Sum per-node 3-vectors vals (F, k, 3) into an (n_nodes, 3) array."""
    out = np.zeros((n_nodes, 3))
    for m in range(3):
        out[:, m] = np.bincount(nodes.ravel(), weights=vals[..., m].ravel(), minlength=n_nodes)
    return out


def _surface_frames(coords, faces, face: FaceType):
    N, dN, w = face.N, face.dN, face.w
    Xf = coords[faces]                                   # (F, k, 3)
    T1 = np.einsum("fam,qa->fqm", Xf, dN[:, :, 0])
    T2 = np.einsum("fam,qa->fqm", Xf, dN[:, :, 1])
    n = np.cross(T1, T2)
    area = np.linalg.norm(n, axis=2)                      # dS = |T1 × T2| dη dζ
    return N, dN, w, T1, T2, n, area


# ---------------------------------------------------------------------- tractions
def face_areas_nodal(coords: np.ndarray, faces: np.ndarray, face=None, lumped: bool = False) -> np.ndarray:
    """Tributary areas (n_nodes,) of the face nodes (0 off the faces).

    Consistent (default): ∫ N_a dS, the nodal load of a unit traction. On P2 faces (triangle6)
    these are 0 at the corners of a flat triangle (and negative on some curved ones), so
    ``lumped=True`` gives positive areas instead: the diagonal of ∫ N_a N_b dS scaled per face
    to the face's area (Hinton–Rock–Zienkiewicz lumping: A/19 at each corner, 16A/57 at each
    midside node of a flat triangle; A/4 per vertex of a parallelogram, A/3 of a triangle).
    """
    faces = np.asarray(faces)
    N, _, w, _, _, _, area = _surface_frames(coords, faces, _face(faces, face))
    if lumped:
        diag = np.einsum("q,qa,fq->fa", w, N * N, area)
        nodal = diag * (np.einsum("q,fq->f", w, area) / diag.sum(axis=1))[:, None]
    else:
        nodal = np.einsum("q,qa,fq->fa", w, N, area)
    return np.bincount(faces.ravel(), weights=nodal.ravel(), minlength=coords.shape[0])


def surface_load(coords: np.ndarray, faces: np.ndarray, traction, face=None) -> np.ndarray:
    """Full load vector of a constant traction t on the faces: L_a = ∫ N_a t dS."""
    faces = np.asarray(faces)
    t = np.asarray(traction, float)
    N, _, w, _, _, _, area = _surface_frames(coords, faces, _face(faces, face))
    nodal = np.einsum("q,qa,fq->fa", w, N, area)         # ∫ N_a dS per face node
    return _scatter(coords.shape[0], faces, nodal[:, :, None] * t).ravel()


def surface_load_shape_contraction(coords, faces, traction, v_full, face=None) -> np.ndarray:
    """vᵀ ∂L/∂x_{c,m} of :func:`surface_load`, array (n_nodes, 3).

    ∂|n|/∂x_c = dN_c/dη (T2 × n̂) + dN_c/dζ (n̂ × T1) with n = T1 × T2.
    """
    faces = np.asarray(faces)
    t = np.asarray(traction, float)
    N, dN, w, T1, T2, n, area = _surface_frames(coords, faces, _face(faces, face))
    nhat = n / area[:, :, None]
    vt = (v_full.reshape(-1, 3)[faces] @ t)             # (F, k) v_a · t
    s = np.einsum("q,qa,fa->fq", w, N, vt)               # Σ_a N_a v_a·t times weight
    g1 = np.cross(T2, nhat)
    g2 = np.cross(nhat, T1)
    vals = (np.einsum("fq,qc,fqm->fcm", s, dN[:, :, 0], g1)
            + np.einsum("fq,qc,fqm->fcm", s, dN[:, :, 1], g2))
    return _scatter(coords.shape[0], faces, vals)


# ---------------------------------------------------------------------- pressure
def pressure_load(coords: np.ndarray, faces: np.ndarray, p: float, face=None) -> np.ndarray:
    """Full load vector of a normal pressure p (p > 0 pushes into the body) following the faces:

        L_a = ∫ N_a (−p n̂) dS = −p Σ_q w_q N_a(q) (T1 × T2)(q),

    n̂ the outward unit normal given by the faces' node order. On a closed surface the total
    force Σ_a L_a is 0; on a flat face it is −p·area·n̂.
    """
    faces = np.asarray(faces)
    N, _, w, _, _, n, _ = _surface_frames(coords, faces, _face(faces, face))
    vals = -float(p) * np.einsum("q,qa,fqm->fam", w, N, n)
    return _scatter(coords.shape[0], faces, vals).ravel()


def pressure_load_shape_contraction(coords, faces, p: float, v_full, face=None) -> np.ndarray:
    """vᵀ ∂L/∂x_{c,m} of :func:`pressure_load`, array (n_nodes, 3).

    With s = Σ_a N_a v_a and ∂(T1 × T2)/∂x_{c,m} = dN_c/dη (e_m × T2) + dN_c/dζ (T1 × e_m):
    vᵀ∂L/∂x_{c,m} = −p Σ_q w_q [dN_c/dη (T2 × s) + dN_c/dζ (s × T1)]_m.
    """
    faces = np.asarray(faces)
    N, dN, w, T1, T2, _, _ = _surface_frames(coords, faces, _face(faces, face))
    s = np.einsum("q,qa,fam->fqm", w, N, v_full.reshape(-1, 3)[faces])
    vals = (np.einsum("qc,fqm->fcm", dN[:, :, 0], np.cross(T2, s))
            + np.einsum("qc,fqm->fcm", dN[:, :, 1], np.cross(s, T1)))
    return _scatter(coords.shape[0], faces, -float(p) * vals)


# ---------------------------------------------------------------------- body force
def _body_args(args, element, elements, n_legacy):
    """(N, dN, w, rest): the new call passes the force first (rule from ``element``), the
    old one N, dN, w, then the force."""
    if len(args) >= n_legacy:
        N, dN, w, *rest = args
        return N, dN, w, rest
    e = _element(elements, element)
    return e.load_N, e.load_dN, e.load_w, list(args)


def body_load(coords: np.ndarray, elements: np.ndarray, *args, element=None) -> np.ndarray:
    """Full load vector of a constant body force f: L_a = ∫ N_a f dx.

    ``body_load(coords, elements, force, element=None)`` integrates with the element type's
    body-load rule; the older ``body_load(coords, elements, N, dN, w, force)`` with the given rule.
    """
    N, dN, w, (force,) = _body_args(args, element, elements, 4)
    f = np.asarray(force, float)
    _, det = element_geometry(coords[elements], dN)
    nodal = np.einsum("q,qa,eq->ea", w, N, det)
    return _scatter(coords.shape[0], elements, nodal[:, :, None] * f).ravel()


def body_load_shape_contraction(coords, elements, *args, element=None) -> np.ndarray:
    """vᵀ ∂L/∂x_{c,m} of :func:`body_load`: ∂ det J/∂x_{c,m} = det J · ∂N_c/∂x_m.

    ``body_load_shape_contraction(coords, elements, force, v_full, element=None)``, or the older
    ``(coords, elements, N, dN, w, force, v_full)``.
    """
    N, dN, w, (force, v_full) = _body_args(args, element, elements, 5)
    f = np.asarray(force, float)
    G, det = element_geometry(coords[elements], dN)
    vf = v_full.reshape(-1, 3)[elements] @ f             # (E, k)
    s = np.einsum("q,qa,ea,eq->eq", w, N, vf, det)
    vals = np.einsum("eq,eqcm->ecm", s, G)
    return _scatter(coords.shape[0], elements, vals)
