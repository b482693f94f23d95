"""Nonlinear, nonsmooth inequality constraints c_i(x) ≤ 0 for the bundle-trust method.

The exact penalty (the ℓ∞ form, as in the minimax problems of Lukšan & Vlček, which are such
penalties of Hock–Schittkowski problems)

    φ_σ(x) = f(x) + σ max(0, c_1(x), …, c_m(x))

has, for σ above the sum Σ_i μ_i of the Lagrange multipliers of a local solution x* of
min f s.t. c ≤ 0 (x* regular), x* as a local minimiser. φ_σ is locally Lipschitz like f and the
c_i, so :func:`~contactopt.optimize.minimize_bundle` minimises it over the polyhedron U as it
minimises f; a subgradient is ``g + σ ∇c_k`` with k the first largest c_k where it is positive,
else g (a Clarke subgradient where the max is attained once). The sum Σ max(0, c_i) is exact
for σ > max μ_i but has a kink per constraint: on Wong 3 (seven constraints active) the bundle
method stalled 3e-5 above f* with it, and reaches 3e-8 with the max.

The weight σ is the method's, not the user's: it starts from a multiplier estimate at x0 (twice
Σ_i μ_i of the non-negative least-squares μ of ``g + Jᵀμ = 0``, or ``‖g‖/max_i ‖∇c_i‖`` where
that is 0), and whenever a bundle run ends at a point that violates a constraint by more
than ``ctol``, σ is multiplied by ``sigma_factor`` and the bundle method restarts from that
point (one *outer* iteration). An infeasible x0 is allowed (it must lie in U; the bundle method
projects it otherwise). The returned x satisfies ``c_i(x) ≤ ctol_i`` for every i when
``success`` holds; ``constraints`` gives c(x).

Resuming: :class:`~contactopt.optimize.constrained.PenaltyState` holds σ, the outer iteration, the counts and history of the
finished bundle runs and the oracle's answer at the current iterate; with the bundle's own
:class:`~contactopt.optimize.BundleState` it makes a run continue bit for bit.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import nnls

from ..errors import OptimizerError
from ._bundle_control import relative_decrease
from ._scaling import variable_scaling
from .bundle import BundleResult, minimize_bundle

logger = logging.getLogger(__name__)

_HISTORY_KEYS = ("iteration", "f", "serious", "t", "stationarity", "nfev")


@dataclass
class PenaltyState:
    """Where the penalty method stands: ``sigma`` the weight, ``outer`` the number of times it
    was raised, ``nit``/``nfev``/``n_serious``/``n_null``/``history`` those of the finished
    bundle runs (history iterations counted from the start), ``at_x`` the oracle's answer
    (f, g, c, J) at the present iterate of the bundle run, ``finished`` (status, message,
    criterion) when that run had stopped (its state then resumes into the next outer step)."""

    sigma: float
    outer: int = 0
    nit: int = 0
    nfev: int = 0
    n_serious: int = 0
    n_null: int = 0
    history: list = field(default_factory=list)
    at_x: tuple | None = None
    finished: tuple | None = None

    def copy(self) -> "PenaltyState":
        at = None if self.at_x is None else tuple(np.array(v, dtype=float) for v in self.at_x)
        return PenaltyState(self.sigma, self.outer, self.nit, self.nfev, self.n_serious, self.n_null,
                            [dict(r) for r in self.history], at, self.finished)

    def to_dict(self) -> dict:
        """Plain arrays (a checkpoint stores them, :mod:`contactopt.io.checkpoint`)."""
        d = {"sigma": float(self.sigma), "counts": np.array([self.outer, self.nit, self.nfev, self.n_serious,
                                                             self.n_null], dtype=np.int64)}
        d["history"] = np.array([[r["iteration"], r["f"], r["step"] == "serious", r["t"], r["stationarity"],
                                  r["nfev"]] for r in self.history], dtype=float).reshape(-1, 6)
        if self.at_x is not None:
            f, g, c, J = self.at_x
            d.update(at_f=float(f), at_g=np.asarray(g, float), at_c=np.asarray(c, float), at_J=np.asarray(J, float))
        if self.finished is not None:
            d.update(finished_status=int(self.finished[0]), finished_message=str(self.finished[1]),
                     finished_criterion=str(self.finished[2] or ""))
        return d

    @classmethod
    def from_dict(cls, d) -> "PenaltyState":
        try:
            outer, nit, nfev, ns, nn = (int(v) for v in np.asarray(d["counts"]))
            hist = [{"iteration": int(r[0]), "f": float(r[1]), "step": "serious" if r[2] else "null",
                     "t": float(r[3]), "stationarity": float(r[4]), "nfev": int(r[5])}
                    for r in np.asarray(d["history"], float).reshape(-1, 6)]
            at = None
            if "at_f" in d:
                at = (float(np.asarray(d["at_f"])), np.array(d["at_g"], float), np.array(d["at_c"], float),
                      np.array(d["at_J"], float))
            fin = None
            if "finished_status" in d:
                fin = (int(np.asarray(d["finished_status"])), str(np.asarray(d["finished_message"])),
                       str(np.asarray(d["finished_criterion"])) or None)
            return cls(float(np.asarray(d["sigma"])), outer, nit, nfev, ns, nn, hist, at, fin)
        except (KeyError, TypeError, ValueError) as exc:
            raise OptimizerError(f"invalid penalty state: {exc}") from exc


def _call(oracle, x):
    out = oracle(x.copy())
    try:
        f, g, c, J = out
        g = np.array(g, dtype=float).reshape(-1)
        c = np.array(c, dtype=float).reshape(-1)
        J = np.array(J, dtype=float).reshape(c.size, g.size)
    except (TypeError, ValueError) as exc:
        raise OptimizerError("the constrained oracle must return (f, g, c, J) with J one subgradient "
                             f"of each c_i per row; got {type(out).__name__}") from exc
    return float(f), g, c, J


def penalty(f, g, c, J, sigma):
    """(φ_σ, one subgradient) from the oracle's answer: φ_σ = f + σ max(0, c_1, …, c_m), the
    subgradient of the first largest c_i where it is positive (module docstring)."""
    k = int(np.argmax(c)) if c.size else -1
    if k < 0 or not c[k] > 0:
        return f, g
    return f + sigma * float(c[k]), g + sigma * J[k]


def multiplier_estimate(g, J) -> float:
    """The σ a run starts from: twice the sum of the non-negative least-squares multipliers of
    ``g + Jᵀμ = 0``, or ‖g‖/max_i‖J_i‖ where that is 0 (a positive number in any case)."""
    mu = nnls(J.T, -g)[0] if J.size else np.zeros(0)
    top = float(mu.sum())
    if top > 0:
        return 2.0 * top
    rows = np.linalg.norm(J, axis=1) if J.size else np.zeros(0)
    gn = float(np.linalg.norm(g))
    return gn / float(rows.max()) if rows.size and rows.max() > 0 and gn > 0 else 1.0


def minimize_constrained(oracle, x0, *, ctol=1e-6, sigma0=None, sigma_factor=10.0, max_outer=10, eps=1e-7,
                         max_iter=1000, callback=None, state=None, bundle_state=None, **kwargs) -> BundleResult:
    """Minimise f over U ∩ {c(x) ≤ 0} by the exact penalty with an adapted weight (module docstring).

    Parameters
    ----------
    oracle : callable
        ``oracle(x) -> (f, g, c, J)``: f and one Clarke subgradient g, the constraint values c
        (m,) and one subgradient of each c_i in the rows of J (m, n).
    x0 : array (n,)
        Start, in U; it may violate c ≤ 0.
    ctol : float or array (m,)
        A run ends successfully only at a point with c_i ≤ ctol_i.
    sigma0 : float, optional
        First penalty weight; default :func:`~contactopt.optimize.constrained.multiplier_estimate` at x0.
    sigma_factor, max_outer :
        σ grows by this factor after a bundle run that ends infeasible, at most ``max_outer`` times.
    eps, max_iter, **kwargs :
        Of :func:`~contactopt.optimize.minimize_bundle` (linear constraints of U and options); ``max_iter`` counts the
        iterations of every bundle run together.
    callback : callable, optional
        ``callback(intermediate_result)`` after every iteration and when a bundle run ends
        before σ grows; the result carries ``penalty`` (a :class:`~contactopt.optimize.constrained.PenaltyState` without the
        bundle state, which is ``intermediate_result.state``). ``StopIteration`` stops.
    state, bundle_state : PenaltyState, BundleState, optional
        Resume from a checkpoint (``x0`` is then ignored).

    Returns
    -------
    BundleResult
        ``x``, ``fun`` (φ_σ at x), ``nit``/``nfev``/``history`` over all bundle runs, plus
        ``constraints`` (c(x)), ``objective`` (f(x)), ``sigma``, ``outer`` and ``penalty``;
        ``success`` only when the last bundle run succeeded and c(x) ≤ ctol.
    """
    if state is None:
        x0 = np.array(x0, dtype=float).reshape(-1)
        first = _call(oracle, x0)
        sigma = float(sigma0) if sigma0 is not None else multiplier_estimate(first[1], first[3])
        pen, start, bstate = PenaltyState(sigma, nfev=1, at_x=first), x0, None
    else:
        pen, bstate = state.copy(), bundle_state
        start = bstate.x
    # a bundle state is in the method's variables z = x/d (minimize_bundle's option scale)
    scaling = variable_scaling(np.asarray(start).size, kwargs.get("lb"), kwargs.get("ub"),
                               kwargs.get("scale", "bounds"))
    if state is not None and scaling is not None:
        start = scaling.outer(start)
    if not (math.isfinite(pen.sigma) and pen.sigma > 0):
        raise OptimizerError(f"penalty weight σ = {pen.sigma}: must be a positive number")
    ctol = np.broadcast_to(np.asarray(ctol, float), pen.at_x[2].shape)
    phi = _Penalty(oracle, pen, start)
    while True:
        fin = pen.finished
        if fin is not None and not (fin[0] == 1 and max_iter > pen.nit + bstate.nit):
            res = _bundle_result(bstate, *fin, kwargs.get("ftol_window", 5))   # resumed at a run's end
            res = res if scaling is None else scaling.result(res)
        else:
            res = minimize_bundle(phi, start, eps=eps, max_iter=max(max_iter - pen.nit, 0),
                                  callback=phi.callback(callback), state=bstate, **kwargs)
        viol = _ended(pen, phi, res, ctol)
        if viol <= 0 or res.status in (1, 2) or pen.outer >= max_outer:
            return _combined(res, pen, viol <= 0, max_outer)
        # infeasible: σ is below this point's multipliers
        if callback is not None:
            try:
                callback(phi.report(res, pen.finished))
            except StopIteration:
                res.status, res.message, res.criterion = 2, "stopped by the callback", "callback"
                return _combined(res, pen, False, max_outer)
        _absorb(pen, res)
        pen.sigma *= sigma_factor
        pen.outer += 1
        pen.finished = None
        start, bstate = res.x, None
        phi.keep(res.x)
        logger.info("a constraint is violated by %.3e beyond ctol: σ raised to %.3e, restart from there",
                    viol, pen.sigma)


class _Penalty:
    """φ_σ (σ of the :class:`PenaltyState` ``pen``) of the oracle's answers, which it keeps from
    one iteration's start on: the answer at the iterate x is then known without a call."""

    def __init__(self, oracle, pen: PenaltyState, start):
        self.oracle, self.pen = oracle, pen
        self.seen = {np.asarray(start, float).tobytes(): pen.at_x}   # answers since the last iteration

    def __call__(self, x):
        ans = self.seen.get(x.tobytes())
        if ans is None:
            ans = _call(self.oracle, x)
            self.seen[x.tobytes()] = ans
        return penalty(*ans, self.pen.sigma)

    def answer(self, x):
        """The oracle's answer at x if it was asked, else that of the last iterate."""
        return self.seen.get(x.tobytes(), self.pen.at_x)

    def keep(self, x) -> None:
        """Forget every answer but x's, the iterate's (only that one is needed later)."""
        self.seen.clear()
        self.seen[x.tobytes()] = self.pen.at_x

    def report(self, inter, finished=None):
        """``inter`` with ``penalty``: a copy of the penalty state at its x (user's variables)."""
        self.pen.at_x = self.answer(inter.x)
        p = self.pen.copy()
        p.finished = finished
        inter.penalty = p
        return inter

    def callback(self, callback):
        """The bundle run's callback: the penalty state into the result, then ``callback``."""
        def inner(inter):
            self.report(inter)
            self.keep(inter.x)
            if callback is not None:
                callback(inter)
        return inner


def _ended(pen: PenaltyState, phi: _Penalty, res, ctol) -> float:
    """Note a finished bundle run in ``pen``; the largest violation c_i − ctol_i at its end."""
    pen.at_x = phi.answer(res.x)
    pen.finished = (int(res.status), str(res.message), res.criterion)
    c = pen.at_x[2]
    logger.info("penalty run %d (σ = %.3e): %s; f = %.10g, largest c = %.3e", pen.outer, pen.sigma,
                res.message, pen.at_x[0], float(np.max(c, initial=-math.inf)))
    return float(np.max(c - ctol, initial=-math.inf))


def _absorb(pen: PenaltyState, res) -> None:
    """Add a finished bundle run's counts and history to the penalty state."""
    # a bundle run's first evaluation is the answer at its start, made before it (nfev − 1 new)
    for r in res.history:
        pen.history.append({**r, "iteration": r["iteration"] + pen.nit, "nfev": r["nfev"] + pen.nfev - 1})
    pen.nit += int(res.nit)
    pen.nfev += int(res.nfev) - 1
    pen.n_serious += int(res.n_serious)
    pen.n_null += int(res.n_null)


def _bundle_result(st, status, message, criterion, ftol_window) -> BundleResult:
    """The result of a bundle run that had ended in state ``st`` (as minimize_bundle returned it)."""
    s = st.copy()
    return BundleResult(x=s.x.copy(), fun=s.f, jac=s.xi.copy(), nit=s.nit, nfev=s.nfev, n_serious=s.n_serious,
                        n_null=s.n_null, success=status in (0, 4, 5), status=status, message=message,
                        criterion=criterion, stationarity=s.stationarity,
                        relative_decrease=relative_decrease(s.history, ftol_window),
                        predicted_decrease=s.predicted, gamma=s.gamma, t=s.t,
                        history=[dict(r) for r in s.history], state=s)


def _combined(res, pen: PenaltyState, feasible: bool, max_outer: int) -> BundleResult:
    """The result over every bundle run (counts, history), with c(x) and σ; ``penalty`` is the
    state before the last run's counts are added (what a checkpoint of the end holds)."""
    last = pen.copy()
    _absorb(pen, res)
    f, _, c, _ = last.at_x
    out = BundleResult(**dict(res))
    out.update(nit=pen.nit, nfev=pen.nfev, n_serious=pen.n_serious, n_null=pen.n_null,
               history=[dict(r) for r in pen.history], constraints=np.array(c), objective=float(f),
               sigma=pen.sigma, outer=pen.outer, penalty=last)
    top = float(np.max(c, initial=-math.inf))
    if res.status == 1:                  # the bundle run's count is of its own iterations
        out.message = f"max_iter reached ({pen.nit} iterations)"
        res = out
    if feasible:
        out.message = f"{res.message}; constraints met (largest c = {top:.2e}, σ = {pen.sigma:.3e})"
    else:
        out.success = False
        why = f"σ was raised {max_outer} times" if res.status not in (1, 2) else res.message
        out.message = f"infeasible: a constraint is violated, largest c = {top:.3e} ({why})"
        if res.status not in (1, 2):
            out.status, out.criterion = 6, "infeasible"
    return out
