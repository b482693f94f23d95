"""The result files of a finished optimization run, written at its optimum.

summary.json says whether the optimum is feasible in two words, one per kind of feasibility:
``admissible`` — the design α lies in the admissible set U (the bounds, slope limits and linear
constraints of [design], to 1e-8) — and ``constraints_satisfied`` — every response of
[[constraints]] is at most its limit within its relative tolerance (null when the run has none).
Its ``chart`` names the coordinates of surface.csv's columns x1, x2 (the chart coordinates ξ1, ξ2 of
the face, :mod:`contactopt.design.chart`; the columns keep their names on every chart).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ..design.chart import chart_summary
from ..design.several import alpha_record, split_design, surfaces_of
from ..errors import ContactOptError
from ..sensitivity.solution import KeptDesign
from .atomic import WriteError, atomic_write_json, atomic_write_text
from .export import export_design
from .forked import Forked
from .plots import (
    plot_contact_response,
    plot_history,
    plot_load_cases,
    plot_node_classes,
    plot_peak_stress,
    plot_stress_comparison,
    plot_surface,
)
from .pressure import contact_pressure, face_classes, pair_reports
from .vtk import write_body_vtu, write_foundation_vtu, write_pvd

log = logging.getLogger(__name__)

__all__ = ["write_outputs"]


def _stopping(res, opt) -> dict:
    """Both stopping tests of the run at its end, and which one fired (summary.json); ``opt`` the
    run's ``[optimizer]``.

    ``criterion``: "stationarity" (certified, status 0), "predicted_decrease" or "f_change"
    (status 4), "roundoff" (5), "max_iter" (1), "callback" (2) or "stalled" (3); the measures are
    those of Θ/Θ(α0).
    ``J_tolerance``: the relative decrease of J that the bundle model still predicts at the last
    iterate, from a step of the size of the last serious step — at a practical stop at most
    ``ftol`` (docs/stopping.md); ``relative_decrease`` the realised one over the last
    ``ftol_window`` serious steps, for comparison."""
    rel = float(res.relative_decrease)
    pred = float(res.predicted_decrease)
    return {"criterion": res.criterion,
            "stationarity": float(res.stationarity), "eps": float(opt.eps),
            "J_tolerance": pred if np.isfinite(pred) else None,
            "relative_decrease": rel if np.isfinite(rel) else None,
            "ftol": float(opt.ftol), "ftol_window": int(opt.ftol_window)}


def write_outputs(out: Path, problem, alpha0, res, oracle, plots: bool = True, designs=None) -> dict:
    """Every result file of a finished optimization at its optimum ``res.x`` (the module
    docstring of :mod:`contactopt.runner` lists them) and summary.json; ``oracle`` the run's
    counts (``count``, ``scale``, ``time``, ``t_start``). ``plots=False``: all but the PNG figures.

    ``designs``: the :class:`~contactopt.sensitivity.solution.KeptDesign` of α0 and of the
    optimum, the optimization's own solves, which the outputs read without solving a state
    again; None: both solved here, without warm start."""
    model = problem.model
    x = np.asarray(res.x)
    t0 = time.perf_counter()
    if designs is None:
        designs = [_solved(problem, a) for a in (alpha0, x)]
    try:
        at0 = _at_design(out, problem, designs[0], "initial", plots)
        at1 = _at_design(out, problem, designs[1], "optimal", plots)
    finally:
        problem.clear_cache()        # a kept design holds no systems: the next request solves
    c1 = at1["combined"]
    s0, s1 = at0["states"][c1.case], at1["states"][c1.case]      # the load case active at the optimum
    target = problem.cases[c1.case].objective.target
    forked, here = _figures(out, model, x, target, s0, s1, res) if plots else ([], [])
    with Forked(forked, directory=out) as figures:      # drawn beside the other files (io/forked.py)
        summary = _write_files(out, problem, x, res, oracle, t0, (at0, at1, s0, s1), here, plots)
        figures.join()
    summary["time_breakdown_s"]["outputs"] = time.perf_counter() - t0
    atomic_write_json(out / "summary.json", summary)
    return summary


def _write_files(out: Path, problem, x, res, oracle, t0, at, figures, plots) -> dict:
    """The result files but the forked figures, and the summary (not yet written); ``figures``
    the figures drawn here."""
    model = problem.model
    at0, at1, s0, s1 = at
    c0, states0, J0, steps0 = at0["combined"], at0["states"], at0["combined"].value, at0["steps"]
    c1, states1, J, steps1 = at1["combined"], at1["states"], at1["combined"].value, at1["steps"]
    write_body_vtu(out / "initial.vtu", model, s0)
    write_body_vtu(out / "optimal.vtu", model, s1)
    pvd = [(0, "initial.vtu"), (1, "optimal.vtu")]
    if model.body.pair_faces:                 # several pairs: each counterpart body its part, 1, 2, …
        for k, pairs in enumerate(model.foundation.pairs):
            if model.foundation.parts[k].n_nodes == 0:      # a rigid counterpart: no mesh of its own
                continue
            name = model.config.assembly.contacts[pairs[0]].counterpart.split(".")[0]
            write_foundation_vtu(out / f"initial_{name}.vtu", model.foundation, s0, pair=k)
            write_foundation_vtu(out / f"optimal_{name}.vtu", model.foundation, s1, pair=k)
            pvd += [(0, f"initial_{name}.vtu", k + 1), (1, f"optimal_{name}.vtu", k + 1)]
    elif model.foundation is not None:        # the elastic foundation: part 1 of each time step
        write_foundation_vtu(out / "initial_foundation.vtu", model.foundation, s0)
        write_foundation_vtu(out / "optimal_foundation.vtu", model.foundation, s1)
        pvd += [(0, "initial_foundation.vtu", 1), (1, "optimal_foundation.vtu", 1)]
    write_pvd(out / "bodies.pvd", pvd)
    for draw in figures:
        draw()
    atomic_write_text(out / "iterations.csv", "iteration,J,step,t,stationarity,evaluations\n" + "".join(
        f"{r['iteration']},{r['f'] * oracle.scale!r},{r['step']},{r['t']:.6e},{r['stationarity']:.6e},"
        f"{r['nfev']}\n" for r in res.history))
    amat = alpha_record(model.surface, x)
    shapes = [list(s.shape) for s in surfaces_of(model.surface)]
    atomic_write_json(out / "alpha.json", {"alpha": amat, "shape": shapes[0] if len(shapes) == 1 else shapes})
    several = len(shapes) > 1           # several designs: surface.csv per design (design, x1, x2, theta)
    rows = []
    for k, (sf, xk) in enumerate(zip(surfaces_of(model.surface), split_design(model.surface, x))):
        g1, g2 = np.meshgrid(np.linspace(sf.x1lo, sf.x1lo + sf.a, 41), np.linspace(sf.x2lo, sf.x2lo + sf.b, 21))
        h = sf.evaluate(xk, g1.ravel(), g2.ravel())
        rows += [(f"{k}," if several else "") + f"{a:.6g},{b:.6g},{c:.10g}\n" for a, b, c in zip(g1.ravel(), g2.ravel(), h)]
    atomic_write_text(out / "surface.csv", ("design," if several else "") + "x1,x2,theta\n" + "".join(rows))
    wall = time.perf_counter() - oracle.t_start
    summary = {
        "name": problem.config.name, "J0": J0, "J": J, "ratio": J / J0 if J0 else None,
        "iterations": int(res.nit), "evaluations": int(oracle.count), "serious_steps": int(res.n_serious),
        "null_steps": int(res.n_null), "success": bool(res.success), "message": str(res.message),
        "status": int(res.status), "stopping": _stopping(res, problem.config.optimizer),
        "alpha": amat, "admissible": bool(model.admissible.is_feasible(x, tol=1e-8)),
        "wall_time_s": wall,
        "time_breakdown_s": {**oracle.time, "outputs": time.perf_counter() - t0},
        "final_state": s1.summary(),
        "chart": chart_summary(model.mesh.chart),
        "contacts": {"initial": pair_reports(model, s0), "optimal": pair_reports(model, s1)},
    }
    if model.foundation is not None:
        summary["foundation"] = model.foundation.summary()
    if problem.term_names():            # each term's value at α0 and at the optimum
        summary["objective"] = {"J0": at0["objective"], "J": at1["objective"]}
    if problem.constraints:             # each response at the optimum: value, limit, margin (≥ 0: met)
        summary["constraints"] = _constraint_outputs(problem, at0["constraints"], at1["constraints"], res)
        summary["constraints_satisfied"] = all(c["satisfied"] for c in summary["constraints"]["responses"].values())
    else:
        summary["constraints_satisfied"] = None
    if problem.has_load_cases:
        summary["load_cases"] = _load_case_outputs(out, problem, (c0, states0), (c1, states1), plots)
    if steps1:
        summary["load_steps"] = {"names": list(steps1), "J0": steps0, "J": steps1, "objective_steps":
                                 problem.config.objective.steps}
    summary["export"] = _export(out, model, x)
    return summary


def _solved(problem, alpha):
    """A :class:`~contactopt.sensitivity.solution.KeptDesign` of α solved here without warm start."""
    return KeptDesign(problem.solution(alpha, warm_start=False), {})


def _at_design(out: Path, problem, design, which: str, plots: bool) -> dict:
    """What the outputs read at one design (``which``: "initial" or "optimal"), with ``design``
    the problem's last design: Θ of the combined load cases, every case's state, the load
    steps' values (and at the optimum their stick/slip maps), the objective's terms and the
    constraints' reports."""
    problem.use_design(design)
    alpha = design.alpha
    return {"combined": problem.evaluate_cases(alpha), "states": problem.solve_states(alpha),
            "steps": _step_outputs(out, problem, which, plots),
            "objective": problem.objective_report(alpha) if problem.term_names() else None,
            "constraints": problem.constraint_report(alpha) if problem.constraints else None}


def _figures(out: Path, model, x, target, s0, s1, res) -> tuple[list, list]:
    """The run's figures as two lists of jobs of about equal time, one for a forked process
    and one drawn here: λ and the contact pressure p = λ/a of the target (where the objective has
    one), α0 and the optimum, the
    optimal surface and the convergence history; the optimum's node classes, contact response and
    von Mises stress."""
    classes = face_classes(model, s1)         # the maps' classes, read by two figures

    def pressure():
        p0, p1 = contact_pressure(model, s0.lam, s0.coords), contact_pressure(model, s1.lam, s1.coords)
        # the target in the same units: λ̄ over the optimal design's areas, as the optimal λ
        p_target = contact_pressure(model, target, s1.coords) if target is not None else None
        plot_stress_comparison(out / "pressure.png", model, p_target, p0, p1,
                               zlabel="contact pressure $p = \\lambda/a$")

    def contact():
        plot_contact_response(out / "contact.png", model, contact_pressure(model, s1.lam, s1.coords), s1.tau,
                              s1.u_c[:, :2], classes, title="optimal design")

    forked = [lambda: plot_stress_comparison(out / "stress.png", model, target, s0.lam, s1.lam),
              pressure, lambda: plot_surface(out / "surface.png", model, x),
              lambda: plot_history(out / "history.png", [{**r, "kind": r.get("step")} for r in res.history])]
    here = [lambda: plot_node_classes(out / "classes.png", model, classes), contact,
            lambda: plot_peak_stress(out / "von_mises.png", model, s1.coords, s1.u, title="optimal design")]
    return forked, here


def _constraint_outputs(problem, initial: dict, optimal: dict, res) -> dict:
    """summary.json's ``constraints``: per constraint its value, limit, margin (limit − value),
    relative violation tolerance and whether it holds, at the optimum and at α0 (the reports
    ``optimal`` and ``initial``), and the penalty weight σ the run ended with (optimize/constrained.py)."""
    out = {}
    for con, (name, rep) in zip(problem.constraints, optimal.items()):
        out[name] = {**rep, "tol": con.tol, "satisfied": bool(rep["value"] <= con.limit * (1 + con.tol)),
                     "initial": {k: initial[name][k] for k in ("value", "margin")}}
    return {"responses": out, "sigma": float(res.get("sigma", float("nan"))), "sigma_raised": int(res.get("outer", 0))}


def _step_outputs(out: Path, problem, which: str, plots: bool = True) -> dict:
    """Load paths: J at each step's end at the design just evaluated, and (at the optimum) a
    stick/slip map per step, classes-<step>.png."""
    if not problem.has_load_steps:
        return {}
    if which == "optimal" and plots:
        for k in range(len(problem.cases)):
            pre = f"{problem.cases[k].name}." if problem.has_load_cases else ""
            for name, sub, state in problem.step_results(k) or []:
                if sub == max(s.substep for s in problem.steps[k] if s.name == name):
                    plot_node_classes(out / f"classes-{pre}{name}.png", problem.model, face_classes(problem.model, state))
    return dict(zip(problem.step_columns(), problem.step_values()))


def _export(out: Path, model, x) -> dict:
    """The optimal design for CAD and other FE tools (contactopt.io.export); a failure is recorded
    in the summary, never lost results: the run's other files are written already."""
    try:
        return export_design(model, x, out, strict=False)
    except WriteError:          # a full disk is not an export problem: the run stops and says so
        raise
    except ContactOptError as exc:
        log.warning("export of the optimal design failed: %s", exc)
        return {"files": {}, "error": str(exc)}


def _load_case_outputs(out: Path, problem, initial, optimal, plots: bool = True) -> dict:
    """Per-case λ maps (cases.png) and the summary's ``load_cases``: Θ_k at α0 and at the
    optimum, the active cases there and the case whose state the other plots show."""
    names = problem.case_names
    (c0, states0), (c1, states1) = initial, optimal
    if plots:
        plot_load_cases(out / "cases.png", problem.model, names, [s.lam for s in states0],
                        [s.lam for s in states1], c0.values, c1.values)
    return {"combine": problem.combination.kind, "names": list(names),
            "weights": dict(zip(names, problem.combination.weights.tolist())),
            "J0": dict(zip(names, c0.values.tolist())), "J": dict(zip(names, c1.values.tolist())),
            "active_at_J0": [names[i] for i in c0.active], "active": [names[i] for i in c1.active],
            "shown": names[c1.case], "active_tol": problem.combination.active_tol}
