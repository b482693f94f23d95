"""Contact with given friction (Tresca) in the dual form (5.1), solved by Kučera's Algorithm 1.

The paper's (5.1) minimises ``f(sigma) = 1/2 sigma^T Q sigma - sigma^T h`` over
``S = {lambda_i >= 0, ||tau_i|| <= g_i}`` with ``Q = B A^{-1} B^T`` and ``h = B A^{-1} L + c``.
In the local convention of :mod:`contactopt.contact.local` (``u = W r + q``, per contact
(normal, tangent1, tangent2)) this reads

    min  1/2 r^T W r + r^T q   over   S_g = {r_N,i >= 0, ||r_T,i|| <= g_i},

i.e. ``sigma = r`` (reordered contact by contact), ``Q = W`` and ``h = -q``. The gradient of
``f`` is ``W r + q = u``, and the optimality condition ``-u ∈ N_{S_g}(r)`` is Signorini's law
(``r_N >= 0``, ``u_N >= 0``, ``r_N u_N = 0``) together with Tresca's law with slip bound
``g_i`` (``||r_T|| < g => u_T = 0``; ``||r_T|| = g => r_T = -g u_T/||u_T||``). The sign of
the tangential components is irrelevant to ``S_g`` (a disc), so the paper's ``tau`` and our
``r_T`` differ at most by that sign.

Algorithm 1 (Kučera [14, 15]; Dostál–Schöberl [5] for bounds): with ``A(r)`` the active set
(``r_N = 0`` or ``||r_T|| = g``), the projected gradient
``g~ = (r - P(r - a g))/a`` for the fixed steplength ``a = alpha_bar in (0, ||W||^{-1}]``
splits into the projected free gradient ``phi~`` (free components) and the projected boundary
gradient ``beta~`` (active ones). If the releasing criterion (5.2)
``beta~^T g <= Gamma phi~^T g`` holds, a conjugate gradient step on the current face is tried and
kept when it stays in the interior of the face; otherwise an expansion step is taken: as in
the MPRGP algorithm of [5] that Algorithm 1 generalises, the CG step is first cut at the
boundary of ``S_g`` (the longest feasible step), then the projected step ``P(r - a phi)`` is
made on the free components. If (5.2) fails, a proportioning step ``r - a beta~`` releases
constraints. The iteration stops when ``||g~|| <= tol * max(||q||, tiny)``.

Two numerical safeguards, both exact in exact arithmetic: (5.2) is evaluated with
``max(v~^T g, ||v~||^2)`` (equal for a convex set, but the dot product of the disc components
cancels to rounding noise near the solution), and the CG recurrence ``g <- g - a W p`` is
replaced by ``W r + q`` every 25 CG steps and before accepting convergence.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ContactNotConverged, ProblemDataError
from .cones import project_tresca_set

__all__ = ["TrescaResult", "solve_tresca", "estimate_norm", "as_matvec"]

log = logging.getLogger(__name__)

_ACTIVE_RTOL = 1e-12  # ||r_T|| >= (1 - rtol) g counts as "on the boundary of the disc"
_REFRESH = 25         # CG steps between recomputations of the gradient as W r + q


@dataclass
class TrescaResult:
    """Result of :func:`solve_tresca`: ``r``, ``u = W r + q`` and counters.

    ``residual`` is the relative projected-gradient norm ``||g~|| / max(||q||, tiny)``;
    ``history`` holds it per iteration; ``steps`` counts CG, expansion and proportioning steps.
    """

    r: np.ndarray
    u: np.ndarray
    iterations: int
    residual: float
    converged: bool
    history: list[float]
    matvecs: int
    steps: dict = field(default_factory=dict)
    alpha_bar: float = 0.0


def as_matvec(W):
    """Return ``x -> W x`` for a dense array, a sparse matrix or a ``LinearOperator``."""
    if isinstance(W, spla.LinearOperator):
        return W.matvec
    if sp.issparse(W):
        Wc = W.tocsr()
        return lambda x: Wc @ x
    Wd = np.asarray(W, dtype=float)
    return lambda x: Wd @ x


def estimate_norm(W, n: int | None = None, *, iters: int = 100, rtol: float = 1e-3,
                  seed: int = 0) -> float:
    """Estimate ``||W||_2`` of a symmetric positive semidefinite ``W`` by power iteration.

    Power iteration approaches the largest eigenvalue from below; the value returned is the
    last Rayleigh quotient times 1.05, so ``1/estimate`` is a safe steplength for Algorithm 1
    (whose expansion step decreases ``f`` for any steplength below ``2/||W||``).
    """
    matvec = as_matvec(W)
    if n is None:
        n = W.shape[0]
    x = np.random.default_rng(seed).standard_normal(n)
    x /= np.linalg.norm(x)
    lam = 0.0
    for _ in range(iters):
        y = matvec(x)
        lam_new = float(x @ y)
        ny = float(np.linalg.norm(y))
        if not np.isfinite(ny):
            raise ProblemDataError("W produced non-finite values in power iteration")
        if ny == 0.0:
            return 0.0
        x = y / ny
        if abs(lam_new - lam) <= rtol * abs(lam_new):
            lam = lam_new
            break
        lam = lam_new
    return 1.05 * max(lam, 0.0)


def _feasible_step(R, P, g, free_n, free_t):
    """Largest ``a >= 0`` with ``R - a P`` in ``S_g`` along the free components (inf if none)."""
    a = np.inf
    pn = P[:, 0]
    sel = free_n & (pn > 0)
    if np.any(sel):
        a = min(a, float(np.min(R[sel, 0] / pn[sel])))
    if np.any(free_t):
        rt, pt, gt = R[free_t, 1:], P[free_t, 1:], g[free_t]
        pp = np.einsum("ij,ij->i", pt, pt)
        rp = np.einsum("ij,ij->i", rt, pt)
        rr = np.einsum("ij,ij->i", rt, rt)
        mov = pp > 0
        if np.any(mov):
            # ||r - a p||^2 = g^2  ->  a = (r.p + sqrt((r.p)^2 + p.p (g^2 - r.r))) / p.p
            disc = rp[mov] ** 2 + pp[mov] * np.maximum(gt[mov] ** 2 - rr[mov], 0.0)
            roots = (rp[mov] + np.sqrt(disc)) / pp[mov]
            a = min(a, float(np.min(roots)))
    return max(a, 0.0)


def solve_tresca(W, q, g, *, r0=None, tol: float = 1e-10, max_iter: int | None = None,
                 alpha_bar: float | None = None, norm_W: float | None = None,
                 gamma: float = 1.0, raise_on_failure: bool = True) -> TrescaResult:
    """Solve the Tresca problem (5.1) ``min 1/2 r^T W r + r^T q`` over ``S_g`` by Algorithm 1.

    Parameters
    ----------
    W : (3p, 3p) symmetric positive (semi)definite Delassus operator: dense array, sparse
        matrix or ``LinearOperator`` (only products ``W x`` are used). For a slightly
        nonsymmetric ``W`` (as in some FCLIB files) the same iteration is applied to the
        variational inequality ``-(W r + q) ∈ N_{S_g}(r)``; the CG steps then lose their
        minimisation property and convergence is not guaranteed.
    q : (3p,) linear term, per contact (normal, tangent1, tangent2).
    g : slip bounds, scalar or (p,), non-negative (``g = 0`` gives frictionless contact).
    r0 : starting point (projected onto ``S_g``); zero if ``None``.
    tol : stop when ``||g~|| <= tol * max(||q||, tiny)`` (projected gradient, relative).
    max_iter : iteration limit (default ``max(1000, 20 * 3p)``).
    alpha_bar : fixed steplength ``a`` in ``(0, ||W||^{-1}]``; from ``norm_W`` (or a power
        iteration estimate of it) when ``None``.
    gamma : the constant ``Gamma~`` of the releasing criterion (5.2); 1 gives the best bound.
    raise_on_failure : raise :class:`ContactNotConverged` when ``max_iter`` is reached.
    """
    matvec = as_matvec(W)
    q = np.asarray(q, dtype=float)
    n = q.size
    if n % 3:
        raise ProblemDataError(f"q must have length 3p, got {n}")
    p = n // 3
    g = np.array(np.broadcast_to(np.asarray(g, dtype=float), (p,)))
    if not np.all(np.isfinite(g)) or np.any(g < 0):
        raise ProblemDataError("slip bounds g must be finite and non-negative")
    if max_iter is None:
        max_iter = max(1000, 20 * n)
    if alpha_bar is None:
        if norm_W is None:
            norm_W = estimate_norm(W, n)
        if norm_W <= 0:
            raise ProblemDataError("W is zero or not positive semidefinite")
        alpha_bar = 1.0 / norm_W
    ab = float(alpha_bar)

    x = project_tresca_set(np.zeros(n) if r0 is None else np.asarray(r0, dtype=float), g)
    G = matvec(x) + q
    nmv = 1
    scale = max(float(np.linalg.norm(q)), np.finfo(float).tiny)
    X = x.reshape(p, 3)
    history: list[float] = []
    steps = {"cg": 0, "expansion": 0, "proportioning": 0}
    restart = True
    pdir = None
    Wp = None
    converged = False
    exact = True          # G was computed as W x + q (not by the CG recurrence)
    n_cg_run = 0
    res = np.inf
    while len(history) < max_iter:
        free_n = X[:, 0] > 0
        free_t = np.hypot(X[:, 1], X[:, 2]) < (1.0 - _ACTIVE_RTOL) * g
        mask = np.column_stack((free_n, free_t, free_t)).reshape(-1)
        y = project_tresca_set(x - ab * G, g)
        gt = (x - y) / ab                       # projected gradient g~
        res = float(np.linalg.norm(gt)) / scale
        if not np.isfinite(res):
            history.append(res)
            raise ContactNotConverged("Tresca solver produced non-finite values", history)
        if res <= tol and not exact:
            # The recurrence G <- G - a W p drifts; confirm with the true gradient.
            G = matvec(x) + q
            nmv += 1
            exact = True
            continue
        history.append(res)
        if res <= tol:
            converged = True
            break
        exact = False
        # phi~^T g and beta~^T g of (5.2). For a convex set v~^T g >= ||v~||^2, and near the
        # solution the dot product of the disc components cancels to rounding noise (v~ is
        # almost orthogonal to g there): the max keeps (5.2) exact and makes it robust.
        phi_t = np.where(mask, gt, 0.0)
        beta_t = gt - phi_t
        phi_g = max(float(phi_t @ G), float(phi_t @ phi_t))
        beta_g = max(float(beta_t @ G), float(beta_t @ beta_t))
        if beta_g <= gamma * phi_g:
            if restart:
                pdir = np.where(mask, G, 0.0)
                restart = False
            Wp = matvec(pdir)
            nmv += 1
            pWp = float(pdir @ Wp)
            gp = float(G @ pdir)
            a_cg = gp / pWp if pWp > 0 else np.inf
            xn = x - a_cg * pdir if np.isfinite(a_cg) else None
            if xn is not None and _in_face_interior(xn.reshape(p, 3), g, free_n, free_t):
                x = xn
                X = x.reshape(p, 3)
                steps["cg"] += 1
                n_cg_run += 1
                if n_cg_run % _REFRESH == 0:
                    G = matvec(x) + q     # residual replacement: the recurrence drifts
                    nmv += 1
                    exact = True
                else:
                    G = G - a_cg * Wp
                phi = np.where(mask, G, 0.0)
                pdir = phi - (float(phi @ Wp) / pWp) * pdir
                continue
            # Expansion: longest feasible step along -p, then a projected step on the free set.
            a_f = _feasible_step(X, pdir.reshape(p, 3), g, free_n, free_t)
            if not np.isfinite(a_f):
                raise ContactNotConverged(
                    "Tresca problem is unbounded below (W singular along a feasible ray)",
                    history)
            a_f = min(a_f, a_cg)
            x = x - a_f * pdir
            G = G - a_f * Wp
            y = project_tresca_set(x - ab * G, g)
            x = np.where(mask, y, x)
            steps["expansion"] += 1
        else:
            x = np.where(mask, x, y)           # proportioning: r - a beta~
            steps["proportioning"] += 1
        X = x.reshape(p, 3)
        G = matvec(x) + q
        nmv += 1
        restart = True
        exact = True
        n_cg_run = 0
    if not exact:
        G = matvec(x) + q
        nmv += 1
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(G))):
        raise ContactNotConverged("Tresca solver produced non-finite values", history)
    out = TrescaResult(r=x, u=G, iterations=len(history) - (1 if converged else 0),
                       residual=res, converged=converged, history=history, matvecs=nmv,
                       steps=steps, alpha_bar=ab)
    if not converged:
        msg = (f"Tresca (Algorithm 1) not converged: projected gradient {res:.3e} > tol "
               f"{tol:.1e} after {max_iter} iterations")
        if raise_on_failure:
            raise ContactNotConverged(msg, history)
        log.debug(msg)
    return out


def _in_face_interior(X, g, free_n, free_t) -> bool:
    """Whether the CG iterate keeps every free constraint strictly inactive."""
    if np.any(X[free_n, 0] <= 0):
        return False
    if np.any(np.hypot(X[free_t, 1], X[free_t, 2]) >= g[free_t]):
        return False
    return True
