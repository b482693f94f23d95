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

One chain for every state solver: :func:`run_chain` drives a :class:`FallbackProblem`, which gives
its first attempt, its fallbacks and its diagnosis. :class:`LocalProblem` is the local problem's
(above); the full-space Newton method's (:class:`contactopt.contact.fullspace.FullSpaceProblem`,
nothing condensed, no W formed) has the parts that apply there: the cold restart (no warm start of
r, u or the zone), the continuation in the friction coefficient, and a continuation in the load
(t L for t = 1/4, 1/2, 3/4, 1, each warm-started from the last), which begins at a small
deformation where the node classes of the start are nearly right; its diagnosis forms W from a
factorization of A where the mesh is small enough, and names a penetrating start on any size.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from typing import Protocol

import numpy as np

from ..errors import ContactNotConverged, ProblemDataError
from ..fem.krylov import KrylovNotConverged
from .local import solve_local
from .result import LocalResult

__all__ = ["solve_with_fallbacks", "run_chain", "FallbackProblem", "LocalProblem", "diagnose", "penetrating_start",
           "FALLBACKS", "FULLSPACE_FALLBACKS"]

log = logging.getLogger(__name__)

FALLBACKS = ("cold restart", "fixed point", "friction continuation")
FULLSPACE_FALLBACKS = ("cold restart", "friction continuation", "load continuation")
_CONTINUATION = (0.0, 0.25, 0.5, 0.75, 1.0)
_EIG_MAX = 6000            # largest local problem whose W is checked by a dense eigenvalue solve
_SINGULAR = 1e-10          # smallest eigenvalue of sym(W) relative to the largest: singular below


class FallbackProblem(Protocol):
    """A state solver the chain of :func:`run_chain` drives: the local problem's
    (:class:`LocalProblem`) or the full-space Newton method's
    (:class:`contactopt.contact.fullspace.FullSpaceProblem`). Its results have ``converged``,
    ``error`` and ``history``; the solver counts their steps and names their stops."""

    what: str           # the problem in messages ("the contact state")
    first_name: str     # the first attempt's name ("newton from the warm start")
    tol: float

    def first(self):
        """The method as asked (the result, not raised)."""

    def attempts(self) -> Iterator[tuple[str, Callable[[], object]]]:
        """(name, thunk) of each fallback, in order."""

    def steps(self, result) -> int:
        """The Newton steps (or the method's own iterations) of a result."""

    def stop(self, result) -> str:
        """Why a result stopped, in words."""

    def converged_by(self, result, name: str, spent: int):
        """The converged ``result`` of the fallback ``name``, marked so (``spent`` steps before it)."""

    def diagnose(self, best) -> str:
        """What in the model keeps the problem from a solution (``best`` the result of least error)."""


def run_chain(problem: FallbackProblem):
    """The first attempt of ``problem``, then each fallback until one converges (the module
    docstring); :class:`ContactNotConverged` with the diagnosis when none does. A solver error of
    an attempt (non-finite iterates, a Krylov solve that fails, W not positive semidefinite) counts
    as that attempt's failure; bad data in the first attempt (ProblemDataError) is raised as it is."""
    what = problem.what
    tried = []
    try:
        first = problem.first()
    except (ContactNotConverged, KrylovNotConverged) as exc:     # bad data (ProblemDataError) is raised as it is
        log.info("%s: %s failed (%s); trying the fallbacks", what, problem.first_name, exc)
    else:
        if first.converged:
            return first
        tried.append((problem.first_name, first))
        log.info("%s: %s did not converge (%s); trying the fallbacks", what, problem.first_name, problem.stop(first))
    for name, attempt in problem.attempts():
        try:
            res = attempt()
        except (ContactNotConverged, ProblemDataError, KrylovNotConverged) as exc:
            log.info("%s: fallback %s failed (%s)", what, name, exc)
            continue
        tried.append((name, res))
        if res.converged:
            log.info("%s: converged by the fallback %s (%s)", what, name, problem.stop(res))
            return problem.converged_by(res, name, sum(problem.steps(t) for _, t in tried[:-1]))
        log.info("%s: fallback %s did not converge (%s)", what, name, problem.stop(res))
    best = min((t for _, t in tried), key=lambda t: t.error) if tried else None
    verdict = problem.diagnose(best)
    attempts = "; ".join(f"{n}: error {t.error:.2e} after {problem.steps(t)} steps" for n, t in tried) or "every path failed"
    exc = ContactNotConverged(f"not converged: no path reached the tolerance {problem.tol:.1e} ({attempts}). {verdict}",
                              best.history if best is not None else [])
    exc.diagnosis = verdict
    raise exc


class LocalProblem:
    """The local problem ``u = W r + q`` (FCLIB order per contact: normal, t1, t2) as a
    :class:`FallbackProblem`: the chain of the module docstring (cold restart, fixed point,
    friction continuation) and :func:`diagnose` of W and q."""

    def __init__(self, W, q, mu, *, method, tol, max_iter, r0, gap, what):
        self.W, self.q, self.mu, self.method, self.tol = W, q, mu, method, tol
        self.max_iter, self.r0, self.gap, self.what = max_iter, r0, gap, what
        self.first_name = method + (" from the warm start" if r0 is not None else "")

    def first(self):
        return solve_local(self.W, self.q, self.mu, method=self.method, tol=self.tol, max_iter=self.max_iter,
                           r0=self.r0, raise_on_failure=False)

    def attempts(self):
        W, q, mu, tol, max_iter = self.W, self.q, self.mu, self.tol, self.max_iter
        newton = dict(method="newton", tol=tol, raise_on_failure=False)
        if max_iter is not None:
            newton["max_iter"] = max_iter
        if self.method != "newton" or self.r0 is not None:
            yield "cold restart", lambda: solve_local(W, q, mu, **newton)
        if self.method == "newton":
            def fixed_point():
                fp = solve_local(W, q, mu, method="fixed-point", tol=tol, max_iter=max_iter, raise_on_failure=False)
                if fp.converged or not np.all(np.isfinite(fp.r)):
                    return fp
                polished = solve_local(W, q, mu, r0=fp.r, **newton)
                polished.iterations += fp.iterations
                return polished
            yield "fixed point", fixed_point
        if float(np.max(mu)) > 0:
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

    def steps(self, result) -> int:
        return result.iterations

    def stop(self, result) -> str:
        return result.message

    def converged_by(self, result, name, spent):
        result.stats = {**result.stats, "fallback": name, "fallback_iterations": spent}
        return result

    def diagnose(self, best) -> str:
        return diagnose(self.W, self.q, self.mu, gap=self.gap)


def solve_with_fallbacks(W, q, mu, *, method: str = "newton", tol: float = 1e-8, max_iter=None,
                         r0=None, gap=None, what: str = "the contact state") -> LocalResult:
    """Solve ``u = W r + q``, ``K_mu ∋ r ⊥ u~ ∈ K_mu*`` by ``method``, then by the fallbacks of
    the module docstring; raise :class:`ContactNotConverged` with a diagnosis if none converges.

    ``gap`` (p,): the initial gaps of the contacts (a negative one is a penetrating start);
    ``what`` names the problem in messages.
    """
    return run_chain(LocalProblem(W, q, mu, method=method, tol=tol, max_iter=max_iter, r0=r0, gap=gap, what=what))


def penetrating_start(gap, scale: float = 0.0) -> list:
    """[the words of a penetrating start] when contact nodes have a negative initial ``gap`` (p,)
    (below −1e-9 of the larger of ``scale`` and the largest |gap|), else []."""
    gap = np.asarray(gap, dtype=float)
    scale = max(scale, float(np.abs(gap).max(initial=0.0)), 1e-300)
    bad = np.flatnonzero(gap < -1e-9 * scale)
    if not bad.size:
        return []
    k = int(bad[np.argmin(gap[bad])])
    return [f"a penetrating start: {bad.size} of {gap.size} contact nodes start inside the obstacle "
            f"(gap {gap[k]:.3g} at contact node {k}); check body.initial_gap, the mesh's "
            "contact face and the obstacle's position"]


def diagnose(W, q, mu, *, gap=None) -> str:
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
        out += penetrating_start(gap, float(np.abs(q).max(initial=0.0)))
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
        else:
            out.append(f"no defect found in the model (W positive definite, condition {top / w[0]:.3g}, "
                       f"no penetrating start); with friction coefficient {float(np.max(mu)):g} the "
                       "Coulomb problem may have no solution the solvers reach: try a smaller "
                       "friction coefficient, or a finer mesh of the contact face")
    if not out:          # W too large for the eigenvalue check
        out.append("no defect found in the model (the local problem has "
                   f"{p} contacts, too many for the eigenvalue check of W); check body.clamped, the "
                   "loads and the initial gap")
    return "The model: " + "; ".join(out) + "."
