"""The admissible set U of control points (paper §5.2) as explicit linear constraints.

    U = { α ∈ R^{(d1+1)×(d2+1)} :  0 ≤ α_ij ≤ C0,
                                   |α_{i+1,j} − α_ij| ≤ C1·a/d1,
                                   |α_{i,j+1} − α_ij| ≤ C1·b/d2,
                                   Σ_ij α_ij = C2·(d1+1)(d2+1) }.

d1, d2 are the polynomial degrees: with them the slope rows guarantee |∂ϑ/∂x_k| ≤ C1, the stated
purpose of the constraints (the derivative of a Bézier surface is a Bézier surface of degree d−1
whose control points are d·Δα/a). ``slope_divisor="count"`` uses d+1 instead (the stricter
reading of the paper's "d1 = 8, d2 = 4").

The optimizer sees only ``lb, ub, A_ub, b_ub, A_eq, b_eq`` (design vector in C order, see
:mod:`contactopt.design.bezier`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InfeasibleDesignError


@dataclass
class AdmissibleSet:
    """Linear description of U: lb ≤ α ≤ ub, A_ub α ≤ b_ub, A_eq α = b_eq."""

    d1: int
    d2: int
    a: float
    b: float
    C0: float
    C1: float
    C2: float
    slope_divisor: str = "degree"
    lb: np.ndarray = field(init=False)
    ub: np.ndarray = field(init=False)
    A_ub: np.ndarray = field(init=False)
    b_ub: np.ndarray = field(init=False)
    A_eq: np.ndarray = field(init=False)
    b_eq: np.ndarray = field(init=False)
    row_names: list = field(init=False)

    def __post_init__(self):
        if self.slope_divisor not in ("degree", "count"):
            raise ValueError("slope_divisor must be 'degree' or 'count'")
        n1, n2 = self.d1 + 1, self.d2 + 1
        n = n1 * n2
        idx = np.arange(n).reshape(n1, n2)
        off = 0 if self.slope_divisor == "degree" else 1
        s1 = self.C1 * self.a / max(self.d1 + off, 1)
        s2 = self.C1 * self.b / max(self.d2 + off, 1)
        rows, rhs, names = [], [], []
        for i in range(n1 - 1):
            for j in range(n2):
                for sign in (1.0, -1.0):
                    r = np.zeros(n)
                    r[idx[i + 1, j]], r[idx[i, j]] = sign, -sign
                    rows.append(r)
                    rhs.append(s1)
                    names.append(f"slope x1: {'+' if sign > 0 else '-'}(α[{i + 1},{j}] − α[{i},{j}]) ≤ {s1:.6g}")
        for i in range(n1):
            for j in range(n2 - 1):
                for sign in (1.0, -1.0):
                    r = np.zeros(n)
                    r[idx[i, j + 1]], r[idx[i, j]] = sign, -sign
                    rows.append(r)
                    rhs.append(s2)
                    names.append(f"slope x2: {'+' if sign > 0 else '-'}(α[{i},{j + 1}] − α[{i},{j}]) ≤ {s2:.6g}")
        self.lb = np.zeros(n)
        self.ub = np.full(n, float(self.C0))
        self.A_ub = np.array(rows).reshape(-1, n)
        self.b_ub = np.array(rhs)
        self.A_eq = np.ones((1, n))
        self.b_eq = np.array([self.C2 * n])
        self.row_names = names

    @property
    def size(self) -> int:
        return (self.d1 + 1) * (self.d2 + 1)

    def constraints(self) -> dict:
        """Keyword arguments for :func:`contactopt.optimize.minimize_bundle`."""
        return dict(lb=self.lb, ub=self.ub, A_ub=self.A_ub, b_ub=self.b_ub,
                    A_eq=self.A_eq, b_eq=self.b_eq)

    def violations(self, alpha, tol: float = 1e-9) -> list[str]:
        """Every violated constraint of U at α, by name and amount (empty when α ∈ U)."""
        x = np.asarray(alpha, float).reshape(-1)
        if x.size != self.size:
            return [f"design has {x.size} entries, expected {self.size}"]
        if not np.all(np.isfinite(x)):
            return ["design contains NaN or infinite entries"]
        out = []
        n2 = self.d2 + 1
        for k in np.flatnonzero(x < self.lb - tol):
            out.append(f"bound: α[{k // n2},{k % n2}] = {x[k]:.6g} < 0")
        for k in np.flatnonzero(x > self.ub + tol):
            out.append(f"bound: α[{k // n2},{k % n2}] = {x[k]:.6g} > C0 = {self.C0:.6g}")
        res = self.A_ub @ x - self.b_ub
        for r in np.flatnonzero(res > tol):
            out.append(f"{self.row_names[r]} violated by {res[r]:.3g}")
        eq = float(self.A_eq[0] @ x - self.b_eq[0])
        if abs(eq) > tol * max(1.0, abs(self.b_eq[0])):
            out.append(f"volume: Σα = {x.sum():.8g} ≠ C2·(d1+1)(d2+1) = {self.b_eq[0]:.8g}")
        return out

    def is_feasible(self, alpha, tol: float = 1e-9) -> bool:
        return not self.violations(alpha, tol)

    def require_feasible(self, alpha, tol: float = 1e-9) -> np.ndarray:
        """Return α as a vector, or raise :class:`InfeasibleDesignError` naming every violation."""
        v = self.violations(alpha, tol)
        if v:
            shown = v[:10] + ([f"... and {len(v) - 10} more"] if len(v) > 10 else [])
            raise InfeasibleDesignError("design is not in the admissible set U:\n  "
                                        + "\n  ".join(shown))
        return np.asarray(alpha, float).reshape(-1).copy()
