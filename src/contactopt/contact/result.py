"""The local contact problem's data check and result type, shared by every local solver.

Problem (FCLIB / Siconos convention): u = W r + q per contact (normal, tangent1, tangent2),
r_N = λ ≥ 0 the normal force on the body (:mod:`contactopt.contact.local`). The solvers
(:mod:`.newton`, :mod:`.fixed_point`) import this module and :mod:`.local` imports them; this
module imports neither.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ProblemDataError
from .cones import node_class

__all__ = ["LocalResult", "check_problem"]


@dataclass
class LocalResult:
    """Outcome of a local contact solve.

    Attributes
    ----------
    r, u : reactions and displacements (``u = W r + q``), stacked per contact (N, T1, T2).
    iterations : main iterations: Newton steps (all proximal rounds together) for
        ``"newton"``, Tresca solves (outer successive approximations) for ``"fixed-point"``.
    error : Siconos error of the returned ``r`` (:func:`contactopt.contact.cones.siconos_error`).
    converged : ``error <= tol``.
    history : error after each main iteration (``len(history) == iterations``).
    method, time_s, message : solver name, wall time, a stop message naming the criterion.
    outer_iterations, inner_iterations : for ``"fixed-point"`` the Tresca solves and the total
        number of iterations of Kučera's algorithm; for ``"newton"`` the proximal-point rounds
        (0 when plain Newton sufficed) and the Newton steps.
    stats : method-specific counters (factorizations, line-search evaluations, step types...).
    """

    r: np.ndarray
    u: np.ndarray
    iterations: int
    error: float
    converged: bool
    history: list[float]
    method: str
    time_s: float
    message: str = ""
    outer_iterations: int = 0
    inner_iterations: int = 0
    stats: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Alias of ``converged`` (scipy style)."""
        return self.converged

    def node_classes(self, mu, *, rtol: float = 1e-8) -> np.ndarray:
        """Table 4.1 class of every contact (see :func:`contactopt.contact.cones.node_class`)."""
        return node_class(self.r, self.u, mu, rtol=rtol)

    def summary(self) -> dict:
        """JSON-ready scalars: method, converged, error, iteration counts, time, message."""
        return {"method": self.method, "converged": bool(self.converged),
                "error": float(self.error), "iterations": int(self.iterations),
                "outer_iterations": int(self.outer_iterations),
                "inner_iterations": int(self.inner_iterations),
                "time_s": float(self.time_s), "message": self.message}

    def __repr__(self) -> str:
        return (f"LocalResult(method={self.method!r}, converged={self.converged}, "
                f"error={self.error:.3e}, iterations={self.iterations}, "
                f"outer/inner={self.outer_iterations}/{self.inner_iterations}, "
                f"time_s={self.time_s:.4f}, contacts={self.r.size // 3})")


def check_problem(W, q, mu, *, r0=None, single=False):
    """Validate and normalise ``(W, q, mu, r0)``; raise :class:`ProblemDataError` listing problems.

    ``W`` may be a dense array, a scipy sparse matrix or a ``LinearOperator`` (the latter is
    accepted by the fixed-point solver only). Returns ``(W, q, mu, r0)`` with ``q`` a float
    vector of length ``3p``, ``mu`` a float vector of length ``p`` and ``r0`` ``None`` or a
    float vector of length ``3p``. A dense float32 ``W`` stays float32 with ``single`` (an
    approximate W that only builds Newton matrices, see :func:`contactopt.contact.newton.solve_newton`).
    """
    problems = []
    q = np.asarray(q, dtype=float)
    if q.ndim != 1 or q.size == 0 or q.size % 3:
        problems.append(f"q must be a non-empty vector of length 3p, got shape {q.shape}")
    elif not np.all(np.isfinite(q)):
        problems.append("q has non-finite entries")
    n = q.size
    p = n // 3
    mu_arr = np.asarray(mu, dtype=float)
    if mu_arr.ndim == 0:
        mu_arr = np.full(p, float(mu_arr))
    if mu_arr.shape != (p,):
        problems.append(f"mu must be a scalar or have length p = {p}, got shape {mu_arr.shape}")
    elif not np.all(np.isfinite(mu_arr)) or np.any(mu_arr < 0):
        problems.append("mu must be finite and non-negative")
    if isinstance(W, spla.LinearOperator):
        if W.shape != (n, n):
            problems.append(f"W must be {n} x {n}, got {W.shape}")
    elif sp.issparse(W):
        if W.shape != (n, n):
            problems.append(f"W must be {n} x {n}, got {W.shape}")
        elif not np.all(np.isfinite(W.data)):
            problems.append("W has non-finite entries")
        W = W.tocsr().astype(float)
    else:
        keep = single and isinstance(W, np.ndarray) and W.dtype == np.float32
        W = W if keep else np.asarray(W, dtype=float)
        if W.shape != (n, n):
            problems.append(f"W must be {n} x {n}, got {W.shape}")
        elif not np.all(np.isfinite(W)):
            problems.append("W has non-finite entries")
    if r0 is not None:
        r0 = np.asarray(r0, dtype=float)
        if r0.shape != (n,):
            problems.append(f"r0 must have length {n}, got shape {r0.shape}")
        elif not np.all(np.isfinite(r0)):
            problems.append("r0 has non-finite entries")
    if problems:
        raise ProblemDataError("invalid contact problem: " + "; ".join(problems))
    return W, q, mu_arr, r0
