"""Preconditioned conjugate gradients with A(α) for large meshes (issue #16): the linear-algebra
core of a path that does not factorize A(α) at every design.

An optimization moves α by 1e-4–1e-3 per step, so A(α) stays close to the A(α_ref) of an earlier
design: the Cholesky factorization of A(α_ref) is a preconditioner M = A(α_ref)⁻¹ with
M A(α) = I + O(|α − α_ref|), and conjugate gradients converge in a few iterations
(:class:`ReusedFactorSolver`, which refactorizes when the count grows past ``refactor_after``).
Where no factorization fits in memory, smoothed-aggregation algebraic multigrid with the six
rigid-body modes as near-null space (pyamg) is the
preconditioner (:func:`amg_preconditioner`).

:func:`pcg` solves a block of right-hand sides at once (each column its own CG, the
preconditioner applied to the whole block: one multi-column triangular solve is cheaper per
column than single ones). Convergence: ‖b_j − A x_j‖ ≤ rtol·‖b_j‖ for every column j. A solve
that does not converge raises :class:`KrylovNotConverged` (a SolverError) with the residual
history; so does a direction of non-positive curvature (A or M not SPD).

:class:`Cholesky` refactorizes numerically with PARDISO's analysis kept, and
:class:`DelassusOperator` gives products W_D r = B_D A⁻¹ B_Dᵀ r by one solve each; :func:`gmres`
solves the non-symmetric systems of the Delassus path's adjoint (4.15) in W-form
(:func:`contactopt.sensitivity.adjoint.solve_adjoint_delassus`). The Delassus path itself is
:class:`contactopt.contact.zone.DelassusZoneProblem` in :class:`contactopt.ShapeProblem`
(docs/large_meshes.md).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from .linsolve import Factorization

log = logging.getLogger(__name__)

__all__ = ["pcg", "gmres", "KrylovResult", "KrylovNotConverged", "Cholesky", "DelassusOperator", "ReusedFactorSolver",
           "amg_preconditioner", "rigid_body_modes"]


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


def pcg(A, b, M=None, *, rtol: float = 1e-10, max_iter: int = 200, x0=None) -> KrylovResult:
    """Solve A x = b (A SPD, sparse or a LinearOperator-like object with ``@``) by preconditioned
    conjugate gradients; ``M(r)`` applies the preconditioner to an (n,) or (n, k) array.

    ``b`` of shape (n,) or (n, k): k independent CG iterations sharing the preconditioner calls.
    Raises :class:`KrylovNotConverged` with the residual history after ``max_iter`` iterations,
    on a non-finite residual, or on non-positive curvature pᵀAp ≤ 0.
    """
    t0 = time.perf_counter()
    b = np.asarray(b, dtype=np.float64)
    vec = b.ndim == 1
    B = b[:, None] if vec else b
    n, k = B.shape
    if A.shape != (n, n):
        raise SolverError(f"A of shape {A.shape} does not match b of shape {b.shape}")
    M = M or (lambda r: r)
    bnorm = np.linalg.norm(B, axis=0)
    bnorm[bnorm == 0] = 1.0               # b_j = 0: absolute residual, x_j = 0 converges at once
    X = np.zeros((n, k)) if x0 is None else np.array(np.reshape(x0, (n, k)), dtype=np.float64)
    R = B - A @ X if x0 is not None else B.copy()
    res = np.linalg.norm(R, axis=0) / bnorm
    history = [float(res.max())]
    active = res > rtol
    if not active.any():
        return KrylovResult(b * 0 if x0 is None else X.reshape(b.shape), 0, history, res,
                            time.perf_counter() - t0)
    Z = np.asarray(M(R)).reshape(n, k)
    P = Z.copy()
    rz = np.einsum("ij,ij->j", R, Z)
    for it in range(1, max_iter + 1):
        AP = np.asarray(A @ P).reshape(n, k)
        pap = np.einsum("ij,ij->j", P, AP)
        if np.any(active & ~(pap > 0)):
            raise KrylovNotConverged(f"conjugate gradients: non-positive curvature pᵀAp = "
                                     f"{pap[active].min():.3g} at iteration {it} (A or the "
                                     f"preconditioner is not SPD)", history)
        a = np.where(active, rz / np.where(active, pap, 1.0), 0.0)
        X += a * P
        R -= a * AP
        res = np.linalg.norm(R, axis=0) / bnorm
        history.append(float(res[active].max()))
        if not np.all(np.isfinite(res)):
            raise KrylovNotConverged(f"conjugate gradients: non-finite residual at iteration {it}", history)
        active &= res > rtol
        if not active.any():
            x = X[:, 0] if vec else X
            return KrylovResult(x, it, history, res, time.perf_counter() - t0)
        Z = np.asarray(M(R)).reshape(n, k)
        rz_new = np.einsum("ij,ij->j", R, Z)
        beta = np.where(active, rz_new / np.where(rz != 0, rz, 1.0), 0.0)
        P = Z + beta * P
        rz = rz_new
    raise KrylovNotConverged(f"conjugate gradients did not converge: relative residual "
                             f"{history[-1]:.3g} > rtol {rtol:g} after {max_iter} iterations "
                             f"({int(active.sum())} of {k} column(s))", history)


def gmres(apply, b, M=None, *, rtol: float = 1e-10, max_iter: int = 100, x0=None,
          verify: bool = True) -> KrylovResult:
    """Solve Q x = b by GMRES, right-preconditioned (Q M y = b, x = M y), without restarts.

    ``apply(x)`` = Q x and ``M(r)`` ≈ Q⁻¹ r on (n,) arrays. Stops when ‖b − Q x‖ ≤ rtol·‖b‖ (the
    Arnoldi estimate, confirmed by one more product with the true residual — ``verify=False``
    leaves that check to the caller, whose next product is at the solution anyway); raises
    :class:`KrylovNotConverged` with the residual history after ``max_iter`` iterations or on a
    non-finite residual. ``history[0]`` is the initial relative residual.
    """
    t0 = time.perf_counter()
    b = np.asarray(b, dtype=np.float64)
    M = M or (lambda r: r)
    bnorm = float(np.linalg.norm(b)) or 1.0
    x = np.zeros_like(b) if x0 is None else np.array(x0, dtype=np.float64)
    history = []
    n_products = 0
    for _restart in range(3):          # a restart only when the estimate and the true residual differ
        r = b - apply(x) if np.any(x) else b.copy()
        n_products += bool(np.any(x))
        beta = float(np.linalg.norm(r))
        history.append(beta / bnorm)
        if not np.isfinite(beta):
            raise KrylovNotConverged("GMRES: non-finite residual", history)
        if beta <= rtol * bnorm:
            return KrylovResult(x, len(history) - 1, history, np.array([beta / bnorm]),
                                time.perf_counter() - t0, {"products": n_products})
        m = max_iter - (len(history) - 1)
        if m <= 0:
            break
        V = np.zeros((m + 1, b.size))
        Zs = []
        H = np.zeros((m + 1, m))
        V[0] = r / beta
        g = np.zeros(m + 1)
        g[0] = beta
        cs, sn = np.zeros(m), np.zeros(m)
        k = 0
        for k in range(m):
            z = np.asarray(M(V[k]), dtype=np.float64)
            Zs.append(z)
            w = apply(z)
            n_products += 1
            for i in range(k + 1):                     # modified Gram–Schmidt, twice
                H[i, k] = V[i] @ w
                w -= H[i, k] * V[i]
            for i in range(k + 1):
                c = V[i] @ w
                H[i, k] += c
                w -= c * V[i]
            H[k + 1, k] = np.linalg.norm(w)
            breakdown = not H[k + 1, k] > 0              # the Krylov space is invariant: exact
            if not breakdown:
                V[k + 1] = w / H[k + 1, k]
            for i in range(k):                          # Givens rotations
                H[i, k], H[i + 1, k] = cs[i] * H[i, k] + sn[i] * H[i + 1, k], -sn[i] * H[i, k] + cs[i] * H[i + 1, k]
            d = np.hypot(H[k, k], H[k + 1, k])
            cs[k], sn[k] = (H[k, k] / d, H[k + 1, k] / d) if d > 0 else (1.0, 0.0)
            H[k, k], H[k + 1, k] = d, 0.0
            g[k], g[k + 1] = cs[k] * g[k], -sn[k] * g[k]
            est = abs(g[k + 1]) / bnorm
            history.append(float(est))
            if not np.isfinite(est):
                raise KrylovNotConverged("GMRES: non-finite residual", history)
            if est <= rtol or breakdown:
                break
        y = np.linalg.solve(np.triu(H[:k + 1, :k + 1]), g[:k + 1])
        x = x + np.column_stack(Zs[:k + 1]) @ y
        if not verify and history[-1] <= rtol:
            return KrylovResult(x, len(history) - 1, history, np.array([history[-1]]),
                                time.perf_counter() - t0, {"products": n_products})
    raise KrylovNotConverged(f"GMRES did not converge: relative residual {history[-1]:.3g} > rtol "
                             f"{rtol:g} after {len(history) - 1} iterations", history)


class Cholesky(Factorization):
    """Cholesky factorization of an SPD A whose values change and pattern does not (a new
    design on the same mesh): :meth:`~contactopt.fem.linsolve.Factorization.refactor` redoes
    only PARDISO's numerical phase, the ordering and symbolic analysis kept. ``solve(b)`` for
    (n,) or (n, k) b; ``timings`` of the last (re)factorization."""


class DelassusOperator:
    """Products with the Delassus block of the DOFs ``dofs`` (e.g. a contact zone, per node
    (t1, t2, ν)): W_D r = B_D A⁻¹ B_Dᵀ r, one solve per product (``solve``: a factorization's
    or a Krylov solver's), never forming W_D (DESIGN.md §3: W = S⁻¹ = B A⁻¹ Bᵀ).

    ``last_full`` keeps A⁻¹ B_Dᵀ r of the last product: with it the displacement of a state is
    u = A⁻¹L + A⁻¹B_Dᵀ r (no further solve), and the A-harmonic extension of the adjoint,
    ṽ = A⁻¹ B_Dᵀ z for v_D = W_D z, is the same by-product. ``n_products`` counts the solves."""

    def __init__(self, solve, n: int, dofs):
        self._solve = solve
        self.n = int(n)
        self.dofs = np.asarray(dofs, dtype=np.int64)
        self.n_products = 0
        self.last_full = None

    def product(self, r):
        r = np.asarray(r, dtype=np.float64)
        if r.shape[0] != self.dofs.size or r.ndim not in (1, 2):
            raise SolverError(f"r must have length {self.dofs.size} (first axis), got {r.shape}")
        f = np.zeros((self.n,) + r.shape[1:])
        f[self.dofs] = r
        x = self._solve(f)
        self.last_full = x
        self.n_products += 1 if r.ndim == 1 else r.shape[1]
        return np.ascontiguousarray(x[self.dofs])

    __matmul__ = product

    @property
    def shape(self):
        return (self.dofs.size, self.dofs.size)

    def dense(self):
        """W_D itself (len(dofs) solves as one block): for checks on small problems only."""
        return self.product(np.eye(self.dofs.size))


class ReusedFactorSolver:
    """Solves with A(α) preconditioned by the Cholesky factorization of an earlier A(α_ref).

    ``solve(A, b)`` runs :func:`pcg`; when it needed more than ``refactor_after`` iterations, A
    becomes the new reference (refactorized numerically for the next call, the analysis kept:
    :class:`Cholesky`). ``n_factorizations`` and ``n_solves`` count.
    """

    def __init__(self, A, *, rtol: float = 1e-10, max_iter: int = 100, refactor_after: int = 15,
                 backend: str = "auto"):
        self.rtol, self.max_iter, self.refactor_after = rtol, max_iter, refactor_after
        self.backend = backend
        self.n_factorizations = 0
        self.n_solves = 0
        self._factor = None
        self.set_reference(A)

    def set_reference(self, A) -> None:
        """Factorize A as the preconditioner of the following solves (numerically only when a
        factorization of the same pattern exists)."""
        if self._factor is None:
            self._factor = Cholesky(A, self.backend)
        else:
            self._factor.refactor(A)
        self.n_factorizations += 1

    def apply(self, r):
        """M r = A(α_ref)⁻¹ r."""
        return self._factor.solve(r)

    def solve(self, A, b, *, x0=None) -> KrylovResult:
        res = pcg(A, b, self.apply, rtol=self.rtol, max_iter=self.max_iter, x0=x0)
        self.n_solves += 1
        if res.iterations > self.refactor_after:
            log.debug("PCG with the reused factorization needed %d iterations: refactorizing", res.iterations)
            self.set_reference(A)
        return res

    def close(self) -> None:
        if self._factor is not None:
            self._factor.close()
            self._factor = None


def rigid_body_modes(coords: np.ndarray, free: np.ndarray) -> np.ndarray:
    """The six rigid-body modes (3 translations, 3 rotations) of nodes ``coords`` (N, 3) on the
    free DOFs ``free`` (full index 3·node + component): an (n_free, 6) array, AMG's near-null space."""
    coords = np.asarray(coords, dtype=np.float64)
    x = coords - coords.mean(axis=0)
    N = coords.shape[0]
    B = np.zeros((3 * N, 6))
    for c in range(3):
        B[c::3, c] = 1.0
    # rotations e_k × x: about x1 (0, −x3, x2), about x2 (x3, 0, −x1), about x3 (−x2, x1, 0)
    B[1::3, 3], B[2::3, 3] = -x[:, 2], x[:, 1]
    B[0::3, 4], B[2::3, 4] = x[:, 2], -x[:, 0]
    B[0::3, 5], B[1::3, 5] = -x[:, 1], x[:, 0]
    return B[np.asarray(free)]


def amg_preconditioner(A, near_null=None, **kw):
    """Smoothed-aggregation AMG V-cycle of A (pyamg) as a preconditioner callable for :func:`pcg`;
    ``near_null`` the rigid-body modes (:func:`rigid_body_modes`). Returns (M, hierarchy)."""
    try:
        import pyamg
    except ImportError as exc:
        raise SolverError("algebraic multigrid needs pyamg: pip install pyamg") from exc
    ml = pyamg.smoothed_aggregation_solver(A.tocsr(), B=near_null, **kw)
    cycle = ml.aspreconditioner()           # one V-cycle, symmetric smoothing: SPD for CG

    def M(r):
        if r.ndim == 1:
            return cycle(r)
        return np.column_stack([cycle(r[:, j]) for j in range(r.shape[1])])

    return M, ml
