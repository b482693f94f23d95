"""Automatic diagonal scaling of the variables of :func:`~contactopt.optimize.minimize_bundle`.

The bundle method is not invariant under a change of the variables' units: its proximal term
‖d‖²/(2t), its locality measure γ‖x − y‖², its first step and its certificate all measure x in
one Euclidean norm.  A problem whose variables live on scales 10⁴ apart (HS114: a flow of size
10⁴ beside a ratio of size 1) then gets a model that is sharp in one variable and blind in
another.  The remedy is the classical one (Gill, Murray & Wright, *Practical Optimization*,
8.7, "scaling by the bounds"): where a variable has a finite box lb_i ≤ x_i ≤ ub_i, its width
is the user's statement of its range, and the method works in ``z = D⁻¹ x`` with ``D_ii``
proportional to that width.

Conventions:

* ``x = D z`` with ``D = diag(d)``; f̃(z) = f(Dz), its subgradient ``g̃ = D g``; the rows of U
  become ``lb/d ≤ z ≤ ub/d``, ``(A_ub D) z ≤ b_ub``, ``(A_eq D) z = b_eq`` (b unchanged);
* ``d_i = 2^round(log₂(w_i/w̄))`` for the variables with a finite positive width
  ``w_i = ub_i − lb_i``, ``w̄`` the geometric mean of those widths; ``d_i = 1`` for the others
  (an unbounded or a fixed variable).  So D changes the shape of the box, not its size (the
  d_i of the bounded variables have a geometric mean of about 1), a box of one width (the
  designs of contactopt's examples) gives D = I exactly, and — d being powers of two — every
  product and quotient above is exact: the scaled problem is the user's problem, written in
  other units, with no rounding of its data;
* the ratio of the largest to the smallest d_i is capped at 2⁴⁰ (a width of 10⁻¹² beside one of
  1 is a nearly fixed variable, not a unit).

The stationarity measure of the scaled run is ``max(‖p̃‖, α_p + σ)/max(1, |f|)`` with
``p̃ = D p`` (p the aggregate subgradient of f + indicator(U) in the user's variables); for a
convex f the certificate reads, in the user's variables,
``f(x) − f(z) ≤ eps·max(1, |f|)·(1 + ‖D⁻¹(z − x)‖)`` for every z ∈ U: distances are measured in
units of the box widths relative to their geometric mean (docs/stopping.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SCALINGS", "VariableScaling", "variable_scaling"]

SCALINGS = ("bounds", "none")
"""Values of ``minimize_bundle``'s option ``scale``: "bounds" (default), "none" (D = I)."""

_MAX_LOG2_RATIO = 40


@dataclass(frozen=True)
class VariableScaling:
    """x = d·z (componentwise, d powers of two): maps the user's problem to the method's."""

    d: np.ndarray

    def inner(self, x):
        """The method's variables z = x/d of a user point x."""
        return None if x is None else np.asarray(x, dtype=float).reshape(-1) / self.d

    def outer(self, z):
        """The user's point x = d·z."""
        return np.asarray(z, dtype=float) * self.d

    def oracle(self, oracle):
        """f̃(z) = f(d·z), g̃ = d·g (a subgradient of the wrong shape is passed on unchanged, so
        that the method's own check names it)."""
        d = self.d

        def scaled(z):
            f, g = oracle(z * d)
            g = np.asarray(g, dtype=float)
            return f, (g * d if g.shape == d.shape else g)
        return scaled

    def constraints(self, lb, ub, A_ub, b_ub, A_eq, b_eq) -> dict:
        """U's rows in z: bounds divided by d, the columns of A_ub and A_eq multiplied by d."""
        d = self.d

        def cols(A):
            return None if A is None else np.asarray(A, dtype=float) * d
        return dict(lb=None if lb is None else np.broadcast_to(np.asarray(lb, float), d.shape) / d,
                    ub=None if ub is None else np.broadcast_to(np.asarray(ub, float), d.shape) / d,
                    A_ub=cols(A_ub), b_ub=b_ub, A_eq=cols(A_eq), b_eq=b_eq)

    def result(self, res):
        """A result of the method in the user's variables: x = d·z, jac = ξ = g̃/d.  The
        ``state`` stays in the method's variables (it resumes a run with the same U)."""
        res.x = self.outer(res.x)
        res.jac = np.asarray(res.jac, dtype=float) / self.d
        return res

    def callback(self, callback):
        if callback is None:
            return None

        def scaled(intermediate):
            return callback(self.result(intermediate))
        return scaled


def variable_scaling(n: int, lb=None, ub=None, mode: str = "bounds") -> VariableScaling | None:
    """The scaling of ``mode`` for the box ``lb ≤ x ≤ ub`` of n variables; None where it is the
    identity (no wrapper at all, so such a run is bit for bit the unscaled one)."""
    if mode == "none" or lb is None or ub is None:
        return None
    try:
        lo = np.broadcast_to(np.asarray(lb, dtype=float), (n,))
        hi = np.broadcast_to(np.asarray(ub, dtype=float), (n,))
    except ValueError:            # a box of the wrong shape: the feasible set's check names it
        return None
    with np.errstate(invalid="ignore"):
        w = hi - lo
    bounded = np.isfinite(w) & (w > 0)
    if np.count_nonzero(bounded) < 2:
        return None
    logw = np.log2(w[bounded])
    k = np.round(logw - float(np.mean(logw)))
    # cap the spread of d (symmetrically about the mean) at 2**40
    half = _MAX_LOG2_RATIO / 2
    k = np.clip(k, -half, half)
    if not np.any(k):
        return None
    d = np.ones(n)
    d[bounded] = np.ldexp(1.0, k.astype(int))
    return VariableScaling(d)
