"""The feasible polyhedron and the quadratic subproblems of the bundle-trust method.

Both QPs are solved with DAQP (dual active-set, Arnström–Bemporad–Axehill 2022):

* the BT direction-finding problem, in the primal variables ``z = (d, v)``::

      minimise    t·v + ½‖d‖²                      (= t·[v + ‖d‖²/(2t)])
      subject to  g_jᵀd − v ≤ α_j                  j in the bundle      (multiplier t·λ_j)
                  lb − x ≤ d ≤ ub − x              (simple bounds)
                  A_ub d ≤ b_ub − A_ub x
                  A_eq d  = b_eq − A_eq x

  Multiplying the BT objective by ``t`` keeps the Hessian ``diag(1,…,1,0)`` independent of
  ``t``; DAQP regularises the zero block (proximal-point iterations) and returns exact
  multipliers.  KKT: ``d = −t·(Σ λ_j g_j + Cᵀμ)``, ``Σ λ_j = 1``, so the multipliers divided
  by ``t`` give the convex weights ``λ`` for aggregation and the constraint multipliers ``μ``;

* the projection ``min ½‖x − x0‖²`` onto the polyhedron, used for an infeasible start.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OptimizerError

try:  # DAQP is a hard dependency; import lazily so that the error names it
    import daqp as _daqp
except ImportError:  # pragma: no cover - exercised only without daqp installed
    _daqp = None

_DAQP_FLAGS = {
    1: "optimal",
    2: "soft optimal",
    -1: "primal infeasible",
    -2: "cycling detected",
    -3: "unbounded",
    -4: "iteration limit reached",
    -5: "nonconvex problem",
    -6: "initial working set overdetermined",
}

# DAQP settings: tight primal feasibility so that x + d stays inside U to round-off.
_QP_OPTS = dict(primal_tol=1e-12, iter_limit=100_000)


def _solve(H, f, A, bupper, blower, sense):
    if _daqp is None:  # pragma: no cover
        raise OptimizerError("the bundle method needs the package 'daqp' (pip install daqp)")
    z, _fval, flag, info = _daqp.solve(H, f, A, bupper, blower, sense, **_QP_OPTS)
    return np.asarray(z, dtype=float), flag, np.asarray(info["lam"], dtype=float), info


@dataclass
class DirectionQP:
    """Solution of the direction-finding QP for one trust parameter ``t``.

    ``d`` the step, ``v = max_j (g_jᵀd − α_j)`` the model decrease (≤ 0), ``lam`` the convex
    weights of the bundle elements, ``p = −d/t = ξ + Cᵀμ`` the aggregate subgradient of
    f + indicator(U), ``xi = Σ λ_j g_j`` the aggregate subgradient of f, ``sigma = μᵀ(b − Cx)``
    the complementarity gap of the constraint multipliers at x (≥ 0).
    """

    d: np.ndarray
    v: float
    lam: np.ndarray
    p: np.ndarray
    xi: np.ndarray
    sigma: float
    qp_iterations: int


class Polyhedron:
    """U = {x : lb ≤ x ≤ ub, A_ub x ≤ b_ub, A_eq x = b_eq} (every part optional)."""

    def __init__(self, n, lb=None, ub=None, A_ub=None, b_ub=None, A_eq=None, b_eq=None):
        problems = []
        self.n = n
        self.lb = self._vec(lb, n, -np.inf, "lb", problems)
        self.ub = self._vec(ub, n, np.inf, "ub", problems)
        self.A_ub, self.b_ub = self._rows(A_ub, b_ub, n, "A_ub", "b_ub", problems)
        self.A_eq, self.b_eq = self._rows(A_eq, b_eq, n, "A_eq", "b_eq", problems)
        if not problems and np.any(self.lb > self.ub):
            i = int(np.argmax(self.lb - self.ub))
            problems.append(f"lb > ub for component {i} ({self.lb[i]:g} > {self.ub[i]:g}):"
                            " the feasible set is empty")
        if problems:
            raise OptimizerError("invalid feasible set:\n" + "\n".join(f"  - {p}" for p in problems))
        self.has_bounds = bool(np.any(np.isfinite(self.lb)) or np.any(np.isfinite(self.ub)))
        self.n_ub = self.A_ub.shape[0]
        self.n_eq = self.A_eq.shape[0]
        # row scale for the feasibility tolerance
        self._scale_ub = 1.0 + np.abs(self.b_ub) + np.abs(self.A_ub).sum(axis=1)
        self._scale_eq = 1.0 + np.abs(self.b_eq) + np.abs(self.A_eq).sum(axis=1)

    @staticmethod
    def _vec(v, n, default, name, problems):
        if v is None:
            return np.full(n, default)
        v = np.asarray(v, dtype=float)
        if v.ndim == 0:
            v = np.full(n, float(v))
        if v.shape != (n,):
            problems.append(f"{name} has shape {v.shape}, expected ({n},)")
            return np.full(n, default)
        if np.any(np.isnan(v)):
            problems.append(f"{name} contains NaN")
        return v.copy()

    @staticmethod
    def _rows(A, b, n, nameA, nameb, problems):
        if A is None and b is None:
            return np.zeros((0, n)), np.zeros(0)
        if A is None or b is None:
            problems.append(f"{nameA} and {nameb} must be given together")
            return np.zeros((0, n)), np.zeros(0)
        A = np.atleast_2d(np.asarray(A, dtype=float))
        b = np.atleast_1d(np.asarray(b, dtype=float))
        ok = True
        if A.ndim != 2 or A.shape[1] != n:
            problems.append(f"{nameA} has shape {A.shape}, expected (m, {n})")
            ok = False
        elif b.shape != (A.shape[0],):
            problems.append(f"{nameb} has shape {b.shape}, expected ({A.shape[0]},)")
            ok = False
        if ok and not (np.all(np.isfinite(A)) and np.all(np.isfinite(b))):
            problems.append(f"{nameA} or {nameb} contains inf or NaN")
            ok = False
        return (A.copy(), b.copy()) if ok else (np.zeros((0, n)), np.zeros(0))

    # ------------------------------------------------------------------ feasibility
    def violation(self, x) -> float:
        """Largest scaled constraint violation at x (0 when x ∈ U)."""
        v = max(float(np.max(self.lb - x, initial=0.0)), float(np.max(x - self.ub, initial=0.0)))
        if self.n_ub:
            v = max(v, float(np.max((self.A_ub @ x - self.b_ub) / self._scale_ub, initial=0.0)))
        if self.n_eq:
            v = max(v, float(np.max(np.abs(self.A_eq @ x - self.b_eq) / self._scale_eq)))
        return v

    def clip(self, x):
        """x with the box enforced exactly (removes round-off of the QP)."""
        return np.minimum(np.maximum(x, self.lb), self.ub)

    def _constraint_block(self, x, extra_cols):
        """Rows and bounds of the constraints of U written for a step d from x."""
        A = np.hstack([self.A_ub, np.zeros((self.n_ub, extra_cols))])
        E = np.hstack([self.A_eq, np.zeros((self.n_eq, extra_cols))])
        bu = np.concatenate([self.b_ub - self.A_ub @ x, self.b_eq - self.A_eq @ x])
        bl = np.concatenate([np.full(self.n_ub, -np.inf), self.b_eq - self.A_eq @ x])
        return np.vstack([A, E]), bu, bl

    def project(self, x0):
        """Euclidean projection of x0 onto U (a QP solved with DAQP)."""
        n = self.n
        A, bu, bl = self._constraint_block(np.zeros(n), 0)
        bu = np.concatenate([self.ub, bu])
        bl = np.concatenate([self.lb, bl])
        sense = np.zeros(bu.size, dtype=np.int32)
        sense[n + self.n_ub:] = 5
        z, flag, _, _ = _solve(np.eye(n), -np.asarray(x0, dtype=float), A, bu, bl, sense)
        if flag in (1, 2):
            return self.clip(z)
        if flag == -1 and self._lp_infeasible():
            raise OptimizerError("the feasible set U is empty (DAQP and scipy.optimize.linprog "
                                 "both report infeasible constraints)")
        raise OptimizerError(f"projection of x0 onto the feasible set failed: DAQP exit flag "
                             f"{flag} ({_DAQP_FLAGS.get(flag, 'unknown')})")

    def _lp_infeasible(self) -> bool:
        from scipy.optimize import linprog

        res = linprog(np.zeros(self.n), A_ub=self.A_ub if self.n_ub else None,
                      b_ub=self.b_ub if self.n_ub else None,
                      A_eq=self.A_eq if self.n_eq else None,
                      b_eq=self.b_eq if self.n_eq else None,
                      bounds=list(zip(np.where(np.isfinite(self.lb), self.lb, None),
                                      np.where(np.isfinite(self.ub), self.ub, None))),
                      method="highs")
        return res.status == 2

    # ------------------------------------------------------------------ BT subproblem
    def direction(self, x, G, alpha, t) -> DirectionQP:
        """Solve the BT direction-finding QP at x for bundle (G, alpha) and parameter t."""
        n, m = self.n, G.shape[0]
        H = np.zeros((n + 1, n + 1))
        H[np.arange(n), np.arange(n)] = 1.0
        f = np.zeros(n + 1)
        f[n] = t
        Ab = np.hstack([G, -np.ones((m, 1))])
        Ac, bu_c, bl_c = self._constraint_block(x, 1)
        A = np.vstack([Ab, Ac])
        bu = np.concatenate([alpha, bu_c])
        bl = np.concatenate([np.full(m, -np.inf), bl_c])
        nb = 0
        if self.has_bounds:
            nb = n
            bu = np.concatenate([self.ub - x, bu])
            bl = np.concatenate([self.lb - x, bl])
        sense = np.zeros(bu.size, dtype=np.int32)
        sense[nb + m + self.n_ub:] = 5
        z, flag, lam_all, info = _solve(H, f, A, bu, bl, sense)
        if flag not in (1, 2) or not np.all(np.isfinite(z)):
            raise OptimizerError(
                f"the direction-finding QP failed (t = {t:.3e}, bundle size {m}, "
                f"{self.n_ub} inequality and {self.n_eq} equality rows): DAQP exit flag "
                f"{flag} ({_DAQP_FLAGS.get(flag, 'unknown')})")
        d = z[:n]
        lam_all = lam_all / t
        lam = np.maximum(lam_all[nb:nb + m], 0.0)
        total = lam.sum()
        if not total > 0.5:  # Σλ = 1 by the KKT conditions; anything else is a QP failure
            raise OptimizerError(f"the direction-finding QP returned bundle multipliers "
                                 f"summing to {total:.3e} instead of 1 (t = {t:.3e})")
        lam = lam / total
        xi = lam @ G
        # complementarity gap μᵀ(b − Cx) ≥ 0 of the constraint multipliers at x
        sigma = 0.0
        if nb:
            mu_b = lam_all[:nb]
            up = np.where(mu_b > 0, self.ub - x, 0.0)
            lo = np.where(mu_b < 0, x - self.lb, 0.0)
            sigma += float(np.sum(np.maximum(mu_b, 0.0) * np.where(np.isfinite(up), up, 0.0)))
            sigma += float(np.sum(np.maximum(-mu_b, 0.0) * np.where(np.isfinite(lo), lo, 0.0)))
        if self.n_ub:
            mu = np.maximum(lam_all[nb + m:nb + m + self.n_ub], 0.0)
            sigma += float(mu @ np.maximum(self.b_ub - self.A_ub @ x, 0.0))
        v = float(np.max(G @ d - alpha))
        return DirectionQP(d=d, v=v, lam=lam, p=-d / t, xi=xi, sigma=sigma,
                           qp_iterations=int(info.get("iterations", 0)))
