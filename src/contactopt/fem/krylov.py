"""The Krylov solver of every path: right-preconditioned restarted GMRES.

Used by the full-space Newton method (:mod:`contactopt.contact.fullspace`), its adjoint
(:mod:`contactopt.sensitivity.adjoint_fullspace`) and the Delassus path's adjoint in W-form
(:func:`contactopt.sensitivity.adjoint.solve_adjoint_delassus`). ``apply`` and ``M`` are
callables (a matrix's ``dot`` serves), as pyamg's Krylov solvers take them; a solve that does
not converge raises :class:`KrylovNotConverged` (a SolverError) with its residual history.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError

__all__ = ["gmres", "KrylovResult", "KrylovNotConverged"]


class KrylovNotConverged(SolverError):
    """A Krylov solve that did not reach its tolerance; ``history`` holds the largest relative
    residual over the columns after each iteration (``history[0]``: the initial one)."""

    def __init__(self, message, history=()):
        self.history = list(history)
        self.iterations = max(len(self.history) - 1, 0)
        super().__init__(message)


@dataclass
class KrylovResult:
    """``x`` (shape of b), ``iterations``, ``history`` (largest relative residual per iteration,
    starting with the initial one), ``residual`` (final, per column), ``seconds``."""

    x: np.ndarray
    iterations: int
    history: list
    residual: np.ndarray
    seconds: float = 0.0
    info: dict = field(default_factory=dict)


def gmres(apply, b, M=None, *, x0=None, atol: float | None = None, rtol: float | None = None,
          restart: int = 60, max_iter: int = 500, scale: float | None = None,
          check: bool = True) -> KrylovResult:
    """Right-preconditioned restarted GMRES for G x = b: stops when ‖b − G x‖ ≤ ``atol`` (or
    ``rtol``·‖b‖).

    ``apply(x)`` is G x, ``M(v)`` the preconditioner. Classical Gram–Schmidt with one
    reorthogonalization (two matrix–vector products with the basis). ``history`` holds the
    residual norm divided by ``scale`` (default ‖b‖) after every iteration, ``history[0]`` the
    initial one. Raises :class:`KrylovNotConverged` with it after ``max_iter`` iterations or on a
    non-finite residual. The residual is confirmed by a product at the solution; ``check=False``
    leaves that to the caller (whose next product is at the solution anyway)."""
    t0 = time.perf_counter()
    b = np.asarray(b, dtype=np.float64)
    if atol is None:
        atol = (1e-10 if rtol is None else rtol) * float(np.linalg.norm(b) or 1.0)
    n = b.size
    M = M or (lambda v: v)
    scale = float(scale or np.linalg.norm(b) or 1.0)
    x = np.zeros(n) if x0 is None else np.array(x0, dtype=np.float64)
    r = b - apply(x) if x0 is not None else b.copy()
    beta = float(np.linalg.norm(r))
    history = [beta / scale]
    its = 0
    V = np.empty((restart + 1, n))
    Z = np.empty((restart, n))
    while True:
        if beta <= atol:
            return KrylovResult(x, its, history, np.array([beta / scale]), time.perf_counter() - t0)
        if its >= max_iter:
            raise KrylovNotConverged(f"GMRES did not converge: residual {beta / scale:.3g} (relative) > "
                                     f"{atol / scale:.3g} after {its} iterations", history)
        if not np.isfinite(beta):
            raise KrylovNotConverged(f"GMRES: non-finite residual after {its} iterations", history)
        H = np.zeros((restart + 1, restart))
        cs, sn = np.zeros(restart), np.zeros(restart)
        g = np.zeros(restart + 1)
        g[0] = beta
        V[0] = r / beta
        j = -1
        for j in range(restart):
            Z[j] = M(V[j])
            w = apply(Z[j])
            its += 1
            h = V[:j + 1] @ w
            w -= h @ V[:j + 1]
            h2 = V[:j + 1] @ w              # reorthogonalization
            w -= h2 @ V[:j + 1]
            h += h2
            hn = float(np.linalg.norm(w))
            H[:j + 1, j] = h
            H[j + 1, j] = hn
            if hn > 0:
                V[j + 1] = w / hn
            for i in range(j):              # previous Givens rotations
                a, c_ = H[i, j], H[i + 1, j]
                H[i, j], H[i + 1, j] = cs[i] * a + sn[i] * c_, -sn[i] * a + cs[i] * c_
            d = float(np.hypot(H[j, j], H[j + 1, j]))
            if d == 0.0:
                raise KrylovNotConverged("GMRES: breakdown (zero Hessenberg column)", history)
            cs[j], sn[j] = H[j, j] / d, H[j + 1, j] / d
            H[j, j], H[j + 1, j] = d, 0.0
            g[j + 1], g[j] = -sn[j] * g[j], cs[j] * g[j]
            res = abs(g[j + 1])
            history.append(res / scale)
            if not np.isfinite(res):
                raise KrylovNotConverged(f"GMRES: non-finite residual at iteration {its}", history)
            if res <= atol or its >= max_iter or hn == 0.0:
                break
        k = j + 1
        y = np.linalg.solve(np.triu(H[:k, :k]), g[:k]) if k else np.zeros(0)
        x += y @ Z[:k]
        if not check and res <= atol:
            return KrylovResult(x, its, history, np.array([res / scale]), time.perf_counter() - t0)
        r = b - apply(x)                    # the true residual (restart or final check)
        beta = float(np.linalg.norm(r))
        history[-1] = beta / scale
