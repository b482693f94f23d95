"""One entry to the optimizers of ``contactopt.optimize``: ``minimize(fun, x0, method=…)``."""

from __future__ import annotations

from ..errors import OptimizerError
from .bundle import BundleResult, minimize_bundle
from .constrained import minimize_constrained

METHODS = {"bundle": minimize_bundle, "constrained": minimize_constrained}
"""The methods of :func:`minimize` and the function each one calls."""


def minimize(fun, x0, *, method: str = "bundle", **options) -> BundleResult:
    """Minimise a locally Lipschitz f over a polyhedron U by the method named ``method``.

    ``"bundle"``
        :func:`~contactopt.optimize.minimize_bundle`: ``fun(x) -> (f, g)`` with g one Clarke
        subgradient; ``state`` (a :class:`~contactopt.optimize.bundle.BundleState`) resumes.
    ``"constrained"``
        :func:`~contactopt.optimize.constrained.minimize_constrained`: ``fun(x) -> (f, g, c, J)``
        with the constraints c(x) ≤ 0 and one subgradient of each c_i in the rows of J, by an
        exact penalty whose weight the method adapts; ``state`` (a
        :class:`~contactopt.optimize.constrained.PenaltyState`) and ``bundle_state`` resume.

    ``options`` are those of the method called (U as ``lb``, ``ub``, ``A_ub``, ``b_ub``,
    ``A_eq``, ``b_eq``; ``eps``, ``max_iter``, ``callback``, the method's parameters).

    Examples
    --------
    >>> import numpy as np
    >>> from contactopt.optimize import minimize
    >>> res = minimize(lambda x: (abs(x[0] - 1.0), np.sign(x - 1.0)), np.array([3.0]), lb=[0.0], ub=[5.0])
    >>> bool(res.success), round(float(res.x[0]), 6)
    (True, 1.0)
    """
    try:
        solver = METHODS[method]
    except KeyError:
        raise OptimizerError(f"unknown optimization method {method!r}: choose one of "
                             f"{', '.join(map(repr, METHODS))}") from None
    return solver(fun, x0, **options)
