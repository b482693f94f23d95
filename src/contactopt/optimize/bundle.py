"""Proximal bundle-trust method for a nonsmooth, nonconvex f over a polyhedron U.

The method of H. Schramm and J. Zowe, *A version of the bundle idea for minimizing a
nonsmooth function: conceptual idea, convergence analysis, numerical results*, SIAM J. Optim.
2 (1992) 121–152 — the BT code used by Beremlijski et al. (2009, Sec. 5) to minimise Θ over
the admissible set U of designs — with the linear constraints of U put into the
direction-finding QP so that every iterate (and every trial point) lies in U.

At a serious iterate x the bundle holds cuts (``fhat_j``, ``g_j``, distance ``s_j``) with the
subgradient locality measures ``α_j = max(|f(x) − fhat_j|, γ s_j²)``; an iteration solves the
QP ``min_d max_j (g_jᵀd − α_j) + dᵀW d/(2t)`` subject to ``x + d ∈ U`` (:mod:`._bundle_qp`),
evaluates f at ``y = x + d`` (:func:`_evaluate`, the one place the loop calls the oracle) and
takes a serious step (descent ``f(y) − f(x) ≤ m1·v``) or a null step (the cut enriches the
model); the trust parameter t follows Kiwiel's proximity control and the metric W the serious
steps' curvature (:mod:`._bundle_control`). The stopping tests: certified stationarity
(status 0), the f-change and predicted-decrease tests (4), the round-off of f (5), stalled (3).

docs/bundle_method.md describes each ingredient, the options and the measurements behind their
defaults; docs/stopping.md the stopping tests on Lukšan & Vlček's collection
(:mod:`contactopt.optimize.gallery`) and on the paper's examples.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, fields

import numpy as np
from scipy.optimize import OptimizeResult

from ..errors import OptimizerError
from ._bundle_control import (
    direction,
    flat_serious_steps,
    is_curvature_pair,
    next_t,
    no_progress,
    relative_decrease,
    update_metric,
)
from ._bundle_qp import DirectionQP, Polyhedron
from ._scaling import SCALINGS, variable_scaling

__all__ = ["minimize_bundle", "BundleResult", "BundleState", "BTOptions"]

logger = logging.getLogger(__name__)

_METRICS = ("auto", "bfgs", "diagonal", "none")

_STATE_VERSION = 6


STATUS_MESSAGES = {
    0: "converged: the certified test max(‖p‖, α_p + σ) ≤ eps holds",
    1: "max_iter reached",
    2: "stopped by the callback",
    3: "stalled: the model predicts no decrease above the round-off of f",
    4: "converged: f changed by less than tolf (at a small stationarity measure), or the bundle "
       "model predicts a relative decrease of f below ftol",
    5: "converged: the bundle model, rebuilt at x, predicts no decrease above the round-off of f",
}
"""Meaning of ``BundleResult.status`` (``success`` is True for 0 and 4)."""

SUCCESS_STATUS = (0, 4, 5)


class BundleResult(OptimizeResult):
    """Result of :func:`~contactopt.optimize.minimize_bundle` (a scipy ``OptimizeResult``).

    Attributes: ``x``, ``fun``, ``jac`` (last aggregate subgradient ξ), ``nit``, ``nfev``,
    ``n_serious``, ``n_null``, ``success`` (status 0, 4 or 5), ``status`` (see
    :data:`~contactopt.optimize.bundle.STATUS_MESSAGES`: 0 converged by the certified test, 4 by the f-change test or the
    predicted decrease,
    5 by the round-off of f, 1 max_iter, 2 stopped by the callback, 3 stalled; −1 in the
    callback's intermediate result), ``message`` (names the criterion and its value),
    ``criterion`` ("stationarity", "f_change", "predicted_decrease", "roundoff", "max_iter",
    "callback", "stalled" or None),
    ``stationarity`` (the certified measure at x), ``relative_decrease`` (of f over the last
    ``ftol_window`` serious steps; inf before there are that many), ``t``, ``history`` (list
    of dicts with keys iteration, f, step ('serious'/'null'), t, stationarity, nfev) and
    ``state`` (the :class:`~contactopt.optimize.bundle.BundleState` from which a run resumes).
    """


@dataclass
class BTOptions:
    """Parameters of the method (keyword ``**options`` of :func:`~contactopt.optimize.minimize_bundle`).

    m1: serious-step (descent) test f(y) − f(x) ≤ m1·v; m2 (> m1): slope test g(y)ᵀd < m2·v
    for the line search beyond a serious step (or for enlarging t with ``extend``); m3:
    null-step test (the new cut must lift the model at d to at least m3·v);
    gamma: weight of ‖x − y‖² in the locality measure α (0 is exact for convex f); None
    (default): set by the run (docs/bundle_method.md) — gamma_t0/t (in the units of f per x², the
    weight of the proximal term times gamma_t0) or gamma_factor times the nonconvexity the
    present bundle shows, whichever is larger, and 0 for the cuts of an affine piece of f;
    locality: a null step needs α(x, y) ≤ ``locality·|v|``, else t is reduced (far trial point);
    t0: initial t (default max(1, ‖x0‖∞)/‖g(x0)‖, a first step of length max(1, ‖x0‖∞));
    t_min, t_max: bounds of t (default 1e-8·t0 and 1e4·t0);
    t_decrease: factor of t in the inner loop (far or useless trial point);
    t_increase: factor of t in the inner loop with ``extend`` (bisection once bracketed);
    extrapolation: largest multiple τ of a serious step's direction that the line search tries
    (τ doubles from 1 while the slope stays steep; 1 switches it off; docs/bundle_method.md);
    t_secant: after a serious step x → x⁺, t is at most the secant step sᵀs/sᵀ(p⁺ − p) of the
    aggregate subgradients (docs/bundle_method.md; off by default);
    extend: enlarge t within an iteration after a serious-step candidate with a steep slope
    (BT's inner loop; costs evaluations);
    adapt_t: Kiwiel's update of t between iterations (docs/bundle_method.md); m_r: decrease ratio
    above which a serious step counts as predicted by the model; t_factor: largest change of
    t per iteration; rise_patience: the null step (counted from the last serious step) at
    which a rise of f (ρ < 0) shrinks t;
    metric, metric_memory, metric_range: variable metric W of the proximal term dᵀWd/(2t) from
    the last metric_memory (20) serious steps, "none" (default, W = I), "auto" (BFGS while three
    quarters of the kept pairs show curvature, else W = I), "diagonal" or "bfgs" (a full matrix,
    the default of ``contactopt run``), its
    eigenvalues within [1/metric_range, metric_range] (docs/bundle_method.md); "none" (or False)
    gives ‖d‖²/(2t), True is "bfgs";
    max_bundle: bundle size including the aggregate (default n + 3, at least 5);
    max_inner: trial points per iteration;
    ftol, ftol_window: practical stop (status 4) when the model predicts a relative decrease
    below ftol after at least ftol_window serious steps (docs/bundle_method.md; ftol = 0, the
    default: off);
    tolf, tolf_steps: the f-change stop (status 4): f changed by at most ``tolf·max(1, |f|)`` in
    each of the last tolf_steps serious steps and the stationarity measure is at most
    sqrt(tolf) (docs/bundle_method.md; default 1e-8 and 2, in every run; tolf = 0: off);
    stall_window: stop (status 3) when over this many iterations (at least 2(n + 1), the null
    steps a polyhedral f may need at one x) f did not decrease and the stationarity measure did
    not halve (eps below the reachable precision);
    feas_tol: scaled feasibility tolerance of iterates;
    scale: the variables the method works in (``contactopt.optimize._scaling``): "bounds" (default) x = D z with
    D_ii the width ub_i − lb_i of each finite box relative to the geometric mean of those widths
    (as a power of two; D = I where the widths are equal or no box is finite, so such a run is
    bit for bit the unscaled one), "none" the user's variables.
    """

    m1: float = 0.01
    m2: float = 0.5
    m3: float = 0.5
    gamma: float | None = None
    gamma_t0: float = 0.0125
    gamma_factor: float = 2.0
    locality: float = 10.0
    t0: float | None = None
    t_min: float | None = None
    t_max: float | None = None
    t_increase: float = 4.0
    t_decrease: float = 0.25
    extend: bool = False
    extrapolation: float = 1.0
    t_secant: bool = False
    adapt_t: bool = True
    m_r: float = 0.5
    t_factor: float = 10.0
    rise_patience: int = 3
    metric: str | bool = "none"
    metric_memory: int = 20
    metric_range: float = 100.0
    max_bundle: int | None = None
    max_inner: int = 10
    ftol: float = 0.0
    ftol_window: int = 5
    tolf: float = 1e-8
    tolf_steps: int = 2
    stall_window: int = 50
    feas_tol: float = 1e-9
    scale: str = "bounds"

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
        if not o.m1 <= o.m_r < 1:
            problems.append(f"need m1 <= m_r < 1 (m1={o.m1}, m_r={o.m_r})")
        if o.gamma is not None and not o.gamma >= 0:
            problems.append(f"need gamma >= 0 or None (gamma={o.gamma})")
        if not (math.isfinite(o.gamma_t0) and o.gamma_t0 >= 0):
            problems.append(f"need gamma_t0 >= 0 (gamma_t0={o.gamma_t0})")
        if not o.gamma_factor >= 1:
            problems.append(f"need gamma_factor >= 1 (gamma_factor={o.gamma_factor})")
        if not (o.t_increase > 1 and 0 < o.t_decrease < 1):
            problems.append("need t_increase > 1 and 0 < t_decrease < 1")
        if not (isinstance(o.rise_patience, int) and o.rise_patience >= 1):
            problems.append(f"need an integer rise_patience >= 1 ({o.rise_patience!r})")
        if not (isinstance(o.extrapolation, (int, float)) and math.isfinite(o.extrapolation)
                and o.extrapolation >= 1):
            problems.append(f"need a finite extrapolation >= 1 ({o.extrapolation!r})")
        if not o.t_factor > 1:
            problems.append(f"need t_factor > 1 (t_factor={o.t_factor})")
        if not o.metric_range >= 1:
            problems.append(f"need metric_range >= 1 (metric_range={o.metric_range})")
        if not (isinstance(o.metric_memory, int) and o.metric_memory >= 1):
            problems.append(f"need an integer metric_memory >= 1 ({o.metric_memory!r})")
        for name in ("extend", "adapt_t", "t_secant"):
            if not isinstance(getattr(o, name), bool):
                problems.append(f"{name} must be True or False ({getattr(o, name)!r})")
        if isinstance(o.metric, bool):
            o.metric = "bfgs" if o.metric else "none"
        if o.metric not in _METRICS:
            problems.append(f"metric must be one of {', '.join(map(repr, _METRICS))} "
                            f"({o.metric!r})")
        if o.scale not in SCALINGS:
            problems.append(f"scale must be one of {', '.join(map(repr, SCALINGS))} "
                            f"({o.scale!r})")
        if o.max_bundle is not None and o.max_bundle < 3:
            problems.append(f"need max_bundle >= 3 (max_bundle={o.max_bundle})")
        if o.max_inner < 1:
            problems.append("need max_inner >= 1")
        if not (isinstance(o.ftol, (int, float)) and 0 <= o.ftol < 1):
            problems.append(f"need 0 <= ftol < 1 (ftol={o.ftol})")
        if not (isinstance(o.tolf, (int, float)) and 0 <= o.tolf < 1):
            problems.append(f"need 0 <= tolf < 1 (tolf={o.tolf})")
        if not (isinstance(o.tolf_steps, int) and o.tolf_steps >= 1):
            problems.append(f"need an integer tolf_steps >= 1 (tolf_steps={o.tolf_steps})")
        if not (isinstance(o.ftol_window, int) and o.ftol_window >= 1):
            problems.append(f"need an integer ftol_window >= 1 (ftol_window={o.ftol_window})")
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
    """Complete state of the method between two iterations; resuming from it is bit-identical.

    ``G``, ``fhat``, ``s``: subgradients, linearisation values at x and distance measures of
    the bundle elements (one row each, oldest first); ``xi``/``stationarity``: last aggregate
    subgradient and stopping measure; ``t_min``, ``t_max`` the bounds of t fixed at the start;
    ``i_t`` Kiwiel's counter of serious (> 0) or null (< 0) steps made at the current t,
    ``eps_v`` his estimate of the variation of f and ``null_run`` the number of null steps
    since the last serious step (used by the update of t); ``w`` the metric (a vector: diagonal;
    a matrix: full) and
    ``S``, ``Y`` the steps and subgradient changes it comes from (None before the first
    serious step).
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
    i_t: int = 0
    eps_v: float = math.inf
    null_run: int = 0
    gamma: float = 0.0                   # the run's weight of s² in α (option gamma None)
    gamma_floor: float = 0.0             # c of the floor c/t of the run's γ
    nonconvex: int = 0                   # 1 once a cut has shown that f is not convex
    verified: int = 0                    # 1 while the bundle holds only cuts made after a restart
    affine: np.ndarray | None = None     # subgradients seen at two points: affine pieces of f
    predicted: float = math.inf          # relative predicted decrease at the last iteration's start
    w: np.ndarray | None = None          # metric of the proximal term (None: I; 1-D: diagonal)
    S: np.ndarray | None = None          # recent serious steps x+ − x (rows)
    Y: np.ndarray | None = None          # and the changes of the subgradient at x
    smooth: np.ndarray | None = None     # 1 where that pair is a curvature pair (metric "auto")
    pending_s: np.ndarray | None = None  # last serious step, until the aggregate at its end is
    pending_p: np.ndarray | None = None  # known (t_secant), and the aggregate p at its start
    history: list = field(default_factory=list)

    def copy(self) -> "BundleState":
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in ("x", "G", "fhat", "s", "xi"):
            kw[name] = np.array(kw[name], dtype=float)
        for name in ("w", "S", "Y", "affine", "smooth", "pending_s", "pending_p"):
            if kw[name] is not None:
                kw[name] = np.array(kw[name], dtype=float)
        kw["history"] = [dict(r) for r in self.history]
        return BundleState(**kw)

    def to_dict(self) -> dict:
        """Plain dict of numpy arrays, floats and ints (for ``np.savez`` or JSON via lists)."""
        d = {"version": _STATE_VERSION}
        for name in ("x", "G", "fhat", "s", "xi"):
            d[name] = np.array(getattr(self, name), dtype=float)
        for name in ("f", "t", "t_min", "t_max", "stationarity", "eps_v", "gamma", "gamma_floor",
                     "predicted"):
            d[name] = float(getattr(self, name))
        for name in ("nit", "nfev", "n_serious", "n_null", "n_stuck", "i_t", "null_run",
                     "nonconvex", "verified"):
            d[name] = int(getattr(self, name))
        n = self.x.size
        d["w"] = np.ones(n) if self.w is None else np.array(self.w, dtype=float)
        d["w_identity"] = int(self.w is None)
        d["smooth"] = np.zeros(0) if self.smooth is None else np.array(self.smooth, dtype=float)
        for name in ("pending_s", "pending_p"):
            v = getattr(self, name)
            d[name] = np.zeros(0) if v is None else np.array(v, dtype=float)
        for name in ("S", "Y", "affine"):
            v = getattr(self, name)
            d[name] = np.zeros((0, n)) if v is None else np.array(v, dtype=float)
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
        """Inverse of :meth:`to_dict`; accepts lists (from JSON) or an ``np.load`` archive.

        A state of version 1 (before the update of t) resumes with ``i_t = 0``, ``eps_v = inf``,
        ``null_run = 0``.
        """
        try:
            version = int(np.asarray(d["version"]))
            if version not in (1, 2, 3, 4, 5, _STATE_VERSION):
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
            v2 = version >= 2
            extra = {}
            if version >= 3 and np.asarray(d["affine"]).size:
                extra["affine"] = np.array(d["affine"], dtype=float).reshape(-1, n)
            if v2 and "w" in d and np.asarray(d["S"]).size:
                w = np.array(d["w"], dtype=float)
                extra["w"] = w.reshape(n) if w.size == n else w.reshape(n, n)
                if version >= 5 and int(np.asarray(d["w_identity"])):
                    extra["w"] = None
                extra["S"] = np.array(d["S"], dtype=float).reshape(-1, n)
                extra["Y"] = np.array(d["Y"], dtype=float).reshape(-1, n)
            if version >= 5 and np.asarray(d["smooth"]).size:
                extra["smooth"] = np.array(d["smooth"], dtype=float).reshape(-1)
            if version >= 6 and np.asarray(d["pending_s"]).size:
                extra["pending_s"] = np.array(d["pending_s"], dtype=float).reshape(n)
                extra["pending_p"] = np.array(d["pending_p"], dtype=float).reshape(n)
            st = cls(**extra, x=arr["x"], f=float(np.asarray(d["f"])), G=arr["G"], fhat=arr["fhat"],
                     s=arr["s"], t=float(np.asarray(d["t"])),
                     t_min=float(np.asarray(d["t_min"])), t_max=float(np.asarray(d["t_max"])),
                     xi=arr["xi"], stationarity=float(np.asarray(d["stationarity"])),
                     nit=int(np.asarray(d["nit"])), nfev=int(np.asarray(d["nfev"])),
                     n_serious=int(np.asarray(d["n_serious"])),
                     n_null=int(np.asarray(d["n_null"])),
                     n_stuck=int(np.asarray(d["n_stuck"])),
                     i_t=int(np.asarray(d["i_t"])) if v2 else 0,
                     null_run=int(np.asarray(d["null_run"])) if v2 else 0,
                     eps_v=float(np.asarray(d["eps_v"])) if v2 else math.inf,
                     gamma=float(np.asarray(d["gamma"])) if version >= 3 else 0.0,
                     gamma_floor=float(np.asarray(d["gamma_floor"])) if version >= 4 else 0.0,
                     nonconvex=int(np.asarray(d["nonconvex"])) if version >= 4 else 0,
                     verified=int(np.asarray(d["verified"])) if version >= 4 else 0,
                     predicted=float(np.asarray(d["predicted"])) if version >= 3 else math.inf,
                     history=hist)
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


def _alpha(st: BundleState, gamma: float | None) -> np.ndarray:
    """Subgradient locality measures α_j = max(|f(x) − fhat_j|, γ s_j²); with the option
    ``gamma`` None, γ = ``st.gamma`` and 0 for the cuts of a known affine piece."""
    g2 = _gamma(st, gamma) * st.s**2
    if gamma is None and st.affine is not None:
        g2 = np.where(_on_affine_piece(st.G, st.affine), 0.0, g2)
    return np.maximum(np.abs(st.f - st.fhat), g2)


def _on_affine_piece(G, affine) -> np.ndarray:
    known = {row.tobytes() for row in affine}
    return np.array([row.tobytes() in known for row in G], dtype=bool)


def _note_affine(st: BundleState, g, limit: int) -> None:
    """A subgradient returned at a second point (bit for bit one already in the bundle) marks an
    affine piece of f: its linearisation is exact on the piece, at any distance."""
    if not np.any(np.all(st.G == g, axis=1)):
        return
    if st.affine is not None and np.any(np.all(st.affine == g, axis=1)):
        return
    rows = g[None, :] if st.affine is None else np.vstack([st.affine, g[None, :]])
    st.affine = rows[-limit:]


def _gamma(st: BundleState, gamma: float | None) -> float:
    if gamma is not None:
        return gamma
    return max(st.gamma, st.gamma_floor / st.t)


def _measure_gamma(st: BundleState, factor: float, y=None, fy=None, anew=False) -> bool:
    """Raise the measured γ where the cuts show that f is not convex; True if it rose.

    For a convex f every cut of the bundle lies below f everywhere: at x, e_j = f(x) − fhat_j ≥ 0,
    and at a trial point y, r_j = f(x) − f(y) + g_jᵀ(y − x) ≤ e_j.  A cut that violates either
    beyond round-off (a negative e_j, or r_j > α_j: the model overestimates f at y) needs
    α_j ≥ max(−e_j, r_j); γ becomes ``factor`` times the largest of those over s_j² seen so far.
    A convex f (every polyhedral test problem) keeps γ = 0 and the exact cutting-plane model."""
    e = st.f - st.fhat
    gs = np.linalg.norm(st.G, axis=1) * st.s
    need = -e
    noise = 1e-10 * (abs(st.f) + np.abs(st.fhat) + gs) + 1e-12 * max(1.0, abs(st.f))
    if y is not None:
        gd = st.G @ (y - st.x)
        r = st.f - fy + gd
        need = np.maximum(need, np.where(r > np.abs(e), r, -np.inf))
        noise = noise + 1e-10 * (abs(fy) + np.abs(gd))
    bad = (need > noise) & (st.s > 0)
    g_new = factor * float(np.max(need[bad] / st.s[bad] ** 2)) if np.any(bad) else 0.0
    if g_new > 0:
        st.nonconvex = 1
    if anew:                     # after a serious step: what the present bundle shows
        old, st.gamma = st.gamma, g_new
        return st.gamma > old
    if g_new <= st.gamma:
        return False
    st.gamma = g_new
    return True


@dataclass
class _Step:
    kind: str                  # "serious", "null", "converged", "roundoff", "restart"
    qp: DirectionQP            # QP of the step taken (aggregation uses its λ)
    t: float
    y: np.ndarray | None = None
    fy: float = 0.0
    gy: np.ndarray | None = None
    alpha_y: float = 0.0       # locality measure of the new cut at x (null step)
    extra: list = field(default_factory=list)   # further (y, f, g) for the bundle
    stalled: bool = False      # null step whose cut was already in the bundle


def _predicted_decrease(poly: Polyhedron, st: BundleState, qp: DirectionQP, alpha, t,
                        window: int) -> float:
    """−v/|f|: the relative decrease of f that the bundle model predicts for a step from x with
    the largest trust parameter of the last ``window`` serious steps (at least the current t; the
    QP is solved anew for it, so that a t cut down on a kink cannot fake a small prediction)."""
    v = qp.v
    t_ref = max([h["t"] for h in st.history if h["step"] == "serious"][-window:], default=t)
    if t_ref > t:
        v = direction(poly, st.x, st.G, alpha, t_ref, st.w).v
    scale = abs(st.f)
    return -v / scale if scale > 0 else (0.0 if v == 0 else math.inf)


def _trial_point(poly: Polyhedron, x, d, feas_tol):
    y = poly.clip(x + d)
    if poly.violation(y) > feas_tol:  # round-off of the QP: project back onto U
        y = poly.project(y)
        if poly.violation(y) > feas_tol:
            raise OptimizerError(f"trial point violates the constraints by "
                                 f"{poly.violation(y):.3e} after projection")
    return y


def _start_tests(poly: Polyhedron, st: BundleState, o: BTOptions, eps: float, qp: DirectionQP,
                 alpha, t: float) -> _Step | None:
    """The stopping tests at the start of an iteration, from the QP ``qp`` at x and no evaluation:
    a stop (or a restart) as a step, else None; sets ``st.xi``, ``st.stationarity`` and
    ``st.predicted``."""
    f = st.f
    alpha_p = float(qp.lam @ alpha)
    st.xi = qp.xi
    # relative to max(1, |f|): eps means the same for f and for 1000·f
    st.stationarity = (max(float(np.linalg.norm(qp.p)), alpha_p + qp.sigma)
                       / max(1.0, abs(f)))
    if st.stationarity <= eps:
        # f not convex: a certificate from cuts made far from x may be false; it is
        # accepted only from a bundle rebuilt at x (restart)
        if o.gamma is None and st.nonconvex and not st.verified and st.G.shape[0] > 1:
            return _Step("restart", qp, t)
        return _Step("converged", qp, t)
    if -qp.v <= 4 * np.finfo(float).eps * max(1.0, abs(f)):
        # the far cuts' locality terms may be what blocks the certificate: once, rebuild
        if o.gamma is None and st.nonconvex and not st.verified and st.G.shape[0] > 1:
            return _Step("restart", qp, t)
        return _Step("roundoff", qp, t)
    # f has stopped changing and the aggregate certifies x at sqrt(tolf): f alone also
    # stops changing on a crawl far from x* (measured: Maxquad, Steiner2, Wong3 1e-6 to
    # 1e-4 above f*; a guard relative to the measure at x0 let HS78 stop 2e-6 above f*
    # under one BLAS kernel)
    if (o.tolf > 0 and st.stationarity <= math.sqrt(o.tolf)
            and -qp.v <= o.tolf * max(1.0, abs(f))
            and flat_serious_steps(st.history, o.tolf_steps, o.tolf)):
        return _Step("fchange", qp, t)
    before, st.predicted = st.predicted, _predicted_decrease(poly, st, qp, alpha, t,
                                                             o.ftol_window)
    # at this x and at the last iteration's, and the run's own progress confirms it: the
    # prediction is local (a model that has not seen the next kink, or a t shrunk on
    # a kink, predicts little while a slow descent goes on — measured: a stop 2.6 %
    # above the optimum on one BLAS kernel, 0.6 % on another)
    if (o.ftol > 0 and max(st.predicted, before) <= o.ftol
            and st.n_serious >= o.ftol_window
            and st.history and st.history[-1]["step"] == "serious"
            and relative_decrease(st.history, o.ftol_window) <= o.ftol_window * o.ftol):
        return _Step("practical", qp, t)
    return None


def _last_iterate_stop(poly: Polyhedron, st: BundleState, o: BTOptions, eps: float, max_iter: int):
    """(state, stop) after ``max_iter`` iterations: the stop of the next iteration's start when its
    tests (no evaluation) end the run there, else max_iter with ``st`` untouched.

    A run capped at the iteration where the uncapped run stops ends as that run does, instead of
    reporting max_iter for an iterate that passes a stopping test; the tests run on a copy, so a
    run that does hit max_iter resumes (with a larger ``max_iter``) bit for bit as before.
    """
    probe = st.copy()
    alpha = _alpha(probe, o.gamma)
    if probe.pending_s is not None:
        _secant_cap(poly, probe, alpha, o.t_factor)
    t = min(max(probe.t, probe.t_min), probe.t_max)
    step = _start_tests(poly, probe, o, eps, direction(poly, probe.x, probe.G, alpha, t, probe.w), alpha, t)
    stop = _converged(step, probe, o, eps) if step is not None else None
    if stop is None:               # no test holds, or a certificate that needs a restart first
        return st, (1, "max_iter", f"max_iter reached ({max_iter} iterations)")   # measures: in the result
    return probe, stop


def _iteration(oracle, poly: Polyhedron, st: BundleState, o: BTOptions, eps: float):
    """One iteration: inner loop on t ending in a serious or null step (or a stop)."""
    x, f = st.x, st.f
    alpha = _alpha(st, o.gamma)
    if st.pending_s is not None:
        _secant_cap(poly, st, alpha, o.t_factor)
    t = min(max(st.t, st.t_min), st.t_max)
    lo, hi = 0.0, math.inf          # bracket of t: descent at lo, failure at hi
    cand: _Step | None = None
    for trial in range(o.max_inner):
        qp = direction(poly, x, st.G, alpha, t, st.w)
        if trial == 0:
            stop = _start_tests(poly, st, o, eps, qp, alpha, t)
            if stop is not None:
                return stop
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
        if o.gamma is None:
            _note_affine(st, gy, 4 * (x.size + 3))
            if _measure_gamma(st, o.gamma_factor, y, fy):
                alpha = _alpha(st, o.gamma)             # cuts that overestimate f at y
        if fy - f <= o.m1 * qp.v:                       # descent: serious-step candidate
            cand = _Step("serious", qp, t, y, fy, gy)
            if not o.extend and o.extrapolation > 1 and gy @ d < o.m2 * qp.v:
                _extrapolate(oracle, poly, st, o, cand, d, qp.v)
                return cand
            if not o.extend or gy @ d >= o.m2 * qp.v or t >= st.t_max or last:
                return cand
            lo = t                                      # steep slope: try a longer step
            t = math.sqrt(lo * hi) if hi < math.inf else t * o.t_increase
            t = min(t, st.t_max)
            continue
        if cand is not None:                            # longer step failed: take the last
            cand.extra.append((y, fy, gy))              # descent point, keep the new cut
            return cand
        alpha_y = max(abs(f - (fy - gy @ d)), _gamma(st, o.gamma) * float(d @ d))
        # a cut already in the bundle (same g, no smaller α) leaves the model unchanged
        same = np.all(st.G == gy, axis=1)
        duplicate = bool(np.any(same)) and alpha_y >= float(np.min(alpha[same]))
        informative = gy @ d - alpha_y >= o.m3 * qp.v and not duplicate
        local = alpha_y <= o.locality * -qp.v              # y close enough to x
        if (informative and local) or t <= st.t_min or last:
            return _Step("null", qp, t, y, fy, gy, alpha_y=alpha_y, stalled=duplicate)
        hi = t                                          # cut useless here: shrink the region
        t = max(t * o.t_decrease, st.t_min)
    raise AssertionError("unreachable")  # pragma: no cover


def _secant_cap(poly: Polyhedron, st: BundleState, alpha, t_factor: float) -> None:
    """t ≤ sᵀs/sᵀ(p⁺ − p) after the serious step s, p and p⁺ the aggregate subgradients of
    f + indicator(U) at its start and end (not below t/t_factor; only where sᵀ(p⁺ − p) > 0).

    p is the gradient of the Moreau–Yosida regularisation of the model, so its change along
    the step measures the curvature the step crossed, kinks included; a t beyond the inverse of
    that curvature overshoots (the scalar quasi-Newton condition on the weight 1/t, one of
    PBUN's updates of its weight).
    """
    t = min(max(st.t, st.t_min), st.t_max)
    p = direction(poly, st.x, st.G, alpha, t, st.w).p
    s, dp = st.pending_s, p - st.pending_p
    st.pending_s = st.pending_p = None
    sd = float(s @ dp)
    if sd > 0:
        st.t = max(min(float(s @ s) / sd, t), t / t_factor, st.t_min)


def _extrapolate(oracle, poly: Polyhedron, st: BundleState, o: BTOptions, cand: _Step, d,
                 v: float) -> None:
    """Line search beyond a serious step y = x + d whose slope g(y)ᵀd is still below m2·v.

    Tries x + τd for τ = 2, 4, … ≤ ``extrapolation`` (clipped to the bounds; a point outside
    the other constraints ends the search) and moves the candidate to each one that passes the
    descent test f − f(x) ≤ m1·τ·v and lowers f, until the slope flattens; the cuts of the
    points passed over (and of a failed one) go into the bundle.  t is not changed: the ratio
    ρ of the next update of t sees the longer step's decrease.
    """
    x, f = st.x, st.f
    tau = 1.0
    while 2.0 * tau <= o.extrapolation:
        y = poly.clip(x + 2.0 * tau * d)
        if poly.violation(y) > o.feas_tol:
            return
        out = _evaluate(oracle, y, trial=True)
        st.nfev += 1
        if out is None:
            return
        fy, gy = out
        if fy - f > o.m1 * 2.0 * tau * v or fy >= cand.fy:
            cand.extra.append((y, fy, gy))
            return
        cand.extra.append((cand.y, cand.fy, cand.gy))
        cand.y, cand.fy, cand.gy = y, fy, gy
        tau *= 2.0
        if gy @ d >= o.m2 * v:
            return


def _update_bundle(st: BundleState, step: _Step, max_bundle: int, gamma: float) -> None:
    """Serious or null step: move x (serious), select or aggregate, append the new elements.

    When the bundle is full, the elements with λ_j = 0 in the step's QP (inactive) leave
    first, oldest first; only if that is not enough are the older active elements replaced
    by the aggregate.  The element with the smallest α (the cut at x) stays.
    """
    lam = step.qp.lam
    keep_cur = int(np.argmin(_alpha(st, gamma)))
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
    excess = m_old + k - max_bundle
    if excess > 0:
        keep = np.ones(m_old, dtype=bool)
        inactive = np.flatnonzero(lam <= 1e-12)         # oldest first
        inactive = inactive[inactive != keep_cur][:excess]
        keep[inactive] = False
        excess -= inactive.size
        sel = np.flatnonzero(keep)
        if excess > 0:                                  # aggregate the older active ones
            room = max(max_bundle - 1 - k, 0)
            recent = [j for j in sel if j != keep_cur][::-1][:max(room - 1, 0)]
            sel = np.array(sorted(set(recent) | ({keep_cur} if room else set())), dtype=int)
            G = np.vstack([agg[0][None, :], G[sel]])
            fhat = np.concatenate([[agg[1]], fhat[sel]])
            s = np.concatenate([[agg[2]], s[sel]])
        else:
            G, fhat, s = G[sel], fhat[sel], s[sel]
    st.G = np.vstack([G] + [g[None, :] for g, _, _ in new])
    st.fhat = np.concatenate([fhat, [fh for _, fh, _ in new]])
    st.s = np.concatenate([s, [sv for _, _, sv in new]])


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
                       t=t0, t_min=t_min, t_max=t_max, xi=g.copy(), nfev=1, gamma=0.0,
                       gamma_floor=o.gamma_t0)


def _result(st: BundleState, status: int, message: str, criterion=None,
            relative_decrease=math.inf) -> BundleResult:
    return BundleResult(
        x=st.x.copy(), fun=st.f, jac=st.xi.copy(), nit=st.nit, nfev=st.nfev,
        n_serious=st.n_serious, n_null=st.n_null, success=status in SUCCESS_STATUS,
        status=status, message=message, criterion=criterion, stationarity=st.stationarity,
        relative_decrease=relative_decrease, predicted_decrease=st.predicted, gamma=st.gamma,
        t=st.t, history=[dict(r) for r in st.history],
        state=st.copy())


# ---------------------------------------------------------------------- driver
def minimize_bundle(oracle, x0, *, lb=None, ub=None, A_ub=None, b_ub=None, A_eq=None,
                    b_eq=None, eps=1e-7, max_iter=1000, callback=None, state=None, **options):
    """Minimise a locally Lipschitz f over U = {lb ≤ x ≤ ub, A_ub x ≤ b_ub, A_eq x = b_eq}.

    Parameters
    ----------
    oracle : callable
        ``oracle(x) -> (f, g)`` with g one Clarke subgradient of f at x.  Called only at
        points of U (feasible to ``feas_tol``, bounds exactly).
    x0 : array (n,)
        Start; when infeasible it is replaced by its Euclidean projection onto U (logged; in
        the scaled variables z when ``scale`` applies).
    eps : float
        Certified stop (status 0) when ``stationarity = max(‖p‖, α_p + σ)/max(1, |f|) ≤ eps``:
        the aggregate subgradient of f + indicator(U) is an ``eps·max(1, |f|)``-subgradient at x
        of that length, so that (for convex f) ``f(x) − f(z) ≤ eps·max(1, |f|)·(1 + ‖z − x‖)``
        for all z ∈ U.  With the variables scaled (option ``scale``, x = D z), p and the norm
        are those of z: ``f(x) − f(z) ≤ eps·max(1, |f|)·(1 + ‖D⁻¹(z − x)‖)``, distances in units
        of the box widths.  Default 1e-7: the 37 problems of Lukšan & Vlček's collection that
        the method solves end within 1e-6 (relative) of f* (docs/stopping.md).  The defaults of
        ``eps``, ``max_iter`` and the options are those of ``contactopt run``'s ``[optimizer]``
        table but two (a test holds them so): ``ftol`` (0 here, 5e-4 there) and ``metric``
        ("none" here, "bfgs" there), docs/stopping.md; the f-change test (``tolf``) is the same
        in both.
    max_iter : int
        Maximum number of iterations (serious + null steps), counted from the start of the
        run including iterations done before a restored ``state``.  The stopping tests of the
        iteration after the last need no evaluation and are made: a run whose last iterate
        passes one ends by it (status 0, 4 or 5), not by max_iter (status 1).
    callback : callable, optional
        ``callback(intermediate_result)`` after every iteration; the argument is a
        :class:`~contactopt.optimize.bundle.BundleResult` with a ``state`` copy.  Raising ``StopIteration`` stops the run
        (``success`` False, status 2).
    state : BundleState, optional
        Resume from a saved state (``x0`` is then ignored); the iterates that follow are
        bit-identical to those of the uninterrupted run with the same options and U.  A state is
        in the method's variables z = x/d (``scale``); results and callbacks are in the user's.
    **options
        Parameters of the method, see :class:`~contactopt.optimize.bundle.BTOptions`; among them the practical stop
        (status 4): the f-change test ``tolf`` (default 1e-8) over ``tolf_steps`` (2) serious
        steps, and the predicted decrease ``ftol`` (default 0: off) with ``ftol_window`` (5),
        see docs/bundle_method.md.

    Returns
    -------
    BundleResult
        ``success`` is True for status 0 (certified), 4 (f-change or predicted decrease) and 5
        (round-off);
        ``message``
        names the criterion that fired and its value, ``criterion`` says which in one word.

    Raises
    ------
    OptimizerError
        Empty feasible set, invalid input, a failed QP subproblem or a non-finite oracle value.
    """
    o = BTOptions.from_kwargs(options)
    oracle, callback, poly, scaling, st = _start(oracle, x0, (lb, ub, A_ub, b_ub, A_eq, b_eq), callback, state, o)
    max_bundle = o.max_bundle if o.max_bundle is not None else max(5, poly.n + 3)
    logger.info("bundle start: n=%d f=%.10g eps=%.1e ftol=%.1e/%d t=%.3e bundle<=%d "
                "(iteration %d)", poly.n, st.f, eps, o.ftol, o.ftol_window, st.t, max_bundle, st.nit)
    rel = relative_decrease(st.history, o.ftol_window)
    while True:
        if st.nit >= max_iter:
            st, stop = _last_iterate_stop(poly, st, o, eps, max_iter)
            break
        step = _iteration(oracle, poly, st, o, eps)
        if step.kind == "restart":
            _restart(st, o.gamma)
            continue
        stop = _converged(step, st, o, eps)
        if stop is not None:
            break
        _advance(st, step, o, max_bundle)
        rel = relative_decrease(st.history, o.ftol_window)
        if callback is not None:
            try:
                callback(_result(st, -1, f"iteration {st.nit}", relative_decrease=rel))
            except StopIteration:
                stop = (2, "callback", f"stopped by the callback after iteration {st.nit}")
                break
        stop = _stalled(st, o, eps, poly.n)
        if stop is not None:
            break
    status, criterion, message = stop
    logger.info("bundle end: %s; f=%.10g nit=%d nfev=%d", message, st.f, st.nit, st.nfev)
    res = _result(st, status, message, criterion, rel)
    return res if scaling is None else scaling.result(res)


def _start(oracle, x0, U: tuple, callback, state, o: BTOptions):
    """The run's oracle and callback (wrapped when the variables are scaled: the method works in
    z = x/d, the state too), U as a :class:`Polyhedron`, the scaling (or None) and the state,
    restored or built at x0."""
    n = state.x.size if state is not None else np.asarray(x0).size
    scaling = variable_scaling(n, U[0], U[1], o.scale)
    if scaling is not None:
        oracle, callback = scaling.oracle(oracle), scaling.callback(callback)
        x0 = scaling.inner(x0) if state is None else x0
        U = tuple(scaling.constraints(*U).values())
    poly = Polyhedron(n, *U)
    if state is None:
        st = _initial_state(oracle, poly, x0, o)
    else:
        st = state.copy()
        if poly.violation(st.x) > o.feas_tol:
            raise OptimizerError("the restored state's x violates the constraints")
    return oracle, callback, poly, scaling, st


def _restart(st: BundleState, gamma) -> None:
    """Cut the bundle to the element with the smallest α (restart before a certificate)."""
    k = int(np.argmin(_alpha(st, gamma)))
    st.G, st.fhat, st.s = st.G[k:k + 1].copy(), st.fhat[k:k + 1].copy(), st.s[k:k + 1].copy()
    st.verified = 1
    logger.debug("restart at f=%.10g: bundle reduced to the cut at x", st.f)


def _converged(step: _Step, st: BundleState, o: BTOptions, eps: float):
    """(status, criterion, message) when the iteration's step is a stop, else None."""
    if step.kind == "converged":
        cmp = "<" if st.stationarity < eps else "<="
        return 0, "stationarity", f"converged: stationarity {st.stationarity:.1e} {cmp} eps {eps:.0e}"
    if step.kind == "practical":
        return 4, "predicted_decrease", (f"converged: the model predicts a relative decrease {st.predicted:.1e} "
                                         f"< ftol {o.ftol:.0e} (stationarity {st.stationarity:.1e}, eps {eps:.0e})")
    if step.kind == "fchange":
        return 4, "f_change", (f"converged: f changed by at most tolf {o.tolf:.0e} (relative) in "
                               f"{o.tolf_steps} serious steps in a row, stationarity "
                               f"{st.stationarity:.1e} <= sqrt(tolf) (eps {eps:.0e})")
    if step.kind == "roundoff":
        return 5, "roundoff", (f"converged: the model predicts a decrease {-step.qp.v:.2e} at the round-off "
                               f"of f (stationarity {st.stationarity:.2e}, eps {eps:.0e})")
    return None


def _advance(st: BundleState, step: _Step, o: BTOptions, max_bundle: int) -> None:
    """The state after a serious or null step: metric, bundle, γ, t, counts and history."""
    f_old = st.f
    if o.t_secant and step.kind == "serious":
        st.pending_s, st.pending_p = step.y - st.x, step.qp.p.copy()
    if o.metric != "none" and step.kind == "serious":
        g_x = st.G[int(np.argmin(_alpha(st, o.gamma)))]
        s_k, y_k = step.y - st.x, step.gy - g_x
        update_metric(st, s_k, y_k, o.metric_memory, o.metric_range, o.metric,
                      o.metric == "auto" and is_curvature_pair(s_k, y_k, st.f, step.fy, g_x, step.gy))
    _update_bundle(st, step, max_bundle, o.gamma)
    if o.gamma is None:
        _measure_gamma(st, o.gamma_factor, anew=step.kind == "serious")
    st.t = next_t(st, step, f_old, o)
    st.n_stuck = st.n_stuck + 1 if step.stalled else 0
    st.nit += 1
    if step.kind == "serious":
        st.n_serious += 1
        st.verified = 0
    else:
        st.n_null += 1
    st.history.append({"iteration": st.nit, "f": st.f, "step": step.kind, "t": step.t,
                       "stationarity": st.stationarity, "nfev": st.nfev})
    logger.debug("it %d %s f=%.10g t=%.3e stat=%.3e nfev=%d", st.nit, step.kind, st.f,
                 step.t, st.stationarity, st.nfev)


def _stalled(st: BundleState, o: BTOptions, eps: float, n: int):
    """(3, "stalled", message) when the run makes no progress, else None."""
    if st.n_stuck >= 3:
        return 3, "stalled", (f"stalled: {st.n_stuck} null steps in a row returned cuts already in the "
                              f"bundle (the QP resolution is reached; stationarity "
                              f"{st.stationarity:.2e} > eps {eps:.0e})")
    # a polyhedral f may need n + 1 null steps at one x: a shorter window is no evidence
    window = max(o.stall_window, 2 * (n + 1))
    if no_progress(st.history, window):
        return 3, "stalled", (f"stalled: f did not decrease in the last {window} iterations and the "
                              f"stationarity measure did not halve ({st.stationarity:.2e} > eps {eps:.0e})")
    return None
