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
nodal forces of a uniform pressure vanish there too: λ/a is 0/0 (and the L²-projection M p = λ
overshoots: negative at the edge of the contact, nonzero outside it). There the pressure is read
in the transformed basis of Popp et al. (``contactopt.fem.mortar.transformed_basis``),
N̂_c = N_c + β Σ N_m over the edges (c, m) at corner c, N̂_m = (1 − 2β) N_m at midside node m,
β = 1/5, whose integrals are all positive:

    p_j = (T λ)_j / (T a)_j,   (T v)_c = v_c + β Σ_(c,m) v_m,   (T v)_m = (1 − 2β) v_m,

the forces and areas the transformed functions gather. A midside node keeps λ_m / a_m, a corner
node takes its own force with those of the midside nodes of its edges. Every p_j ≥ 0 where λ ≥ 0,
p_j = 0 more than one element away from the forces, and a uniform p̄ is recovered exactly
(λ_m = p̄ a_m). :func:`face_classes` classes the corner nodes with the same weights. With mortar
partners on an elastic foundation the forces are already those of the transformed basis: there
p_m = λ_m / (T a)_m, the dual pressure.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..contact.state import classify_nodes
from ..fem.elements import face_for
from ..fem.mortar import transformed_basis

__all__ = ["contact_areas", "contact_pressure", "face_classes", "face_mass", "transformed_weights"]



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
    if lam.shape == (model.n_contact,) and model.n_contact > nodes.size:   # faces on other bodies (fem.faces):
        return np.concatenate([contact_pressure(model, lam[:nodes.size], coords),   # no design moves them
                               lam[nodes.size:] / model.foundation.off_areas])
    if lam.shape != nodes.shape:
        raise ValueError(f"expected one force per contact node ({nodes.size},), got shape {lam.shape}")
    faces = np.asarray(model.body.contact_faces, np.int64)
    coords = np.asarray(coords, float)
    if face_for(faces).degree == 1:
        return lam / contact_areas(coords, faces, nodes)
    basis = None if model.foundation is None else model.foundation.basis
    T = transformed_weights(faces, nodes)
    if basis is not None:       # mortar partners: forces of the transformed basis, areas ∫ N̂_m = T a
        return _ratio(lam, T @ contact_areas(coords, faces, nodes))
    return _ratio(T @ lam, T @ contact_areas(coords, faces, nodes))


def _ratio(num, den):
    out = np.zeros_like(num)
    np.divide(num, den, out=out, where=den > 0)
    return out


def transformed_weights(faces: np.ndarray, nodes: np.ndarray) -> sp.csr_matrix:
    """T of the module docstring on six-node triangles ``faces`` (F, 6; corners, then the
    midpoints of the edges 01, 12, 20), restricted to ``nodes`` (rows and columns in their order):
    ``contactopt.fem.mortar.transformed_basis`` on the face's nodes. Nodal forces and areas pass
    through T as the transformed functions gather them."""
    faces = np.asarray(faces, np.int64)
    nodes = np.asarray(nodes, np.int64)
    n = max(int(faces.max(initial=-1)), int(nodes.max(initial=-1))) + 1
    return transformed_basis(face_for(faces), faces, n)[nodes][:, nodes].tocsr()


def face_classes(model, state) -> np.ndarray:
    """The node classes of a state's maps (codes into ``CLASS_NAMES``, contact-node order): the
    state's own on linear faces; on six-node triangles each node classed by the forces T λ, T τ
    and the clearance T(a (u_ν + g)) / (T a) of the transformed functions (module docstring), so that
    a corner node inside the contact, which carries no force of its own, is classed by the forces
    around it. The state's classes (the ones its subgradient takes) are not changed. With mortar
    partners on an elastic foundation the state's law already acts on the transformed forces and
    displacements: its own classes are those of the maps.

    Sign convention: as the state's, per contact node (t1, t2, ν): λ ≥ 0 pushes the body off its
    counterpart, τ = −r_t, u_ν + g ≥ 0 the clearance."""
    faces = np.asarray(model.body.contact_faces, np.int64)
    if face_for(faces).degree == 1 or (model.foundation is not None and model.foundation.basis is not None):
        return np.asarray(state.classes)
    nodes = np.asarray(model.contact_nodes, np.int64)
    T = transformed_weights(faces, nodes)
    areas = contact_areas(np.asarray(state.coords, float), faces, nodes)
    u_c = np.array(state.u_c, float).reshape(-1, 3)
    gap = np.asarray(state.gap, float)
    u_c[:, 2] = _ratio(T @ (areas * (u_c[:, 2] + gap)), T @ areas) - gap
    if state.slip_ref is not None:
        u_c[:, :2] -= state.slip_ref
    lam = T @ np.asarray(state.lam, float)
    tau = T @ np.asarray(state.tau, float).reshape(-1, 2)
    return classify_nodes(u_c, lam, tau, gap, state.friction, u=state.u)


def contact_pairs(model) -> list[tuple[object, np.ndarray]]:
    """The contact pairs of ``model`` (:class:`contactopt.config.assembly.Pair`, in ``[[contacts]]``
    order) with the contact-node indices m of each: every contact node belongs to one pair."""
    pairs = model.config.assembly.contacts
    which = model.pair_of
    if which is None:                       # one pair: every contact node
        return [(pair, np.arange(model.n_contact)) for pair in pairs]
    return [(pair, np.flatnonzero(which == k)) for k, pair in enumerate(pairs)]


def pair_index(model) -> np.ndarray:
    """(p,) per contact node the index of its pair in ``[[contacts]]``."""
    out = np.full(model.n_contact, -1, np.int64)
    for k, (_, nodes) in enumerate(contact_pairs(model)):
        out[nodes] = k
    return out


def pair_reports(model, state) -> list[dict]:
    """Per contact pair: its name, face and counterpart, the resultant normal force Σλ on its face
    (λ ≥ 0, the normal force on the face's body), the peak contact pressure (force per unit area) and
    the node classes of Table 4.1 on it."""
    from ..contact.state import class_counts
    pressure = contact_pressure(model, state.lam, state.coords)
    lam, classes = np.asarray(state.lam, float), np.asarray(state.classes, int)
    return [{"name": pair.name, "face": pair.face, "counterpart": pair.counterpart, "nodes": int(nodes.size),
             "total_normal_force": float(lam[nodes].sum()), "peak_pressure": float(pressure[nodes].max(initial=0.0)),
             "node_classes": class_counts(classes[nodes])} for pair, nodes in contact_pairs(model)]
