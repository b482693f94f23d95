"""Bézier design space and the admissible set U."""

import numpy as np
import pytest
from scipy.optimize import linprog

from contactopt.design.admissible import AdmissibleSet
from contactopt.design.bezier import BezierSurface, bernstein
from contactopt.errors import InfeasibleDesignError


def test_bernstein_partition_of_unity_and_corners():
    t = np.linspace(0, 1, 11)
    B = bernstein(7, t)
    assert np.allclose(B.sum(axis=1), 1.0, atol=1e-14)
    assert B[0, 0] == 1.0 and B[-1, -1] == 1.0
    surf = BezierSurface(7, 3, 2.0, 1.0)
    alpha = np.arange(32.0).reshape(8, 4)
    # corner points of the surface are the corner control points
    vals = surf.evaluate(alpha, [0, 2, 0, 2], [0, 0, 1, 1])
    assert np.allclose(vals, [alpha[0, 0], alpha[-1, 0], alpha[0, -1], alpha[-1, -1]])


def test_surface_derivatives_match_finite_differences():
    surf = BezierSurface(5, 3, 2.0, 1.0)
    alpha = np.random.default_rng(0).random(surf.size)
    x1, x2 = np.array([0.3, 1.1, 1.9]), np.array([0.2, 0.5, 0.9])
    D1, D2 = surf.derivative_matrices(x1, x2)
    h = 1e-6
    fd1 = (surf.evaluate(alpha, x1 + h, x2) - surf.evaluate(alpha, x1 - h, x2)) / (2 * h)
    fd2 = (surf.evaluate(alpha, x1, x2 + h) - surf.evaluate(alpha, x1, x2 - h)) / (2 * h)
    assert np.allclose(D1 @ alpha, fd1, rtol=1e-7)
    assert np.allclose(D2 @ alpha, fd2, rtol=1e-7)


def paper_set(**kw):
    return AdmissibleSet(7, 3, 2.0, 1.0, 0.75, 0.5, 0.01, **kw)


def test_initial_design_is_admissible_and_violations_are_named():
    U = paper_set()
    assert U.is_feasible(np.full(32, 0.01))
    assert U.A_ub.shape == (2 * (7 * 4 + 8 * 3), 32)
    bad = np.full(32, 0.01)
    bad[0] = -0.02
    bad[1] = 0.3
    msgs = U.violations(bad)
    assert any(m.startswith("bound: α[0,0]") for m in msgs)
    assert any("slope x2" in m for m in msgs)
    with pytest.raises(InfeasibleDesignError, match="volume"):
        U.require_feasible(np.full(32, 0.02))


@pytest.mark.parametrize("seed", range(3))
def test_slope_rows_bound_the_surface_slope(seed):
    """With the degree as divisor, every design of U has |∂ϑ/∂x_k| ≤ C1 (the stated purpose)."""
    U = paper_set()
    surf = BezierSurface(7, 3, 2.0, 1.0)
    c = np.random.default_rng(seed).standard_normal(32)
    # an extreme point of U: maximise a random linear function
    res = linprog(-c, A_ub=U.A_ub, b_ub=U.b_ub, A_eq=U.A_eq, b_eq=U.b_eq, bounds=list(zip(U.lb, U.ub)))
    assert res.status == 0 and U.is_feasible(res.x, tol=1e-7)
    g1, g2 = np.meshgrid(np.linspace(0, 2, 81), np.linspace(0, 1, 41))
    D1, D2 = surf.derivative_matrices(g1.ravel(), g2.ravel())
    assert np.abs(D1 @ res.x).max() <= 0.5 + 1e-9
    assert np.abs(D2 @ res.x).max() <= 0.5 + 1e-9
