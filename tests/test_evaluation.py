"""The evaluation as values: one Solution per design serves Θ and every constraint; objectives say
on which DOFs their ∂J/∂u lives; a constraint's problem is the same problem answering for it."""

import dataclasses

import numpy as np
import pytest

from contactopt import load_config
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.partials import CONTACT, FULL

SMALL = {"mesh": {"nx": 8, "ny": 4, "nz": 3}}
CONSTRAINTS = [{"type": "compliance", "max": 1.0}, {"type": "peak_stress", "max": 1.0}]


@pytest.fixture(scope="module")
def problem():
    return ShapeProblem(load_config("example1").with_updates({**SMALL, "constraints": CONSTRAINTS}))


def test_one_solve_serves_theta_and_every_constraint(problem):
    alpha = problem.model.initial_design() + 1e-3 * np.cos(np.arange(problem.model.n_design))
    before = problem.n_state_solves
    solution = problem.solution(alpha)
    value, xi = problem.evaluate(alpha)
    cons = problem.constraint_subgradients(alpha)
    assert problem.n_state_solves == before + 1 and problem.solution(alpha) is solution
    assert [c.value for c in cons] == problem.constraint_values(alpha)
    assert value == problem.evaluate_value(alpha) and np.all(np.isfinite(xi))


def test_a_constraint_problem_answers_for_the_constraint_alone(problem):
    alpha = problem.model.initial_design()
    peak = problem.for_constraint(1)
    assert peak.evaluate_value(alpha) == problem.constraint_values(alpha)[1]
    assert problem.response.name == "objective" and peak.response.name == "peak_stress"
    assert peak.model is problem.model and peak.n_state_solves == problem.n_state_solves


def test_an_objective_says_on_which_dofs_its_derivative_lives(problem):
    alpha = problem.model.initial_design()
    solution = problem.solution(alpha)
    state, system = solution.cases[0].state, solution.cases[0].system
    target = problem.objective.evaluate(state, system).derivatives
    peak = problem.constraints[1].objectives[0].evaluate(state, system).derivatives
    assert target.space == CONTACT and target.du.size == 3 * state.lam.size
    assert peak.space == FULL and peak.du.size == problem.model.assembler.n_full


def test_the_solution_is_a_value(problem):
    solution = problem.solution(problem.model.initial_design())
    with pytest.raises(dataclasses.FrozenInstanceError):
        solution.cases = ()
    with pytest.raises(dataclasses.FrozenInstanceError):
        solution.cases[0].states = ()
