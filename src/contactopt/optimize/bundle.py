"""Bundle-trust (BT) method for a nonsmooth, nonconvex f over a polyhedron U.

The method of H. Schramm and J. Zowe, *A version of the bundle idea for minimizing a
nonsmooth function: conceptual idea, convergence analysis, numerical results*, SIAM J. Optim.
2 (1992) 121–152 — the BT code used by Beremlijski et al. (2009, Sec. 5) to minimise Θ over
the admissible set U of designs — with the linear constraints of U put into the
direction-finding QP so that every iterate (and every trial point) lies in U.

Notation (current serious iterate x, bundle elements j):

* ``f_j``, ``g_j`` value and one Clarke subgradient at a trial point ``y_j``; an element is
  stored by its linearisation value at x, ``fhat_j = f_j + g_jᵀ(x − y_j)``, and a distance
  measure ``s_j ≥ ‖x − y_j‖`` (updated by the triangle inequality after serious steps, which
  also serves the aggregate element, as in Kiwiel's aggregation);
* the subgradient locality measure of Lemaréchal–Zowe / Schramm–Zowe, made safe for a
  nonconvex f: ``α_j = max(|f(x) − fhat_j|, γ s_j²)``;
* the BT QP with trust parameter t (solved by DAQP, see :mod:`._bundle_qp`)::

      min_d  max_j (g_jᵀd − α_j) + ‖d‖²/(2t)   subject to x + d ∈ U,

  with solution d, convex weights λ, model decrease ``v = Σλ_j (g_jᵀd − α_j) < 0``, aggregate
  subgradient ``ξ = Σλ_j g_j``, aggregate error ``α_p = Σλ_j α_j``, aggregate subgradient of
  f + indicator(U) ``p = −d/t = ξ + Cᵀμ`` (μ the multipliers of the constraints) and
  complementarity gap ``σ = μᵀ(b − Cx) ≥ 0`` of those multipliers at x;
* inner loop of BT on t (one *iteration* = one serious or one null step): the trial point
  ``y = x + d(t)`` gives a **serious step** when ``f(y) − f(x) ≤ m1·v`` and either the slope
  test ``g(y)ᵀd ≥ m2·v`` holds or t cannot grow (t = t_max, or the trial limit); when the
  slope test fails, t is enlarged and the QP re-solved (a later failure falls back to the
  last descent point, keeping the new cut).  Without descent the step is a **null step**
  when the new cut changes the model, ``g(y)ᵀd − α(x, y) ≥ m3·v``, and y is local,
  ``α(x, y) ≤ locality·|v|`` (or t has reached t_min); otherwise t is reduced and the QP
  re-solved.  t is carried to the next iteration;
* aggregation: when the bundle is full it keeps the aggregate element ``(ξ, Σλ fhat, Σλ s)``
  plus the most recent elements.

Stopping test (what ``eps`` means).  At the start of an iteration, with the current bundle,

    stationarity = max(‖p‖, α_p + σ) ≤ eps,

i.e. the aggregate subgradient of f + indicator(U) is shorter than eps and it is an
eps-subgradient at x: for every z ∈ U (exactly so for a convex f, approximately otherwise)
``f(z) ≥ f(x) − (α_p + σ) + pᵀ(z − x)``, hence ``f(x) − f(z) ≤ eps·(1 + ‖z − x‖)``.  ``eps`` is
thus an absolute tolerance in the units of f (and of f per unit of x); scale f when its values
are far from 1.  In double precision ``‖p‖`` cannot go much below ``sqrt(1e-16·|f|·curvature)``;
a run that cannot certify its eps stops as *stalled* (status 3) with its best point.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, fields

import numpy as np
from scipy.optimize import OptimizeResult

from ..errors import OptimizerError
from ._bundle_qp import DirectionQP, Polyhedron

__all__ = ["minimize_bundle", "BundleResult", "BundleState", "BTOptions"]

logger = logging.getLogger(__name__)

_STATE_VERSION = 1


class BundleResult(OptimizeResult):
    """Result of :func:`minimize_bundle` (a scipy ``OptimizeResult``).

    Attributes: ``x``, ``fun``, ``jac`` (last aggregate subgradient ξ), ``nit``, ``nfev``,
    ``n_serious``, ``n_null``, ``success``, ``status`` (0 converged, 1 max_iter, 2 stopped by
    the callback, 3 stalled; −1 in the callback's intermediate result), ``message``, ``stationarity``, ``t``, ``history`` (list of dicts
    with keys iteration, f, step ('serious'/'null'), t, stationarity, nfev) and ``state`` (the
    :class:`BundleState` from which a run resumes).
    """


@dataclass
class BTOptions:
    """Parameters of BT (passed as keyword ``**options`` of :func:`minimize_bundle`).

    m1: serious-step (descent) test f(y) − f(x) ≤ m1·v; m2 (> m1): slope test for enlarging t;
    m3: null-step test (the new cut must lift the model at d to at least m3·v);
    gamma: weight of ‖x − y‖² in the locality measure α (0 is exact for convex f);
    locality: a null step needs α(x, y) ≤ locality·|v|, else t is reduced (far trial point);
    t0: initial t (default max(1, ‖x0‖∞)/‖g(x0)‖, a first step of length max(1, ‖x0‖∞));
    t_min, t_max: bounds of t (default 1e-8·t0 and 1e4·t0);
    t_increase, t_decrease: factors for the inner loop (bisection once bracketed);
    max_bundle: bundle size including the aggregate (default min(n + 3, 40), at least 5);
    max_inner: trial points per iteration;
    stall_window: stop (status 3) when over this many iterations f fell by no more than its
    round-off and the stationarity measure did not halve (eps below the reachable precision);
    feas_tol: scaled feasibility tolerance of iterates.
    """

    m1: float = 0.01
    m2: float = 0.5
    m3: float = 0.5
    gamma: float = 1.0
    locality: float = 10.0
    t0: float | None = None
    t_min: float | None = None
    t_max: float | None = None
    t_increase: float = 4.0
    t_decrease: float = 0.25
    max_bundle: int | None = None
    max_inner: int = 10
    stall_window: int = 50
    feas_tol: float = 1e-9

    @classmethod
    def from_kwargs(cls, options: dict) -> "BTOptions":
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - names)
        if unknown:
            raise OptimizerError(f"unknown option(s) {', '.join(unknown)}; "
                                 f"known: {', '.join(sorted(names))}")
        o = cls(**options)
        problems = []
        if not 0 < o.m1 < o.m2 < 1:
            problems.append(f"need 0 < m1 < m2 < 1 (m1={o.m1}, m2={o.m2})")
        if not 0 < o.m3 < 1:
            problems.append(f"need 0 < m3 < 1 (m3={o.m3})")
        if not o.gamma >= 0:
            problems.append(f"need gamma >= 0 (gamma={o.gamma})")
        if not (o.t_increase > 1 and 0 < o.t_decrease < 1):
            problems.append("need t_increase > 1 and 0 < t_decrease < 1")
        if o.max_bundle is not None and o.max_bundle < 3:
            problems.append(f"need max_bundle >= 3 (max_bundle={o.max_bundle})")
        if o.max_inner < 1:
            problems.append("need max_inner >= 1")
        if o.stall_window < 2:
            problems.append("need stall_window >= 2")
        for name in ("t0", "t_min", "t_max"):
            val = getattr(o, name)
            if val is not None and not (np.isfinite(val) and val > 0):
                problems.append(f"{name} must be a positive number ({val})")
        if problems:
            raise OptimizerError("invalid options:\n" + "\n".join(f"  - {p}" for p in problems))
        return o


@dataclass
class BundleState:
    """Complete state of BT between two iterations; resuming from it is bit-identical.

    ``G``, ``fhat``, ``s``: subgradients, linearisation values at x and distance measures of
    the bundle elements (one row each); ``xi``/``stationarity``: last aggregate subgradient and
    stopping measure; ``t_min``, ``t_max`` the bounds of t fixed at the start.
    """

    x: np.ndarray
    f: float
    G: np.ndarray
    fhat: np.ndarray
    s: np.ndarray
    t: float
    t_min: float
    t_max: float
    xi: np.ndarray
    stationarity: float = math.inf
    nit: int = 0
    nfev: int = 0
    n_serious: int = 0
    n_null: int = 0
    n_stuck: int = 0
    history: list = field(default_factory=list)

    def copy(self) -> "BundleState":
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in ("x", "G", "fhat", "s", "xi"):
            kw[name] = np.array(kw[name], dtype=float)
        kw["history"] = [dict(r) for r in self.history]
        return BundleState(**kw)

    def to_dict(self) -> dict:
        """Plain dict of numpy arrays, floats and ints (for ``np.savez`` or JSON via lists)."""
        d = {"version": _STATE_VERSION}
        for name in ("x", "G", "fhat", "s", "xi"):
            d[name] = np.array(getattr(self, name), dtype=float)
        for name in ("f", "t", "t_min", "t_max", "stationarity"):
            d[name] = float(getattr(self, name))
        for name in ("nit", "nfev", "n_serious", "n_null", "n_stuck"):
            d[name] = int(getattr(self, name))
        h = self.history
        d["history_iteration"] = np.array([r["iteration"] for r in h], dtype=np.int64)
        d["history_f"] = np.array([r["f"] for r in h], dtype=float)
        d["history_serious"] = np.array([r["step"] == "serious" for r in h], dtype=np.int64)
        d["history_t"] = np.array([r["t"] for r in h], dtype=float)
        d["history_stationarity"] = np.array([r["stationarity"] for r in h], dtype=float)
        d["history_nfev"] = np.array([r["nfev"] for r in h], dtype=np.int64)
        return d

    @classmethod
    def from_dict(cls, d) -> "BundleState":
        """Inverse of :meth:`to_dict`; accepts lists (from JSON) or an ``np.load`` archive."""
        try:
            version = int(np.asarray(d["version"]))
            if version != _STATE_VERSION:
                raise OptimizerError(f"bundle state version {version} is not supported")
            arr = {k: np.array(d[k], dtype=float) for k in ("x", "G", "fhat", "s", "xi")}
            n = arr["x"].size
            arr["G"] = arr["G"].reshape(-1, n)
            hist = [
                {"iteration": int(i), "f": float(fv), "step": "serious" if int(sv) else "null",
                 "t": float(tv), "stationarity": float(wv), "nfev": int(ev)}
                for i, fv, sv, tv, wv, ev in zip(
                    *(np.atleast_1d(np.asarray(d["history_" + k]))
                      for k in ("iteration", "f", "serious", "t", "stationarity", "nfev")))
            ]
            st = cls(x=arr["x"], f=float(np.asarray(d["f"])), G=arr["G"], fhat=arr["fhat"],
                     s=arr["s"], t=float(np.asarray(d["t"])),
                     t_min=float(np.asarray(d["t_min"])), t_max=float(np.asarray(d["t_max"])),
                     xi=arr["xi"], stationarity=float(np.asarray(d["stationarity"])),
                     nit=int(np.asarray(d["nit"])), nfev=int(np.asarray(d["nfev"])),
                     n_serious=int(np.asarray(d["n_serious"])),
                     n_null=int(np.asarray(d["n_null"])),
                     n_stuck=int(np.asarray(d["n_stuck"])), history=hist)
        except (KeyError, TypeError, ValueError) as exc:
            raise OptimizerError(f"invalid bundle state: {exc}") from exc
        m = st.G.shape[0]
        if m == 0 or st.fhat.shape != (m,) or st.s.shape != (m,) or st.xi.shape != (n,):
            raise OptimizerError("invalid bundle state: inconsistent bundle arrays")
        return st


# ---------------------------------------------------------------------- helpers
def _evaluate(oracle, x, trial=False):
    """(f, g) from the oracle; at a trial point a non-finite answer returns None."""
    out = oracle(x.copy())
    try:
        f, g = out
        f = float(f)
        g = np.array(g, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise OptimizerError(f"the oracle must return (f, g); got {type(out).__name__}") from exc
    if g.shape != x.shape:
        raise OptimizerError(f"the oracle returned a subgradient of shape {g.shape}, "
                             f"expected {x.shape}")
    if not (math.isfinite(f) and np.all(np.isfinite(g))):
        if trial:
            logger.warning("the oracle returned a non-finite value (f = %s) at a trial point; "
                           "reducing the trust parameter", f)
            return None
        raise OptimizerError(f"the oracle returned a non-finite value (f = {f}) at a feasible "
                             f"point; |x|max = {np.max(np.abs(x)):.3e}")
    return f, g


def _alpha(st: BundleState, gamma: float) -> np.ndarray:
    """Subgradient locality measures α_j = max(|f(x) − fhat_j|, γ s_j²)."""
    return np.maximum(np.abs(st.f - st.fhat), gamma * st.s**2)


@dataclass
class _Step:
    kind: str                  # "serious", "null", "converged", "stalled"
    qp: DirectionQP            # QP of the step taken (aggregation uses its λ)
    t: float
    y: np.ndarray | None = None
    fy: float = 0.0
    gy: np.ndarray | None = None
    extra: list = field(default_factory=list)   # further (y, f, g) for the bundle
    stalled: bool = False      # null step whose cut was already in the bundle


def _trial_point(poly: Polyhedron, x, d, feas_tol):
    y = poly.clip(x + d)
    if poly.violation(y) > feas_tol:  # round-off of the QP: project back onto U
        y = poly.project(y)
        if poly.violation(y) > feas_tol:
            raise OptimizerError(f"trial point violates the constraints by "
                                 f"{poly.violation(y):.3e} after projection")
    return y


def _bt_iteration(oracle, poly: Polyhedron, st: BundleState, o: BTOptions, eps: float):
    """One BT iteration: inner loop on t ending in a serious or null step (or a stop)."""
    x, f = st.x, st.f
    alpha = _alpha(st, o.gamma)
    t = min(max(st.t, st.t_min), st.t_max)
    lo, hi = 0.0, math.inf          # bracket of t: descent at lo, failure at hi
    cand: _Step | None = None
    for trial in range(o.max_inner):
        qp = poly.direction(x, st.G, alpha, t)
        if trial == 0:
            alpha_p = float(qp.lam @ alpha)
            st.xi = qp.xi
            st.stationarity = max(float(np.linalg.norm(qp.p)), alpha_p + qp.sigma)
            if st.stationarity <= eps:
                return _Step("converged", qp, t)
            if -qp.v <= 4 * np.finfo(float).eps * max(1.0, abs(f)):
                return _Step("stalled", qp, t)
        y = _trial_point(poly, x, qp.d, o.feas_tol)
        out = _evaluate(oracle, y, trial=True)
        st.nfev += 1
        last = trial == o.max_inner - 1
        if out is None:                                 # f undefined at y: y is too far
            if cand is not None:
                return cand
            if t <= st.t_min or last:
                raise OptimizerError(f"the oracle returned non-finite values at every trial "
                                     f"point down to t = {t:.3e}")
            hi = t
            t = max(t * o.t_decrease, st.t_min)
            continue
        fy, gy = out
        d = y - x
        if fy - f <= o.m1 * qp.v:                       # descent: serious-step candidate
            cand = _Step("serious", qp, t, y, fy, gy)
            if gy @ d >= o.m2 * qp.v or t >= st.t_max or last:
                return cand
            lo = t                                      # steep slope: try a longer step
            t = math.sqrt(lo * hi) if hi < math.inf else t * o.t_increase
            t = min(t, st.t_max)
            continue
        if cand is not None:                            # longer step failed: take the last
            cand.extra.append((y, fy, gy))              # descent point, keep the new cut
            return cand
        alpha_y = max(abs(f - (fy - gy @ d)), o.gamma * float(d @ d))
        # a cut already in the bundle (same g, no smaller α) leaves the model unchanged
        same = np.all(st.G == gy, axis=1)
        duplicate = bool(np.any(same)) and alpha_y >= float(np.min(alpha[same]))
        informative = gy @ d - alpha_y >= o.m3 * qp.v and not duplicate
        local = alpha_y <= o.locality * -qp.v              # y close enough to x
        if (informative and local) or t <= st.t_min or last:
            return _Step("null", qp, t, y, fy, gy, stalled=duplicate)
        hi = t                                          # cut useless here: shrink the region
        t = max(t * o.t_decrease, st.t_min)
    raise AssertionError("unreachable")  # pragma: no cover


def _no_progress(history: list, window: int) -> bool:
    """True when the last ``window`` iterations neither decreased f beyond its round-off nor
    halved the best stationarity measure seen before them."""
    if len(history) <= window:
        return False
    f_then, f_now = history[-window - 1]["f"], history[-1]["f"]
    if f_then - f_now > 100 * np.finfo(float).eps * max(1.0, abs(f_now)):
        return False
    before = min(h["stationarity"] for h in history[:-window])
    recent = min(h["stationarity"] for h in history[-window:])
    return recent >= 0.5 * before


def _update_bundle(st: BundleState, step: _Step, max_bundle: int) -> None:
    """Serious or null step: move x (serious), aggregate, append the new elements."""
    lam = step.qp.lam
    agg = (lam @ st.G, float(lam @ st.fhat), float(lam @ st.s))
    G, fhat, s = st.G, st.fhat, st.s
    new = []
    if step.kind == "serious":
        dx = step.y - st.x
        shift, dist = G @ dx, float(np.linalg.norm(dx))
        fhat, s = fhat + shift, s + dist
        agg = (agg[0], agg[1] + float(agg[0] @ dx), agg[2] + dist)
        st.x, st.f = step.y.copy(), step.fy
        new.append((step.gy, step.fy, 0.0))
    else:
        d = step.y - st.x
        new.append((step.gy, step.fy - float(step.gy @ d), float(np.linalg.norm(d))))
    for y, fy, gy in step.extra:
        r = st.x - y
        new.append((gy, fy + float(gy @ r), float(np.linalg.norm(r))))
    m_old, k = G.shape[0], len(new)
    if m_old + k > max_bundle:                   # keep aggregate + most recent
        keep = max(max_bundle - 1 - k, 0)
        sl = slice(m_old - keep, m_old)
        G = np.vstack([agg[0][None, :], G[sl]])
        fhat = np.concatenate([[agg[1]], fhat[sl]])
        s = np.concatenate([[agg[2]], s[sl]])
    st.G = np.vstack([G] + [g[None, :] for g, _, _ in new])
    st.fhat = np.concatenate([fhat, [fh for _, fh, _ in new]])
    st.s = np.concatenate([s, [sv for _, _, sv in new]])
    st.t = step.t


def _initial_state(oracle, poly: Polyhedron, x0, o: BTOptions) -> BundleState:
    x0 = np.array(x0, dtype=float).reshape(-1)
    if not np.all(np.isfinite(x0)):
        raise OptimizerError("x0 contains inf or NaN")
    viol = poly.violation(x0)
    x = poly.clip(x0)
    if viol > o.feas_tol:
        x = poly.project(x0)
        logger.warning("x0 violates the constraints by %.3e; starting from its projection "
                       "onto the feasible set (moved by %.3e)", viol,
                       float(np.linalg.norm(x - x0)))
    f, g = _evaluate(oracle, x)
    gnorm = float(np.linalg.norm(g))
    scale = max(1.0, float(np.max(np.abs(x), initial=0.0)))
    t0 = o.t0 if o.t0 is not None else (scale / gnorm if gnorm > 0 else 1.0)
    t_min = o.t_min if o.t_min is not None else 1e-8 * t0
    t_max = o.t_max if o.t_max is not None else 1e4 * t0
    if not t_min <= t0 <= t_max:
        raise OptimizerError(f"need t_min <= t0 <= t_max ({t_min:g}, {t0:g}, {t_max:g})")
    return BundleState(x=x, f=f, G=g[None, :].copy(), fhat=np.array([f]), s=np.zeros(1),
                       t=t0, t_min=t_min, t_max=t_max, xi=g.copy(), nfev=1)


def _result(st: BundleState, status: int, message: str) -> BundleResult:
    return BundleResult(
        x=st.x.copy(), fun=st.f, jac=st.xi.copy(), nit=st.nit, nfev=st.nfev,
        n_serious=st.n_serious, n_null=st.n_null, success=status == 0, status=status,
        message=message, stationarity=st.stationarity, t=st.t,
        history=[dict(r) for r in st.history], state=st.copy())


# ---------------------------------------------------------------------- driver
def minimize_bundle(oracle, x0, *, lb=None, ub=None, A_ub=None, b_ub=None, A_eq=None,
                    b_eq=None, eps=1e-4, max_iter=1000, callback=None, state=None, **options):
    """Minimise a locally Lipschitz f over U = {lb ≤ x ≤ ub, A_ub x ≤ b_ub, A_eq x = b_eq}.

    Parameters
    ----------
    oracle : callable
        ``oracle(x) -> (f, g)`` with g one Clarke subgradient of f at x.  Called only at
        points of U (feasible to ``feas_tol``, bounds exactly).
    x0 : array (n,)
        Start; when infeasible it is replaced by its Euclidean projection onto U (logged).
    eps : float
        Stop when ``stationarity = max(‖p‖, α_p + σ) ≤ eps``: the aggregate subgradient of
        f + indicator(U) is shorter than eps and is an eps-subgradient at x, so that (for
        convex f) ``f(x) − f(z) ≤ eps·(1 + ‖z − x‖)`` for all z ∈ U.  Absolute, in the units
        of f; see the module docstring.
    max_iter : int
        Maximum number of iterations (serious + null steps), counted from the start of the
        run including iterations done before a restored ``state``.
    callback : callable, optional
        ``callback(intermediate_result)`` after every iteration; the argument is a
        :class:`BundleResult` with a ``state`` copy.  Raising ``StopIteration`` stops the run
        (``success`` False, status 2).
    state : BundleState, optional
        Resume from a saved state (``x0`` is then ignored); the iterates that follow are
        bit-identical to those of the uninterrupted run with the same options.
    **options
        Parameters of BT, see :class:`BTOptions`.

    Returns
    -------
    BundleResult

    Raises
    ------
    OptimizerError
        Empty feasible set, invalid input, a failed QP subproblem or a non-finite oracle value.
    """
    o = BTOptions.from_kwargs(options)
    if state is not None:
        st = state.copy()
        n = st.x.size
    else:
        n = np.asarray(x0).size
    poly = Polyhedron(n, lb, ub, A_ub, b_ub, A_eq, b_eq)
    if state is None:
        st = _initial_state(oracle, poly, x0, o)
    elif poly.violation(st.x) > o.feas_tol:
        raise OptimizerError("the restored state's x violates the constraints")
    max_bundle = o.max_bundle if o.max_bundle is not None else max(5, min(n + 3, 40))
    logger.info("BT start: n=%d f=%.10g eps=%.1e t=%.3e bundle<=%d (iteration %d)",
                n, st.f, eps, st.t, max_bundle, st.nit)
    while True:
        if st.nit >= max_iter:
            status, message = 1, f"max_iter reached ({max_iter} iterations)"
            break
        step = _bt_iteration(oracle, poly, st, o, eps)
        if step.kind == "converged":
            status = 0
            rel = "<" if st.stationarity < eps else "<="
            message = f"converged: stationarity {st.stationarity:.1e} {rel} eps {eps:.0e}"
            break
        if step.kind == "stalled":
            status = 3
            message = (f"stalled: predicted decrease {-step.qp.v:.2e} is at the round-off of f "
                       f"(stationarity {st.stationarity:.2e} > eps {eps:.0e})")
            break
        _update_bundle(st, step, max_bundle)
        st.n_stuck = st.n_stuck + 1 if step.stalled else 0
        st.nit += 1
        if step.kind == "serious":
            st.n_serious += 1
        else:
            st.n_null += 1
        st.history.append({"iteration": st.nit, "f": st.f, "step": step.kind, "t": st.t,
                           "stationarity": st.stationarity, "nfev": st.nfev})
        logger.debug("it %d %s f=%.10g t=%.3e stat=%.3e nfev=%d", st.nit, step.kind, st.f,
                     st.t, st.stationarity, st.nfev)
        if callback is not None:
            try:
                callback(_result(st, -1, f"iteration {st.nit}"))
            except StopIteration:
                status, message = 2, f"stopped by the callback after iteration {st.nit}"
                break
        if st.n_stuck >= 3:
            status = 3
            message = (f"stalled: {st.n_stuck} null steps in a row returned cuts already in the "
                       f"bundle (the QP resolution is reached; stationarity "
                       f"{st.stationarity:.2e} > eps {eps:.0e})")
            break
        if _no_progress(st.history, o.stall_window):
            status = 3
            message = (f"stalled: no progress in the last {o.stall_window} iterations (f at its "
                       f"round-off; stationarity {st.stationarity:.2e} > eps {eps:.0e})")
            break
    logger.info("BT end: %s; f=%.10g nit=%d nfev=%d", message, st.f, st.nit, st.nfev)
    return _result(st, status, message)
