"""Mechanics as transforms of the contact system that every path consumes.

Every path solves one problem: per contact node m, in the order (t1, t2, ν), the contact law on
(u_c, r) with the gap g (non-penetration u_ν + g ≥ 0, λ = r_ν ≥ 0 the normal force on the body,
τ = −r_t), the body's contact displacement u_c = S⁻¹(ℓ + r) seen through W = S⁻¹. A mechanic of a
configuration is a small object applied to these contact data, not a mode of a path:

==============  ==========================================================  =====================
transform       what it does to the contact data                            object
==============  ==========================================================  =====================
rotate          per node frame R_m = (t1, t2, n): u_loc = R_mᵀ u_c, the     ``Rotate``
                system Qᵀ S Q, Qᵀ ℓ (Q = diag(R_m)); on an obstacle
shift           an obstacle's tangential translation per node frame: the    ``Shift``
                law sees w = u_c − shift (its normal part is in the gap)
couple          an elastic counterpart: W = S⁻¹ + C on the relative         :class:`~contactopt.fem.foundation.Foundation`
                displacement (:mod:`.condensation`)
basis           quadratic faces with mortar partners: the transformed       ``Basis``
                nodal values û = V⁻ᵀ u_c, forces r̂ = V r, the system
                V S Vᵀ, V ℓ (V = T ⊗ I₃, :mod:`contactopt.fem.mortar`)
anchor          a body held only by contact: S singular, an anchored        :class:`~contactopt.mesh.rigid.RigidModes`
                problem iterated until the anchor carries no force          (:mod:`.rigid`)
search          a force-controlled obstacle: an outer search over the       :class:`~.force.ForceSearch`
                translation s that balances the force (:mod:`.force`)
==============  ==========================================================  =====================

:class:`Mechanics` collects those a model has (None where it has none); a path asks it rather
than the model, and declares in its :class:`~.base.Capabilities` only what its linear algebra
takes (the couple and the anchor need S on every contact DOF: the condensation). Rules between
mechanics are the configuration's (:func:`contactopt.config.validation.check_interactions`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..fem.amg import rigid_body_modes
from .force import ForceSearch


def to_frames(v: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Qᵀ v: a (3p,) vector of global components per contact node into the nodes' frames R (p, 3, 3)."""
    return np.einsum("mij,mi->mj", R, v.reshape(-1, 3)).ravel()


def from_frames(v: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Q v: a (3p,) vector in the nodes' frames back to global components."""
    return np.einsum("mij,mj->mi", R, v.reshape(-1, 3)).ravel()


def to_frames_matrix(S: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Qᵀ S Q of a (3p, 3p) matrix on the contact DOFs, symmetric as S is."""
    p = R.shape[0]
    S4 = S.reshape(p, 3, p, 3)
    out = np.einsum("mai,makb,kbj->mikj", R, S4, R, optimize=True).reshape(3 * p, 3 * p)
    return np.ascontiguousarray(0.5 * (out + out.T))


def frame_rotation(contact_dofs: np.ndarray, frames: np.ndarray, n_free: int) -> sp.csr_matrix:
    """T (n_free × n_free, orthogonal, sparse): the identity but at each contact node, whose free DOFs
    (x1, x2, x3) it maps from the node's frame (t1, t2, n): u = T u_loc."""
    cd = np.asarray(contact_dofs).reshape(-1, 3)
    other = np.setdiff1d(np.arange(n_free), cd.ravel())
    rows = np.concatenate([other, np.repeat(cd, 3, axis=1).ravel()])
    cols = np.concatenate([other, np.tile(cd, (1, 3)).ravel()])
    vals = np.concatenate([np.ones(other.size), frames.reshape(-1)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n_free, n_free))


@dataclass(frozen=True)
class Rotate:
    """The contact nodes' frames on an obstacle other than the plane: ``R`` (p, 3, 3), columns
    (t1, t2, n) of node m; Q = diag(R_m) maps a node's local components to global ones."""

    R: np.ndarray

    def vector(self, v: np.ndarray) -> np.ndarray:
        """Qᵀ v: global components of a (3p,) contact vector into the nodes' frames."""
        return to_frames(v, self.R)

    def back(self, v: np.ndarray) -> np.ndarray:
        """Q v: a (3p,) contact vector in the nodes' frames back to global components."""
        return from_frames(v, self.R)

    def matrix(self, S: np.ndarray) -> np.ndarray:
        """Qᵀ S Q of a (3p, 3p) matrix on the contact DOFs."""
        return to_frames_matrix(S, self.R)

    def on_free_dofs(self, contact_dofs: np.ndarray, n_free: int) -> sp.csr_matrix:
        """T on every free DOF (the identity off the contact nodes): u = T u_loc."""
        return frame_rotation(contact_dofs, self.R, n_free)


class Basis:
    """The transformed basis of six-node triangles with mortar partners (:mod:`contactopt.fem.mortar`):
    ``T`` (p × p) on the contact nodes, N̂ = T N; V = T ⊗ I₃ on the contact DOFs. Displacements
    u_c = Vᵀ û, forces r̂ = V r, so the contact law acts per node on (û, r̂) with the system
    Ŝ = V S Vᵀ, ℓ̂ = V ℓ and the gaps ĝ = T⁻ᵀ g; per node the order (t1, t2, ν) of the
    untransformed system is kept. The resultant and moment of the forces are unchanged on faces
    with straight edges."""

    def __init__(self, T):
        self.T = sp.csr_matrix(T)
        self.V = sp.csr_matrix(sp.kron(self.T, sp.identity(3)))
        self._VT = spla.splu(sp.csc_matrix(self.V.T))
        self._V = spla.splu(sp.csc_matrix(self.V))

    def vector(self, v: np.ndarray) -> np.ndarray:
        """V v: a (3p,) force, load or derivative with respect to u_c into the transformed basis."""
        return self.V @ np.ravel(v)

    def back(self, v: np.ndarray) -> np.ndarray:
        """Vᵀ v: transformed nodal values (a displacement) back to the nodes' own."""
        return self.V.T @ np.ravel(v)

    def displacement(self, u: np.ndarray) -> np.ndarray:
        """V⁻ᵀ u: the nodes' displacement (3p,) into transformed nodal values."""
        return self._VT.solve(np.ravel(u).astype(float))

    def force(self, r: np.ndarray) -> np.ndarray:
        """V⁻¹ r̂: transformed forces (3p,) back to the nodes' own."""
        return self._V.solve(np.ravel(r).astype(float))

    def matrix(self, S: np.ndarray) -> np.ndarray:
        """V S Vᵀ of a (3p, 3p) matrix on the contact DOFs, symmetric as S is."""
        out = np.asarray(self.V @ (self.V @ S).T).T
        return np.ascontiguousarray(0.5 * (out + out.T))

    def gaps(self, g: np.ndarray) -> np.ndarray:
        """T⁻ᵀ g of per-node values (p,) or (p, k): the gaps in the transformed basis."""
        lu = spla.splu(sp.csc_matrix(self.T.T))
        return lu.solve(np.asarray(g, float))


@dataclass(frozen=True)
class Shift:
    """An obstacle's prescribed tangential translation under the contact nodes: ``slip`` (p, 3) per
    node frame (t1, t2, n), normal parts 0 (the normal part moves the gap instead). The contact law
    sees the displacement relative to the obstacle, w = u_c − slip; the body's own is w + slip."""

    slip: np.ndarray

    @property
    def vector(self) -> np.ndarray:
        """(3p,) per node (t1, t2, n)."""
        return self.slip.ravel()

    @property
    def tangential(self) -> np.ndarray:
        """(p, 2) the (t1, t2) parts: the slip's reference of the full-space Newton method."""
        return self.slip[:, :2]


@dataclass(frozen=True)
class Mechanics:
    """The transforms of a model's contact system (module docstring), None where it has none:
    ``rotate`` (``Rotate``), ``shift`` (``Shift``), ``couple`` an elastic foundation,
    ``anchor`` the rigid motions that contact alone holds, ``search`` a force-controlled obstacle's
    :class:`~.force.ForceSearch`, ``basis`` the transformed basis of quadratic faces (``Basis``)."""

    rotate: Rotate | None = None
    shift: Shift | None = None
    couple: object = None
    anchor: object = None
    search: ForceSearch | None = None
    basis: Basis | None = None

    @classmethod
    def of(cls, model) -> "Mechanics":
        """The mechanics of an :class:`~contactopt.fem.model.ElasticModel`."""
        return cls(rotate=None if model.frames is None else Rotate(model.frames),
                   shift=None if model.slip_shift is None else Shift(model.slip_shift),
                   couple=model.foundation, anchor=model.body.rigid,
                   search=None if model.obstacle_force is None else ForceSearch(model.obstacle_force),
                   basis=None if model.foundation is None or model.foundation.basis is None else Basis(model.foundation.basis))

    @property
    def frames(self) -> np.ndarray | None:
        """(p, 3, 3) the nodes' frames, None on the plane."""
        return None if self.rotate is None else self.rotate.R


class FrameChange:
    """The full-space unknowns of a body on a rigid obstacle other than the plane: u = T u_loc with
    T = :func:`frame_rotation` (orthogonal), the contact DOFs in the nodes' frames (t1, t2, n). It
    has the interface of :class:`~contactopt.paths.coupled.FullSpaceCouple` that the PETSc path
    reads (``T``, ``n``, ``n_body``, ``parts``, ``split``, ``extend``, ``load``, ``joint_modes``,
    ``inverse``), with no counterpart DOFs."""

    parts = ()

    def __init__(self, contact_dofs: np.ndarray, frames: np.ndarray, n_free: int):
        self.T = frame_rotation(contact_dofs, frames, n_free)
        self.T.sort_indices()
        self.n = self.n_body = n_free
        self.cd, self.pinned_nodes = np.asarray(contact_dofs, np.int64), []     # the Newton system's contact DOFs

    def split(self, u_loc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T u_loc, no counterpart DOFs)."""
        return self.T @ u_loc, np.zeros(0)

    def extend(self, y: np.ndarray) -> np.ndarray:
        """Tᵀ y: a derivative with respect to the free DOFs into u_loc."""
        return self.T.T @ np.asarray(y, float)

    def load(self, L: np.ndarray) -> np.ndarray:
        return np.asarray(L, float)

    def modes(self, coords: np.ndarray, free: np.ndarray) -> np.ndarray:
        """Tᵀ (the rigid-body modes): the AMG near-null space in u_loc."""
        return np.asarray(self.T.T @ rigid_body_modes(coords, free))

    joint_modes = modes                 # one body: its six modes

    def inverse(self) -> sp.csr_matrix:
        return sp.csr_matrix(self.T.T)
