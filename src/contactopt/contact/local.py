"""The local (Delassus) form of the contact problem with Coulomb friction and its driver.

Problem (FCLIB / Siconos convention): given the Delassus operator ``W`` (``3p x 3p``), the
free displacement ``q`` (``3p``) and friction coefficients ``mu`` (``p``), find ``r, u`` with

    u = W r + q,   K_mu ∋ r  ⊥  u + mu ||u_T|| e_N ∈ K_mu*,

contact by contact, each ordered (normal, tangent1, tangent2). In the shape problem ``r`` is
the contact force on the body (``r_N = lambda >= 0``, ``r_T = tau``), ``u`` the contact
displacement with the initial gap added to its normal component, ``W = S^{-1}`` the inverse of
the condensed stiffness (the paper's ``Q`` in (5.1)). The conditions say: ``r_N >= 0``,
``u_N >= 0``, ``r_N u_N = 0``, ``||r_T|| <= mu r_N`` and ``r_T = -mu r_N u_T/||u_T||`` where
``u_T != 0``.

:func:`solve_local` dispatches to :func:`contactopt.contact.newton.solve_newton` (semismooth
Newton, default) or :func:`contactopt.contact.fixed_point.solve_fixed_point` (the paper's
successive approximations, Cor. 3.9, with Kučera's Algorithm 1 inside).
"""

from __future__ import annotations

from ..errors import ProblemDataError
from .fixed_point import solve_fixed_point
from .newton import solve_newton
from .result import LocalResult, check_problem

__all__ = ["LocalResult", "solve_local", "check_problem"]

METHODS = ("newton", "fixed-point")


def solve_local(W, q, mu, *, method: str = "newton", tol: float = 1e-8, max_iter=None,
                r0=None, raise_on_failure: bool = True, **options) -> LocalResult:
    """Solve the local Coulomb friction problem ``u = W r + q``, ``K_mu ∋ r ⊥ u~ ∈ K_mu*``.

    Parameters
    ----------
    W : (3p, 3p) Delassus operator (dense, sparse, or ``LinearOperator`` for fixed-point).
    q : (3p,) free displacement/velocity; per contact (normal, tangent1, tangent2).
    mu : friction coefficient, scalar or (p,).
    method : ``"newton"`` (semismooth Alart–Curnier Newton with a proximal fallback) or
        ``"fixed-point"`` (successive approximations of Cor. 3.9, each a Tresca problem (5.1)
        solved by Kučera's Algorithm 1).
    tol : target Siconos error.
    max_iter : Newton steps / Tresca solves; method default when ``None``.
    r0 : warm start (reactions).
    raise_on_failure : raise :class:`contactopt.errors.ContactNotConverged` (carrying the error
        history) when ``tol`` is not reached; with ``False`` return ``converged=False`` instead.
    options : passed on to the method (see ``solve_newton`` and ``solve_fixed_point``).
    """
    if method == "newton":
        solver = solve_newton
    elif method in ("fixed-point", "fixed_point", "fp"):
        solver = solve_fixed_point
    else:
        raise ProblemDataError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    kwargs = dict(tol=tol, r0=r0, raise_on_failure=raise_on_failure, **options)
    if max_iter is not None:
        kwargs["max_iter"] = max_iter
    return solver(W, q, mu, **kwargs)
