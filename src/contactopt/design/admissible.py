"""The admissible set U of control points (paper §5.2) as explicit linear constraints.

    U = { α ∈ R^{(d1+1)×(d2+1)} :  lower ≤ α_ij ≤ C0,
                                   |α_{i+1,j} − α_ij| ≤ C1·a/d1,
                                   |α_{i,j+1} − α_ij| ≤ C1·b/d2,
                                   Σ_ij α_ij = C2·(d1+1)(d2+1),
                                   g0_m + ϑ_α(x'_m) ≥ 0 at every node m of the contact face }.

The paper's U has lower = 0. A negative ``lower`` admits crowned faces (a paraboloid needs a
negative control point although ϑ_α ≥ 0 everywhere); the last rows keep the face off its
counterpart at its nodes (g0 the face's initial gap: its height above the foundation plane in the
reference mesh, 0 on the plane, or its distance to an obstacle).
With lower ≥ 0 and g0 ≥ 0 they follow from the bounds (Bernstein polynomials are ≥ 0 and sum to
1, so ϑ_α ≥ min α), and in general every row that cannot be active on the other constraints is
dropped: the paper's U has exactly its bound, slope and volume rows.

d1, d2 are the polynomial degrees: with them the slope rows guarantee |∂ϑ/∂x_k| ≤ C1, the stated
purpose of the constraints (the derivative of a Bézier surface is a Bézier surface of degree d−1
whose control points are d·Δα/a). ``slope_divisor="count"`` uses d+1 instead (the stricter
reading of the paper's "d1 = 8, d2 = 4").

The optimizer sees only ``lb, ub, A_ub, b_ub, A_eq, b_eq`` (design vector in C order, see
:mod:`contactopt.design.bezier`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from ..errors import InfeasibleDesignError

log = logging.getLogger(__name__)


@dataclass
class AdmissibleSet:
    """Linear description of U: lb ≤ α ≤ ub, A_ub α ≤ b_ub, A_eq α = b_eq.

    ``gap_basis`` (p, n): ϑ_α = gap_basis @ α at the p nodes of the contact face,
    ``gap_offset`` (p,) their initial gap g0 (default 0); given, the rows −ϑ_α(x'_m) ≤ g0_m that
    can be active join A_ub after the slope rows (``gap_rows`` lists which face nodes they are).
    ``gap_nodes``, ``gap_points``: node numbers and (x1, x2) of those nodes, for messages, and
    ``counterpart`` what the face meets (the foundation plane, an obstacle, an elastic foundation's face).
    """

    d1: int
    d2: int
    a: float
    b: float
    C0: float
    C1: float
    C2: float
    slope_divisor: str = "degree"
    lower: float = 0.0
    gap_basis: np.ndarray | None = None
    gap_offset: np.ndarray | None = None
    gap_nodes: np.ndarray | None = None
    gap_points: np.ndarray | None = None
    counterpart: str = "the foundation plane"
    direction: str = "both"
    initial: np.ndarray | None = None
    linear: tuple = ()
    lb: np.ndarray = field(init=False)
    ub: np.ndarray = field(init=False)
    A_ub: np.ndarray = field(init=False)
    b_ub: np.ndarray = field(init=False)
    A_eq: np.ndarray = field(init=False)
    b_eq: np.ndarray = field(init=False)
    row_names: list = field(init=False)
    gap_rows: np.ndarray = field(init=False)

    def __post_init__(self):
        if self.slope_divisor not in ("degree", "count"):
            raise ValueError("slope_divisor must be 'degree' or 'count'")
        if not self.lower <= self.C0:
            raise ValueError(f"lower = {self.lower:g} > C0 = {self.C0:g}: the box of the control points is empty")
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
        self.lb = np.zeros(n) if self.lower == 0 else np.full(n, float(self.lower))
        self.ub = np.full(n, float(self.C0))
        self.A_ub = np.array(rows).reshape(-1, n)
        self.b_ub = np.array(rhs)
        self.A_eq = np.ones((1, n))
        self.b_eq = np.array([self.C2 * n])
        self.row_names = names
        self.n_slope = len(rows)
        self.volume = "equal"
        self.gap_rows = np.zeros(0, np.int64)
        self.linear_rows = np.zeros(0, np.int64)     # rows of A_ub from `linear`, after the gap rows
        self.linear_eq = np.zeros(0, np.int64)       # rows of A_eq from `linear`
        if self.direction != "both":
            self._apply_direction()
        if self.gap_basis is not None:
            self._add_gap_rows()
        if self.linear:
            self._add_linear_rows()

    # ------------------------------------------------------------------ grow / shrink, user rows
    def _apply_direction(self) -> None:
        """``grow``: α ≥ initial, the mean value an upper bound Σα ≤ C2·n (the material that may be
        added); ``shrink``: α ≤ initial, Σα ≥ C2·n. The equality would leave only the initial design."""
        if self.direction not in ("grow", "shrink"):
            raise ValueError("direction must be 'both', 'grow' or 'shrink'")
        a0 = np.asarray(self.initial, float).reshape(-1)
        if self.direction == "grow":
            self.lb = np.maximum(self.lb, a0)
            row, rhs, self.volume = self.A_eq, self.b_eq, "at_most"
        else:
            self.ub = np.minimum(self.ub, a0)
            row, rhs, self.volume = -self.A_eq, -self.b_eq, "at_least"
        self.A_ub = np.vstack([self.A_ub, row])
        self.b_ub = np.concatenate([self.b_ub, rhs])
        self.row_names = self.row_names + [f"volume: Σα {'≤' if self.volume == 'at_most' else '≥'} "
                                           f"C2·(d1+1)(d2+1) = {self.b_eq[0]:.8g}"]
        self.n_slope += 1
        self.A_eq, self.b_eq = np.zeros((0, self.size)), np.zeros(0)

    def _add_linear_rows(self) -> None:
        """The rows of ``linear``: (coefficients (d1+1)×(d2+1), "upper" | "equal", value)."""
        ub, eq = [], []
        for k, (coef, kind, value) in enumerate(self.linear):
            c = np.asarray(coef, float).reshape(-1)
            (ub if kind == "upper" else eq).append((k, c, float(value)))
        if ub:
            self.linear_rows = self.A_ub.shape[0] + np.arange(len(ub))
            self.A_ub = np.vstack([self.A_ub] + [c[None] for _, c, _ in ub])
            self.b_ub = np.concatenate([self.b_ub, [v for _, _, v in ub]])
            self.row_names = self.row_names + [f"design.linear[{k}]: Σ c·α ≤ {v:.6g}" for k, _, v in ub]
        if eq:
            self.linear_eq = self.A_eq.shape[0] + np.arange(len(eq))
            self.A_eq = np.vstack([self.A_eq] + [c[None] for _, c, _ in eq])
            self.b_eq = np.concatenate([self.b_eq, [v for _, _, v in eq]])
            self.eq_names = [f"design.linear[{k}]: Σ c·α = {v:.6g}" for k, _, v in eq]

    def nonempty(self, A_ub=None, b_ub=None, A_eq=None, b_eq=None, lb=None, ub=None) -> bool:
        """Whether U (or the given linear set, default U's own rows) holds a point: one LP."""
        A_ub = self.A_ub if A_ub is None else A_ub
        b_ub = self.b_ub if b_ub is None else b_ub
        A_eq = self.A_eq if A_eq is None else A_eq
        b_eq = self.b_eq if b_eq is None else b_eq
        lb = self.lb if lb is None else lb
        ub = self.ub if ub is None else ub
        if np.any(lb > ub):
            return False
        res = linprog(np.zeros(lb.size), A_ub=A_ub if A_ub.size else None, b_ub=b_ub if A_ub.size else None,
                      A_eq=A_eq if A_eq.size else None, b_eq=b_eq if A_eq.size else None,
                      bounds=list(zip(lb, ub)), method="highs")
        return res.status == 0

    # ------------------------------------------------------------------ ϑ_α ≥ 0 on the face
    def _gap(self):
        B = np.asarray(self.gap_basis, float)
        g0 = np.zeros(B.shape[0]) if self.gap_offset is None else np.asarray(self.gap_offset, float)
        return B, g0

    def _add_gap_rows(self) -> None:
        """Append −ϑ_α(x'_m) ≤ g0_m for the face nodes m where it can be active on the rest of U.

        ϑ_α(x'_m) = Σ_k B_mk α_k with B ≥ 0, Σ_k B_mk = 1, so ϑ_α(x'_m) ≥ Σ_k B_mk ℓ_k for any
        lower bounds ℓ_k of the control points on U: first ℓ = lower (the box), then, for the rows
        this leaves, the least value of each α_k over the box, slope and volume rows (one small
        LP per control point, independent of the mesh)."""
        B, g0 = self._gap()
        keep = self.lower + g0 < 0
        if np.any(keep):
            ell = self._least_control_points()
            if ell is not None:
                keep &= B @ ell + g0 < 0
        self.gap_rows = np.flatnonzero(keep)
        if not self.gap_rows.size:
            return
        self.A_ub = np.vstack([self.A_ub, -B[self.gap_rows]])
        self.b_ub = np.concatenate([self.b_ub, g0[self.gap_rows]])
        self.row_names = self.row_names + [f"gap: ϑ ≥ {-g0[m]:.6g} at {self._where(m)}" for m in self.gap_rows]
        log.info("admissible set: ϑ_α ≥ 0 at %d of %d nodes of the contact face (the others cannot "
                 "be active)", self.gap_rows.size, B.shape[0])

    def _least_control_points(self):
        """min α_k over the box, slope and volume rows, for every k (None if that set is empty)."""
        n = self.size
        A, b = self.A_ub, self.b_ub
        out = np.empty(n)
        for k in range(n):
            c = np.zeros(n)
            c[k] = 1.0
            res = linprog(c, A_ub=A, b_ub=b, A_eq=self.A_eq if self.A_eq.size else None,
                          b_eq=self.b_eq if self.A_eq.size else None,
                          bounds=list(zip(self.lb, self.ub)), method="highs")
            if res.status != 0:
                return None
            out[k] = res.fun - 1e-9 * max(1.0, abs(self.C0))     # the LP's tolerance, to the safe side
        return out

    def _where(self, m) -> str:
        node = f"node {int(self.gap_nodes[m])}" if self.gap_nodes is not None else f"face node {int(m)}"
        if self.gap_points is not None:
            node += " (" + ", ".join(f"{v:.4g}" for v in self.gap_points[m]) + ")"
        return node

    def gap_violations(self, alpha, tol: float = 1e-9) -> list[str]:
        """ϑ_α + g0 < 0 at nodes of the contact face (all of them, not only the kept rows): one line."""
        if self.gap_basis is None:
            return []
        B, g0 = self._gap()
        gap = B @ np.asarray(alpha, float).reshape(-1) + g0
        bad = np.flatnonzero(gap < -tol)
        if not bad.size:
            return []
        m = int(bad[np.argmin(gap[bad])])
        plane = self.counterpart == "the foundation plane"
        what = "ϑ ≥ 0" if not np.any(g0) else "height + ϑ ≥ 0" if plane else "distance + ϑ ≥ 0"
        where = "below" if plane else "into"
        return [f"gap: {what} broken at {bad.size} of {gap.size} nodes of the contact face (the face "
                f"{where} {self.counterpart}), the deepest {gap[m]:.6g} at {self._where(m)}"]

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
        low = "0" if self.lower == 0 else f"lower = {self.lower:.6g}"
        if self.direction == "grow":
            low += " or its initial value (design.direction = 'grow')"
        for k in np.flatnonzero((x > self.ub + tol) & (self.ub < self.C0)):
            out.append(f"bound: α[{k // n2},{k % n2}] = {x[k]:.6g} > its initial value {self.ub[k]:.6g} "
                       "(design.direction = 'shrink')")
        for k in np.flatnonzero(x < self.lb - tol):
            out.append(f"bound: α[{k // n2},{k % n2}] = {x[k]:.6g} < {low}")
        for k in np.flatnonzero((x > self.ub + tol) & ~(self.ub < self.C0)):
            out.append(f"bound: α[{k // n2},{k % n2}] = {x[k]:.6g} > C0 = {self.C0:.6g}")
        n_slope = self.n_slope        # slope rows (and the volume row of grow / shrink)
        res = self.A_ub[:n_slope] @ x - self.b_ub[:n_slope]
        for r in np.flatnonzero(res > tol):
            out.append(f"{self.row_names[r]} violated by {res[r]:.3g}")
        if self.volume == "equal":
            eq = float(self.A_eq[0] @ x - self.b_eq[0])
            if abs(eq) > tol * max(1.0, abs(self.b_eq[0])):
                out.append(f"volume: Σα = {x.sum():.8g} ≠ C2·(d1+1)(d2+1) = {self.b_eq[0]:.8g}")
        for r in self.linear_rows:
            v = float(self.A_ub[r] @ x - self.b_ub[r])
            if v > tol * max(1.0, abs(self.b_ub[r])):
                out.append(f"{self.row_names[r]} violated by {v:.3g}")
        for k, r in enumerate(self.linear_eq):
            v = float(self.A_eq[r] @ x - self.b_eq[r])
            if abs(v) > tol * max(1.0, abs(self.b_eq[r])):
                out.append(f"{self.eq_names[k]} violated by {v:.3g}")
        return out + self.gap_violations(x, tol)

    def is_feasible(self, alpha, tol: float = 1e-9) -> bool:
        return feasible(self, alpha, tol)

    def require_feasible(self, alpha, tol: float = 1e-9) -> np.ndarray:
        """Return α as a vector, or raise :class:`InfeasibleDesignError` naming every violation."""
        return required(self, alpha, tol)


def feasible(admissible, alpha, tol: float = 1e-9) -> bool:
    """Whether α lies in an admissible set (one with ``violations``), to ``tol``."""
    return not admissible.violations(alpha, tol)


def required(admissible, alpha, tol: float = 1e-9) -> np.ndarray:
    """α as a vector, or :class:`InfeasibleDesignError` naming every violation of ``admissible``."""
    v = admissible.violations(alpha, tol)
    if v:
        shown = v[:10] + ([f"... and {len(v) - 10} more"] if len(v) > 10 else [])
        raise InfeasibleDesignError("design is not in the admissible set U:\n  " + "\n  ".join(shown))
    return np.asarray(alpha, float).reshape(-1).copy()
