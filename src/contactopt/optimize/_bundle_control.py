"""Proximity control, variable metric and stopping measures of the bundle method.

Helpers of :mod:`.bundle` (see its docstring for the rules and references): Kiwiel's
safeguarded update of t with the rise test (:func:`next_t`), the variable metric of the
proximal term, damped BFGS or diagonal (:func:`update_metric`, :func:`direction`), and the
measures of the practical and stall stops (:func:`relative_decrease`, :func:`no_progress`).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ._bundle_qp import DirectionQP, Polyhedron

logger = logging.getLogger("contactopt.optimize.bundle")


def direction(poly: Polyhedron, x, G, alpha, t, w):
    """The QP with the proximal term dᵀWd/(2t), solved in e = Lᵀd for W = LLᵀ.

    ``w`` None is W = I; a vector is a diagonal W (then L = diag(√w) and the box of U stays a
    box); a matrix is a full W, whose box becomes general rows of the transformed polyhedron.
    """
    if w is None:
        return poly.direction(x, G, alpha, t)
    if w.ndim == 1:
        r = np.sqrt(w)
        pe = Polyhedron(poly.n, poly.lb * r, poly.ub * r,
                        poly.A_ub / r if poly.n_ub else None, poly.b_ub if poly.n_ub else None,
                        poly.A_eq / r if poly.n_eq else None, poly.b_eq if poly.n_eq else None)
        qp = pe.direction(x * r, G / r, alpha, t)
        d = qp.d / r
        return DirectionQP(d=d, v=qp.v, lam=qp.lam, p=-w * d / t, xi=qp.lam @ G,
                           sigma=qp.sigma, solver=qp.solver)
    L = np.linalg.cholesky(w)
    M = np.linalg.inv(L).T                              # d = M e
    up, lo = np.isfinite(poly.ub), np.isfinite(poly.lb)
    A_ub = np.vstack([poly.A_ub @ M, M[up], -M[lo]])
    b_ub = np.concatenate([poly.b_ub, poly.ub[up], -poly.lb[lo]])
    pe = Polyhedron(poly.n, None, None, A_ub if A_ub.shape[0] else None,
                    b_ub if A_ub.shape[0] else None,
                    poly.A_eq @ M if poly.n_eq else None, poly.b_eq if poly.n_eq else None)
    qp = pe.direction(L.T @ x, G @ M, alpha, t)
    d = M @ qp.d
    return DirectionQP(d=d, v=qp.v, lam=qp.lam, p=-(w @ d) / t, xi=qp.lam @ G, sigma=qp.sigma,
                       solver=qp.solver)


# metric "auto": a pair (s, y) of a serious step is a curvature pair when the trapezoidal rule,
# exact for a quadratic, holds along the step to within SMOOTH_DEFECT·sᵀy; the BFGS metric is
# used while at least SMOOTH_SHARE of the kept pairs (and at least SMOOTH_MIN) are such pairs
SMOOTH_DEFECT = 0.1
SMOOTH_SHARE = 0.75
SMOOTH_MIN = 4


def is_curvature_pair(s, y, f_old: float, f_new: float, g_old, g_new) -> bool:
    """True when f along the step s behaves like a quadratic with positive curvature.

    For a quadratic, f(x + s) − f(x) = ½(g(x) + g(x + s))ᵀs exactly and sᵀy = sᵀHs > 0; across
    a kink the subgradient jumps and the rule fails by a share of sᵀy near one (an affine piece
    has sᵀy = 0).
    """
    sy = float(s @ y)
    defect = abs(f_new - f_old - 0.5 * float((g_old + g_new) @ s))
    return sy > 0.0 and defect <= SMOOTH_DEFECT * sy


def update_metric(st, s, y, memory: int, bound: float, kind: str = "bfgs",
                  smooth: bool = False) -> None:
    """The metric W of the proximal term from the last ``memory`` serious steps (s, y).

    ``"diagonal"``: the secant estimate w_i = Σ|y_i s_i| / Σ s_i².  ``"bfgs"``: damped BFGS
    updates (Powell's damping, sᵀy ≥ 0.2 sᵀWs, keeps W positive definite where f is not convex)
    with the pairs oldest first, from that diagonal.  Either is normalised to geometric mean 1 of
    its eigenvalues (t keeps its scale) and its eigenvalues clipped to [1/bound, bound].
    ``"auto"``: that BFGS metric while at least ``SMOOTH_SHARE`` of the kept pairs (and
    ``SMOOTH_MIN`` of them) are curvature pairs (``smooth``, :func:`is_curvature_pair`), else
    W = I — the exact cutting-plane model of a polyhedral f, whose subgradient changes are
    jumps, not curvature.
    """
    n = st.x.size
    S = np.zeros((0, n)) if st.S is None else st.S
    Y = np.zeros((0, n)) if st.Y is None else st.Y
    st.S = np.vstack([S, s[None, :]])[-memory:]
    st.Y = np.vstack([Y, y[None, :]])[-memory:]
    if kind == "auto":
        flags = np.zeros(0) if st.smooth is None else st.smooth
        st.smooth = np.concatenate([flags, [1.0 if smooth else 0.0]])[-memory:]
        if st.smooth.size < SMOOTH_MIN or st.smooth.mean() < SMOOTH_SHARE:
            st.w = None
            return
    num = np.abs(st.Y * st.S).sum(axis=0)
    den = (st.S ** 2).sum(axis=0)
    ok = (den > 0) & (num > 0)
    if ok.sum() < 1:
        return
    w = np.ones(n)
    w[ok] = num[ok] / den[ok]
    w[~ok] = np.exp(np.mean(np.log(w[ok])))
    if kind == "diagonal":
        w = w / np.exp(np.mean(np.log(w)))
        st.w = np.clip(w, 1.0 / bound, bound)
        return
    W = np.diag(w)
    for sk, yk in zip(st.S, st.Y):
        Ws = W @ sk
        sWs, sy = float(sk @ Ws), float(sk @ yk)
        if not sWs > 0:
            continue
        if sy < 0.2 * sWs:                              # Powell's damping
            theta = 0.8 * sWs / (sWs - sy)
            yk = theta * yk + (1.0 - theta) * Ws
            sy = float(sk @ yk)
        W = W - np.outer(Ws, Ws) / sWs + np.outer(yk, yk) / sy
    ev, V = np.linalg.eigh(0.5 * (W + W.T))
    ev = np.maximum(ev, np.finfo(float).tiny)
    ev = np.clip(ev / np.exp(np.mean(np.log(ev))), 1.0 / bound, bound)
    W = (V * ev) @ V.T
    st.w = 0.5 * (W + W.T)


def next_t(st, step, f_old: float, o) -> float:
    """Kiwiel's (1990) safeguarded update of t after a serious or null step; updates i_t, ε_v.

    ρ = (f(y) − f(x))/v is the share of the predicted decrease that was realised and
    t_int = t/(2(1 − ρ)) the quadratic interpolation (docs/bundle_method.md).
    """
    t, v = step.t, step.qp.v
    if not o.adapt_t:
        return t
    rho = (step.fy - f_old) / v if v < 0 else 0.0
    t_int = t / (2.0 * (1.0 - rho)) if rho < 1.0 else math.inf
    logger.debug("t update: %s rho=%.3f v=%.3e alpha_y=%.3e eps_v=%.3e i_t=%d", step.kind, rho,
                 v, step.alpha_y, st.eps_v, st.i_t)
    if step.kind == "serious":
        t_new = t
        if rho >= o.m_r and st.i_t > 0:                 # decrease as the model predicted
            t_new = t_int
        elif st.i_t > 3:                                # many serious steps at this t
            t_new = 2.0 * t
        t_new = min(max(t_new, t), o.t_factor * t, st.t_max)
        st.eps_v = max(st.eps_v, -2.0 * v)
        st.i_t = 1 if t_new != t else max(st.i_t + 1, 1)
        st.null_run = 0
        return t_new
    # null step: the aggregate linearisation error α̃_p = −v − t‖p‖² ≥ α_p + σ
    p2 = float(step.qp.p @ step.qp.p)
    st.eps_v = min(st.eps_v, math.sqrt(p2) + max(-v - t * p2, 0.0))
    t_new = t
    # the cut shows the model far off: a linearisation error at x above Kiwiel's variation
    # estimate (after more than three null steps at this t), or f rose where the model
    # predicted a decrease (ρ < 0: the model's error at y exceeds its whole prediction) at the
    # rise_patience-th null step since the last serious step (once per run of null steps, so
    # that polyhedral f, whose long null runs are normal, keep their t)
    st.null_run += 1
    if ((step.alpha_y > max(st.eps_v, -10.0 * v) and st.i_t < -3)
            or (rho < 0.0 and st.null_run == o.rise_patience)):
        t_new = t_int
    t_new = max(min(t_new, t), t / o.t_factor, st.t_min)
    st.i_t = -1 if t_new != t else min(st.i_t - 1, -1)
    return t_new


def no_progress(history: list, window: int) -> bool:
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


def _last_serious_f(history: list, count: int) -> list:
    """f of the last ``count`` + 1 serious steps, newest first (fewer where there are fewer)."""
    fs = []
    for h in reversed(history):
        if h["step"] == "serious":
            fs.append(h["f"])
            if len(fs) > count:
                break
    return fs


def relative_decrease(history: list, window: int) -> float:
    """(f_then − f_now)/|f_now| over the last ``window`` serious steps (inf before there are
    window + 1 of them)."""
    fs = _last_serious_f(history, window)
    if len(fs) <= window:
        return math.inf
    drop = fs[-1] - fs[0]
    return drop / abs(fs[0]) if fs[0] != 0 else (0.0 if drop == 0 else math.inf)


def flat_serious_steps(history: list, count: int, tol: float) -> bool:
    """True when each of the last ``count`` serious steps changed f by at most
    ``tol·max(1, |f|)`` and the last iteration was one of them."""
    if not history or history[-1]["step"] != "serious":
        return False
    fs = _last_serious_f(history, count)
    if len(fs) <= count:
        return False
    return all(abs(a - b) <= tol * max(1.0, abs(a)) for a, b in zip(fs[:-1], fs[1:]))
