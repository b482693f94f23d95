"""Responses: scalar functions of a :class:`~contactopt.sensitivity.solution.Solution`.

A response is data: per load case an objective (``contactopt.sensitivity.objectives``), the
cases joined by a ``contactopt.sensitivity.cases.Combination`` and, on a load path, the
steps' values joined by a ``contactopt.sensitivity.steps.StepChoice``. Θ of ``[objective]``
is one; each ``[[constraints]]`` entry is another (its objectives of the constraint's type, the
cases joined by the max, its own ``steps``). :func:`evaluate_response` gives the value and, per
case, the partial derivatives with respect to every solve, which
:func:`~contactopt.sensitivity.subgradient.subgradient` turns into one Clarke subgradient.

Conventions of the derivatives: :mod:`contactopt.sensitivity.partials` (per contact node the
order (t1, t2, ν), λ = r_ν ≥ 0, τ = −r_t).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cases import Combination, Combined
from .partials import add_solve
from .steps import StepChoice, step_objective


@dataclass(frozen=True)
class Response:
    """``objectives`` (one per load case), joined over the cases by ``combination`` and over a load
    path's steps by ``steps``; ``name`` for messages."""

    name: str
    objectives: tuple
    combination: Combination
    steps: StepChoice

    def resolve(self) -> None:
        """Compute what the objectives need from other designs (a 'design' target) now."""
        for obj in self.objectives:
            obj.resolve()


@dataclass(frozen=True)
class CaseValue:
    """Θ_k of one load case: ``value``, its derivatives ``solves`` {solve: Derivatives} (a load path:
    the chosen steps' combined), ``terms`` the [[objective.terms]] values (combined over the steps
    as Θ_k is) and ``ends`` {solve: J} at the end of every step of a load path (empty without)."""

    value: float
    solves: dict
    terms: dict
    ends: dict


@dataclass(frozen=True)
class ResponseValue:
    """A response at one :class:`~contactopt.sensitivity.solution.Solution`: ``combined`` over the
    cases (``contactopt.sensitivity.cases.Combined``) and each case's :class:`CaseValue`."""

    combined: Combined
    cases: tuple
    kind: str = "sum"        # the combination's kind: "max" or "sum"

    @property
    def value(self) -> float:
        return self.combined.value


def evaluate_response(response: Response, solution, steps: list) -> ResponseValue:
    """The response at ``solution``; ``steps`` each case's load path (None: the static problem)."""
    cases = tuple(case_value(obj, sol, path, response.steps)
                  for obj, sol, path in zip(response.objectives, solution.cases, steps))
    return ResponseValue(response.combination.combine([c.value for c in cases]), cases, response.combination.kind)


def case_value(objective, solution, steps, choice: StepChoice) -> CaseValue:
    """Θ_k of a load case from its :class:`~contactopt.sensitivity.solution.CaseSolution`: its
    objective, or on a load path the steps' objectives combined as ``choice`` says (the friction
    work depends on every solve up to the step's end; sensitivity/steps.py)."""
    if not steps:
        part = objective.evaluate(solution.state, solution.system)
        return CaseValue(part.value, dict(part.solves), dict(part.terms), {})
    memo, parts = {}, {}
    for j, step in enumerate(steps):
        if step.end:
            parts[j] = step_objective(objective, steps, solution.states, solution.systems, j, memo)
    value, coef = choice.combine({j: (steps[j].name, parts[j].value) for j in parts})
    rhs = {}
    for j, c in coef.items():
        for i, d in parts[j].solves.items():
            add_solve(rhs, i, d.scaled(c))
    last = parts[max(parts)].terms
    terms = {name: float(sum(c * parts[j].terms[name] for j, c in coef.items())) for name in last}
    return CaseValue(value, rhs, terms, {j: float(p.value) for j, p in parts.items()})


def max_combination(combination: Combination) -> Combination:
    """The cases joined by the max, each of weight 1 (a constraint holds in every case)."""
    return Combination("max", np.ones(len(combination.names)), combination.active_tol, combination.names)
