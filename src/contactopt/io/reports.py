"""What state.json, summary.json and the history say about a design's objective and constraints.

Each report is a dictionary built from the values of the problem's responses at a design
(:mod:`contactopt.sensitivity.responses`): the objective ``{type, value, terms}`` (``terms`` maps
each [[objective.terms]] entry's name to its value, unweighted, and its weight), a constraint
``{type, value, limit, margin}`` (margin = limit − value ≥ 0 where the constraint holds). The
problem is a :class:`contactopt.ShapeProblem`; nothing here solves more than it asks of it.
"""

from __future__ import annotations

from ..sensitivity.steps import step_objective


def limit(con, value: float) -> dict:
    """{type, value, limit, margin} of constraint ``con`` with response ``value``."""
    return {"type": con.type, "value": float(value), "limit": con.limit, "margin": con.limit - float(value)}


def term_names(problem) -> list:
    """The names of the [[objective.terms]] (their type, numbered from the second of a type on)."""
    return [name for name, _, _ in _terms(problem.objective)]


def _terms(objective) -> list:
    """The (name, weight, objective) of a sum of terms; empty for an objective of one type."""
    return list(objective.terms) if objective.name == "sum" else []


def objective_report(problem, alpha, case: int | None = None, **kw) -> dict:
    """{type, value, terms} of the objective at α: the combined load cases' value (``case`` None; the
    terms of the case the combination picks) or load case ``case``'s own Θ_k and terms. ``kw`` go
    to :meth:`~contactopt.ShapeProblem.solve_state`."""
    rv = problem.response_value(alpha, **kw)
    k = rv.combined.case if case is None else case
    value = rv.value if case is None else float(rv.combined.values[case])
    terms = rv.cases[k].terms
    return {"type": problem.config.objective.type, "value": float(value),
            "terms": {name: {"value": terms[name], "weight": w} for name, w, _ in _terms(problem.cases[k].objective)}}


def constraint_report(problem, alpha, case: int | None = None, **kw) -> dict:
    """{name: {type, value, limit, margin}} at α (the worst load case, or load case ``case``);
    empty without [[constraints]]."""
    return {con.name: limit(con, v) for con, v in zip(problem.constraints, problem.constraint_values(alpha, case, **kw))}


def step_columns(problem) -> list[str]:
    """The names of the steps' objective values (:meth:`~contactopt.ShapeProblem.step_values`):
    ``<step>``, with load cases ``<case>.<step>``; empty without load steps."""
    out = []
    for k, steps in enumerate(problem.steps):
        pre = f"{problem.cases[k].name}." if problem.has_load_cases else ""
        out += [pre + s.name for s in steps or [] if s.end]
    return out


def step_reports(problem, alpha, case: int = 0, **kw) -> list | None:
    """[(step name, objective {type, value, terms}, constraints {name: {type, value, limit, margin}})]
    at the end of every step of load case ``case``'s path at α (None without steps): each value is
    the response at that step's end alone (the friction work from the start of the path up to
    it), before ``[objective] steps`` or a constraint's ``steps`` combine them."""
    steps = problem.steps[case]
    if not steps:
        return None
    solution = problem.solution(alpha, **kw)
    ends = [j for j, s in enumerate(steps) if s.end]
    objective = _at_ends(problem.cases[case].objective, solution.cases[case], steps, ends)
    responses = [_at_ends(con.objectives[case], solution.cases[case], steps, ends) for con in problem.constraints]
    out = []
    for n, j in enumerate(ends):
        part = objective[n]
        terms = {name: {"value": part.terms[name], "weight": w} for name, w, _ in _terms(problem.cases[case].objective)}
        cons = {con.name: limit(con, r[n].value) for con, r in zip(problem.constraints, responses)}
        out.append((steps[j].name, {"type": problem.config.objective.type, "value": float(part.value),
                                    "terms": terms}, cons))
    return out


def _at_ends(objective, case, steps, ends) -> list:
    """The :class:`~contactopt.sensitivity.partials.Partials` of ``objective`` at each step end."""
    memo = {}
    return [step_objective(objective, steps, case.states, case.systems, j, memo) for j in ends]
