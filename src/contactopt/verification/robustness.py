"""The state solve at random designs of the box [lower, C0] of a configuration: does each converge,
with how many Newton steps, which fallbacks of :mod:`contactopt.contact.fallback`, in what time
against the solve at α0. Used by the robustness tier of the tests and by benchmarks/robustness.py.

Each design draws every control point uniformly from its box; the slope and volume rows of U are
not imposed (any design of the box gives a valid mesh, and the state must exist there). Each solve
starts from nothing (no warm start, a fresh cache).
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import ContactOptError
from ..problem import ShapeProblem

__all__ = ["box_designs", "solve_at", "random_design_solves"]


def box_designs(model, n: int, seed: int) -> list[np.ndarray]:
    """``n`` designs drawn uniformly from the box [lb, ub] of the model's control points."""
    A = model.admissible
    a0 = model.initial_design()
    if model.n_design == A.size:
        lb = np.broadcast_to(np.asarray(A.lb, float), a0.shape)
        ub = np.broadcast_to(np.asarray(A.ub, float), a0.shape)
    else:                             # a reduced design: the box of its values
        lb, ub = np.full(a0.shape, float(np.min(A.lb))), np.full(a0.shape, float(np.max(A.ub)))
    rng = np.random.default_rng(seed)
    return [lb + (ub - lb) * rng.random(a0.size) for _ in range(n)]


def solve_at(problem, alpha) -> dict:
    """One state solve of every load case from nothing: ``converged``, ``newton_steps``,
    ``fallbacks`` (the names of those used), ``time_s``; ``error`` (the message) on a failure."""
    problem.clear_cache()
    t0 = time.perf_counter()
    try:
        states = problem.solve_states(alpha, warm_start=False)
    except ContactOptError as exc:
        return {"converged": False, "error": f"{type(exc).__name__}: {exc}", "time_s": time.perf_counter() - t0}
    return {"converged": all(s.converged for s in states),
            "newton_steps": int(sum(s.iterations for s in states)),
            "fallbacks": [s.stats.extra["fallback"] for s in states if "fallback" in s.stats.extra],
            "time_s": time.perf_counter() - t0}


def random_design_solves(config, n: int, seed: int = 0) -> dict:
    """The state at α0 and at ``n`` random designs of the box of ``config``: one summary row."""
    problem = ShapeProblem(config)
    base = solve_at(problem, problem.model.initial_design())
    rows = [solve_at(problem, alpha) for alpha in box_designs(problem.model, n, seed)]
    ok = [r for r in rows if r["converged"]]
    return {"config": str(config), "designs": n, "converged": len(ok), "alpha0_converged": base["converged"],
            "fallbacks": sum(len(r.get("fallbacks", ())) for r in rows),
            "fallbacks_used": sorted({f for r in rows for f in r.get("fallbacks", ())}),
            "newton_steps_max": max((r["newton_steps"] for r in ok), default=None),
            "time_alpha0_s": base["time_s"],
            "time_mean_s": float(np.mean([r["time_s"] for r in rows])) if rows else None,
            "failures": [r["error"] for r in rows if not r["converged"]][:3]}
