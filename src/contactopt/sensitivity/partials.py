"""What an objective returns: its value and its partial derivatives, as typed records.

Conventions: on the contact DOFs ∂J/∂u is (3p,), per contact node the order (t1, t2, ν) (λ = r_ν ≥ 0
the normal contact force, τ = −r_t, paper (3.17)); on every DOF it is (3·n_nodes,), DOF 3n + m.
Which of the two a record holds is its ``space`` field, never guessed from an array's length.
∂J/∂α is taken at fixed (u, λ) and ∂J/∂λ is (p,).

A load path has several solves (``contactopt.sensitivity.steps``); J at a step's end may
depend on every solve up to it (the friction work), so :class:`Partials` maps a solve's index
along the path to that solve's :class:`Derivatives` (a static problem: the one solve 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

CONTACT = "contact"     # ∂J/∂u on the contact DOFs (3p, per node (t1, t2, ν))
FULL = "full"           # ∂J/∂u on every DOF of the body (3·n_nodes)


@dataclass(frozen=True)
class Derivatives:
    """∂J/∂u (``du``, on ``space``), ∂J/∂λ (``dlam``, p) and ∂J/∂α at fixed (u, λ) (``dalpha``) of one solve."""

    du: np.ndarray
    dlam: np.ndarray
    dalpha: np.ndarray
    space: str = CONTACT

    def scaled(self, c: float) -> Derivatives:
        return Derivatives(c * self.du, c * self.dlam, c * self.dalpha, self.space)

    def on_every_dof(self, contact_dofs: np.ndarray, n_full: int) -> Derivatives:
        """The same derivatives with ∂J/∂u on every DOF (zero off the contact DOFs ``contact_dofs``)."""
        if self.space == FULL:
            return self
        du = np.zeros(n_full)
        du[contact_dofs] = self.du
        return Derivatives(du, self.dlam, self.dalpha, FULL)

    def plus(self, other: Derivatives) -> Derivatives:
        """The sum of two solves' derivatives on the same space."""
        if other.space != self.space:
            raise ValueError(f"derivatives on the {self.space} and the {other.space} DOFs do not add")
        return Derivatives(self.du + other.du, self.dlam + other.dlam, self.dalpha + other.dalpha, self.space)


@dataclass(frozen=True)
class Partials:
    """J's ``value`` and its derivatives ``solves`` {solve index: :class:`Derivatives`}; ``terms`` the
    values of the [[objective.terms]] (unweighted; empty for an objective of one type)."""

    value: float
    solves: dict
    terms: dict = field(default_factory=dict)

    @property
    def derivatives(self) -> Derivatives:
        """The derivatives of an objective of one solve."""
        (out,) = self.solves.values()
        return out

    def at_solve(self, j: int) -> Partials:
        """An objective of one solve, evaluated at solve ``j`` of a load path."""
        return Partials(self.value, {j: self.derivatives}, self.terms)


def add_solve(out: dict, i: int, d: Derivatives) -> None:
    """Add solve ``i``'s derivatives ``d`` to ``out`` {solve: Derivatives}."""
    out[i] = out[i].plus(d) if i in out else d
