"""Semismooth Newton method for the local Coulomb problem (Alart–Curnier), with a PROX fallback.

Convention of :mod:`contactopt.contact.local`: ``u = W r + q``, per contact (normal, t1, t2).

Formulation. Per contact, with a scalar ``rho_i > 0``, ``x_N = r_N - rho u_N`` and
``x_T = r_T - rho u_T``, the Alart–Curnier function is

    Phi_N = r_N - max(0, x_N),      Phi_T = r_T - P_{D(mu max(0, x_N))}(x_T),

where ``P_D(s)`` projects onto the disc of radius ``s``; ``Phi(r) = 0`` exactly at solutions.
Why this map rather than the natural map or Fischer–Burmeister of the SOCCP: it is piecewise
smooth with three closed-form pieces per contact, and on each piece the Newton rows are cheap
and well structured: *separated* contacts (``x_N <= 0``) give ``Phi = r``, identity rows, so
their unknowns decouple (``dr_i = -r_i``) and each step solves a dense system on the contacts
in contact only; *sticking* contacts give ``Phi = rho u``, i.e. plain rows of ``W`` (no
nonsmooth ``||u_T||`` at the solution, unlike the natural map, whose sticking rows carry the
kink of ``mu ||u_T||`` exactly where the solution sits); *sliding* contacts give rows that mix
one normal and two tangential rows of ``W`` with a rank-one correction. It is also the map of
Siconos' NSN_AC solver.

Newton step. With ``dPhi = A dr + B du`` (3x3 blocks per contact) and ``du = W dr``, the step
solves ``(A + B W) d = -Phi``. Separated contacts are eliminated (``d_i = -r_i``); on a sliding
contact the slip-direction row minus ``mu`` times the normal row is local and gives that
component of ``d`` explicitly, so the dense system left has 3 unknowns per sticking and 2 per
sliding contact (see ``_Solver.direction``); it is factorised by LAPACK ``getrf``.

Globalisation. Armijo backtracking on the merit ``1/2 ||Phi||^2`` (non-monotone over the last
few values). When plain Newton fails (line search exhausted, singular Jacobian — rigid-body
FCLIB problems have singular ``W`` — or stagnation), the solver switches to the proximal point
method of Siconos' PROX: round ``k`` solves, by the same Newton iteration, the problem with
``W + alpha_k I`` and ``q - alpha_k r_k`` (same solution set at convergence, a nonsingular
Jacobian for ``alpha_k > 0``), with ``alpha_k = sigma * error_k * mean(diag W)`` shrinking as the
error falls and growing tenfold after a failed round, up to ``1e8 mean(diag W)`` (the rounds stop
there: they would no longer move ``r``).

Inexact W. Given the exact product ``v -> W v`` separately (``product``), ``W`` itself need only
approximate the Delassus operator: the Newton matrices come from it, everything else from the
exact product, and the factorization may be kept over steps with unchanged contact and slip sets
(``chord``). The state solves of an optimization use this with the block of an earlier design.
"""

from __future__ import annotations

import copy
import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ContactNotConverged, ProblemDataError
from ..fem.dense import LUFactor
from .cones import siconos_error
from .result import LocalResult, check_problem

__all__ = ["solve_newton", "alart_curnier"]

log = logging.getLogger(__name__)

_PREDICTOR_TOL = 1e-6    # Siconos error at which the frictionless predictor stops
_PREDICTOR_STEPS = 20    # and its step budget
_RCOND_MIN = 1e-13       # reciprocal condition below which a Newton matrix counts as singular
_PIVOT_SCREEN = 1e-8     # LU pivot ratio above which the condition estimate is skipped
_CHORD_RATE = 0.2        # a reused factorization must cut the error by this factor per step
_ALPHA_MAX = 1e8        # proximal alpha_k at most this times mean(diag W): beyond it a round
                         # hardly moves r (and a float32 Newton matrix would overflow)
_FAST = 1e-3             # a fresh step that cut the error by more than 1/_FAST: W is nearly
                         # exact, Newton nearly quadratic, so the next step refactorizes too
_REASONS = {
    "max": "Newton step limit of the phase reached",
    "budget": "max_iter Newton steps used",
    "singular": "singular Newton matrix (W singular? use proximal='auto' or 'always')",
    "linesearch": "line search found no decrease of the merit 1/2 ||Phi||^2",
    "stagnation": "no progress over 10 Newton steps",
    "inner": "proximal round converged, outer tolerance not reached",
    "alpha": "proximal parameter reached its bound (1e8 mean(diag W)) without progress",
}


@dataclass
class _Piece:
    """Which smooth piece of Phi each contact is on, and the data of its Jacobian."""

    active: np.ndarray   # (p,) x_N > 0: in contact
    slip: np.ndarray     # (p,) ||x_T|| > mu x_N, or a zero disc (mu x_N = 0)
    nvec: np.ndarray     # (p, 2) x_T / ||x_T|| (0 where x_T = 0)
    c: np.ndarray        # (p,) mu max(0, x_N) / ||x_T|| on sliding contacts, else 0


def alart_curnier(r, u, mu, rho):
    """Alart–Curnier function ``Phi(r)`` (stacked (N, T1, T2)) and its smooth piece."""
    R = r.reshape(-1, 3)
    U = u.reshape(-1, 3)
    xn = R[:, 0] - rho * U[:, 0]
    xt = R[:, 1:] - rho[:, None] * U[:, 1:]
    pn = np.maximum(xn, 0.0)
    rad = mu * pn
    nxt = np.hypot(xt[:, 0], xt[:, 1])
    slip = (nxt > rad) | (rad <= 0.0)
    safe = np.where(nxt > 0, nxt, 1.0)
    nvec = xt / safe[:, None]
    c = np.where(slip, rad / safe, 0.0)
    Phi = np.empty_like(R)
    Phi[:, 0] = R[:, 0] - pn
    Phi[:, 1:] = np.where(slip[:, None], R[:, 1:] - c[:, None] * xt, R[:, 1:] - xt)
    return Phi.reshape(-1), _Piece(active=xn > 0, slip=slip, nvec=nvec, c=c)


class _Solver:
    """Holds the dense problem and the counters shared by the plain and proximal phases."""

    def __init__(self, W, q, mu, tol, rho_scale=1.0, product=None, chord=None):
        self.rho_scale = rho_scale
        self.W = W                  # the matrix of the Newton steps (exact or approximate W)
        self.apply = product if product is not None else W.dot   # the exact product v -> W v
        # with an inexact W the steps are inexact anyway: the factorization is then kept while
        # the pieces of Phi (contact, slip sets) stay the same (see direction)
        self.freeze = (product is not None) if chord is None else bool(chord)
        self._frozen = None         # (pieces key, LU) of the last factorization
        self.last_frozen = False    # whether the last direction reused it
        self.q = q
        self.mu = mu
        self.tol = tol
        self.n = q.size
        self.p = q.size // 3
        idx = np.arange(self.p)
        diag_blocks = W.reshape(self.p, 3, self.p, 3)[idx, :, idx, :]      # (p, 3, 3)
        self.wdiag = np.trace(diag_blocks, axis1=1, axis2=2).astype(np.float64) / 3.0
        self._wnorm_inf = None
        self.mu_max = float(mu.max(initial=0.0))
        self.wscale = float(np.mean(np.abs(self.wdiag))) or 1.0
        self.history: list[float] = []
        self.best = (np.inf, None, None)
        self.counts = {"factorizations": 0, "reused_factorizations": 0, "line_search_evals": 0,
                       "singular": 0, "line_search_failures": 0}
        self.active_trace: list[tuple[int, int]] = []

    @property
    def wnorm_inf(self) -> float:
        """||W||_inf, computed on first use (only a Newton matrix with bad pivots needs it).

        ||M||_inf of every Newton matrix is within a small factor of this bound; dgecon only
        needs the order of magnitude to flag singular matrices."""
        if self._wnorm_inf is None:
            self._wnorm_inf = float(np.abs(self.W).sum(axis=1).max())
        return self._wnorm_inf

    def frictionless(self, tol):
        """The same problem with ``mu = 0`` (shares W and its derived quantities)."""
        other = copy.copy(self)
        other.mu = np.zeros_like(self.mu)
        other.mu_max = 0.0
        other.tol = tol
        other.history = []
        other.best = (np.inf, None, None)
        other.counts = dict.fromkeys(self.counts, 0)
        other.active_trace = []
        return other

    def rho(self, alpha):
        d = self.wdiag + alpha
        return self.rho_scale / np.where(d > 0, d, self.wscale + alpha)

    # -- one Newton direction ------------------------------------------------------------
    def direction(self, r, Phi, piece, rho, alpha, fresh=False):
        """Solve ``(A + B (W + alpha I)) d = -Phi``; return ``d`` or ``None`` if singular.

        With ``freeze`` (W inexact) and unless ``fresh``, the LU factorization of the previous
        direction is reused when the contact and slip sets are unchanged: only the slip
        directions and ``c`` in the matrix are then those of the earlier iterate (a chord step).

        Rows scaled by ``1/rho``, ``f = -Phi/rho``, ``W_a = W + alpha I``:

        * separated contacts: ``d_i = -r_i``;
        * sticking contacts: ``(W_a d)_i = f_i``;
        * sliding contacts, in the frame (e_N, n, t) with ``t`` orthogonal to the slip
          direction ``n``: ``(W_a d)_N = f_N``; ``c (W_a d)_t + (1 - c) d_t / rho = f_t``; and
          the ``n`` row, minus ``mu`` times the normal row, is local:
          ``d_n = mu d_N + rho (f_n - mu f_N)``.

        Eliminating ``d_n`` (and ``d_t`` when ``mu = 0``) leaves a dense system with 3 unknowns
        per sticking and 2 per sliding contact, factorised by LAPACK ``getrf``. Its unknowns are
        grouped as (plain: the three of each sticking contact and ``d_N`` of frictionless
        sliding ones | ``z_N`` | ``z_t`` of frictional sliding ones), so that the reduced
        matrix is built from whole rows of W and three column gathers, with no scatter.
        """
        W, mu = self.W, self.mu
        act = piece.active
        A = np.flatnonzero(act)
        k = A.size
        d = -Phi.copy()                       # separated contacts: Phi = r, so d = -r
        self.active_trace.append((int(k), int(np.count_nonzero(act & ~piece.slip))))
        if k == 0:
            return d
        ia = (3 * A[:, None] + np.arange(3)).ravel()
        f = -(Phi[ia] / np.repeat(rho[A], 3)).reshape(k, 3)
        slide = piece.slip[A]
        S = np.flatnonzero(slide)             # local indices of the sliding contacts
        gS = A[S]
        n = piece.nvec[gS]
        t = np.column_stack((-n[:, 1], n[:, 0]))
        c = piece.c[gS]
        muS, rhoS = mu[gS], rho[gS]
        fric = c > 0                          # mu = 0 on the others: their d_T is local
        f_n = np.einsum("ij,ij->i", n, f[S, 1:])
        f_t = np.einsum("ij,ij->i", t, f[S, 1:])
        e = np.zeros((k, 3))                  # the part of d_A fixed by the local equations
        e[S, 1:] = (rhoS * (f_n - muS * f[S, 0]))[:, None] * n
        e[S[~fric], 1:] += (rhoS * f_t)[~fric, None] * t[~fric]
        dfix = d.copy()
        dfix[ia] = e.ravel()
        v = ((W @ dfix.astype(W.dtype, copy=False))[ia].reshape(k, 3) + alpha * e) \
            if np.any(dfix) else np.zeros((k, 3))
        # unknown groups, as positions of W: plain (3 per sticking contact, N of frictionless
        # sliding ones), and per frictional sliding contact its N, T1, T2
        SF, SN = S[fric], S[~fric]
        stick = np.flatnonzero(~slide)
        plain = np.concatenate([(3 * A[stick, None] + np.arange(3)).ravel(), 3 * A[SN]])
        plain_loc = np.concatenate([(3 * stick[:, None] + np.arange(3)).ravel(), 3 * SN])
        gF = A[SF]
        iN, i1, i2 = 3 * gF, 3 * gF + 1, 3 * gF + 2
        nF, tF, cF, muF = n[fric], t[fric], c[fric], muS[fric]
        a, b = plain.size, plain.size + SF.size
        m = b + SF.size
        rhs = np.empty(m)
        rhs[:a] = (f - v).ravel()[plain_loc]
        rhs[a:b] = f[SF, 0] - v[SF, 0]
        rhs[b:] = f_t[fric] - cF * np.einsum("ij,ij->i", tF, v[SF, 1:])
        key = (alpha, act.tobytes(), piece.slip.tobytes())
        self.last_frozen = bool(self.freeze and not fresh and self._frozen is not None
                                and self._frozen[0] == key)
        if self.last_frozen:
            self.counts["reused_factorizations"] += 1
            return self._finish_direction(d, ia, e, plain_loc, a, b, SF, muF, nF, tF,
                                          self._frozen[1].solve(rhs))
        # rows: W rows of the plain and N unknowns, c (t . W_T) for the t rows
        # (in W's precision: a float32 W, approximate anyway, gives a single-precision LU)
        dt = W.dtype
        R = np.empty((m, W.shape[1]), dtype=dt)
        W.take(np.concatenate([plain, iN]), axis=0, out=R[:b])
        R[b:] = (cF * tF[:, 0]).astype(dt)[:, None] * W.take(i1, axis=0)
        R[b:] += (cF * tF[:, 1]).astype(dt)[:, None] * W.take(i2, axis=0)
        # columns: e_N + mu n for the z_N unknowns, t for the z_t unknowns
        M = np.empty((m, m), dtype=dt)
        R.take(plain, axis=1, out=M[:, :a]) if a else None
        C1, C2 = R.take(i1, axis=1), R.take(i2, axis=1)
        M[:, a:b] = R.take(iN, axis=1) + (muF * nF[:, 0]).astype(dt) * C1 + (muF * nF[:, 1]).astype(dt) * C2
        M[:, b:] = tF[:, 0].astype(dt) * C1 + tF[:, 1].astype(dt) * C2
        dval = (1.0 - cF) / rhoS[fric]
        diag = M.reshape(-1)[:: m + 1]
        diag[b:] += dval
        if alpha:                              # (W + alpha I) in the same frame
            diag[:b] += alpha
            diag[b:] += cF * alpha
        lu = LUFactor(M, sequential=True)   # small: one MKL thread (fem/dense.py)
        self.counts["factorizations"] += 1
        # dgecon costs about a quarter of the factorization: only when the pivots look bad
        if lu.info != 0 or (not lu.pivot_ratio() > _PIVOT_SCREEN
                            and not lu.rcond((1.0 + self.mu_max) * self.wnorm_inf + alpha
                                             + float(dval.max(initial=0.0))) > _RCOND_MIN):
            self.counts["singular"] += 1
            return None
        self._frozen = (key, lu) if self.freeze else None
        return self._finish_direction(d, ia, e, plain_loc, a, b, SF, muF, nF, tF, lu.solve(rhs))

    def _finish_direction(self, d, ia, e, plain_loc, a, b, SF, muF, nF, tF, z):
        if not np.all(np.isfinite(z)):
            self.counts["singular"] += 1
            return None
        dA = e.copy()                         # sliding: d_T = mu z_N n + z_t t + e_T
        dA.ravel()[plain_loc] = z[:a]
        zN, zt = z[a:b], z[b:]
        dA[SF, 0] = zN
        dA[SF, 1:] += (muF * zN)[:, None] * nF + zt[:, None] * tF
        # frictionless sliding: d_N solved (plain), d_T = e_T (local)
        d[ia] = dA.ravel()
        return d

    def _line_search(self, r, ua, theta, recent, d, rho, alpha):
        """Non-monotone Armijo backtracking on 1/2 ||Phi||^2; ``None`` if no step is found."""
        Wd = self.apply(d)
        Wad = Wd + alpha * d if alpha else Wd
        t = 1.0
        ref = max(recent[-4:])
        for _ in range(30):
            self.counts["line_search_evals"] += 1
            r_t = r + t * d
            ua_t = ua + t * Wad
            Phi_t, piece_t = alart_curnier(r_t, ua_t, self.mu, rho)
            theta_t = 0.5 * float(Phi_t @ Phi_t)
            if theta_t <= ref - 2e-4 * t * theta:
                return t, Wd, r_t, ua_t, Phi_t, piece_t, theta_t
            t *= 0.5
        return None

    # -- Newton iterations on the problem (W + alpha I, q - alpha rc) ----------------------
    def newton(self, r, alpha, rc, inner_tol, max_steps, budget):
        """Run Newton steps; return ``(r, status)`` with status in
        ``converged | inner | max | singular | linesearch | stagnation | budget``."""
        q, mu = self.q, self.mu
        rho = self.rho(alpha)
        u = self.apply(r) + q
        qa = q - alpha * rc if alpha else q
        ua = u + alpha * (r - rc) if alpha else u
        Phi, piece = alart_curnier(r, ua, mu, rho)
        theta = 0.5 * float(Phi @ Phi)
        recent = [theta]
        err_hist = []
        steps = 0
        fresh = False
        prev = siconos_error(r, u, q, mu) if self.freeze else np.inf
        while True:
            if steps >= max_steps:
                return r, "max"
            if len(self.history) >= budget:
                return r, "budget"
            d = self.direction(r, Phi, piece, rho, alpha, fresh=fresh)
            if d is None and self.last_frozen:
                d = self.direction(r, Phi, piece, rho, alpha, fresh=True)
            if d is None:
                return r, "singular"
            step = self._line_search(r, ua, theta, recent, d, rho, alpha)
            if step is None and self.last_frozen:    # the chord step failed: a fresh one
                d = self.direction(r, Phi, piece, rho, alpha, fresh=True)
                step = None if d is None else self._line_search(r, ua, theta, recent, d, rho, alpha)
            if step is None:
                self.counts["line_search_failures"] += 1
                return r, "linesearch"
            t, Wd, r_t, ua_t, Phi_t, piece_t, theta_t = step
            r, ua, Phi, piece, theta = r_t, ua_t, Phi_t, piece_t, theta_t
            u = u + t * Wd
            recent.append(theta)
            steps += 1
            if not (np.all(np.isfinite(r)) and np.all(np.isfinite(u))):
                raise ContactNotConverged("Newton produced non-finite values", self.history)
            err = siconos_error(r, u, q, mu)
            # refactorize next time after a chord step that gained less than a factor
            # _CHORD_RATE, and after a fresh step that gained more than 1/_FAST
            ratio = err / prev if prev > 0 else 0.0
            fresh = ratio > _CHORD_RATE if self.last_frozen else ratio < _FAST
            prev = err
            self.history.append(err)
            err_hist.append(err)
            if err < self.best[0]:
                self.best = (err, r.copy(), u.copy())
            log.debug("newton step %d (alpha %.2e): error %.3e, step %.3g, active %d",
                      len(self.history), alpha, err, t, self.active_trace[-1][0])
            if err <= self.tol:
                return r, "converged"
            if alpha and siconos_error(r, ua, qa, mu) <= inner_tol:
                return r, "inner"
            if len(err_hist) > 10 and err > 0.5 * err_hist[-11]:
                return r, "stagnation"


def solve_newton(W, q, mu, *, tol: float = 1e-8, max_iter: int = 200, r0=None,
                 proximal: str = "auto", plain_max_iter: int = 50, prox_sigma: float = 0.1,
                 prox_inner_max_iter: int = 25, rho_scale: float = 0.5,
                 predictor: str = "frictionless", raise_on_failure: bool = True,
                 product=None, chord: bool | None = None) -> LocalResult:
    """Semismooth Newton (Alart–Curnier) for ``u = W r + q``, ``K_mu ∋ r ⊥ u~ ∈ K_mu*``.

    Parameters
    ----------
    W : (3p, 3p) Delassus operator, dense or sparse (densified: the steps use dense LAPACK);
        need not be symmetric nor nonsingular.
    q, mu : see :func:`contactopt.contact.local.solve_local`.
    tol : target Siconos error.
    max_iter : total number of Newton steps (plain and proximal together).
    r0 : warm start (e.g. the solution for a nearby ``q``).
    proximal : ``"auto"`` (plain Newton, PROX fallback), ``"never"`` or ``"always"``.
    plain_max_iter : Newton steps of the plain phase before switching to PROX.
    prox_sigma : ``alpha_k = prox_sigma * error_k * mean(diag W)``.
    prox_inner_max_iter : Newton steps per proximal round.
    rho_scale : the Alart–Curnier parameter is ``rho_i = rho_scale / (tr(W_ii)/3 + alpha)``
        (``W_ii`` the diagonal 3x3 block of contact ``i``); 0.5 balanced the iteration counts
        of the elastic and the FCLIB problems (smaller values misclassify fewer contacts in
        the first steps of a cold start, larger ones suit the rigid-body problems).
    predictor : cold starts only (``r0`` None): ``"frictionless"`` first solves the problem
        with ``mu = 0`` (one unknown per contact in contact, so its Newton steps cost a small
        fraction of the Coulomb ones) to a loose tolerance and starts from its solution, which
        already has the contact set nearly right; ``"none"`` starts from ``r = 0``. A predictor
        that fails is ignored. Its steps are counted in ``stats["predictor_iterations"]``.
    raise_on_failure : raise :class:`ContactNotConverged` (with the error history) on failure.
    product : optional callable ``v -> W_exact v``. Then ``W`` need only approximate the
        Delassus operator (e.g. the one of a nearby design): the Newton matrices are built from
        ``W`` (an inexact Jacobian: the convergence becomes linear, at a rate of the order of
        ``||W - W_exact||`` relative), while ``u``, the line search and the stopping test use the
        exact product, so the result solves the exact problem to ``tol``.
    chord : keep a factorization while the contact and slip sets stay the same (chord steps,
        each a fraction of the cost of a factorization, converging linearly); by default when
        ``product`` is given, i.e. when the steps are inexact anyway. A chord step that gains
        less than a factor ``_CHORD_RATE``, and a fresh step that gains more than ``1/_FAST``
        (nearly quadratic: W nearly exact), are followed by a fresh factorization.
    """
    t0 = time.perf_counter()
    if isinstance(W, spla.LinearOperator):
        raise ProblemDataError("the Newton solver needs W as a matrix, not a LinearOperator")
    W, q, mu, r0 = check_problem(W, q, mu, r0=r0, single=product is not None)
    if proximal not in ("auto", "never", "always"):
        raise ProblemDataError(f"proximal must be 'auto', 'never' or 'always', got {proximal!r}")
    if predictor not in ("frictionless", "none"):
        raise ProblemDataError(f"predictor must be 'frictionless' or 'none', got {predictor!r}")
    if sp.issparse(W):
        W = W.toarray()
    W = np.ascontiguousarray(W)
    n_pred = 0
    if product is not None and not callable(product):
        raise ProblemDataError("product must be a callable v -> W v")
    S = _Solver(W, q, mu, tol, rho_scale, product, chord)
    if r0 is None and predictor == "frictionless" and S.mu_max > 0:
        pred = S.frictionless(max(tol, _PREDICTOR_TOL))
        pred.newton(np.zeros(q.size), 0.0, None, 0.0, _PREDICTOR_STEPS, _PREDICTOR_STEPS)
        n_pred = len(pred.history)
        if pred.best[1] is not None:          # the iterates are checked finite as they come
            r0 = pred.best[1]
    r = np.zeros(q.size) if r0 is None else r0.copy()
    u = S.apply(r) + q
    err0 = siconos_error(r, u, q, mu)
    S.best = (err0, r.copy(), u.copy())
    status = "converged" if err0 <= tol else ""
    phase = "plain"
    prox_rounds = 0
    alphas: list[float] = []
    if not status and proximal != "always":
        r, status = S.newton(r, 0.0, None, 0.0, min(plain_max_iter, max_iter), max_iter)
        if status != "converged":
            log.debug("plain Newton stopped (%s) after %d steps, error %.3e",
                      status, len(S.history), S.best[0])
    if status != "converged" and proximal != "never":
        phase = "proximal"
        err, r, _ = S.best
        alpha = prox_sigma * err * S.wscale
        while len(S.history) < max_iter and prox_rounds < max_iter:
            prox_rounds += 1
            alphas.append(alpha)
            rc = r.copy()
            inner_tol = max(0.1 * err, 0.1 * tol)
            r, status = S.newton(r, alpha, rc, inner_tol, prox_inner_max_iter, max_iter)
            if status == "converged":
                break
            err_new = siconos_error(r, S.apply(r) + q, q, mu)
            if status == "inner" and err_new < err:
                err = err_new
                alpha = prox_sigma * err * S.wscale
            elif status in ("max", "stagnation") and err_new < err:
                err = err_new              # progress, but the inner Newton struggled: keep alpha
            else:
                r = rc if err_new > err else r
                err = min(err, err_new)
                alpha *= 10.0
                if alpha > _ALPHA_MAX * S.wscale:
                    status = "alpha"
                    break
            log.debug("PROX round %d: status %s, error %.3e, next alpha %.2e",
                      prox_rounds, status, err, alpha)
    err, r, _ = S.best
    u = S.apply(r) + q          # the iteration updates u incrementally: report the exact one
    err = siconos_error(r, u, q, mu)
    converged = err <= tol
    elapsed = time.perf_counter() - t0
    n_steps = len(S.history)
    if converged:
        msg = f"converged: Siconos error {err:.3e} <= tol {tol:.1e} ({phase} Newton)"
    else:
        msg = (f"not converged: Siconos error {err:.3e} > tol {tol:.1e} after {n_steps} Newton "
               f"steps ({phase} phase; last stop: {_REASONS.get(status, status)})")
    result = LocalResult(
        r=r, u=u, iterations=n_steps, error=err, converged=converged, history=list(S.history),
        method="newton", time_s=elapsed, message=msg, outer_iterations=prox_rounds,
        inner_iterations=n_steps,
        stats={**S.counts, "phase": phase, "predictor_iterations": n_pred, "alphas": alphas, "last_status": status,
               "active_contacts": [a for a, _ in S.active_trace],
               "sticking_contacts": [s for _, s in S.active_trace]})
    if not converged and raise_on_failure:
        raise ContactNotConverged(msg, S.history)
    return result
