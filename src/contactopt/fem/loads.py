"""Consistent nodal loads (paper (2.9)) and their design-derivative contractions.

Surface tractions t (force per unit area, a fixed vector in the global frame) act on boundary
quadrilaterals that may move with α (the right face does); body force f (per unit volume) acts in
Ω(α). Both are integrated with 2×2 (faces) and 2×2×2 (volume) Gauss rules on the current
geometry, and differentiated exactly with respect to the node coordinates.
Vectors are full-length (3·n_nodes, DOF 3n + m).
"""

from __future__ import annotations

import numpy as np

from .elasticity import GAUSS_1D, element_geometry

_QSIGN = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], float)   # quad vertices in [−1,1]²


def quad_reference():
    """Bilinear N (4 gp, 4), dN/d(η,ζ) (4 gp, 4, 2), weights (4,) on [−1,1]²."""
    q = np.array([(x, y) for y in GAUSS_1D for x in GAUSS_1D])
    lin = 1.0 + q[:, None, :] * _QSIGN[None]
    N = lin[:, :, 0] * lin[:, :, 1] / 4.0
    dN = np.stack([_QSIGN[None, :, 0] * lin[:, :, 1], _QSIGN[None, :, 1] * lin[:, :, 0]], axis=2) / 4.0
    return N, dN, np.ones(q.shape[0])


def _scatter(n_nodes: int, nodes: np.ndarray, vals: np.ndarray) -> np.ndarray:
    """Sum per-vertex 3-vectors vals (F, k, 3) into an (n_nodes, 3) array."""
    out = np.zeros((n_nodes, 3))
    for m in range(3):
        out[:, m] = np.bincount(nodes.ravel(), weights=vals[..., m].ravel(), minlength=n_nodes)
    return out


def _surface_frames(coords, quads):
    N, dN, w = quad_reference()
    Xf = coords[quads]                                   # (F, 4, 3)
    T1 = np.einsum("fam,qa->fqm", Xf, dN[:, :, 0])
    T2 = np.einsum("fam,qa->fqm", Xf, dN[:, :, 1])
    n = np.cross(T1, T2)
    area = np.linalg.norm(n, axis=2)                      # dS = |T1 × T2| dη dζ
    return N, dN, w, T1, T2, n, area


def surface_load(coords: np.ndarray, quads: np.ndarray, traction) -> np.ndarray:
    """Full load vector of a constant traction on the quadrilaterals ``quads``: ∫ N_a t dS."""
    t = np.asarray(traction, float)
    N, _, w, _, _, _, area = _surface_frames(coords, quads)
    nodal = np.einsum("q,qa,fq->fa", w, N, area)         # ∫ N_a dS per face vertex
    return _scatter(coords.shape[0], quads, nodal[:, :, None] * t).ravel()


def surface_load_shape_contraction(coords, quads, traction, v_full) -> np.ndarray:
    """vᵀ ∂L/∂x_{c,m} of :func:`surface_load`, array (n_nodes, 3).

    ∂|n|/∂x_c = dN_c/dη (T2 × n̂) + dN_c/dζ (n̂ × T1) with n = T1 × T2.
    """
    t = np.asarray(traction, float)
    N, dN, w, T1, T2, n, area = _surface_frames(coords, quads)
    nhat = n / area[:, :, None]
    vt = (v_full.reshape(-1, 3)[quads] @ t)             # (F, 4) v_a · t
    s = np.einsum("q,qa,fa->fq", w, N, vt)               # Σ_a N_a v_a·t times weight
    g1 = np.cross(T2, nhat)
    g2 = np.cross(nhat, T1)
    vals = (np.einsum("fq,qc,fqm->fcm", s, dN[:, :, 0], g1)
            + np.einsum("fq,qc,fqm->fcm", s, dN[:, :, 1], g2))
    return _scatter(coords.shape[0], quads, vals)


def body_load(coords: np.ndarray, elements: np.ndarray, N: np.ndarray, dN: np.ndarray, w: np.ndarray, force) -> np.ndarray:
    """Full load vector of a constant body force f: ∫ N_a f dx."""
    f = np.asarray(force, float)
    _, det = element_geometry(coords[elements], dN)
    nodal = np.einsum("q,qa,eq->ea", w, N, det)
    return _scatter(coords.shape[0], elements, nodal[:, :, None] * f).ravel()


def body_load_shape_contraction(coords, elements, N, dN, w, force, v_full) -> np.ndarray:
    """vᵀ ∂L/∂x_{c,m} of :func:`body_load`: ∂ det J/∂x_{c,m} = det J · ∂N_c/∂x_m."""
    f = np.asarray(force, float)
    G, det = element_geometry(coords[elements], dN)
    vf = v_full.reshape(-1, 3)[elements] @ f             # (E, 8)
    s = np.einsum("q,qa,ea,eq->eq", w, N, vf, det)
    vals = np.einsum("eq,eqcm->ecm", s, G)
    return _scatter(coords.shape[0], elements, vals)
