"""The contact zone: the local Coulomb problem on the contact nodes near the foundation.

The condensed system (paper (3.17)) lives on all p contact nodes, but a node that stays off the
foundation carries no force (λ = 0, τ = 0). With the nodes split into a zone Z and the rest N,
and r_N = 0, the rows of N give u_N = S_NN⁻¹(ℓ_N − S_NZ u_Z), and the rows of Z

    S̃ u_Z − ℓ̃ = r_Z,    S̃ = S_ZZ − S_ZN S_NN⁻¹ S_NZ,    ℓ̃ = ℓ_Z − S_ZN S_NN⁻¹ ℓ_N,

so the local problem of the zone has the Delassus operator W_Z = S̃⁻¹ = (S⁻¹)_ZZ, a principal
block of W. One Cholesky factorization of S ordered (N, Z), S = L Lᵀ with
L = [[L_NN, 0], [L_ZN, L̃]], gives everything: L̃ L̃ᵀ = S̃, ℓ̃ = ℓ_Z − L_ZN y with
y = L_NN⁻¹ℓ_N, and u_N = L_NN⁻ᵀ(y − L_ZNᵀ u_Z). That costs (1/3)(3p)³ + (2/3)(3z)³ flops
instead of (3p)³ for the whole W, and the zone's local problem is smaller.

The solution on Z is the solution of the whole problem exactly when every node of N ends with
an open gap. That is checked after each solve: a node of N with clearance u_ν + g ≤ tol
(tol = ``CLEARANCE_RTOL`` times the displacement scale, the tolerance with which
:func:`contactopt.contact.state.classify_nodes` calls a gap closed) is a *miss*, the zone grows
by the misses and by every node within the margin, and the zone's problem is solved again. So
the state never depends on the zone, and every node outside the final zone is of class L
(no contact) of Table 4.1.

Conventions: ``S``, ``ell`` and displacements are per contact node (t1, t2, ν), u_ν = u3 (the
foundation x3 ≤ 0 has normal e3), clearance = u_ν + g; the local problem of the zone is in the
FCLIB order (ν, t1, t2) per node, r_N = λ ≥ 0 the normal force on the body.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..fem.dense import cholesky_lower, inverse_from_cholesky

CLEARANCE_RTOL = 1e-7        # the gap-closed tolerance of classify_nodes (relative)
MIN_ZONE = 8                 # a zone has at least this many nodes (or all, if fewer)

_LOCAL = np.array([2, 0, 1])  # per node (t1, t2, ν) -> (ν, t1, t2)


def displacement_scale(u_c: np.ndarray, gap: np.ndarray) -> float:
    """max(|u_c|, |g|): the scale of clearances (as in classify_nodes)."""
    return max(np.abs(u_c).max(initial=0.0), np.abs(gap).max(initial=0.0), 1e-300)


def missed_nodes(zone: np.ndarray, clearance: np.ndarray, u_scale: float) -> np.ndarray:
    """Contact nodes outside ``zone`` whose gap is closed or violated (the zone must grow)."""
    outside = np.ones(clearance.size, dtype=bool)
    outside[zone] = False
    return np.flatnonzero(outside & (clearance <= CLEARANCE_RTOL * u_scale))


def near_nodes(lam: np.ndarray, clearance: np.ndarray, u_scale: float, margin: float) -> np.ndarray:
    """Nodes in contact (λ > 0) or within ``margin``·scale of the foundation; at least MIN_ZONE
    nodes (those of smallest clearance)."""
    idx = np.flatnonzero((lam > 0) | (clearance <= margin * u_scale))
    k = min(MIN_ZONE, clearance.size)
    if idx.size < k:
        idx = np.union1d(idx, np.argsort(clearance, kind="stable")[:k])
    return idx


class ZoneProblem:
    """The local problem of the zone ``zone`` (sorted node indices) of the condensed system.

    Attributes: ``W`` (3z × 3z, FCLIB order per node), ``q0 = W ℓ̃`` (FCLIB order, without the
    gap), ``zone``. :meth:`displacements` returns the contact displacements of all p nodes for
    the zone's contact forces.
    """

    def __init__(self, S: np.ndarray, ell: np.ndarray, zone: np.ndarray):
        p = ell.size // 3
        self.zone = np.asarray(zone)
        inside = np.zeros(p, dtype=bool)
        inside[self.zone] = True
        self.rest = np.flatnonzero(~inside)
        self._dof_z = (3 * self.zone[:, None] + _LOCAL).ravel()        # FCLIB order
        self._dof_n = (3 * self.rest[:, None] + np.arange(3)).ravel()
        order = np.concatenate([self._dof_n, self._dof_z])
        self.n_rest = self._dof_n.size
        L = np.array(S[np.ix_(order, order)], order="C")
        cholesky_lower(L)
        k = self.n_rest
        self.W = inverse_from_cholesky(L, k)
        self._L_nn = L[:k, :k]
        self._L_zn = L[k:, :k]
        self._y = sla.solve_triangular(self._L_nn, ell[self._dof_n], lower=True, check_finite=False) \
            if k else np.zeros(0)
        self.ell = ell[self._dof_z] - (self._L_zn @ self._y if k else 0.0)   # ℓ̃, FCLIB order
        self.q0 = self.W @ self.ell

    def displacements(self, r_loc: np.ndarray) -> np.ndarray:
        """u_c (p, 3) per node (t1, t2, ν) for the zone's contact forces ``r_loc`` (FCLIB order)."""
        p = (self._dof_z.size + self._dof_n.size) // 3
        u = np.empty(3 * p)
        u_z = self.W @ (r_loc + self.ell)
        u[self._dof_z] = u_z
        if self.n_rest:
            rhs = self._y - self._L_zn.T @ u_z
            u[self._dof_n] = sla.solve_triangular(self._L_nn, rhs, lower=True, trans="T", check_finite=False)
        return u.reshape(p, 3)
