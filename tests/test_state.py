"""The state of the paper's examples: the two Coulomb solvers agree and every contact condition holds.

The contact conditions (3.17): λ ≥ 0, u_ν + g ≥ 0, λ(u_ν + g) = 0, ‖τ‖ ≤ Fλ, τ = Fλ u_t/‖u_t‖ where u_t ≠ 0 — at the
configurations' default tolerance, on the example meshes, at α0 and at random admissible designs.
"""

from __future__ import annotations

import numpy as np
import pytest

from contactopt.problem import ShapeProblem


def random_admissible(model, seed, amp=0.003):
    d = np.random.default_rng(seed).standard_normal(model.n_design)
    a = model.initial_design() + amp * (d - d.mean())
    assert model.admissible.is_feasible(a)
    return a


@pytest.mark.parametrize("example", [pytest.param("example1", marks=pytest.mark.integration), "example2"])
def test_newton_and_fixed_point_agree_and_the_contact_conditions_hold(example):
    newton, fixed = ShapeProblem(example, method="newton"), ShapeProblem(example, method="fixed-point")
    model = newton.model
    for alpha in (model.initial_design(), random_admissible(model, 1)):
        sn, sf = newton.solve_state(alpha), fixed.solve_state(alpha)
        assert sn.converged and sf.converged
        assert np.abs(sn.lam - sf.lam).max() <= 1e-7 * sf.lam.max()
        assert np.abs(sn.tau - sf.tau).max() <= 1e-7 * sf.lam.max()
        assert np.abs(sn.u - sf.u).max() <= 1e-7 * np.abs(sf.u).max()
        assert sn.complementarity <= 1e-9 and sf.complementarity <= 1e-9
        assert 0 < np.sum(sn.lam > 0) < sn.lam.size          # a partial contact, both cases exercised
