"""Verification of subgradients against finite differences of Θ (a Taylor test)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from .adjoint import subgradient

log = logging.getLogger(__name__)


@dataclass
class GradientCheck:
    value: float
    gradient: np.ndarray
    directions: np.ndarray
    fd: np.ndarray
    predicted: np.ndarray
    rel_errors: np.ndarray
    taylor_h: np.ndarray
    taylor_remainder: np.ndarray
    taylor_rate: float
    n_degenerate: int
    counts: dict
    tol: float
    passed: bool
    extra: dict = field(default_factory=dict)


def random_directions(model, n: int, seed: int) -> np.ndarray:
    """Unit directions tangent to the volume constraint (Σ d = 0), seeded."""
    rng = np.random.default_rng(seed)
    d = rng.standard_normal((n, model.n_design))
    d -= d.mean(axis=1, keepdims=True)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def directional_fd(problem, alpha, d, h, classes=None, max_halvings: int = 6):
    """Richardson-extrapolated central difference (4 D(h/2) − D(h))/3, error O(h⁴).

    The extrapolation lets h stay large enough that the state's round-off (Θ to ~1e-13 relative)
    does not swamp directional derivatives much smaller than ‖ξ‖. When a stencil point has other
    node classes than α (the difference would straddle a kink of Θ), h is halved.
    """
    def value(x):
        st = problem.solve_state(x)
        if classes is not None and not np.array_equal(st.classes, classes):
            raise _Kink
        return problem.evaluate_value(x)

    def central(step):
        return (value(alpha + step * d) - value(alpha - step * d)) / (2 * step)

    for _ in range(max_halvings):
        try:
            return (4.0 * central(0.5 * h) - central(h)) / 3.0
        except _Kink:
            h *= 0.5
    return (4.0 * central(0.5 * h) - central(h)) / 3.0 if classes is None else \
        directional_fd(problem, alpha, d, h, None, 0)


class _Kink(Exception):
    pass


def check_gradient(problem, alpha, *, seed: int = 0, n_directions: int = 10, h: float = 1e-3,
                   tol: float = 1e-6, directions=None, state_method: str | None = None,
                   state_tol: float | None = None) -> GradientCheck:
    """Compare ξᵀd with central differences in seeded random directions; Taylor table in d_0.

    The step is h·max(|α|) so it is relative to the design's size. A difference quotient divides
    the state error by h, so every state of the check is solved to ``state_tol`` with
    ``state_method``: by default the successive approximations to 1e-14, and where their anchor
    of a body held only by contact (paths/rigid.py, a stiffer one for that solver) does not
    settle to 1e-14, the check again with the Newton solver to its round-off floor, 1e-13 (which
    costs the quotient a digit).
    """
    if state_method is not None:
        return _checked(problem, alpha, seed, n_directions, h, tol, directions, state_method,
                        1e-14 if state_tol is None else state_tol)
    try:
        return _checked(problem, alpha, seed, n_directions, h, tol, directions, "fixed-point",
                        1e-14 if state_tol is None else state_tol)
    except SolverError as exc:
        if problem.model.body.rigid is None and (problem.model.foundation is None
                                                 or problem.model.foundation.kernel() is None):
            raise
        log.info("gradient check: %s; the states again by Newton to 1e-13", exc)
        return _checked(problem, alpha, seed, n_directions, h, tol, directions, "newton", 1e-13)


def _checked(problem, alpha, seed, n_directions, h, tol, directions, state_method, state_tol) -> GradientCheck:
    """:func:`_check` with the states solved by ``state_method`` to ``state_tol``."""
    saved = (problem.method, problem.tol)
    problem.method, problem.tol = state_method, state_tol
    problem.clear_cache()
    try:
        return _check(problem, alpha, seed, n_directions, h, tol, directions)
    finally:
        problem.method, problem.tol = saved
        problem.clear_cache()


def _check(problem, alpha, seed, n_directions, h, tol, directions) -> GradientCheck:
    alpha = np.asarray(alpha, float).reshape(-1)
    res = subgradient(problem, alpha)
    dirs = random_directions(problem.model, n_directions, seed) if directions is None else np.atleast_2d(directions)
    step = h * max(np.abs(alpha).max(), 1e-3)
    fd = np.array([directional_fd(problem, alpha, d, step, res.state.classes.copy()) for d in dirs])
    pred = dirs @ res.gradient
    scale = np.maximum(np.abs(fd), 1e-12 * np.linalg.norm(res.gradient))
    rel = np.abs(fd - pred) / scale
    hs = max(np.abs(alpha).max(), 1e-3) * np.logspace(-2, -5, 4)
    rem = np.array([abs(problem.evaluate_value(alpha + t * dirs[0]) - res.value - t * pred[0]) for t in hs])
    ok = rem > 0
    rate = float(np.polyfit(np.log(hs[ok]), np.log(rem[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")
    return GradientCheck(value=res.value, gradient=res.gradient, directions=dirs, fd=fd, predicted=pred,
                         rel_errors=rel, taylor_h=hs, taylor_remainder=rem, taylor_rate=rate,
                         n_degenerate=res.n_degenerate, counts=res.state.counts, tol=tol,
                         passed=bool(np.all(rel <= tol)))
