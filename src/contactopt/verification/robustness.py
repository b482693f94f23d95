"""The state solve at random designs of the box [lower, C0] of a configuration: does each converge,
with how many Newton steps, which fallbacks of :mod:`contactopt.contact.fallback`, in what time
against the solve at α0. Used by the robustness tier of the tests and by benchmarks/robustness.py.

Each design draws every control point uniformly from its box; the slope and volume rows of U are
not imposed (any design of the box gives a valid mesh, and the state must exist there). Each solve
starts from nothing (no warm start, a fresh cache).
"""

from __future__ import annotations

import time
from pathlib import Path

import meshio
import numpy as np

from ..config import validate
from ..errors import ContactOptError
from ..mesh.block import block_mesh
from ..problem import ShapeProblem

__all__ = ["box_designs", "solve_at", "random_design_solves", "generated_variants", "GENERATED"]


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


def random_design_solves(config, n: int, seed: int = 0, name: str | None = None) -> dict:
    """The state at α0 and at ``n`` random designs of the box of ``config``: one summary row
    (``name`` its ``config``, else the configuration's path or name as given). The box is checked
    as a run checks it (every design of it keeps the mesh valid). A model without designs has no
    box: its row is the state at α0 alone (``designs`` 0)."""
    problem = ShapeProblem(config, optimizing=True)
    base = solve_at(problem, problem.model.initial_design())
    if not problem.config.assembly.designs:     # a model of states only: no box to draw from
        n = 0
    rows = [solve_at(problem, alpha) for alpha in box_designs(problem.model, n, seed)]
    ok = [r for r in rows if r["converged"]]
    return {"config": name or str(config), "designs": n, "converged": len(ok), "alpha0_converged": base["converged"],
            "fallbacks": sum(len(r.get("fallbacks", ())) for r in rows),
            "fallbacks_used": sorted({f for r in rows for f in r.get("fallbacks", ())}),
            "newton_steps_max": max((r["newton_steps"] for r in ok), default=None),
            "time_alpha0_s": base["time_s"],
            "time_mean_s": float(np.mean([r["time_s"] for r in rows])) if rows else base["time_s"],
            "failures": [r["error"] for r in rows if not r["converged"]][:3]}


# ----------------------------------------------------------------------------- generated variants
GENERATED = ("crowned face", "crowned face, force control", "symmetry plane", "load steps", "elastic foundation",
             "full-space path")


def generated_variants(seed: int, folder) -> list:
    """Small configurations of the block 2 × 1 × 1 (hexahedra 8 × 4 × 3), one per entry of
    :data:`GENERATED`, with data drawn from ``seed`` (the same seed, the same configurations):

    * ``crowned face``: a mesh written to ``folder`` whose contact face is the graph of a random
      crown and tilt, x3 = h(x1, x2) ≥ 0 (``initial_gap = "mesh"``), random friction and loads;
    * ``crowned face, force control``: that face pressed by a force-controlled plane of random force;
    * ``symmetry plane``: the block clamped on its top and in u2 on its face x2 = 0;
    * ``load steps``: pressed, then sheared by a random traction below F × the normal load;
    * ``elastic foundation``: on a slab of random stiffness, clamped at its bottom;
    * ``full-space path``: the block with a symmetry plane solved by the full-space Newton method
      (:mod:`contactopt.contact.fullspace`, its own fallback chain).

    Returns [(name, Config)]. Convention: the plane x3 = 0, normal e3, the body above it."""
    rng = np.random.default_rng(seed)
    folder = Path(folder)
    base = {"geometry": {"a": 2.0, "b": 1.0, "c": 1.0}, "mesh": {"nx": 8, "ny": 4, "nz": 3},
            "design": {"degree": [3, 2], "C0": 0.05, "C1": 0.5, "C2": 0.01, "initial": 0.01}}

    def friction():
        return {"coefficient": float(rng.uniform(0.1, 0.5))}

    def loads(shear=True):
        top = -float(rng.uniform(0.05, 0.12))
        side = float(rng.uniform(0.0, 0.05)) if shear else 0.0
        return {"top_traction": [0.0, 0.0, top], "right_traction": [side, 0.0, 0.0]}

    # the crowned face: every node lifted by h(x1, x2)(1 − x3), the top x3 = 1 kept
    hexes = block_mesh(2.0, 1.0, 1.0, 8, 4, 3)
    x = hexes.points.copy()
    k1, k2, tilt = rng.uniform(0.0, 0.02), rng.uniform(0.0, 0.02), rng.uniform(-0.005, 0.005)
    h = k1 * (x[:, 0] - 1.0) ** 2 + k2 * (x[:, 1] - 0.5) ** 2 + tilt * (x[:, 0] - 1.0)
    h -= h[x[:, 2] == 0.0].min()
    x[:, 2] += h * (1.0 - x[:, 2])
    mesh = folder / f"crowned_{seed}.vtu"
    meshio.write(mesh, meshio.Mesh(x, [("hexahedron", hexes.cells)]))
    hmax = float(h[x[:, 2] <= h + 1e-12].max())
    crowned = {"mesh": str(mesh), "initial_gap": "mesh", "clamped": {"x1": 0.0},
               "contact": {"box": [[-1.0, 3.0], [-1.0, 2.0], [-1e-9, hmax + 1e-6]]}}
    grow = {"degree": [3, 2], "lower": 0.0, "C0": 0.02, "C1": 0.5, "C2": 0.01, "direction": "grow", "initial": 0.0}
    out = []
    out.append({"body": crowned, "friction": friction(), "design": grow,
                "loads": {"traction": [{"on": {"x3": 1.0}, "value": [float(rng.uniform(0, 0.03)), 0.0,
                                                                     -float(rng.uniform(0.05, 0.12))]}]}})
    out.append({"friction": {"coefficient": float(rng.choice([0.0, rng.uniform(0.1, 0.4)]))},
                "design": grow, "body": {**crowned, "clamped": {"x3": 1.0}}, "loads": {"traction": []},
                "obstacle": {"shape": "plane", "control": "force", "force": [0.0, 0.0, float(rng.uniform(0.05, 0.2))]}})
    out.append({**base, "body": {"clamped": ["clamped", {"on": {"x2": 0.0}, "components": [2]}]},
                "friction": friction(), "loads": loads()})
    fr = friction()
    n_load = float(rng.uniform(0.05, 0.1))
    shear = float(rng.uniform(0.2, 0.8)) * fr["coefficient"] * 2.0 * n_load     # Q < F N, N = 2 × traction
    out.append({**base, "friction": fr,
                "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
                "load_steps": [{"name": "press", "top_traction": [0.0, 0.0, -n_load]},
                               {"name": "shear", "top_traction": [0.0, 0.0, -n_load], "right_traction": [shear, 0.0, 0.0]}],
                "objective": {"steps": "last"}})
    out.append({**base, "friction": friction(), "loads": loads(),
                "foundation": {"block": {"size": [3.0, 2.0, 1.0], "cells": [6, 4, 2], "origin": [-0.5, -0.5]},
                               "top": "top", "clamped": "bottom",
                               "material": {"E": float(rng.uniform(0.2, 2.0)), "nu": 0.3}}})
    out.append({**base, "body": {"clamped": ["clamped", {"on": {"x2": 0.0}, "components": [2]}]},
                "friction": friction(), "loads": loads(), "linear_solver": {"path": "fullspace"},
                "objective": {"type": "max_pressure"}})
    configs = []
    for name, upd in zip(GENERATED, out):
        data = {"name": name.replace(" ", "_").replace(",", ""), "material": {"E": 2.0, "nu": 0.3},
                "objective": {"type": "compliance"}, "state": {"method": "newton", "tol": 1e-12, "max_iter": 200},
                **({} if "mesh" in upd.get("body", {}) else {k: base[k] for k in ("geometry", "mesh")}),
                "design": base["design"], **upd}
        if "type" not in data["objective"]:
            data["objective"] = {"type": "compliance", **data["objective"]}
        configs.append((f"{name} (seed {seed})", validate(data, f"generated: {name} (seed {seed})")))
    return configs
