"""The feasible polyhedron and the quadratic subproblems of the bundle-trust method.

* The BT direction-finding problem (Schramm–Zowe), in the primal variables ``(d, v)``::

      minimise    v + ‖d‖²/(2t)
      subject to  g_jᵀd − v ≤ α_j                  j in the bundle      (multipliers λ_j)
                  lb − x ≤ d ≤ ub − x              (simple bounds)      (μ)
                  A_ub d ≤ b_ub − A_ub x                                (μ)
                  A_eq d  = b_eq − A_eq x                               (μ, free sign)

  KKT: ``d = −t·(Σ λ_j g_j + Cᵀμ)`` and ``Σ λ_j = 1``; λ are the convex weights of the
  aggregation.  The Hessian is singular in v; DAQP (dual active-set, Arnström, Bemporad &
  Axehill 2022) handles that by proximal-point iterations.  The QP is passed in scaled
  variables with unit rows (see :meth:`Polyhedron.direction`); a dense interior-point method
  is the fallback for the rare degenerate bundles on which DAQP cycles, and every answer must
  pass a KKT check before it is used.
* The projection ``min ½‖x − x0‖²`` onto the polyhedron, used for an infeasible start (DAQP;
  an empty set is confirmed with ``scipy.optimize.linprog``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

from ..errors import OptimizerError

logger = logging.getLogger(__name__)

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

    ``d`` the step, ``v = Σλ_j (g_jᵀd − α_j) = max_j (g_jᵀd − α_j)`` the model decrease (≤ 0),
    ``lam`` the convex weights of the bundle elements, ``p = −d/t = ξ + Cᵀμ`` the aggregate
    subgradient of f + indicator(U), ``xi = Σ λ_j g_j`` the aggregate subgradient of f,
    ``sigma = μᵀ(b − Cx)`` the complementarity gap of the constraint multipliers at x (≥ 0),
    ``solver`` the solver that produced the answer ("daqp" or "ipm").
    """

    d: np.ndarray
    v: float
    lam: np.ndarray
    p: np.ndarray
    xi: np.ndarray
    sigma: float
    solver: str


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
            raise OptimizerError("invalid feasible set:\n"
                                 + "\n".join(f"  - {p}" for p in problems))
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
        if flag in (1, 2) and np.all(np.isfinite(z)):
            return self.clip(z)
        if self._lp_infeasible():
            raise OptimizerError("the feasible set U is empty (DAQP and scipy.optimize.linprog "
                                 "both report infeasible constraints)")
        raise OptimizerError(f"projection of x0 onto the feasible set failed: DAQP exit flag "
                             f"{flag} ({_DAQP_FLAGS.get(flag, 'unknown')})")

    def _lp_infeasible(self) -> bool:

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
        """Solve the BT direction-finding QP at x for bundle (G, alpha) and parameter t.

        The QP reaches the solver scaled: with a subgradient scale γ_s, ``d = t·γ_s·d̃`` and
        ``v = t·γ_s²·ṽ`` turn the objective into ``ṽ + ½‖d̃‖²`` and the bundle rows into
        ``(g_j/γ_s)ᵀd̃ − ṽ ≤ α_j/(t·γ_s²)``; every row is then normalised to unit length
        (multipliers are mapped back).  Attempts, in order: DAQP with γ_s = ‖g‖ of the element
        with the smallest α (the subgradient at x), the largest and the smallest nonzero
        ‖g_j‖ (degenerate bundles can make the active-set method cycle at one scale and not
        at another), then a dense interior-point method.  Each answer must pass a KKT check.
        """
        keep, G_u, alpha_u = _dedup(G, alpha)
        norms = np.linalg.norm(G_u, axis=1)
        nz = norms > 0
        if np.any(nz):
            cur = int(np.flatnonzero(nz)[np.argmin(alpha_u[nz])])
            scales = list(dict.fromkeys([float(norms[cur]), float(norms[nz].max()),
                                         float(norms[nz].min())]))
        else:
            scales = [1.0]
        failures = []
        attempts = [("daqp", g) for g in scales] + [("ipm", scales[0])]
        for k, (solver, gs) in enumerate(attempts):
            prob = _ScaledQP(self, x, G_u, alpha_u, t, gs)
            sol = prob.solve_daqp() if solver == "daqp" else prob.solve_ipm()
            if isinstance(sol, str):
                failures.append(f"{solver} at scale {gs:.2e}: {sol}")
                continue
            if k:
                logger.debug("direction QP solved by %s at scale %.2e after: %s", solver, gs,
                             "; ".join(failures))
            d_s, lam_u, mu_up, mu_lo, mu_ub = sol
            d = prob.delta * d_s
            lam = np.zeros(G.shape[0])
            lam[keep] = lam_u
            # complementarity gap μᵀ(b − Cx) ≥ 0 of the constraint multipliers at x
            sigma = gs * (float(mu_up @ _finite(self.ub - x)) + float(mu_lo @ _finite(x - self.lb))
                          + float(mu_ub @ np.maximum(self.b_ub - self.A_ub @ x, 0.0)))
            xi = lam @ G
            # model value at d from the active cuts (max_j would amplify the solver tolerance
            # on steep cuts): v = Σλ_j (g_jᵀd − α_j) = −t‖p‖² − α_p − μᵀC d ≤ 0
            v = min(float(xi @ d - lam @ alpha), 0.0)
            return DirectionQP(d=d, v=v, lam=lam, p=-d / t, xi=xi, sigma=sigma, solver=solver)
        raise OptimizerError(
            f"the direction-finding QP failed (t = {t:.3e}, bundle size {G.shape[0]}, "
            f"{self.n_ub} inequality and {self.n_eq} equality rows): " + "; ".join(failures))


def _finite(v):
    return np.where(np.isfinite(v), np.maximum(v, 0.0), 0.0)


def _dedup(G, alpha):
    """Drop bundle rows with a duplicate subgradient, keeping the smallest α (same QP)."""
    order = np.lexsort((np.arange(alpha.size), alpha))        # by α, then index
    _, first = np.unique(G[order], axis=0, return_index=True)
    keep = np.sort(order[first])
    return keep, G[keep], alpha[keep]


def _unit_rows(A, b):
    w = np.linalg.norm(A, axis=1)
    w[w == 0] = 1.0
    return A / w[:, None], b / w, w


class _ScaledQP:
    """The BT QP in scaled variables z = (d̃, ṽ) with unit rows, see Polyhedron.direction."""

    def __init__(self, poly: Polyhedron, x, G, alpha, t, gs):
        n, m = poly.n, G.shape[0]
        self.poly, self.n, self.m = poly, n, m
        self.delta = t * gs
        nu = t * gs * gs
        self.B, self.bB, self.wB = _unit_rows(np.hstack([G / gs, -np.ones((m, 1))]), alpha / nu)
        zc = np.zeros((poly.n_ub, 1))
        self.C, self.bC, self.wC = _unit_rows(np.hstack([poly.A_ub, zc]),
                                              (poly.b_ub - poly.A_ub @ x) / self.delta)
        ze = np.zeros((poly.n_eq, 1))
        self.E, self.bE, self.wE = _unit_rows(np.hstack([poly.A_eq, ze]),
                                              (poly.b_eq - poly.A_eq @ x) / self.delta)
        self.lo = (poly.lb - x) / self.delta
        self.hi = (poly.ub - x) / self.delta

    def _kkt_error(self, z, lam, mu_up, mu_lo, mu_ub, mu_eq):
        """None if (z, multipliers of the unit rows) satisfy the KKT conditions tightly."""
        n = self.n
        d = z[:n]
        tol = 1e-9 * (1.0 + float(np.max(np.abs(z))))
        il, iu = np.isfinite(self.lo), np.isfinite(self.hi)
        viol = max(np.max(self.B @ z - self.bB),
                   np.max(self.C @ z - self.bC, initial=-np.inf),
                   np.max(np.abs(self.E @ z - self.bE), initial=-np.inf),
                   np.max(self.lo[il] - d[il], initial=-np.inf),
                   np.max(d[iu] - self.hi[iu], initial=-np.inf))
        if not viol <= tol:
            return f"infeasible solution ({viol:.1e})"
        total = float(lam @ (1.0 / self.wB))          # Σλ_j in the original rows
        if not abs(total - 1.0) <= 1e-6:
            return f"bundle multipliers sum to {total:.12g}, not 1"
        grad = self.B.T @ lam + self.C.T @ mu_ub + self.E.T @ mu_eq
        grad[:n] += d + mu_up - mu_lo
        grad[n] += 1.0
        ref = 1.0 + np.linalg.norm(d) + float(np.abs(lam).sum())
        if not np.linalg.norm(grad) <= 1e-8 * ref:
            return f"stationarity residual {np.linalg.norm(grad):.1e}"
        return None

    def solve_daqp(self):
        n, m, P = self.n, self.m, self.poly
        H = np.zeros((n + 1, n + 1))
        H[np.arange(n), np.arange(n)] = 1.0
        f = np.zeros(n + 1)
        f[n] = 1.0
        A = np.vstack([self.B, self.C, self.E])
        bu = np.concatenate([self.bB, self.bC, self.bE])
        bl = np.concatenate([np.full(m + P.n_ub, -np.inf), self.bE])
        nb = n if P.has_bounds else 0
        if nb:
            bu = np.concatenate([self.hi, bu])
            bl = np.concatenate([self.lo, bl])
        sense = np.zeros(bu.size, dtype=np.int32)
        sense[nb + m + P.n_ub:] = 5
        z, flag, lam_all, _ = _solve(H, f, A, bu, bl, sense)
        if flag not in (1, 2) or not np.all(np.isfinite(z)):
            return f"exit flag {flag} ({_DAQP_FLAGS.get(flag, 'unknown')})"
        mu_b = lam_all[:nb] if nb else np.zeros(n)
        k = nb + m + P.n_ub
        return self._finish(z, lam_all[nb:nb + m], np.maximum(mu_b, 0.0),
                            np.maximum(-mu_b, 0.0), lam_all[nb + m:k], lam_all[k:])

    def solve_ipm(self):
        n, m, P = self.n, self.m, self.poly
        N = n + 1
        H = np.zeros((N, N))
        H[np.arange(n), np.arange(n)] = 1.0
        f = np.zeros(N)
        f[n] = 1.0
        iu = np.flatnonzero(np.isfinite(self.hi))
        il = np.flatnonzero(np.isfinite(self.lo))
        eye = np.eye(N)
        A = np.vstack([self.B, self.C, eye[iu], -eye[il]])
        b = np.concatenate([self.bB, self.bC, self.hi[iu], -self.lo[il]])
        try:
            z, lam_all, mu_eq = _ipm(H, f, A, b, self.E, self.bE)
        except (np.linalg.LinAlgError, FloatingPointError, RuntimeError) as exc:
            return f"interior point failed ({exc})"
        mu_up, mu_lo = np.zeros(n), np.zeros(n)
        k = m + P.n_ub
        mu_up[iu] = lam_all[k:k + iu.size]
        mu_lo[il] = lam_all[k + iu.size:]
        return self._finish(z, lam_all[:m], mu_up, mu_lo, lam_all[m:k], mu_eq)

    def _finish(self, z, lam, mu_up, mu_lo, mu_ub, mu_eq):
        bad = self._kkt_error(z, lam, mu_up, mu_lo, mu_ub, mu_eq)
        if bad:
            return bad
        lam = np.maximum(lam, 0.0) / self.wB
        mu_ub = np.maximum(mu_ub, 0.0) / self.wC
        return z[:self.n], lam / lam.sum(), mu_up, mu_lo, mu_ub


def _ipm(H, f, A, b, E, e, tol=1e-12, max_iter=100):
    """Dense Mehrotra predictor-corrector for min ½zᵀHz + fᵀz s.t. Az ≤ b, Ez = e.

    Fallback for degenerate bundles on which the active-set method cycles; H may be
    singular as long as H + AᵀDA is not (true here: every bundle row contains ṽ).  Returns
    the iterate with the smallest KKT error (ill-conditioning ends the progress near 1e-12).
    """
    N, m, p = H.shape[0], A.shape[0], E.shape[0]
    z = np.zeros(N)
    s = np.maximum(b - A @ z, 1.0)
    lam = np.ones(m)
    y = np.zeros(p)
    scale = 1.0 + max(np.abs(b).max(initial=0.0), np.abs(e).max(initial=0.0))
    best, best_err = None, np.inf
    for _ in range(max_iter):
        rd = H @ z + f + A.T @ lam + E.T @ y
        rp = A @ z + s - b
        re = E @ z - e
        mu = float(s @ lam) / m
        err = max(np.abs(rd).max(), np.abs(rp).max(initial=0.0), np.abs(re).max(initial=0.0),
                  mu) / scale
        if err < best_err:
            best, best_err = (z.copy(), lam.copy(), y.copy()), err
        if err <= tol:
            break
        D = lam / s
        K = np.block([[H + A.T @ (D[:, None] * A), E.T], [E, np.zeros((p, p))]])

        def newton(rc):
            rhs = np.concatenate([-rd - A.T @ ((rc + lam * rp) / s), -re])
            sol = np.linalg.solve(K, rhs)
            dz = sol[:N]
            ds = -rp - A @ dz
            return dz, ds, (rc - lam * ds) / s, sol[N:]

        def max_step(v, dv):
            neg = dv < 0
            return min(1.0, float(np.min(-v[neg] / dv[neg]))) if np.any(neg) else 1.0

        try:
            dz, ds, dl, dy = newton(-s * lam)
            a = min(max_step(s, ds), max_step(lam, dl))
            sigma = (float((s + a * ds) @ (lam + a * dl)) / m / mu) ** 3
            dz, ds, dl, dy = newton(-s * lam - ds * dl + sigma * mu)
        except np.linalg.LinAlgError:
            break
        a = min(1.0, 0.99 * min(max_step(s, ds), max_step(lam, dl)))
        z, s, lam, y = z + a * dz, s + a * ds, lam + a * dl, y + a * dy
        if not (np.all(np.isfinite(z)) and np.all(np.isfinite(lam))):
            break
    if best is None or best_err > 1e-7:
        raise RuntimeError(f"KKT error {best_err:.1e} after {max_iter} iterations")
    return best
