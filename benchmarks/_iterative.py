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

import numpy as np

from contactopt.errors import SolverError
from contactopt.fem.amg import rigid_body_modes  # noqa: F401  (the near-null space of amg_preconditioner)
from contactopt.fem.krylov import KrylovNotConverged, KrylovResult
from contactopt.fem.linsolve import Factorization

log = logging.getLogger(__name__)

__all__ = ["pcg", "Cholesky", "DelassusOperator", "ReusedFactorSolver", "amg_preconditioner"]


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


class Cholesky(Factorization):
    """Cholesky factorization of an SPD A whose values change and pattern does not (a new
    design on the same mesh): :meth:`~contactopt.fem.linsolve.Factorization.refactor` redoes
    only PARDISO's numerical phase, the ordering and symbolic analysis kept. ``solve(b)`` for
    (n,) or (n, k) b; ``timings`` of the last (re)factorization."""


class DelassusOperator:
    """Products with the Delassus block of the DOFs ``dofs`` (e.g. a contact zone, per node
    (t1, t2, ν)): W_D r = B_D A⁻¹ B_Dᵀ r, one solve per product (``solve``: a factorization's
    or a Krylov solver's), never forming W_D (W = S⁻¹ = B A⁻¹ Bᵀ).

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
