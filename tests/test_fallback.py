"""The state solve's fallback chain (contactopt.contact.fallback): a solve that needs no fallback is
the chosen method's, bit for bit; a stalled one is completed by another path to the same solution,
which the result names; when no path converges, the error names what in the model to check.

Convention: u = W r + q per contact (normal, t1, t2), r_N >= 0 the normal force on the body."""

from __future__ import annotations

import numpy as np
import pytest

from contactopt.contact.cones import complementarity_violations
from contactopt.contact.fallback import diagnose, solve_with_fallbacks
from contactopt.contact.local import solve_local
from contactopt.errors import ContactNotConverged


def spd_problem(p=12, seed=0, mu=0.3):
    """A random Delassus-like W (symmetric positive definite, diagonally dominant blocks) and a q
    that presses half of the contacts and lifts the others, with shear."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((3 * p, 3 * p))
    W = B @ B.T / (3 * p) + np.eye(3 * p)
    q = rng.standard_normal(3 * p) * 0.3
    q[0::3] = np.where(np.arange(p) % 2, 0.5, -1.0)
    return W, q, mu


def test_a_solve_that_needs_no_fallback_is_the_methods_own():
    W, q, mu = spd_problem()
    a = solve_local(W, q, mu, tol=1e-12)
    b = solve_with_fallbacks(W, q, mu, tol=1e-12)
    assert np.array_equal(a.r, b.r) and a.iterations == b.iterations and "fallback" not in b.stats


def test_a_stalled_newton_is_completed_by_a_fallback_that_the_result_names():
    # three Newton steps cannot solve it (nor can a cold restart with three): the paper's
    # fixed-point method does, and the result says so
    W, q, mu = spd_problem()
    assert not solve_local(W, q, mu, tol=1e-12, max_iter=3, raise_on_failure=False).converged
    res = solve_with_fallbacks(W, q, mu, tol=1e-12, max_iter=3, r0=np.zeros(q.size))
    assert res.converged and res.stats["fallback"] in ("fixed point", "friction continuation")
    assert max(complementarity_violations(res.r, res.u, mu).values()) <= 1e-9
    ref = solve_local(W, q, mu, tol=1e-12)
    np.testing.assert_allclose(res.r, ref.r, atol=1e-9 * np.abs(ref.r).max())


def test_no_state_is_reported_with_what_in_the_model_to_check():
    # W not positive semidefinite: no solution, and the message says why
    W, q = np.diag([-1.0, 1e-30, 1e-30]), np.array([-1.0, 0.5, 0.0])
    with pytest.raises(ContactNotConverged, match="not positive semidefinite") as err:
        solve_with_fallbacks(W, q, 0.3, tol=1e-10)
    assert "check [material]" in err.value.diagnosis
    assert "not converged: no path reached the tolerance" in str(err.value) and "newton: error" in str(err.value)


def test_the_diagnosis_names_a_penetrating_start_and_a_rigid_motion():
    text = diagnose(np.eye(6), np.array([-1.0, 0, 0, 0.5, 0, 0]), 0.3, gap=np.array([0.0, -0.2]))
    assert "penetrating start" in text and "contact node 1" in text
    z = np.array([1.0, 0, 0, -1.0, 0, 0]) / np.sqrt(2)
    text = diagnose(np.eye(6) - np.outer(z, z), np.array([0.5, 0, 0, 0.5, 0, 0]), 0.3)
    assert "a rigid motion" in text and "body.clamped" in text
    z = np.array([1.0, 0, 0, 1.0, 0, 0]) / np.sqrt(2)
    text = diagnose(np.eye(6) - np.outer(z, z), np.array([-1.0, 0, 0, -1.0, 0, 0]), 0.3)
    assert "an unbalanced load" in text
