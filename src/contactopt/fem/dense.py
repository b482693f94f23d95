"""Dense symmetric positive definite kernels for the condensed system, in MKL's thread pool.

The condensed stiffness S is dense (3p × 3p). Its Cholesky factor and the inverse of a trailing
block of it are the only large dense factorizations of a state solve; they run in MKL's LAPACK
(the thread pool PARDISO uses, see :mod:`contactopt._threads`) when ``libmkl_rt`` loads, else in
SciPy's LAPACK. Arrays are C-ordered; "lower" is the lower triangle of the C array
(``a = L Lᵀ``), which LAPACK sees as the upper triangle of the column-major transpose.
"""

from __future__ import annotations

import ctypes
from contextlib import contextmanager

import numpy as np
import scipy.linalg as sla

from ..errors import SolverError
from . import _pardiso

_COL_MAJOR = 102   # the C array's lower triangle is the column-major upper one: no transposed copy


def _mkl(name):
    """(function, MKL_INT ctype) of a LAPACKE routine, or None without MKL."""
    if not _pardiso.available():
        return None
    lib, int_dtype = _pardiso._load()
    cint = ctypes.c_int64 if int_dtype == np.int64 else ctypes.c_int32
    fn = getattr(lib, name)
    fn.restype = cint
    return fn, cint


@contextmanager
def mkl_threads(n: int):
    """MKL (LAPACK and PARDISO) on ``n`` threads inside, for the calling thread only, restored
    after; ``n = 0`` changes nothing (MKL's own count: MKL_NUM_THREADS, else one per core).

    A thread count changes the order of MKL's sums: on one thread the results are those of a
    run with ``MKL_NUM_THREADS=1``, bit for bit."""
    setter = _mkl_threads_local() if n else None
    if setter is None:
        yield
        return
    previous = setter(int(n))
    try:
        yield
    finally:
        setter(previous)


def mkl_sequential(on: bool = True):
    """:func:`mkl_threads` (1) where ``on``: for the small dense factorizations of a contact solve
    (the Newton matrices, a few hundred to a few thousand rows), where two threads in lock step
    gain little and lose several times over when another process holds a core
    (docs/measurements.md, "Threads on a shared machine")."""
    return mkl_threads(1 if on else 0)


def _mkl_threads_local():
    """MKL_Set_Num_Threads_Local (returns the previous local count, 0: the global one), or None."""
    if not _pardiso.available():
        return None
    lib, _ = _pardiso._load()
    fn = getattr(lib, "MKL_Set_Num_Threads_Local", None)
    if fn is not None:
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_int]
    return fn


def _square(a, name, dtypes=(np.float64,)):
    if not (isinstance(a, np.ndarray) and a.ndim == 2 and a.shape[0] == a.shape[1]
            and a.dtype in dtypes and a.flags.c_contiguous):
        kinds = " or ".join(np.dtype(d).name for d in dtypes)
        raise SolverError(f"{name} needs a C-contiguous square {kinds} array")
    return a.shape[0]


def cholesky_lower(a: np.ndarray) -> np.ndarray:
    """Overwrite the lower triangle of the SPD array ``a`` with L, a = L Lᵀ; returns ``a``.

    The strict upper triangle is left as it was. Raises :class:`SolverError` when ``a`` is not
    positive definite.
    """
    n = _square(a, "cholesky_lower")
    mkl = _mkl("LAPACKE_dpotrf")
    if mkl is not None:
        fn, cint = mkl
        info = fn(ctypes.c_int(_COL_MAJOR), ctypes.c_char(b"U"), cint(n), _pardiso._ptr(a), cint(n))
    else:
        _, info = sla.lapack.dpotrf(a.T, lower=0, overwrite_a=1, clean=0)
    if info != 0:
        raise SolverError(f"Cholesky factorization failed (potrf info {info}): "
                          + ("the matrix is not positive definite" if info > 0 else "illegal argument"))
    return a


def inverse_from_cholesky(a: np.ndarray, start: int = 0) -> np.ndarray:
    """(L̃ L̃ᵀ)⁻¹ for the trailing lower-triangular block L̃ = a[start:, start:] of a Cholesky factor.

    With a = L Lᵀ from :func:`cholesky_lower` of a matrix M ordered (N, Z), the trailing block
    of L is the Cholesky factor of the Schur complement M_ZZ − M_ZN M_NN⁻¹ M_NZ, so this returns
    (M⁻¹)_ZZ as a new full symmetric array; ``a`` is not modified.
    """
    n = _square(a, "inverse_from_cholesky")
    if not 0 <= start < n:
        raise SolverError(f"inverse_from_cholesky: start {start} outside [0, {n})")
    k = n - start
    inv = np.array(a[start:, start:], order="C")
    mkl = _mkl("LAPACKE_dpotri")
    if mkl is not None:
        fn, cint = mkl
        info = fn(ctypes.c_int(_COL_MAJOR), ctypes.c_char(b"U"), cint(k), _pardiso._ptr(inv), cint(k))
    else:
        inv, info = sla.lapack.dpotri(inv.T, lower=0, overwrite_c=1)   # column-major upper = L̃ᵀ
        inv = inv.T
    if info != 0:
        raise SolverError(f"inverting the Cholesky factor failed (potri info {info})")
    return symmetrize_lower(np.ascontiguousarray(inv))


def cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x = (L Lᵀ)⁻¹ b with L the lower triangle of ``a`` (from :func:`cholesky_lower`); b (n,) or (n, m)."""
    U = a.T                     # Fortran-ordered view: its upper triangle is Lᵀ, no copy
    y = sla.solve_triangular(U, b, lower=False, trans="T", check_finite=False)
    return sla.solve_triangular(U, y, lower=False, trans="N", check_finite=False, overwrite_b=True)


def symmetrize_lower(a: np.ndarray, block: int = 128) -> np.ndarray:
    """Copy the strict lower triangle of the square array ``a`` onto its upper one, in place.

    Block by block, which is several times faster than fancy indexing with ``triu_indices``.
    """
    n = a.shape[0]
    for i in range(0, n, block):
        j = min(i + block, n)
        a[i:j, j:] = a[j:, i:j].T
        d = a[i:j, i:j]
        iu = np.triu_indices(j - i, 1)
        d[iu] = d.T[iu]
    return a


class LUFactor:
    """LU factorization with partial pivoting of a dense square matrix M, for solves M x = b.

    The C-ordered M is factorized in place as the column-major Mᵀ (no copy), and solves use the
    transposed factor. ``rcond(anorm)`` is LAPACK's estimate of 1/κ_∞(M) given ``anorm`` ≈ ‖M‖_∞.
    MKL's LAPACK (its thread pool) when available, else SciPy's. ``info`` is getrf's: > 0 means
    an exactly singular M. A float32 M is factorized in single precision (``sgetrf``: half the
    memory traffic and about half the time, for matrices that need not be exact, such as
    approximate Newton matrices); solutions are returned in float64 either way. ``sequential``:
    getrf, getrs and gecon on one MKL thread (:func:`mkl_sequential`).
    """

    def __init__(self, M: np.ndarray, *, sequential: bool = False):
        self.n = _square(M, "LUFactor", (np.float64, np.float32))
        self.dtype = M.dtype
        self.sequential = sequential
        self._p = "s" if M.dtype == np.float32 else "d"
        self._real = ctypes.c_float if self._p == "s" else ctypes.c_double
        self._mkl = _mkl(f"LAPACKE_{self._p}getrf")
        if self._mkl is not None:
            fn, cint = self._mkl
            self._cint = cint
            self.a = M
            self.piv = np.zeros(self.n, dtype=np.int64 if cint is ctypes.c_int64 else np.int32)
            with mkl_sequential(sequential):
                self.info = int(fn(ctypes.c_int(_COL_MAJOR), cint(self.n), cint(self.n),
                                   _pardiso._ptr(M), cint(self.n), _pardiso._ptr(self.piv)))
        else:
            getrf, = sla.get_lapack_funcs(("getrf",), dtype=M.dtype)
            self.a, self.piv, self.info = getrf(M.T, overwrite_a=True)

    def pivot_ratio(self) -> float:
        """min |u_ii| / max |u_ii| of the factor U: an O(n) sign of (near) singularity.

        Cheap screening only: a small ratio flags an ill-conditioned M, but a moderate one does
        not prove M well conditioned; :meth:`rcond` estimates 1/κ.
        """
        if self.n == 0:
            return 1.0
        dg = np.abs(np.diagonal(self.a.reshape(self.n, self.n)))
        top = float(dg.max())
        return float(dg.min()) / top if top > 0 else 0.0

    def rcond(self, anorm: float) -> float:
        if self._mkl is not None:
            fn, cint = _mkl(f"LAPACKE_{self._p}gecon")
            out = self._real(0.0)
            with mkl_sequential(self.sequential):
                info = fn(ctypes.c_int(_COL_MAJOR), ctypes.c_char(b"1"), cint(self.n),
                          _pardiso._ptr(self.a), cint(self.n), self._real(anorm), ctypes.byref(out))
            return float(out.value) if info == 0 else 0.0
        gecon, = sla.get_lapack_funcs(("gecon",), dtype=self.dtype)
        rc, info = gecon(self.a, anorm, norm="1")
        return float(rc) if info == 0 else 0.0

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x with M x = b (b of length n), in float64; non-finite entries signal a failure."""
        if self._mkl is not None:
            fn, cint = _mkl(f"LAPACKE_{self._p}getrs")
            x = np.array(b, dtype=self.dtype)
            with mkl_sequential(self.sequential):
                info = fn(ctypes.c_int(_COL_MAJOR), ctypes.c_char(b"T"), cint(self.n), cint(1),
                          _pardiso._ptr(self.a), cint(self.n), _pardiso._ptr(self.piv), _pardiso._ptr(x),
                          cint(self.n))
        else:
            getrs, = sla.get_lapack_funcs(("getrs",), dtype=self.dtype)
            x, info = getrs(self.a, self.piv, np.asarray(b, dtype=self.dtype), trans=1)
        if info != 0:
            x = np.full(self.n, np.nan)
        return np.asarray(x, dtype=np.float64)


def spd_inverse(S: np.ndarray) -> np.ndarray:
    """Inverse of a dense symmetric positive definite matrix (Cholesky, then potri)."""
    a = np.array(S, dtype=np.float64, order="C")
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise SolverError(f"spd_inverse needs a square matrix, got shape {a.shape}")
    return inverse_from_cholesky(cholesky_lower(a), 0)
