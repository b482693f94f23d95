"""Coulomb friction by successive approximations (the paper's method, Cor. 3.9 and §5.1).

With ``Gamma(g)`` the normal force of the Tresca problem (5.1) with slip bounds ``g``, the
paper iterates ``lambda^(k+1) = Gamma(lambda^(k))``; in the local convention of
:mod:`contactopt.contact.local` that is

    g^(k) = mu * r_N^(k),   r^(k+1) = argmin { 1/2 r^T W r + r^T q : r_N >= 0, ||r_T|| <= g^(k) },

starting from ``g^(0) = mu r0_N`` (``0``, i.e. frictionless, without a warm start). Each
Tresca problem is solved by Kučera's Algorithm 1 (:func:`contactopt.contact.tresca.solve_tresca`)
warm-started from the previous ``r``. The iteration stops on the Siconos error of the Coulomb
problem. By Theorem 3.8, ``Gamma`` is a contraction for small friction (3.16); when the
increments ``||r_N^(k+1) - r_N^(k)||`` stop decreasing the iteration is not contracting, which
is an observable sign that the friction is above the uniqueness bound and that several
solutions may exist: this is logged as a warning and reported in ``stats``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ..errors import ContactNotConverged
from .cones import siconos_error
from .result import LocalResult, check_problem
from .tresca import estimate_norm, solve_tresca

__all__ = ["solve_fixed_point"]

log = logging.getLogger(__name__)


def solve_fixed_point(W, q, mu, *, tol: float = 1e-8, max_iter: int = 200, r0=None,
                      inner_tol: float | None = None, inner_max_iter: int | None = None,
                      gamma: float = 1.0, norm_W: float | None = None,
                      stall_window: int = 3, raise_on_failure: bool = True) -> LocalResult:
    """Solve the local Coulomb problem by the successive approximations of Cor. 3.9.

    Parameters
    ----------
    W, q, mu : the local problem (see :func:`contactopt.contact.local.solve_local`); ``W``
        symmetric positive (semi)definite, dense, sparse or ``LinearOperator``.
    tol : target Siconos error; ``max_iter`` bounds the number of Tresca solves.
    r0 : warm start; gives the first slip bound ``mu r0_N`` and the first Tresca start.
    inner_tol : fixed relative projected-gradient tolerance of the Tresca solves; by default it
        is adaptive, ``0.1 * (last Coulomb error)`` clipped to ``[1e-3 tol, 1e-4]`` and tightened
        further when the outer error stalls.
    inner_max_iter, gamma : passed to Algorithm 1 (``gamma`` is ``Gamma~`` of (5.2)).
    norm_W : ``||W||`` if known (the steplength of Algorithm 1 is ``1/norm_W``); estimated once
        by power iteration otherwise.
    stall_window : number of consecutive non-contracting steps before the warning.
    """
    t0 = time.perf_counter()
    W, q, mu, r0 = check_problem(W, q, mu, r0=r0)
    n = q.size
    p = n // 3
    if norm_W is None:
        norm_W = estimate_norm(W, n)
    alpha_bar = 1.0 / norm_W if norm_W > 0 else None

    r = np.zeros(n) if r0 is None else r0.copy()
    g = mu * np.maximum(r[0::3], 0.0)
    history: list[float] = []
    inner_counts: list[int] = []
    ratios: list[float] = []
    steps = {"cg": 0, "expansion": 0, "proportioning": 0}
    matvecs = 0
    err = np.inf
    itol_floor = 1e-3 * tol
    itol = inner_tol if inner_tol is not None else 1e-4
    prev_dn = None
    n_bad = 0
    warned = False
    converged = False
    u = q.copy()
    for k in range(max_iter):
        res = solve_tresca(W, q, g, r0=r, tol=itol, max_iter=inner_max_iter,
                           alpha_bar=alpha_bar, gamma=gamma, raise_on_failure=False)
        inner_counts.append(res.iterations)
        matvecs += res.matvecs
        for key in steps:
            steps[key] += res.steps[key]
        dn = float(np.linalg.norm(res.r[0::3] - r[0::3]))
        r, u = res.r, res.u
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(u))):
            raise ContactNotConverged("fixed point produced non-finite values", history)
        err_prev, err = err, siconos_error(r, u, q, mu)
        history.append(err)
        g = mu * r[0::3]
        if prev_dn is not None and prev_dn > 0:
            ratio = dn / prev_dn
            ratios.append(ratio)
            n_bad = n_bad + 1 if ratio >= 1.0 else 0
            if n_bad >= stall_window and not warned and dn > 0:
                warned = True
                log.warning(
                    "successive approximations are not contracting (||dr_N|| ratio %.3g for "
                    "%d steps at iteration %d): the friction may exceed the uniqueness bound "
                    "(3.16) and the Coulomb problem may have several solutions",
                    ratio, n_bad, k + 1)
        prev_dn = dn
        log.debug("fixed point %d: error %.3e, Tresca its %d (tol %.1e), ||dr_N|| %.3e",
                  k + 1, err, res.iterations, itol, dn)
        if err <= tol:
            converged = True
            break
        if inner_tol is None:
            itol = min(itol, max(0.1 * err, itol_floor))
            if err > 0.5 * err_prev:     # outer error stalls: the inner solves are too coarse
                itol = max(0.1 * itol, itol_floor)
    elapsed = time.perf_counter() - t0
    if converged:
        msg = f"converged: Siconos error {err:.3e} <= tol {tol:.1e}"
    else:
        msg = (f"not converged: Siconos error {err:.3e} > tol {tol:.1e} after {len(history)} "
               f"Tresca solves")
    result = LocalResult(
        r=r, u=u, iterations=len(history), error=err, converged=converged, history=history,
        method="fixed-point", time_s=elapsed, message=msg, outer_iterations=len(history),
        inner_iterations=int(sum(inner_counts)),
        stats={"tresca_iterations": inner_counts, "steps": steps, "matvecs": matvecs,
               "contraction_ratios": ratios, "non_contracting": warned,
               "norm_W": norm_W, "p": p})
    if not converged and raise_on_failure:
        raise ContactNotConverged(msg, history)
    return result
