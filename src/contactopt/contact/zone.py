"""The contact zone: the local Coulomb problem on the contact nodes near the foundation.

The condensed system (paper (3.17)) lives on all p contact nodes, but a node that stays off the
foundation carries no force (λ = 0, τ = 0). With the nodes split into a zone Z and the rest N,
and r_N = 0, the rows of N give u_N = S_NN⁻¹(ℓ_N − S_NZ u_Z), and the rows of Z

    S̃ u_Z − ℓ̃ = r_Z,    S̃ = S_ZZ − S_ZN S_NN⁻¹ S_NZ,    ℓ̃ = ℓ_Z − S_ZN S_NN⁻¹ ℓ_N,

so the local problem of the zone has the Delassus operator W_Z = S̃⁻¹ = (S⁻¹)_ZZ, a principal
block of W, and the free displacement q = W_Z ℓ̃ = (S⁻¹ℓ)_Z. The Cholesky factor of S gives
q, the products W_Z r = (S⁻¹ E_Z r)_Z and the displacements of all nodes u = S⁻¹(ℓ + r), by two
triangular solves each. When W_Z itself is needed, the Cholesky factor of S ordered (N, Z),
S = L Lᵀ with L = [[L_NN, 0], [L_ZN, L̃]], has L̃ L̃ᵀ = S̃, so W_Z = (L̃ L̃ᵀ)⁻¹: (1/3)(3p)³ +
(2/3)(3z)³ flops instead of (3p)³ for the whole W, and the zone's local problem is smaller.
Within an optimization most state solves never form W_Z (:mod:`contactopt.paths.zone_paths`), so the
factor of S in its natural order (no reordered copy of S) serves the products there, and the
ordered one is computed only if W_Z is asked for (``ordered=False``).

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

from ..fem.dense import cholesky_lower, cholesky_solve, inverse_from_cholesky, spd_inverse
from ..fem.linsolve import Condensation, SolverSlot
from .state import CLASS_RTOL, TO_FCLIB

CLEARANCE_RTOL = CLASS_RTOL  # a gap closes exactly where classify_nodes calls it closed
MIN_ZONE = 8                 # a zone has at least this many nodes (or all, if fewer)



def missed_nodes(zone: np.ndarray, clearance: np.ndarray, u_scale: float) -> np.ndarray:
    """Contact nodes outside ``zone`` whose gap is closed or violated (the zone must grow)."""
    outside = np.ones(clearance.size, dtype=bool)
    outside[zone] = False
    return np.flatnonzero(outside & (clearance <= CLEARANCE_RTOL * u_scale))


def near_nodes(lam: np.ndarray, clearance: np.ndarray, u_scale: float, margin: float,
               min_nodes: int = MIN_ZONE) -> np.ndarray:
    """Nodes in contact (λ > 0) or within ``margin``·scale of the foundation; at least
    ``min_nodes`` nodes (those of smallest clearance)."""
    idx = np.flatnonzero((lam > 0) | (clearance <= margin * u_scale))
    k = min(min_nodes, clearance.size)
    if idx.size < k:
        idx = np.union1d(idx, np.argsort(clearance, kind="stable")[:k])
    return idx


class ZoneProblem:
    """The local problem of the zone ``zone`` (sorted node indices) of the condensed system.

    Attributes: ``W`` (3z × 3z, FCLIB order per node), ``q0`` = (S⁻¹ℓ)_Z = W ℓ̃ (FCLIB order,
    without the gap), ``zone``. :meth:`displacements` returns the contact displacements of all p
    nodes for the zone's contact forces; :meth:`grow` adds nodes to the zone without a new
    factorization (the columns of S⁻¹ of the added DOFs come from two triangular solves each).
    """

    def __init__(self, S: np.ndarray, ell: np.ndarray, zone: np.ndarray, *, ordered: bool = True):
        self.p = ell.size // 3
        zone = self._factor(S, zone, ordered)
        self._parent = None
        self._set_zone(zone, None, self.solve(ell))

    def _factor(self, S: np.ndarray, zone, ordered: bool) -> np.ndarray:
        """Keep S and its Cholesky factor; the zone as an array. ``ordered``: the factor of S
        ordered (N, Z), which also gives W_Z; otherwise the factor in S's own order (no reordered
        copy of S), for solves that use the products only (a W_Z asked for later then costs a
        second factorization)."""
        self._S = S
        zone = np.asarray(zone)
        if ordered:
            self._order, self._start, self._L = self._ordered_factor(zone)
        else:
            self._order, self._start = None, 0
            self._L = cholesky_lower(np.array(S, dtype=np.float64, order="C"))
        return zone

    def _ordered_factor(self, zone):
        """(order, start, L): the Cholesky factor of S ordered (N, Z), Z from position start."""
        inside = np.zeros(self.p, dtype=bool)
        inside[zone] = True
        dof_n = _node_dofs(np.flatnonzero(~inside))
        order = np.concatenate([dof_n, _local_dofs(zone)])
        # two takes: several times faster than S[np.ix_(order, order)] for a 1536² matrix
        L = cholesky_lower(np.ascontiguousarray(self._S.take(order, axis=0).take(order, axis=1)))
        return order, dof_n.size, L

    def _set_zone(self, zone, W, z):
        self.zone, self._W, self._z = zone, W, z
        self._dof_z = _local_dofs(zone)
        self.q0 = z[self._dof_z]

    @property
    def W(self) -> np.ndarray:
        """W_Z = (S⁻¹)_ZZ in FCLIB order, formed on first use (the inverse of the trailing factor
        block, plus two triangular solves per DOF added by :meth:`grow`)."""
        if self._W is None:
            if self._parent is None:
                self._W = self._zone_inverse()
            else:
                self._W = self._grown_inverse(self._parent.W, self._parent.zone)
        return self._W

    def _zone_inverse(self) -> np.ndarray:
        """W_Z = (S̃)⁻¹ from the Cholesky factor of S ordered (N, Z) (module docstring)."""
        if self._order is not None:
            return inverse_from_cholesky(self._L, self._start)
        _, start, L = self._ordered_factor(self.zone)
        return inverse_from_cholesky(L, start)

    @property
    def grown(self) -> bool:
        """Whether this zone came from :meth:`grow` (its W_Z then extends the first zone's)."""
        return self._parent is not None

    @property
    def has_W(self) -> bool:
        """Whether W_Z has been formed already."""
        return self._W is not None

    def product(self, r_loc: np.ndarray) -> np.ndarray:
        """W_Z r_loc (FCLIB order) without forming W_Z: two triangular solves with the factor."""
        return self._response(r_loc)[self._dof_z]

    def _response(self, r_loc: np.ndarray) -> np.ndarray:
        """S⁻¹ r for the zone's forces ``r_loc`` (FCLIB order), r = 0 outside the zone."""
        f = np.zeros(3 * self.p)
        f[self._dof_z] = r_loc
        return self.solve(f)

    def relative_gap(self, W_other: np.ndarray, v: np.ndarray | None = None) -> float:
        """‖(W_other − W_Z) v‖ / ‖W_Z v‖ for a fixed smooth v (or the given one, e.g. the warm
        start, whose product the solve that follows needs anyway): how far an approximate block
        (of an earlier design) is from this zone's, without forming W_Z."""
        if v is None or not np.any(v):
            v = np.sin(0.7 * np.arange(W_other.shape[0]) + 0.3)
        w = self.product(v)
        return float(np.linalg.norm(W_other @ v.astype(W_other.dtype) - w) / max(np.linalg.norm(w), 1e-300))

    def block_from(self, zone: np.ndarray, W: np.ndarray, max_new: float = 0.25):
        """An approximation of W_Z from the block ``W`` of another zone ``zone`` (sorted; e.g. of
        an earlier design): its entries on the common nodes, exact columns for this zone's other
        nodes. None when those are more than ``max_new`` of the zone."""
        if zone.size == self.zone.size and np.array_equal(zone, self.zone):
            return W
        pos = np.searchsorted(zone, self.zone).clip(max=zone.size - 1)
        known = zone[pos] == self.zone
        if np.count_nonzero(~known) > max_new * self.zone.size:
            return None
        # FCLIB order is kept per node; the rows and columns of the other nodes are gathered
        # from node 0 and overwritten below (two gathers, no scatter)
        dof = _node_dofs(np.where(known, pos, 0))
        out = W.take(dof, axis=0).take(dof, axis=1)
        if not np.all(known):
            md = _node_dofs(np.flatnonzero(~known))
            X = self.columns(self.zone[~known])
            out[:, md] = X
            out[md, :] = X.T
        return out

    def columns(self, nodes: np.ndarray) -> np.ndarray:
        """The columns of W_Z of the zone nodes ``nodes`` (3z × 3k, FCLIB order): two
        triangular solves each."""
        E = np.zeros((3 * self.p, 3 * len(nodes)))
        E[_local_dofs(nodes), np.arange(3 * len(nodes))] = 1.0
        return self.solve(E)[self._dof_z]

    def solve(self, b: np.ndarray) -> np.ndarray:
        """S⁻¹ b for b of length 3p (or (3p, m)), per node (t1, t2, ν)."""
        b = np.asarray(b, dtype=np.float64)
        if self._order is None:
            return cholesky_solve(self._L, b)
        x = np.empty_like(b)
        x[self._order] = cholesky_solve(self._L, b[self._order])
        return x

    def displacements(self, r_loc: np.ndarray) -> np.ndarray:
        """u_c (p, 3) per node (t1, t2, ν) for the zone's contact forces ``r_loc`` (FCLIB order):
        u = S⁻¹(ℓ + r) with r = 0 outside the zone."""
        return (self._z + self._response(r_loc)).reshape(self.p, 3)

    def grow(self, nodes: np.ndarray) -> "ZoneProblem":
        """The problem of the zone ∪ ``nodes`` (a new object sharing the factorization; its W_Z,
        when needed, extends this zone's by the columns of the added DOFs)."""
        new = np.union1d(self.zone, nodes)
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__)      # the factorization and its solves are shared
        if new.size == self.zone.size:
            out._parent = self._parent
            out._set_zone(self.zone, self._W, self._z)
        else:
            out._parent = self
            out._set_zone(new, None, self._z)
        return out

    def _grown_inverse(self, W_old: np.ndarray, old_zone: np.ndarray) -> np.ndarray:
        new = self.zone
        was_in = np.isin(new, old_zone, assume_unique=True)
        old_dofs, add_dofs = _node_dofs(np.flatnonzero(was_in)), _node_dofs(np.flatnonzero(~was_in))
        X = self.columns(new[~was_in])                 # columns of S⁻¹ of the added DOFs
        W = np.empty((self._dof_z.size, self._dof_z.size))
        W[np.ix_(old_dofs, old_dofs)] = W_old
        W[:, add_dofs] = X
        W[add_dofs, :] = X.T
        B = X[add_dofs]                                # S⁻¹ on the added DOFs: symmetric up to round-off
        W[np.ix_(add_dofs, add_dofs)] = 0.5 * (B + B.T)
        return W


class CoupledZoneProblem(ZoneProblem):
    """The zone's local problem of a body coupled with elastic counterparts
    (:class:`~contactopt.fem.foundation.Coupling`): its contact law has the compliance
    W = S⁻¹ + C (C the counterparts' condensed compliance, the same for every design) and the
    free displacement W ℓ_eff = S⁻¹ℓ − ``offset`` (:meth:`~contactopt.fem.foundation.Coupling.free_displacement`).

    The same problem as :class:`ZoneProblem` on S_eff = W⁻¹, without S_eff: the Cholesky factor
    of the body's S (in S's order, or ordered (N, Z)) gives the products W b = S⁻¹b + C b and the
    block W_Z = (S⁻¹)_ZZ + C_ZZ, from the factor's trailing block as in :class:`ZoneProblem`.
    :meth:`body_solve` is S⁻¹b with the same factor (the adjoint's S⁻¹ S_eff v_u = S⁻¹ s).
    Conventions as :class:`ZoneProblem`; ``S``, ``C``, ``ell`` and ``offset`` per node (t1, t2, ν)."""

    def __init__(self, S: np.ndarray, C: np.ndarray, ell: np.ndarray, offset: np.ndarray, zone: np.ndarray, *,
                 ordered: bool = True):
        self._C = C
        self.p = ell.size // 3
        zone = self._factor(S, zone, ordered)
        self._factor_zone = zone if ordered else None
        self._parent = None
        self._set_zone(zone, None, self.body_solve(ell) - offset)

    def on_load(self, ell: np.ndarray, offset: np.ndarray, zone: np.ndarray) -> "CoupledZoneProblem":
        """The problem of another load ℓ (and offset) and zone on this factor."""
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__)
        out._parent = None
        out._set_zone(np.asarray(zone), None, self.body_solve(ell) - offset)
        return out

    def body_solve(self, b: np.ndarray) -> np.ndarray:
        """S⁻¹ b (the body's own compliance) for b of length 3p (or (3p, m))."""
        return ZoneProblem.solve(self, b)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """W b = S⁻¹ b + C b for b of length 3p (or (3p, m)), per node (t1, t2, ν)."""
        b = np.asarray(b, dtype=np.float64)
        return self.body_solve(b) + self._C @ b

    def _zone_inverse(self) -> np.ndarray:
        """W_Z = (S̃)⁻¹ + C_ZZ, S̃ from the factor of S ordered (N, Z) (ordered anew for another zone)."""
        if self._factor_zone is not None and np.array_equal(self._factor_zone, self.zone):
            inv = inverse_from_cholesky(self._L, self._start)
        else:
            _, start, L = self._ordered_factor(self.zone)
            inv = inverse_from_cholesky(L, start)
        dof = self._dof_z
        inv += self._C.take(dof, axis=0).take(dof, axis=1)
        return inv


class DelassusZoneProblem(ZoneProblem):
    """The zone's local problem without the condensed stiffness S (large meshes, issue #16).

    The same problem as :class:`ZoneProblem`, with every solve by S replaced by one with the
    sparse factorization of A(α): S⁻¹ b = W b = B A⁻¹ Bᵀ b (B selects the contact
    DOFs ``contact`` of the free DOFs, per node (t1, t2, ν)), q0 = (A⁻¹L)_c on the zone, and the
    full displacement u = A⁻¹L + A⁻¹Bᵀ r is the by-product of the last solve
    (:meth:`free_displacement`). W_Z itself, when asked for, is the inverse of the Schur complement
    of A onto the zone's DOFs (``zone_block(dofs)`` returns that complement, dense, in the order of
    ``dofs``): S_Z = (W_Z)⁻¹ (a principal block of W is the inverse of the Schur complement onto
    its DOFs), computed by a factorization that eliminates the zone's DOFs last.

    ``solve(b)`` for b of length 3p (or (3p, m)) is one sparse solve (m right-hand sides at once);
    conventions as :class:`ZoneProblem` (S, W per node (t1, t2, ν); the local problem in FCLIB order).
    """

    def __init__(self, factor, contact: np.ndarray, x0: np.ndarray, zone: np.ndarray, zone_block):
        self.p = contact.size // 3
        self._factor, self._contact, self._x0 = factor, np.asarray(contact), x0
        self._zone_block = zone_block
        self._order, self._start, self._parent = None, 0, None
        self._last = None                 # (forces on the contact DOFs, A⁻¹Bᵀ of them)
        self.n_solves = 0
        self._set_zone(np.asarray(zone), None, np.ascontiguousarray(x0[self._contact]))

    def with_load(self, x0: np.ndarray, zone: np.ndarray) -> "DelassusZoneProblem":
        """The problem of another load (A⁻¹L = ``x0``) and zone on the same factorization."""
        return DelassusZoneProblem(self._factor, self._contact, x0, zone, self._zone_block)

    def _full_solve(self, b: np.ndarray) -> np.ndarray:
        """A⁻¹ Bᵀ b (free DOFs) for contact forces b (3p per node (t1, t2, ν), or (3p, m))."""
        f = np.zeros((self._x0.size,) + b.shape[1:])
        f[self._contact] = b
        self.n_solves += 1 if b.ndim == 1 else b.shape[1]
        return self._factor.solve(f)

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        last = self._last
        if b.ndim == 1 and last is not None and np.array_equal(last[0], b):
            return last[1][self._contact]           # e.g. the displacements at Newton's last iterate
        x = self._full_solve(b)
        if b.ndim == 1:
            self._last = (b.copy(), x)
        return x[self._contact]

    def _zone_inverse(self) -> np.ndarray:
        S = self._zone_block(self._contact[self._dof_z])
        W = spd_inverse(S)
        current = self._factor.current if isinstance(self._factor, SolverSlot) else None
        if isinstance(current, Condensation) and current.S is S:
            # the zone's condensation now serves this design's solves: it takes W = S⁻¹ for
            # them and drops S (one dense (3z)² array less at the peak of the design)
            current.S_inverse, current.S = W, None
        return W

    def free_displacement(self, r_loc: np.ndarray) -> np.ndarray:
        """u = A⁻¹(L + Bᵀr) on the free DOFs for the zone's forces ``r_loc`` (FCLIB order): the
        last solve's by-product when it was for these forces, else one solve."""
        f = np.zeros(3 * self.p)
        f[self._dof_z] = r_loc
        last = self._last
        x = last[1] if last is not None and np.array_equal(last[0], f) else self._full_solve(f)
        return self._x0 + x


def _local_dofs(nodes: np.ndarray) -> np.ndarray:
    """Contact-vector positions of the DOFs of ``nodes``, per node in FCLIB order (ν, t1, t2)."""
    return (3 * np.asarray(nodes)[:, None] + TO_FCLIB).ravel()


def _node_dofs(k: np.ndarray) -> np.ndarray:
    """Positions 3k, 3k+1, 3k+2 of the nodes (or zone positions) ``k``, in their own order."""
    return (3 * np.asarray(k)[:, None] + np.arange(3)).ravel()


class FramedDelassusZoneProblem(DelassusZoneProblem):
    """:class:`DelassusZoneProblem` in the contact nodes' frames (a rigid obstacle other than the
    plane, :mod:`contactopt.mesh.obstacle`): ``frames`` (p, 3, 3) with columns (t1, t2, n), so that
    W = Qᵀ B A⁻¹ Bᵀ Q, Q = diag(R_m), and forces, displacements, q0 and W_Z are per node in its frame,
    (t1, t2, n) on the contact vector and (n, t1, t2) in the FCLIB order of the zone. The full
    displacement (:meth:`free_displacement`) stays global. ``shift`` (3p, per node frame, normal
    parts 0): an obstacle's tangential translation; the law's displacement is then w = u − shift
    (q0 and :meth:`displacements` are w's)."""

    def __init__(self, factor, contact, x0, zone, zone_block, frames, shift=None):
        self._R, self._shift = frames, shift
        self.p = contact.size // 3
        self._factor, self._contact, self._x0 = factor, np.asarray(contact), x0
        self._zone_block = zone_block
        self._order, self._start, self._parent = None, 0, None
        self._last = None
        self.n_solves = 0
        z = self._to_local(x0[self._contact])
        self._set_zone(np.asarray(zone), None, z if shift is None else z - shift)

    def with_load(self, x0, zone, shift=False):
        """Another load (and zone) on the same factorization; ``shift`` another translation (False: this one's)."""
        return FramedDelassusZoneProblem(self._factor, self._contact, x0, zone, self._zone_block, self._R,
                                         self._shift if shift is False else shift)

    def _to_local(self, v):
        v = np.asarray(v, dtype=np.float64)
        return np.einsum("mji,mjk->mik", self._R, v.reshape(self.p, 3, -1)).reshape(v.shape)

    def _to_global(self, v):
        v = np.asarray(v, dtype=np.float64)
        return np.einsum("mij,mjk->mik", self._R, v.reshape(self.p, 3, -1)).reshape(v.shape)

    def _full_solve(self, b):
        return super()._full_solve(self._to_global(b))

    def solve(self, b):
        b = np.asarray(b, dtype=np.float64)
        last = self._last
        if b.ndim == 1 and last is not None and np.array_equal(last[0], b):
            return self._to_local(last[1][self._contact])
        x = self._full_solve(b)
        if b.ndim == 1:
            self._last = (b.copy(), x)
        return self._to_local(x[self._contact])

    def _zone_inverse(self):
        S = self._zone_block(self._contact[self._dof_z])       # global components in FCLIB order (x3, x1, x2)
        perm = TO_FCLIB
        T = self._R[self.zone][:, perm][:, :, perm]           # (z, 3, 3): FCLIB-local → FCLIB-global
        z = self.zone.size
        S4 = S.reshape(z, 3, z, 3)
        S_loc = np.einsum("mai,makb,kbj->mikj", T, S4, T, optimize=True).reshape(3 * z, 3 * z)
        return spd_inverse(np.ascontiguousarray(0.5 * (S_loc + S_loc.T)))
