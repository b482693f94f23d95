"""Contact pressure from the nodal contact forces: p_m = λ_m / a_m.

λ_m = (S u_c − ℓ)_ν is a nodal force (paper (3.17)): it grows with the area a node carries, so a
map of λ on an unstructured face looks patchy where the nodal spacing varies. Dividing by the
node's lumped contact area gives a pressure (force per unit area, in the model's units), the
quantity a designer compares with a material limit or a target.

Lumped areas ``a_m = ∫_Γc N_m dS`` (the row sums of the face mass matrix ∫ N_m N_n dS) are
integrated with the face's rule on the *current* coordinates of Ω(α) — the design's surface,
which the morph has lifted — over every face of the contact face, clamped nodes' faces included
(a node's force gathers the pressure from all faces around it). For a uniform pressure p̄ the
consistent nodal forces are λ_m = p̄·a_m exactly on linear faces (triangles, bilinear quads), so
p_m = p̄ to round-off.

On six-node triangles (P2) ∫ N_m dS vanishes at the corners of a flat face, and the consistent
nodal forces of a uniform pressure vanish there too: λ/a is 0/0. There the pressure is the
L²-projection instead, the solution of M p = λ with the consistent face mass matrix restricted to
the contact nodes, which recovers a uniform p̄ exactly when no node of the face is clamped (next to
clamped nodes the missing rows make it an approximation). With mortar partners on an elastic
foundation the forces are those of the transformed basis N̂ = T N (``contactopt.fem.mortar``),
whose areas ∫ N̂_m dS = (T a)_m are positive at every node: p_m = λ_m / (T a)_m, the dual
pressure, uniform under a uniform pressure.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..fem.elements import face_for

__all__ = ["contact_areas", "contact_pressure", "face_mass"]


def _face_jacobians(coords: np.ndarray, faces: np.ndarray):
    face = face_for(faces)
    X = coords[faces]                                          # (F, k, 3)
    T1 = np.einsum("fam,qa->fqm", X, face.dN[:, :, 0])
    T2 = np.einsum("fam,qa->fqm", X, face.dN[:, :, 1])
    dS = np.linalg.norm(np.cross(T1, T2), axis=2) * face.w     # (F, Q): weight · |T1 × T2|
    return face, dS


def contact_areas(coords: np.ndarray, faces: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Lumped areas a_m = ∫ N_m dS of ``nodes`` over ``faces`` at the coordinates ``coords``."""
    faces = np.asarray(faces, np.int64)
    face, dS = _face_jacobians(np.asarray(coords, float), faces)
    nodal = np.einsum("fq,qa->fa", dS, face.N)
    per_node = np.bincount(faces.ravel(), weights=nodal.ravel(), minlength=coords.shape[0])
    return per_node[np.asarray(nodes, np.int64)]


def face_mass(coords: np.ndarray, faces: np.ndarray, nodes: np.ndarray) -> sp.csr_matrix:
    """Consistent face mass matrix ∫ N_m N_n dS restricted to ``nodes`` (in their order)."""
    faces = np.asarray(faces, np.int64)
    face, dS = _face_jacobians(np.asarray(coords, float), faces)
    Me = np.einsum("fq,qa,qb->fab", dS, face.N, face.N)
    index = np.full(coords.shape[0], -1, np.int64)
    index[np.asarray(nodes, np.int64)] = np.arange(len(nodes))
    r = np.repeat(index[faces], faces.shape[1], axis=1).ravel()
    c = np.tile(index[faces], (1, faces.shape[1])).ravel()
    keep = (r >= 0) & (c >= 0)
    n = len(nodes)
    return sp.csr_matrix((Me.ravel()[keep], (r[keep], c[keep])), shape=(n, n))


def contact_pressure(model, lam, coords) -> np.ndarray:
    """Contact pressure p (one value per contact node, contact-node order) of nodal forces ``lam``
    on the design whose node coordinates are ``coords`` (``state.coords``); see the module
    docstring. Units: the unit of λ per unit of area of the mesh coordinates."""
    lam = np.asarray(lam, float)
    nodes = np.asarray(model.contact_nodes, np.int64)
    if lam.shape != nodes.shape:
        raise ValueError(f"expected one force per contact node ({nodes.size},), got shape {lam.shape}")
    faces = np.asarray(model.body.contact_face.faces, np.int64)
    coords = np.asarray(coords, float)
    if face_for(faces).degree == 1:
        return lam / contact_areas(coords, faces, nodes)
    if model.foundation is not None and model.foundation.basis is not None:
        # mortar partners: forces of the transformed basis, areas ∫ N̂_m = T a
        return lam / (model.foundation.basis @ contact_areas(coords, faces, nodes))
    return spla.spsolve(face_mass(coords, faces, nodes).tocsc(), lam)
