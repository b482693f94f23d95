"""The state solve's fallback chain: when the chosen local solver stalls, other paths to the same
solution, and when all of them fail, a diagnosis of the model instead of "not converged" alone.

Convention of :mod:`contactopt.contact.local`: ``u = W r + q`` per contact (normal, t1, t2), ``r_N``
the normal force on the body (≥ 0), ``u_N`` the normal displacement plus the gap (≥ 0 where the
body is clear of the obstacle).

The chain, tried in this order until one converges to the same tolerance:

1. the chosen method as asked (semismooth Newton from the warm start, or the fixed-point method);
2. ``cold restart``: semismooth Newton from the frictionless predictor, without the warm start
   (a warm start from a distant design can put Newton on a wrong piece of the Alart–Curnier map);
3. ``fixed point``: the paper's successive approximations (Cor. 3.9), each step a convex Tresca
   problem, followed by Newton from its last iterate when it stalls near the solution;
4. ``friction continuation``: Newton along F = 0 (a convex QP, always solvable with W positive
   definite), F/4, F/2, 3F/4, F, each step warm-started from the one before.

Each path is bounded by the same ``max_iter`` (Newton steps, Tresca solves; per friction step of the
continuation). A solve that needs no fallback is exactly the first attempt (the same numbers, bit for bit). A
converged fallback sets ``stats["fallback"]`` to its name. When every path fails,
:func:`diagnose` inspects the problem: a singular W (a rigid motion that contact does not hold),
a load that pushes along that motion (an unbalanced load), a negative initial gap (a penetrating
start); the exception's message and its ``diagnosis`` attribute say which, and what to check.
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import ContactNotConverged, ProblemDataError
from .local import solve_local
from .result import LocalResult

__all__ = ["solve_with_fallbacks", "diagnose", "FALLBACKS"]

log = logging.getLogger(__name__)

FALLBACKS = ("cold restart", "fixed point", "friction continuation")
_CONTINUATION = (0.0, 0.25, 0.5, 0.75, 1.0)
_EIG_MAX = 6000            # largest local problem whose W is checked by a dense eigenvalue solve
_SINGULAR = 1e-10          # smallest eigenvalue of sym(W) relative to the largest: singular below


def _attempts(W, q, mu, method, tol, max_iter, r0):
    """(name, thunk) of each fallback, in order."""
    newton = dict(method="newton", tol=tol, raise_on_failure=False)
    if max_iter is not None:
        newton["max_iter"] = max_iter
    if method != "newton" or r0 is not None:
        yield "cold restart", lambda: solve_local(W, q, mu, **newton)
    if method == "newton":
        def fixed_point():
            fp = solve_local(W, q, mu, method="fixed-point", tol=tol, max_iter=max_iter, raise_on_failure=False)
            if fp.converged or not np.all(np.isfinite(fp.r)):
                return fp
            polished = solve_local(W, q, mu, r0=fp.r, **newton)
            polished.iterations += fp.iterations
            return polished
        yield "fixed point", fixed_point
    mu_max = float(np.max(mu))
    if mu_max > 0:
        def continuation():
            r, total, res = None, 0, None
            for t in _CONTINUATION:
                res = solve_local(W, q, np.asarray(mu) * t, r0=r, **newton)
                total += res.iterations
                # an intermediate friction need not be solved exactly: go on from where it stopped
                r = res.r if np.all(np.isfinite(res.r)) else r
            res.iterations = total
            return res
        yield "friction continuation", continuation


def solve_with_fallbacks(W, q, mu, *, method: str = "newton", tol: float = 1e-8, max_iter=None,
                         r0=None, gap=None, what: str = "the contact state") -> LocalResult:
    """Solve ``u = W r + q``, ``K_mu ∋ r ⊥ u~ ∈ K_mu*`` by ``method``, then by the fallbacks of
    the module docstring; raise :class:`ContactNotConverged` with a diagnosis if none converges.

    ``gap`` (p,): the initial gaps of the contacts (a negative one is a penetrating start);
    ``what`` names the problem in messages.
    """
    first = solve_local(W, q, mu, method=method, tol=tol, max_iter=max_iter, r0=r0,
                        raise_on_failure=False)
    if first.converged:
        return first
    tried = [(method + (" from the warm start" if r0 is not None else ""), first)]
    log.info("%s: %s did not converge (%s); trying the fallbacks", what, tried[0][0], first.message)
    for name, attempt in _attempts(W, q, mu, method, tol, max_iter, r0):
        try:
            res = attempt()
        except (ContactNotConverged, ProblemDataError) as exc:   # non-finite iterates, W not PSD
            log.info("%s: fallback %s failed (%s)", what, name, exc)
            continue
        tried.append((name, res))
        if res.converged:
            res.stats = {**res.stats, "fallback": name,
                         "fallback_iterations": sum(t.iterations for _, t in tried[:-1])}
            log.info("%s: converged by the fallback %s (%s)", what, name, res.message)
            return res
        log.info("%s: fallback %s did not converge (%s)", what, name, res.message)
    best = min((t for _, t in tried), key=lambda t: t.error)
    verdict = diagnose(W, q, mu, gap=gap, r=best.r)
    attempts = "; ".join(f"{n}: error {t.error:.2e} after {t.iterations} steps" for n, t in tried)
    exc = ContactNotConverged(f"not converged: no path reached the tolerance {tol:.1e} ({attempts}). {verdict}",
                              best.history)
    exc.diagnosis = verdict
    raise exc


def diagnose(W, q, mu, *, gap=None, r=None) -> str:
    """What in the model keeps the local problem from a solution, in words, with what to check.

    Looks for, in order: a penetrating start (a negative gap), a rigid motion (``sym(W)``
    singular: a direction of the contact forces that moves nothing, so the body is not held
    in it) and an unbalanced load (the free displacement ``q`` has a part along that motion
    pushing towards the obstacle, which no contact force can balance).
    """
    W = np.asarray(W.toarray() if hasattr(W, "toarray") else W, dtype=float)
    q = np.asarray(q, dtype=float)
    p = q.size // 3
    out = []
    if gap is not None:
        gap = np.asarray(gap, dtype=float)
        scale = max(float(np.abs(q).max(initial=0.0)), float(np.abs(gap).max(initial=0.0)), 1e-300)
        bad = np.flatnonzero(gap < -1e-9 * scale)
        if bad.size:
            k = int(bad[np.argmin(gap[bad])])
            out.append(f"a penetrating start: {bad.size} of {p} contact nodes start inside the obstacle "
                       f"(gap {gap[k]:.3g} at contact node {k}); check body.initial_gap, the mesh's "
                       "contact face and the obstacle's position")
    if W.shape[0] <= _EIG_MAX:
        S = 0.5 * (W + W.T)
        w, V = np.linalg.eigh(S)
        top = max(float(np.abs(w).max(initial=0.0)), 1e-300)
        null = np.flatnonzero(np.abs(w) <= _SINGULAR * top)
        if w[0] < -_SINGULAR * top:
            out.append(f"W is not positive semidefinite (eigenvalue {w[0]:.3g} against {top:.3g}): the "
                       "stiffness is not; check [material] (E > 0, 0 <= nu < 0.5) and the mesh's cells")
        elif null.size:
            z = V[:, null]
            push = z @ (z.T @ q)                   # q's part along the free motions
            zn = push[0::3]
            if np.any(zn < -1e-8 * max(float(np.linalg.norm(q)), 1e-300)):
                out.append(f"an unbalanced load: the contact forces have {null.size} direction(s) "
                           "that move nothing (W singular) and the load drives the body along one "
                           "of them into the obstacle; no contact force balances it. Check "
                           "body.clamped and the loads (a support missing, a force without reaction)")
            else:
                out.append(f"a rigid motion: W is singular ({null.size} zero eigenvalue(s), "
                           f"smallest {w[0]:.3g} against {top:.3g}), so the body is not held in some "
                           "direction of the contact forces; check body.clamped (a support or a "
                           "symmetry plane missing)")
        elif r is not None and np.all(np.isfinite(r)):
            out.append(f"no defect found in the model (W positive definite, condition {top / w[0]:.3g}, "
                       f"no penetrating start); with friction coefficient {float(np.max(mu)):g} the "
                       "Coulomb problem may have no solution the solvers reach: try a smaller "
                       "friction coefficient, or a finer mesh of the contact face")
    if not out:
        out.append("no defect found in the model (the local problem has "
                   f"{p} contacts, too many for the eigenvalue check of W); check body.clamped, the "
                   "loads and the initial gap")
    return "The model: " + "; ".join(out) + "."
