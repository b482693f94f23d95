"""Sparse direct solvers and condensation of the FEM system onto the contact DOFs.

With the DOFs split into interior (i) and Schur/contact (c) DOFs, :func:`condense` computes

    S = A_cc − A_ci A_ii⁻¹ A_ic          (dense condensed stiffness, rows/cols in the order of c)
    ℓ = L_c − A_ci A_ii⁻¹ L_i            (condensed load, :meth:`Condensation.condense_load`)
    u_i = A_ii⁻¹ (L_i − A_ic u_c)         (interior recovery, :meth:`Condensation.recover`)

for a sparse symmetric positive definite A with one sparse factorization in which the DOFs c
are eliminated last (S is *not* formed column by column). Forcing c last costs fill: for a
contact face of a 3D body, expect about twice the time of a plain factorization of A
(``benchmarks/bench_schur.py``). :func:`factorize` is that plain factorization, the timing
reference of the benchmarks. For a new A with the same sparsity pattern (a new design on the
same mesh) :meth:`Condensation.refactor` reuses the ordering and symbolic analysis.

Backends
--------
``"pardiso"``: MKL PARDISO through ctypes (:mod:`._pardiso`), Schur-complement mode
(``iparm[35] = 2``). Phase 22 returns S; the forward (331) and backward (333) partial solves
of the same factorization give ℓ and the interior solves, so nothing is factorized twice:
the forward substitution of L leaves exactly ℓ in the Schur rows, and the backward
substitution with the Schur rows set to u_c returns u_i = A_ii⁻¹(L_i − A_ic u_c).

``"scipy"``: SciPy only (SuperLU). A fill-reducing ordering of A_ii (minimum degree on the
graph compressed to supervariables, e.g. the three DOFs of a node) is extended by c, and A in
that order is factorized without pivoting, A = L U; the trailing block gives S = L_cc U_cc
exactly. Interior quantities come from solves with the full factorization (see
:class:`ScipyCondensation`).

``"auto"`` picks PARDISO when ``libmkl_rt`` loads, else SciPy, and logs the choice.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from .._progress import task
from ..errors import SolverError
from . import _pardiso
from .dense import cholesky_lower, cholesky_solve

logger = logging.getLogger(__name__)

BACKENDS = ("auto", "pardiso", "scipy")

__all__ = ["condense", "factorize", "Condensation", "PardisoCondensation", "ScipyCondensation",
           "Factorization", "SolverSlot", "pardiso_available", "BACKENDS"]


def pardiso_available() -> bool:
    """True if MKL PARDISO can be loaded."""
    return _pardiso.available()


# ---------------------------------------------------------------------------------- checks

def _check_matrix(A, trusted=False):
    """Return A as CSR float64 with sorted indices; raise SolverError on obviously bad input.

    ``trusted``: A is symmetric with a positive diagonal by construction (an assembled
    stiffness); only the shape, the format and the finiteness are checked."""
    if not sp.issparse(A):
        A = np.asarray(A)
        if A.ndim != 2:
            raise SolverError(f"A must be a 2-D matrix, got an array of shape {A.shape}")
    if A.shape[0] != A.shape[1]:
        raise SolverError(f"A must be square, got shape {A.shape}")
    A = sp.csr_matrix(A, dtype=np.float64)
    if not A.has_canonical_format:       # sorted, no duplicates (PARDISO needs both)
        A = A.copy()
        A.sum_duplicates()
    if not np.all(np.isfinite(A.data)):
        raise SolverError("A has non-finite entries (nan or inf)")
    if trusted:
        return A
    # PARDISO reads the upper triangle only: catch an unsymmetric A by a randomized test
    # (two products, a few ms) instead of forming A − Aᵀ.
    rng = np.random.default_rng(0)
    x, y = rng.standard_normal((2, A.shape[0]))
    Ax, Ay = A @ x, A @ y
    if abs(y @ Ax - x @ Ay) > 1e-10 * (np.linalg.norm(Ax) * np.linalg.norm(y)
                                       + np.linalg.norm(Ay) * np.linalg.norm(x)):
        raise SolverError("A is not symmetric")
    diag = A.diagonal()
    bad = np.flatnonzero(~(diag > 0))
    if bad.size:
        raise SolverError(f"A is not positive definite: {bad.size} diagonal entries <= 0 "
                          f"(first at row {bad[0]}: {diag[bad[0]]:g})")
    return A


def _check_schur_dofs(c, n):
    c = np.asarray(c)
    if c.ndim != 1:
        raise SolverError(f"c must be a 1-D array of DOF indices, got shape {c.shape}")
    if c.size and not np.issubdtype(c.dtype, np.integer):
        raise SolverError(f"c must hold integer DOF indices, got dtype {c.dtype}")
    c = c.astype(np.int64)
    problems = []
    if c.size == 0:
        problems.append("c is empty")
    out = c[(c < 0) | (c >= n)]
    if out.size:
        problems.append(f"{out.size} indices out of range [0, {n}) (e.g. {out[0]})")
    uniq, counts = np.unique(c, return_counts=True)
    if np.any(counts > 1):
        problems.append(f"{np.sum(counts > 1)} duplicate indices (e.g. {uniq[counts > 1][0]})")
    if not problems and c.size == n:
        problems.append("c holds every DOF: there is no interior to condense")
    if problems:
        raise SolverError("invalid Schur DOFs: " + "; ".join(problems))
    return c


def _pick_backend(backend):
    if backend not in BACKENDS:
        raise SolverError(f"unknown backend {backend!r}; choose one of {BACKENDS}")
    if backend == "auto":
        backend = "pardiso" if _pardiso.available() else "scipy"
        logger.info("linear solver backend: %s", backend)
    return backend


def _have_pyamg() -> bool:
    try:
        import pyamg  # noqa: F401
    except ImportError:
        return False
    return True


def _upper_triangle(owner, A, hint=""):
    """The upper triangle of A (same pattern as the matrix ``owner._ps`` analysed) as CSR.

    The positions of the upper-triangle entries in A's CSR arrays are found once (kept on
    ``owner``); for a matrix with the same full pattern (a new design on the same mesh) the upper
    triangle is then a gather of A.data.
    """
    pat = owner._full_pattern
    if pat is not None and A.nnz == pat[0].size and np.array_equal(A.indices, pat[0]) \
            and np.array_equal(A.indptr, pat[1]):
        return sp.csr_matrix((A.data[pat[2]], owner._ps.ja, owner._ps.ia), shape=A.shape, copy=False)
    upper = sp.triu(A, format="csr")
    if A.shape[0] != owner.n or not owner._ps.same_pattern(upper):
        raise SolverError("refactor needs a matrix with the same sparsity pattern" + hint)
    row = np.repeat(np.arange(owner.n), np.diff(A.indptr))
    owner._full_pattern = (A.indices.copy(), A.indptr.copy(), np.flatnonzero(A.indices >= row))
    return upper


def _check_S(S):
    """The Schur block itself is not factorized: catch the cheap symptoms of a non-SPD A."""
    d = np.diagonal(S)
    if not np.all(np.isfinite(S)):
        raise SolverError("the condensed stiffness S has non-finite entries")
    if not np.all(d > 0):
        raise SolverError("A is not positive definite: the condensed stiffness S has "
                          f"{np.sum(~(d > 0))} diagonal entries <= 0")


# ----------------------------------------------------------------------- common interface

class Condensation:
    """Condensation of an SPD system onto the DOFs ``c`` (see the module docstring).

    Attributes: ``S`` (dense, order of ``c``), ``c``, ``interior`` (sorted), ``n``,
    ``backend``, ``timings`` (seconds per stage), ``stats`` (size of the factor, and for
    PARDISO its factorization MFlop). Vectors are full length ``n`` unless named
    ``*_c`` (order of ``c``) or ``*_i`` (order of ``interior``).
    """

    backend = ""
    S_inverse = None      # S⁻¹ when the caller has it: solve() then needs no factor of S
    _chol_S = None        # (S, its Cholesky factor) once solve() needed it
    _full_pattern = None  # (indices, indptr, upper-triangle positions) of A's CSR pattern (_upper_triangle)

    def __init__(self, A, c):
        self.n = A.shape[0]
        self.c = c
        mask = np.zeros(self.n, dtype=bool)
        mask[c] = True
        self._mask = mask
        self.interior = np.flatnonzero(~mask)
        self.S = None
        self.timings = {}
        self.stats = {}

    # -- to be provided by the backends
    def condense_load(self, L):
        """ℓ = L_c − A_ci A_ii⁻¹ L_i; ``L`` of shape (n,) or (n, k) → (len(c),) or (len(c), k)."""
        raise NotImplementedError

    def recover(self, L, u_c):
        """Full u with u[c] = u_c and u[interior] = A_ii⁻¹(L_i − A_ic u_c)."""
        raise NotImplementedError

    def extend(self, v_c):
        """Full ṽ with ṽ[c] = v_c and ṽ[interior] = −A_ii⁻¹ A_ic v_c (the A-harmonic extension)."""
        raise NotImplementedError

    def solve_interior(self, b_i):
        """A_ii⁻¹ b_i for ``b_i`` of shape (n_i,) or (n_i, k)."""
        raise NotImplementedError

    def solve(self, b):
        """A⁻¹ b for b of shape (n,) or (n, k), from the same factorization: with ℓ_b the
        condensed right-hand side, x_c = S⁻¹ℓ_b (dense Cholesky of S, computed on first use) and
        x_i = A_ii⁻¹(b_i − A_ic x_c)."""
        b = self._full(b, "b")
        ell = self.condense_load(b)
        if self.S_inverse is not None:          # S⁻¹ given (the Delassus block of a zone)
            return self.recover(b, self.S_inverse @ ell)
        if self._chol_S is None or self._chol_S[0] is not self.S:
            self._chol_S = (self.S, cholesky_lower(np.array(self.S, dtype=np.float64, order="C")))
        return self.recover(b, cholesky_solve(self._chol_S[1], ell))

    def refactor(self, A, *, trusted=False):
        """Redo the factorization for new values of A with the same sparsity pattern, reusing
        the ordering; updates ``S`` (a new array) and ``timings``; returns self. ``trusted``
        skips the checks of symmetry and of the diagonal (an assembled stiffness has both by
        construction; a matrix that is not positive definite still fails in the factorization
        or in the checks of S)."""
        raise NotImplementedError

    def close(self):
        """Release the factorization (no-op where memory is managed by Python)."""

    # -- shared helpers
    def _full(self, v, name):
        v = np.asarray(v, dtype=np.float64)
        if v.ndim not in (1, 2) or v.shape[0] != self.n:
            raise SolverError(f"{name} must have length n = {self.n} (first axis), got {v.shape}")
        return v

    def _on_c(self, v, name):
        v = np.asarray(v, dtype=np.float64)
        if v.ndim not in (1, 2) or v.shape[0] != len(self.c):
            raise SolverError(f"{name} must have length len(c) = {len(self.c)}, got {v.shape}")
        return v

    def _on_interior(self, v, name):
        v = np.asarray(v, dtype=np.float64)
        if v.ndim not in (1, 2) or v.shape[0] != len(self.interior):
            raise SolverError(f"{name} must have length {len(self.interior)} (interior DOFs), "
                              f"got {v.shape}")
        return v

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return (f"<{type(self).__name__} n={self.n} n_c={len(self.c)} backend={self.backend} "
                f"timings={ {k: round(v, 4) for k, v in self.timings.items()} }>")


# ---------------------------------------------------------------------------------- PARDISO

class PardisoCondensation(Condensation):
    """Condensation with MKL PARDISO's Schur-complement mode (``iparm[35] = 2``)."""

    backend = "pardiso"

    def __init__(self, A, c):
        super().__init__(A, c)
        # PARDISO returns S in increasing DOF order; `rank` maps the order of c onto it.
        order = np.sort(c)
        self._rank = None if np.array_equal(order, c) else np.searchsorted(order, c)
        t0 = time.perf_counter()
        self._full_pattern = None
        self._fwd_cache = None
        self._ps = _pardiso.PardisoSPD(sp.triu(A, format="csr"), schur_mask=self._mask)
        self._ps.analyze()
        t1 = time.perf_counter()
        self._set_S(self._ps.factor())
        t2 = time.perf_counter()
        self.timings = {"analyze": t1 - t0, "factor_schur": t2 - t1}
        self.stats = {"nnz_factor": self._ps.nnz_factor, "mflop": self._ps.mflops_factor}
        logger.debug("PARDISO Schur: n=%d n_c=%d nnz(L)=%d %s MFlop, %.3f s analyze, "
                     "%.3f s factor", self.n, len(c), self._ps.nnz_factor,
                     self._ps.mflops_factor, t1 - t0, t2 - t1)

    def _set_S(self, S):
        _check_S(S)
        self.S = S if self._rank is None else S[np.ix_(self._rank, self._rank)]

    def refactor(self, A, *, trusted=False):
        """New values of A with the same sparsity pattern: skip the analysis, redo phase 22."""
        A = _check_matrix(A, trusted)
        upper = self._upper(A)
        t0 = time.perf_counter()
        self._set_S(self._ps.factor(upper))
        self._fwd_cache = None
        self.timings = {"analyze": 0.0, "factor_schur": time.perf_counter() - t0}
        return self

    def _upper(self, A):
        return _upper_triangle(self, A, "; call condense() for a new pattern")

    def _forward(self, b):
        """Phase 331: interior forward substitution; the c rows then hold the condensed load."""
        return self._ps.solve(b, phase=331)

    def _forward_cached(self, L):
        """Forward substitution of a load vector, kept for the last L of this factorization
        (``condense_load`` and ``recover`` of one state solve share it)."""
        c = self._fwd_cache
        if c is not None and c[0].shape == L.shape and np.array_equal(c[0], L):
            return c[1].copy()
        y = self._forward(L)
        self._fwd_cache = (L.copy(), y.copy())
        return y

    def _backward(self, y):
        """Phase 333 with y[c] = u_c: returns u with u[c] = u_c, u_i = A_ii⁻¹(b_i − A_ic u_c)."""
        return self._ps.solve(y, phase=333)

    def condense_load(self, L):
        y = self._forward_cached(self._full(L, "L"))
        return np.ascontiguousarray(y[self.c])

    def recover(self, L, u_c):
        L = self._full(L, "L")
        u_c = self._on_c(u_c, "u_c")
        y = self._forward_cached(L)
        y[self.c] = u_c
        u = self._backward(y)
        u[self.c] = u_c
        return np.ascontiguousarray(u)

    def extend(self, v_c):
        v_c = self._on_c(v_c, "v_c")
        y = np.zeros((self.n,) + v_c.shape[1:])
        y[self.c] = v_c
        v = self._backward(y)
        v[self.c] = v_c
        return np.ascontiguousarray(v)

    def solve_interior(self, b_i):
        b_i = self._on_interior(b_i, "b_i")
        b = np.zeros((self.n,) + b_i.shape[1:])
        b[self.interior] = b_i
        y = self._forward(b)
        y[self.c] = 0.0
        return np.ascontiguousarray(self._backward(y)[self.interior])

    def close(self):
        self._ps.close()


# ------------------------------------------------------------------------------------ SciPy

def _supervariable_order(A):
    """Fill-reducing ordering of the SPD pattern of A (CSR, sorted): minimum degree on the
    graph whose vertices are supervariables (rows with identical patterns, e.g. the 3 DOFs of
    a node); SuperLU's MMD on the compressed graph is ~27x cheaper than on A itself."""
    n = A.shape[0]
    rng = np.random.default_rng(12345)
    weights = rng.integers(1, 2**62, size=n, dtype=np.uint64)
    row = np.repeat(np.arange(n), np.diff(A.indptr))
    h = np.zeros(n, dtype=np.uint64)
    np.add.at(h, row, weights[A.indices])  # wraps mod 2**64: a hash of the row pattern
    key = np.stack([h, np.diff(A.indptr).astype(np.uint64)], axis=1)
    _, first, sv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    # number the supervariables in order of their first DOF: minimum degree breaks ties by
    # the initial numbering, and the mesh numbering is a much better start than hash order
    relabel = np.empty(len(first), dtype=np.int64)
    relabel[np.argsort(first)] = np.arange(len(first))
    sv = relabel[sv.ravel()]
    n_sv = len(first)
    P = sp.csr_matrix((np.ones(n), (np.arange(n), sv)), shape=(n, n_sv))
    Q = (P.T @ (abs(A) > 0).astype(np.float64) @ P).tocsr()
    Q.data[:] = -1.0
    Q.setdiag(0)
    Q.eliminate_zeros()
    deg = -np.asarray(Q.sum(axis=1)).ravel()
    M = (Q + sp.diags(deg + 1.0)).tocsc()  # diagonally dominant: any pivot order is stable
    lu = sla.splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options=dict(SymmetricMode=True))
    # perm_c[s] is the new position of supervariable s; a DOF inherits it (stable sort keeps
    # the DOFs of one supervariable together and in order)
    return np.argsort(lu.perm_c[sv], kind="stable")


def _trailing_block(T, m):
    """Dense T[n-m:, n-m:] of a CSC factor (row slicing a large CSC matrix is slow)."""
    n = T.shape[0]
    start, stop = T.indptr[n - m], T.indptr[n]
    rows = T.indices[start:stop]
    cols = np.repeat(np.arange(m), np.diff(T.indptr[n - m:]))
    keep = rows >= n - m
    out = np.zeros((m, m))
    out[rows[keep] - (n - m), cols[keep]] = T.data[start:stop][keep]
    return out


def _splu_natural(B, check_spd=True):
    """SuperLU of an SPD matrix in the given order (no pivoting, SymmetricMode).

    ``check_spd`` verifies that all pivots are positive, which needs the factor U as a SciPy
    matrix (a conversion costing ~30 % of the factorization; free when U is needed anyway).
    """
    try:
        lu = sla.splu(B.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                      options=dict(SymmetricMode=True))
    except RuntimeError as exc:
        raise SolverError(f"SuperLU factorization failed: {exc}") from exc
    if check_spd:
        d = lu.U.diagonal()
        if not np.all(d > 0) or not np.array_equal(lu.perm_r, lu.perm_c):
            raise SolverError("SuperLU: the matrix is not positive definite "
                              f"(min pivot {d.min():g})")
    return lu


class ScipyCondensation(Condensation):
    """Condensation with SciPy's SuperLU.

    A is factorized once in the order (ordering of A_ii, then c): A_perm = L U. The trailing
    block gives S = L_cc U_cc. With one full solve x = A⁻¹[b_i; f_c] the identities

        ℓ = L_c + S x_c                         for x = A⁻¹[L_i; 0],
        extend(v_c) = A⁻¹[0; S v_c],
        recover(L, u_c) = x + extend(u_c − x_c)  for x = A⁻¹[L_i; 0],
        A_ii⁻¹ b_i = (x + extend(−x_c))_i        for x = A⁻¹[b_i; 0]

    give every interior quantity from the same factorization (at most two solves).
    """

    backend = "scipy"

    def __init__(self, A, c):
        super().__init__(A, c)
        t0 = time.perf_counter()
        Aii = A[self.interior][:, self.interior]
        self._order = np.concatenate([self.interior[_supervariable_order(Aii)], c])
        self._pattern = (A.indptr.copy(), A.indices.copy())
        t_order = time.perf_counter() - t0
        self._factor(A)
        self.timings["analyze"] += t_order

    def _factor(self, A):
        n, m = self.n, len(self.c)
        t0 = time.perf_counter()
        B = A[self._order][:, self._order]
        t1 = time.perf_counter()
        lu = _splu_natural(B)
        pos = lu.perm_c[n - m:] - (n - m)   # SuperLU may postorder; c must stay trailing
        if not np.array_equal(np.sort(pos), np.arange(m)):
            raise SolverError("SuperLU moved Schur DOFs out of the trailing block")
        S = _trailing_block(lu.L, m) @ _trailing_block(lu.U, m)
        S = S[np.ix_(pos, pos)]
        S = 0.5 * (S + S.T)
        _check_S(S)
        self.S, self._lu = S, lu
        self.stats = {"nnz_factor": lu.nnz}
        self.timings = {"analyze": t1 - t0, "factor_schur": time.perf_counter() - t1}
        logger.debug("SciPy Schur: n=%d n_c=%d nnz(L+U)=%d, %.3f s factor",
                     n, m, lu.nnz, self.timings["factor_schur"])

    def refactor(self, A, *, trusted=False):
        A = _check_matrix(A, trusted)
        if (A.shape[0] != self.n or not np.array_equal(A.indptr, self._pattern[0])
                or not np.array_equal(A.indices, self._pattern[1])):
            raise SolverError("refactor needs a matrix with the same sparsity pattern; "
                              "call condense() for a new pattern")
        self._factor(A)
        return self

    def _solve(self, f):
        """x = A⁻¹ f for full-length f (1 or 2-D), in the original DOF numbering."""
        x = np.empty_like(f)
        x[self._order] = self._lu.solve(np.ascontiguousarray(f[self._order]))
        return x

    def _rhs_interior(self, b_i):
        f = np.zeros((self.n,) + b_i.shape[1:])
        f[self.interior] = b_i
        return f

    def condense_load(self, L):
        L = self._full(L, "L")
        x = self._solve(self._rhs_interior(L[self.interior]))
        return L[self.c] + self.S @ x[self.c]

    def extend(self, v_c):
        v_c = self._on_c(v_c, "v_c")
        f = np.zeros((self.n,) + v_c.shape[1:])
        f[self.c] = self.S @ v_c
        v = self._solve(f)
        v[self.c] = v_c
        return v

    def recover(self, L, u_c):
        L = self._full(L, "L")
        u_c = self._on_c(u_c, "u_c")
        x = self._solve(self._rhs_interior(L[self.interior]))
        u = x + self.extend(u_c - x[self.c])
        u[self.c] = u_c
        return u

    def solve_interior(self, b_i):
        b_i = self._on_interior(b_i, "b_i")
        x = self._solve(self._rhs_interior(b_i))
        return (x + self.extend(-x[self.c]))[self.interior]


# ---------------------------------------------------------------------------------- public

def condense(A, c, backend="auto") -> Condensation:
    """Condense the SPD system matrix ``A`` (n×n sparse) onto the DOFs ``c`` (order kept).

    Returns a :class:`Condensation` with the dense condensed stiffness ``S`` (rows/columns
    in the order of ``c``) and the interior operations. Raises :class:`SolverError` for a
    non-square or non-SPD A, duplicate or out-of-range indices in ``c``, or a solver failure.
    """
    A = _check_matrix(A)
    c = _check_schur_dofs(c, A.shape[0])
    if _pick_backend(backend) == "pardiso":
        return PardisoCondensation(A, c)
    return ScipyCondensation(A, c)


class Factorization:
    """A full sparse factorization of an SPD matrix; ``solve(b)`` for (n,) or (n, k) b.

    PARDISO (Cholesky) rejects an indefinite A; SciPy's SuperLU (LU without pivoting) only
    fails on a zero pivot and otherwise solves a nonsingular indefinite A correctly.
    """

    _full_pattern = None  # (indices, indptr, upper-triangle positions) of A's CSR pattern (_upper_triangle)

    def __init__(self, A, backend="auto"):
        A = _check_matrix(A)
        self.n = A.shape[0]
        self.backend = _pick_backend(backend)
        t0 = time.perf_counter()
        with task(f"factorizing a matrix of {self.n:,} unknowns".replace(",", " ")):
            if self.backend == "pardiso":
                self._ps = _pardiso.PardisoSPD(sp.triu(A, format="csr"))
                self._ps.analyze()
                t1 = time.perf_counter()
                self._ps.factor()
                self.stats = {"nnz_factor": self._ps.nnz_factor, "mflop": self._ps.mflops_factor}
            else:
                self._order = _supervariable_order(A)
                B = A[self._order][:, self._order]
                t1 = time.perf_counter()
                self._lu = _splu_natural(B, check_spd=False)
                self.stats = {"nnz_factor": self._lu.nnz}
        self.timings = {"analyze": t1 - t0, "factor": time.perf_counter() - t1}

    def refactor(self, A) -> "Factorization":
        """New values of A with the same sparsity pattern (a new design on the same mesh): only
        the numerical factorization is redone, the ordering and analysis kept."""
        A = _check_matrix(A, trusted=True)
        t0 = time.perf_counter()
        if self.backend == "pardiso":
            self._ps.factor(self._upper(A))
        else:
            self._lu = _splu_natural(A[self._order][:, self._order], check_spd=False)
        self.timings = {"analyze": 0.0, "factor": time.perf_counter() - t0}
        return self

    def _upper(self, A):
        return _upper_triangle(self, A)

    def solve(self, b):
        b = np.asarray(b, dtype=np.float64)
        if b.ndim not in (1, 2) or b.shape[0] != self.n:
            raise SolverError(f"b must have length n = {self.n} (first axis), got {b.shape}")
        if self.backend == "pardiso":
            return np.ascontiguousarray(self._ps.solve(b, phase=33))
        x = np.empty_like(b)
        x[self._order] = self._lu.solve(np.ascontiguousarray(b[self._order]))
        return x

    def close(self):
        if self.backend == "pardiso":
            self._ps.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class SolverSlot:
    """The factorization through which a design's sparse solves go (the Delassus path): the
    sparse Cholesky of A(α), or — after a contact zone's Schur complement has been formed, for
    which the Cholesky is released to bound the peak memory — that condensation, which solves
    with A(α) just as well (:meth:`Condensation.solve`). ``solve(b)`` = A⁻¹b either way."""

    def __init__(self, factorization=None):
        self.current = factorization

    def set(self, factorization) -> None:
        """Make ``factorization`` current; a previous one that is not it is released."""
        old = self.current
        if old is not None and old is not factorization:
            old.close()
        self.current = factorization

    def solve(self, b):
        return self.current.solve(b)

    @property
    def backend(self) -> str:
        return getattr(self.current, "backend", "?")


def factorize(A, backend="auto") -> Factorization:
    """Factorize the SPD matrix ``A`` (the benchmarks' "one factorization of A")."""
    return Factorization(A, backend)
