"""Smoothed-aggregation AMG (pyamg) for the full-space path: the near-null space of
elasticity, and a hierarchy of an A(α_ref) that hands out V-cycle preconditioners for later
Newton systems and designs (:class:`ContactHierarchy`; docs/large_meshes.md)."""

from __future__ import annotations

import time

import numpy as np
import pyamg
import scipy.sparse as sp
from pyamg.aggregation.aggregate import standard_aggregation
from pyamg.aggregation.tentative import fit_candidates
from pyamg.relaxation.relaxation import gauss_seidel, gauss_seidel_indexed
from pyamg.relaxation.utils import relaxation_as_linear_operator
from pyamg.util.linalg import approximate_spectral_radius
from scipy.sparse.linalg import LinearOperator

from .._progress import progress, progress_level
from ..errors import SolverError

__all__ = ["ContactHierarchy", "VCycle", "rigid_body_modes", "block_positions"]

_COARSE_DIAG_MIN = 1e-10              # a coarse unknown whose diagonal fell below this fraction
                                      # of A(α_ref)'s lives (almost) inside D: decoupled
_ROWS_AT_A_TIME = 1 << 16
_HELD_CHANGE_MAX = 0.5                # the coarse operators' update from the last Newton system's
                                      # when at most this fraction of D changed, else afresh
INTERFACE_SWEEPS = 2                  # extra symmetric Gauss–Seidel sweeps on the rows that couple
                                      # two bodies, before the pre- and after the post-smoothing



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


def block_positions(A, rows, cols):
    """Positions in A.data of the entries (rows[i], cols[i]) (A CSR with sorted indices)."""
    out = np.empty(rows.size, dtype=np.int64)
    ip, ind = A.indptr, A.indices
    for i, (r_, c_) in enumerate(zip(rows.tolist(), cols.tolist())):
        a, b = ip[r_], ip[r_ + 1]
        k = a + int(np.searchsorted(ind[a:b], c_))
        if k >= b or ind[k] != c_:
            raise SolverError(f"entry ({r_}, {c_}) is not in the sparsity pattern of A")
        out[i] = k
    return out


def per_body_solver(A, B, body_modes: int, *, omega: float = 4.0 / 3.0, transform=None, **amg_kw):
    """pyamg's smoothed aggregation of A (symmetric) with a near-null space B of ``body_modes``
    columns per body (each block zero off its body but at the DOFs coupling the bodies), its
    first tentative prolongator built per aggregate from the columns of the bodies its DOFs belong
    to only: (the first level's prolongator, pyamg's solver of the first coarse operator).

    The first level is pyamg's (symmetric strength, standard aggregation, four symmetric
    Gauss–Seidel sweeps on B, Jacobi smoothing of the tentative prolongator with ω/ρ(D⁻¹A)), built
    here so that its smoothing forms D⁻¹A T and not the two copies of D⁻¹A that pyamg keeps
    beside A; the coarse operator is handed to pyamg in blocks of the near-null columns.

    ``transform`` = (T, T⁻¹) of a two bodies' system A = Tᵀ diag(A_1, …) T (:mod:`contactopt.paths.coupled`):
    the first level is then each body's own, built on the bodies' matrix T⁻ᵀ A T⁻¹
    (:func:`bodies_matrix`) with the near-null space T B, and handed back as T⁻¹ P. With nothing
    held at the contact its coarse operator is the bodies' own, Pᵀ diag(A_1, …) P; in A's unknowns a
    slab's coarse unknown moves the contact DOFs above it by −Π_loc (the relative displacement w
    that keeps the body still), which aggregates of A's own graph — a contact DOF in a body's
    aggregate, its partners in the slab's — cannot represent."""
    A = sp.csr_matrix(A)
    A.symmetry = "hermitian"
    B = np.asarray(B, dtype=np.float64)
    nb, k = B.shape[1] // body_modes, B.shape[1]
    owner = np.stack([np.any(B[:, j * body_modes:(j + 1) * body_modes] != 0, axis=1) for j in range(nb)], axis=1)
    A_loc, Tinv = A, None
    if transform is not None:
        T, Tinv = (sp.csr_matrix(M_) for M_ in transform)
        B = np.asarray(T @ B)
        label = body_label(B, body_modes)
        owner = np.stack([label == j for j in range(nb)], axis=1)
        B = np.where(np.repeat(owner, body_modes, axis=1), B, 0.0)
        A = bodies_matrix(A, Tinv, label)
    AggOp, _ = standard_aggregation(strength_pattern(A))
    AggOp = sp.csr_matrix(AggOp)
    relax = relaxation_as_linear_operator(("block_gauss_seidel", {"sweep": "symmetric", "iterations": 4}), A,
                                          np.zeros((A.shape[0], 1)))
    B = relax @ B
    del relax                          # (it holds A: the bodies' matrix goes with A below)
    agg = np.full(A.shape[0], -1, dtype=np.int64)     # the aggregate of each DOF (−1: none, an
    inside = np.diff(AggOp.indptr) > 0                 # isolated row of the bodies' own matrix)
    agg[inside] = AggOp.indices
    held = np.zeros((AggOp.shape[1], nb), dtype=bool)
    for j in range(nb):
        held[:, j] = np.bincount(agg[inside], weights=owner[inside, j], minlength=AggOp.shape[1]) > 0
    B = np.where(np.repeat(held[agg] & inside[:, None], body_modes, axis=1), B, 0.0)
    T, B1 = fit_candidates(AggOp, B)
    del B
    T = sp.csr_matrix(T)
    d = A.diagonal()
    d_inv = np.divide(1.0, d, out=np.zeros_like(d), where=d != 0)
    rho = approximate_spectral_radius(LinearOperator(A.shape, matvec=lambda v: d_inv * (A @ v.ravel()),
                                                     dtype=A.dtype))
    U = sp.csr_matrix(A @ T)             # P = T − (ω/ρ) D⁻¹A T
    U.data *= np.repeat((omega / rho) * d_inv, np.diff(U.indptr))
    P = sp.csr_matrix(T - U)
    del T, U
    if Tinv is not None:
        P = sp.csr_matrix(Tinv @ P)
        A = A_loc
    A1 = sp.csr_matrix(P.T @ sp.csr_matrix(A @ P)).tobsr(blocksize=(k, k))
    first = type("Level", (), {})()
    first.P, first.R, first.A = P, None, None
    ml = pyamg.smoothed_aggregation_solver(A1, B=B1, improve_candidates=None, **amg_kw)
    return [first] + list(ml.levels)


def strength_pattern(A):
    """pyamg's symmetric strength of connection of A (CSR) at θ = 0 as standard aggregation reads
    it, its pattern only: at θ = 0 it keeps every entry of A (|a_ij|² ≥ 0·|a_ii a_jj|), and the
    aggregation reads no values. A's own index arrays with one byte an entry, where the strength
    matrix, its absolute values and their row scaling made two to three copies of A — the largest
    step of the first level's set-up."""
    return sp.csr_matrix((np.ones(A.nnz, dtype=np.int8), A.indices, A.indptr), shape=A.shape, copy=False)


def body_label(B, body_modes: int) -> np.ndarray:
    """The body of each row of a near-null space B in the bodies' own coordinates (blocks of
    ``body_modes`` columns per body): the first block nonzero there."""
    nb = B.shape[1] // body_modes
    nz = np.stack([np.any(B[:, j * body_modes:(j + 1) * body_modes] != 0, axis=1) for j in range(nb)], axis=1)
    return np.argmax(nz, axis=1)


def bodies_matrix(A, Tinv, label):
    """T⁻ᵀ A T⁻¹ without its entries between rows of different bodies (``label``): the bodies'
    own block-diagonal stiffness diag(A, K_f) of a two bodies' system A = Tᵀ diag(A, K_f) T, its
    round-off between the bodies dropped.

    With T⁻¹ = I + F, F nonzero on the contact rows c only, T⁻ᵀ A T⁻¹ = A + Δ, Δ = F_cᵀ A_c +
    A_{:c} F_c + F_cᵀ A_cc F_c supported near the contact DOFs (as :mod:`contactopt.paths.coupled`
    forms the system): one matrix of A's size beside A, where the products T⁻ᵀ (A T⁻¹) held three
    or four at once (an evaluation's peak at 10⁶ DOFs)."""
    A = sp.csr_matrix(A)
    n = A.shape[0]
    F = sp.csr_matrix(sp.csr_matrix(Tinv) - sp.identity(n, format="csr"))
    F.eliminate_zeros()
    c = np.flatnonzero(np.diff(F.indptr))
    Fc = sp.csr_matrix(F[c])
    Ac = sp.csr_matrix(A[c])
    cols = sp.csr_matrix((np.ones(c.size), (np.arange(c.size), c)), shape=(c.size, n))
    left = sp.csr_matrix(Fc.T @ Ac)                       # F_cᵀ A_c; A_{:c} F_c is its transpose (A symmetric)
    delta = left + sp.csr_matrix(left.T) + sp.csr_matrix(Fc.T @ sp.csr_matrix((Ac @ cols.T) @ Fc))
    out = sp.csr_matrix(A + delta)
    del left, delta
    ip = out.indptr
    for start in range(0, n, _ROWS_AT_A_TIME):          # a block of rows at a time: no array of nnz(A)
        stop = min(start + _ROWS_AT_A_TIME, n)
        rows = np.repeat(np.arange(start, stop, dtype=np.int64), np.diff(ip[start:stop + 1]))
        cross = label[rows] != label[out.indices[ip[start]:ip[stop]]]
        out.data[ip[start]:ip[stop]][cross] = 0.0
    out.eliminate_zeros()           # (in place; as the products, no explicit zeros)
    out.sort_indices()
    out.symmetry = "hermitian"
    return out


def interface_rows(A, B, body_modes: int) -> np.ndarray:
    """The rows of A (CSR) that couple two bodies: those with an entry in a column whose bodies —
    the blocks of ``body_modes`` columns of the near-null space B nonzero there — are not the row's
    own (A's pattern is symmetric, so the columns of those entries are among them). On the two
    bodies' system of :mod:`contactopt.paths.coupled` these are the contact DOFs, the body's DOFs
    next to them and the counterpart's DOFs under them: the band where Gauss–Seidel on the
    whole system leaves the error that the coarse levels miss."""
    nb = B.shape[1] // body_modes
    label = np.zeros(A.shape[0], dtype=np.int64)
    for j in range(nb):
        label |= np.any(B[:, j * body_modes:(j + 1) * body_modes] != 0, axis=1).astype(np.int64) << j
    out, ip = [], A.indptr
    for start in range(0, A.shape[0], _ROWS_AT_A_TIME):        # a block of rows at a time: no array of nnz(A)
        stop = min(start + _ROWS_AT_A_TIME, A.shape[0])
        rows = np.repeat(np.arange(start, stop, dtype=np.int64), np.diff(ip[start:stop + 1]))
        cross = label[rows] != label[A.indices[ip[start]:ip[stop]]]
        out.append(np.unique(rows[cross]))
    return np.concatenate(out + [np.zeros(0, np.int64)])


def galerkin_near(delta, P):
    """Pᵀ Δ P for Δ (sparse, symmetric pattern) supported on a few rows and columns S, formed from
    the rows S of P only (P_Sᵀ Δ_SS P_S), in double precision."""
    delta = sp.csr_matrix(delta)
    S = np.union1d(np.flatnonzero(np.diff(delta.indptr)), delta.indices)
    PS = sp.csr_matrix(P[S], dtype=np.float64)
    dS = sp.csr_matrix(delta[S][:, S])
    return sp.csr_matrix(sp.csr_matrix(PS.T) @ (dS @ PS))


def drop_zero_columns(levels):
    """(P_l, A_l) of pyamg's ``levels`` (A_0 None) without the coarse unknowns whose column of
    P_l is zero — their rows and columns of A_{l+1} and rows of P_{l+1} are zero too: the same
    V-cycle on smaller coarse levels. Each level's matrices are released as they are taken."""
    P, A, kept = [], [None], None        # kept: the coarse unknowns kept of the level above, None: all
    for lvl in range(len(levels) - 1):
        P_ = _csr_released(levels[lvl], "P")
        levels[lvl].R = None
        if kept is not None:
            P_ = _without_rows(P_, kept)
        keep = np.flatnonzero(np.bincount(P_.indices, minlength=P_.shape[1]) > 0)
        kept = None if keep.size == P_.shape[1] else keep
        if kept is not None:
            P_ = _with_columns(P_, kept)
        P.append(P_)
        Ac = _csr_released(levels[lvl + 1], "A")
        A.append(Ac if kept is None else _with_columns(_without_rows(Ac, kept), kept))
    return P, A


def _csr_released(level, name):
    """``level.name`` as CSR without its explicit zeros, the level's reference dropped."""
    M = sp.csr_matrix(getattr(level, name))
    setattr(level, name, None)
    M.eliminate_zeros()
    return M


def _without_rows(M, keep):
    """The rows ``keep`` of CSR M whose other rows are empty (no copy of the entries)."""
    lens = np.diff(M.indptr)
    if lens.sum() != lens[keep].sum():
        return sp.csr_matrix(M[keep])
    indptr = np.append(M.indptr[keep], M.indptr[-1])
    return sp.csr_matrix((M.data, M.indices, indptr), shape=(keep.size, M.shape[1]))


def _with_columns(M, keep):
    """The columns ``keep`` of CSR M whose other columns are empty, renumbered."""
    new = np.full(M.shape[1], -1, dtype=M.indices.dtype)
    new[keep] = np.arange(keep.size, dtype=M.indices.dtype)
    out = sp.csr_matrix((M.data, new[M.indices], M.indptr), shape=(M.shape[0], keep.size))
    if out.nnz and out.indices.min() < 0:
        raise SolverError("a dropped coarse unknown has entries")
    return out


class ContactHierarchy:
    """The smoothed-aggregation hierarchy of an A(α_ref) (pyamg, rigid-body modes), kept to
    precondition the Newton systems of later steps and designs.

    Keeps the prolongations P_l, restrictions R_l = P_lᵀ, the coarse operators A_l (l ≥ 1) and
    the rows of A(α_ref) of the contact DOFs (all Dirichlet DOFs of a Newton system are contact
    DOFs), not the fine matrix itself. :meth:`preconditioner` returns the V-cycle of a fine matrix
    H (same pattern as A) with Dirichlet DOFs D, its coarse operators updated by Galerkin products
    supported near D (:mod:`contactopt.contact.fullspace`). ``setup_seconds``, ``uses`` (Newton systems served),
    ``reference_iterations`` (Krylov iterations of the first solve with it; the caller may
    rebuild when later solves need many more).

    ``precision="single"`` (default) runs the V-cycle in float32 — the fine matrix of the smoother
    (:meth:`fine_matrix`), the prolongations and the coarse operators: a preconditioner need not be
    exact, and GMRES keeps its preconditioned directions (flexible GMRES), so the solves reach the
    same tolerances with the same iterations, while the memory traffic of the smoothing sweeps —
    about half of an iteration — drops by a third (measured at 113k: GMRES time −18 %, the same
    iteration counts).

    ``body_modes``: the near-null space holds that many columns per body, each block zero off its
    body (the two bodies' system of :mod:`contactopt.paths.coupled`); every aggregate then takes
    the columns of its own bodies only (:func:`per_body_solver`) and the coarse unknowns left zero
    are dropped (:func:`drop_zero_columns`): half the coarse unknowns of an aggregate inside one
    body (docs/foundation.md, "At scale"). Its V-cycles then also smooth the rows that couple
    two bodies (``interface``, :func:`interface_rows`) with :data:`INTERFACE_SWEEPS` extra sweeps:
    the smoothing on the whole system leaves an error there that the coarse levels do not
    correct (at 80k DOFs 37 GMRES iterations of the adjoint with them against 46, 73 of the
    state against 92; docs/scaling.md, "Two bodies at scale on one process").

    ``transform`` = (T, T⁻¹), the change of unknowns of such a system (A = Tᵀ diag(A_1, …) T): the
    first level is built in the bodies' own coordinates (:func:`per_body_solver`), and the band's
    extra sweeps correct in the basis Z = T⁻¹ without the frames' rotation, on the contact DOFs
    that the Newton system leaves free (:meth:`band_basis`): in A's unknowns a slab's DOF under the
    contact carries the body's stiffness beside its own (moving it moves the body's contact DOFs),
    so Gauss–Seidel there hardly corrects the slab's own error; in Z's, where moving it moves w
    by −Π_loc, it does. At 80k DOFs 31 GMRES iterations of the adjoint against 37, 61 of the state
    against 73, the same Θ and ξ (docs/scaling.md)."""

    def __init__(self, A, near_null=None, *, contact_dofs, max_coarse: int = 10,
                 precision: str = "single", body_modes: int | None = None, transform=None, **amg_kw):
        try:
            import pyamg
        except ImportError as exc:
            raise SolverError("algebraic multigrid needs pyamg: pip install pyamg") from exc
        t0 = time.perf_counter()
        A = sp.csr_matrix(A)
        A.sort_indices()
        if precision not in ("single", "double"):
            raise SolverError(f"precision must be 'single' or 'double', got {precision!r}")
        self.dtype = np.float32 if precision == "single" else np.float64
        progress.log(progress_level(A.shape[0], t0), "AMG hierarchy of %d DOFs: set-up started", A.shape[0])
        if body_modes is None:
            ml = pyamg.smoothed_aggregation_solver(A, B=near_null, max_coarse=max_coarse, **amg_kw)
        else:
            ml = per_body_solver(A, near_null, body_modes, max_coarse=max_coarse, transform=transform, **amg_kw)
        progress.log(progress_level(A.shape[0], t0), "AMG hierarchy of %d DOFs: %d levels in %.1f s",
                     A.shape[0], len(ml.levels) if body_modes is None else len(ml), time.perf_counter() - t0)
        self.n = A.shape[0]
        if body_modes is None:
            self.P = [sp.csr_matrix(lvl.P, dtype=self.dtype) for lvl in ml.levels[:-1]]
            self.R = [sp.csr_matrix(lvl.R, dtype=self.dtype) for lvl in ml.levels[:-1]]
            self.A = [None] + [sp.csr_matrix(lvl.A) for lvl in ml.levels[1:]]
            self.operator_complexity = float(ml.operator_complexity())
        else:
            levels, ml = ml, None
            P, self.A = drop_zero_columns(levels)
            del levels
            self.P, self.R = [], []
            while P:
                P_ = sp.csr_matrix(P.pop(0), dtype=self.dtype)
                self.P.append(P_)
                self.R.append(sp.csr_matrix(P_.T))
            self.operator_complexity = 1.0 + sum(M_.nnz for M_ in self.A[1:]) / A.nnz
        del ml
        for M_ in self.A[1:]:
            M_.sort_indices()
        cdofs = np.unique(np.asarray(contact_dofs, dtype=np.int64))
        self.contact_rows = A[cdofs]                 # rows of A(α_ref) at the contact DOFs
        # ... and their product with the first prolongation: Pᵀ Δ P of a Newton system from the
        # rows of its Dirichlet DOFs (:meth:`preconditioner`)
        self._contact_P = None
        if self.P:                                   # (the rows of P_0 that the contact rows reach only)
            near = np.unique(self.contact_rows.indices)
            cols = sp.csr_matrix((np.ones(near.size), (np.arange(near.size), near)), shape=(near.size, self.n))
            self._contact_P = sp.csr_matrix((self.contact_rows @ cols.T)
                                            @ sp.csr_matrix(self.P[0][near], dtype=np.float64))
        self.interface = (None if body_modes is None or near_null is None
                          else interface_rows(A, np.asarray(near_null), body_modes).astype(A.indptr.dtype))
        # the band smoothed in the bodies' own coordinates: T⁻¹'s entries off the contact DOFs' own
        # columns (rows c: −Π_loc on the counterparts' DOFs)
        self._zoff = None
        if transform is not None and self.interface is not None:
            Tinv = sp.csr_matrix(transform[1])
            rows = sp.csr_matrix((np.ones(cdofs.size), (cdofs, cdofs)), shape=(self.n, self.n))
            Zc = sp.csr_matrix(rows @ Tinv)
            Zc = sp.csr_matrix(Zc - Zc @ rows)
            Zc.eliminate_zeros()
            self._zoff = Zc
        self._row_of = np.full(self.n, -1, dtype=np.int64)
        self._row_of[cdofs] = np.arange(cdofs.size)
        self._diagonals = [M_.diagonal() for M_ in self.A[1:]]
        self._held = None
        self.setup_seconds = time.perf_counter() - t0
        self.uses = 0
        self.reference_iterations = None

    @property
    def levels(self) -> int:
        return len(self.A)

    def sizes(self) -> list:
        return [self.n] + [M_.shape[0] for M_ in self.A[1:]]

    def coarse_compliance(self, contact_dofs, max_size: int = 2000, max_flops: float = 2e9):
        """Per contact node, tr((Φ A_l⁻¹ Φᵀ)_mm)/3 with Φ = B P_0 ⋯ P_{l−1} the composite
        prolongation of the contact DOFs to level l (the finest level with at most ``max_size``
        unknowns and a cost 3p·n_l² within ``max_flops``): the part of the Delassus diagonal W_mm
        that the global, smooth deformations of the body contribute (a Galerkin projection of A⁻¹,
        so at most W_mm). Cached per contact DOFs (it depends on A(α_ref) only)."""
        cd = np.asarray(contact_dofs, dtype=np.int64)
        key = cd.tobytes()
        if getattr(self, "_compliance", (None,))[0] == key:
            return self._compliance[1]
        sizes = self.sizes()
        lvl = next((k for k in range(1, len(sizes))
                    if sizes[k] <= max_size and cd.size * sizes[k] ** 2 <= max_flops), len(sizes) - 1)
        Phi = sp.csr_matrix((np.ones(cd.size), (np.arange(cd.size), cd)), shape=(cd.size, self.n))
        for k in range(lvl):
            Phi = sp.csr_matrix(Phi @ self.P[k].astype(np.float64))
        Ac = self.A[lvl].toarray()
        w, Q = np.linalg.eigh(0.5 * (Ac + Ac.T))
        keep = w > 1e-12 * max(w.max(initial=0.0), 1e-300)
        Y = sp.csr_matrix(Phi) @ (Q[:, keep] / np.sqrt(w[keep]))       # Φ A_l^{-1/2}
        out = np.einsum("ij,ij->i", Y, Y).reshape(-1, 3).mean(axis=1)
        self._compliance = (key, out)
        return out

    def fine_matrix(self, A):
        """A copy of A in the V-cycle's precision, to be changed in place into H = A + K_t."""
        return sp.csr_matrix(A, dtype=self.dtype, copy=True)

    def preconditioner(self, H, dirichlet, kt=None) -> "VCycle":
        """V-cycle for H (a :meth:`fine_matrix`) restricted to the DOFs outside ``dirichlet``
        (boolean mask); ``kt`` the sparse part H − A added on free rows (the Robin blocks), for the
        coarse operators: A_l + P_{l−1}ᵀ ⋯ P_0ᵀ (Π A Π − A + K_t) P_0 ⋯ P_{l−1}, Π the projection
        onto the DOFs outside D. The part of Π A Π − A is updated from the last Newton system's
        (:meth:`_held_parts`); call :meth:`forget_updates` where a solve starts."""
        self.uses += 1
        D = np.flatnonzero(dirichlet)
        if D.size and np.any(self._row_of[D] < 0):
            raise SolverError("Dirichlet DOFs outside the contact DOFs of the hierarchy")
        held = self._held_parts(D)
        robin = (self._down_levels(galerkin_near(kt, self.P[0])) if kt is not None and kt.nnz and self.P
                 else [None] * len(self.P))
        ops = []
        for lvl in range(len(self.P)):
            Ac = self.A[lvl + 1]
            delta = held[lvl] if robin[lvl] is None else sp.csr_matrix(held[lvl] + robin[lvl])
            delta.sort_indices()
            Anew = sp.csr_matrix(Ac + delta) if delta.nnz else Ac
            d_ref = self._diagonals[lvl]
            bad = ~(d_ref + delta.diagonal() > _COARSE_DIAG_MIN * d_ref)
            if np.any(bad):            # unknowns (almost) inside D: decouple, keep them harmless
                keepm = sp.diags((~bad).astype(float))
                Anew = (keepm @ Anew @ keepm + sp.diags(np.where(bad, d_ref, 0.0))).tocsr()
            Anew.sort_indices()
            ops.append(Anew)
        return VCycle(H, dirichlet, self.P, self.R, ops, self.dtype, band=self.interface,
                      band_basis=self.band_basis(H, dirichlet))

    def forget_updates(self) -> None:
        """Form the next Newton system's coarse operators afresh: a solve that starts here repeats
        bit for bit whatever was solved with the hierarchy before it (a resumed run)."""
        self._held = None

    def _held_parts(self, D):
        """[P_0ᵀ (Π A Π − A) P_0, P_1ᵀ P_0ᵀ (Π A Π − A) P_0 P_1, …] for the Dirichlet DOFs D: the last
        Newton system's parts plus the Galerkin products of their change (:meth:`_held_change`),
        supported near the DOFs that entered or left D — a few per Newton step, where the parts
        themselves reach every DOF of D (at 360k DOFs 2,900 DOFs in D, 290 to 0 changed a step,
        docs/scaling.md). Afresh after :meth:`forget_updates` or when most of D changed."""
        if not self.P:
            return []
        last = self._held
        added, removed = D, D[:0]
        if last is not None:
            added = np.setdiff1d(D, last[0], assume_unique=True)
            removed = np.setdiff1d(last[0], D, assume_unique=True)
            if added.size + removed.size > _HELD_CHANGE_MAX * max(D.size, 1):
                last, added, removed = None, D, D[:0]
        if last is not None and not added.size and not removed.size:
            return last[1]
        changes = self._down_levels(self._held_change(D, added, removed))
        parts = changes if last is None else [sp.csr_matrix(old + ch) for old, ch in zip(last[1], changes)]
        self._held = (D, parts)
        return parts

    def _down_levels(self, first):
        """[M, P_1ᵀ M P_1, P_2ᵀ P_1ᵀ M P_1 P_2, …] from M on the first coarse level: the Galerkin
        products of a change near the contact, level by level (:func:`galerkin_near`)."""
        out = [first]
        for lvl in range(1, len(self.P)):
            prev = out[-1]
            out.append(galerkin_near(prev, self.P[lvl]) if prev.nnz else sp.csr_matrix(self.A[lvl + 1].shape))
        return out

    def _held_change(self, D, added, removed):
        """P_0ᵀ (Π' A Π' − Π A Π) P_0 on the first coarse level, for D' = D (Π' the projection onto
        the DOFs outside it) from the last Dirichlet set (Π) with the DOFs ``added`` to it and
        ``removed`` from it: with s = Π − Π' (+1 on the added DOFs C⁺, −1 on the removed C⁻, C = C⁺ ∪ C⁻),
        Π' A Π' − Π A Π = −(s A Π' + Π' A s) − s A s, whose product is −(X + Xᵀ) − P_Cᵀ s A_CC s P_C with
        X = P_Cᵀ s (A Π' P_0)_C = P_Cᵀ s ((A P_0)_C − A_{C,D'} P_{D'}) — from the rows of A and of
        A P_0 at the contact DOFs kept at set-up, a product over C and D' only. From no Dirichlet
        DOFs (C = D'): P_0ᵀ (Π' A Π' − A) P_0."""
        nc = self.P[0].shape[1]
        C = np.concatenate([added, removed])
        if not C.size:
            return sp.csr_matrix((nc, nc))
        s = sp.diags(np.concatenate([np.ones(added.size), -np.ones(removed.size)]))
        r = self._row_of[C]
        rows = self.contact_rows[r]                             # A_{C,·}
        PC = sp.csr_matrix(self.P[0][C], dtype=np.float64)
        Y = self._contact_P[r]
        if D.size:
            Y = Y - sp.csr_matrix(rows[:, D]) @ sp.csr_matrix(self.P[0][D], dtype=np.float64)
        PCs = sp.csr_matrix(s @ PC)                             # s P_C
        X = sp.csr_matrix(sp.csr_matrix(PCs.T) @ Y)
        out = -(X + sp.csr_matrix(X.T)) - sp.csr_matrix(PCs.T) @ (sp.csr_matrix(rows[:, C]) @ PCs)
        out = sp.csr_matrix(out)
        out.sum_duplicates()
        return out

    def band_basis(self, H, dirichlet):
        """(J, Z_J, H_J, Z_Jᵀ H_JJ Z_J): the band's free rows J, the basis Z_J of the subspace its
        sweeps correct in, the bodies' own coordinates where the contact DOFs are not held
        (a free contact DOF's correction moves its counterparts' DOFs with it, w − Π_loc δu_f;
        a held one stays), and H's rows J; None without a transform. With Z_J = I + F (F: the
        entries off the contact DOFs' own columns, in a few rows) and H symmetric,
        Z_Jᵀ H_JJ Z_J = H_JJ + W + Wᵀ + Fᵀ W with W = H_JJ F: products over F's rows only."""
        if self._zoff is None or self.interface is None:
            return None
        J = self.interface[~np.asarray(dirichlet)[self.interface]]
        F = sp.csr_matrix(self._zoff[J][:, J], dtype=np.float64)
        HJ = H[J]
        HJJ = sp.csr_matrix(HJ[:, J], dtype=np.float64)
        W = sp.csr_matrix(HJJ @ F)
        Hy = sp.csr_matrix(HJJ + W + sp.csr_matrix(W.T) + sp.csr_matrix(F.T) @ W, dtype=self.dtype)
        Hy.sort_indices()
        Z = sp.csr_matrix(sp.identity(J.size, format="csr") + F, dtype=self.dtype)
        return J, Z, sp.csr_matrix(HJ, dtype=self.dtype), Hy

    def _first_delta(self, D, kt):
        """P_0ᵀ Δ P_0 on the first coarse level, Δ = Π (A_ref + K_t) Π − A_ref, afresh (what
        :meth:`preconditioner` forms from no Dirichlet DOFs plus the Robin blocks' product)."""
        out = self._held_change(D, D, D[:0])
        if kt is not None and kt.nnz:
            out = out + galerkin_near(kt, self.P[0])
        return sp.csr_matrix(out)


class VCycle:
    """One multigrid cycle for H on the DOFs outside D, as a callable v ↦ M v with (M v)_D = 0:
    symmetric Gauss–Seidel pre- and post-smoothing, a dense pseudo-inverse on the coarsest level,
    and on every coarse level between a K-cycle (Notay and Vassilevski): two steps of flexible
    conjugate gradients on A_l, each preconditioned by the cycle of that level, where a V-cycle
    applies the cycle once. On the two bodies' system the V-cycle's coarse correction was the weak
    part (on the last Newton system of the 80k model, an exact solve on the first coarse level took
    18 GMRES iterations against 29, twice the finest level's smoothing 27); at 360k the K-cycle
    took 16 against 27 (one body at 210k: 13 against 21), for about 30 % more work per cycle
    (docs/scaling.md, "The K-cycle"). M is therefore not linear in v — GMRES keeps the
    preconditioned directions (flexible, :func:`contactopt.fem.krylov.gmres`) — but a function of v
    alone: the same v gives the same M v, bit for bit. Computed in ``dtype`` (the hierarchy's
    precision), returned in double precision. ``band``: fine rows smoothed
    :data:`INTERFACE_SWEEPS` more times, before the pre-smoothing and after the post-smoothing;
    its Dirichlet rows are left out."""

    def __init__(self, H, dirichlet, P, R, ops, dtype=np.float64, band=None, band_basis=None):
        self._gs, self._gs_idx = gauss_seidel, gauss_seidel_indexed
        if H.dtype != dtype:
            raise SolverError(f"the fine matrix is {H.dtype}, the hierarchy {np.dtype(dtype)}")
        self.dtype = dtype
        self.H = H
        self.D = np.flatnonzero(dirichlet)
        self.rows = np.flatnonzero(~np.asarray(dirichlet)).astype(H.indptr.dtype)
        self.band = None if band is None else band[~np.asarray(dirichlet)[band]]
        self.band_basis = band_basis
        self.P, self.R = P, R
        self.A = [H] + [sp.csr_matrix(o, dtype=dtype) for o in ops]
        Ac = ops[-1].toarray() if ops else H.toarray()
        Ac = 0.5 * (Ac + Ac.T).astype(np.float64)
        w, Q = np.linalg.eigh(Ac)
        keep = w > 1e-12 * max(w.max(initial=0.0), 1e-300)
        self._coarse = ((Q[:, keep] / w[keep]) @ Q[:, keep].T).astype(dtype)
        self.calls = 0

    sweeps = ("symmetric", "symmetric")   # (pre, post); ("forward", "backward") is also symmetric

    def _smooth(self, lvl, x, b, which):
        sweep = self.sweeps[which]
        if lvl == 0:
            if which == 1:
                self._gs_idx(self.H, x, b, self.rows, sweep=sweep)
            if self.band_basis is not None and self.band.size:
                J, Z, HJ, Hy = self.band_basis
                rhs = Z.T @ (b[J] - HJ @ x)
                d = np.zeros_like(rhs)
                self._gs(Hy, d, rhs, iterations=INTERFACE_SWEEPS, sweep="symmetric")
                x[J] += Z @ d
            elif self.band is not None and self.band.size:      # pre: band, then all; post: all, then band
                for _ in range(INTERFACE_SWEEPS):
                    self._gs_idx(self.H, x, b, self.band, sweep="symmetric")
            if which == 0:
                self._gs_idx(self.H, x, b, self.rows, sweep=sweep)
        else:
            self._gs(self.A[lvl], x, b, sweep=sweep)

    def _cycle(self, lvl, b):
        if lvl == len(self.A) - 1:
            return self._coarse @ b
        A = self.A[lvl]
        x = np.zeros_like(b)
        self._smooth(lvl, x, b, 0)
        r = b - A @ x
        if lvl == 0:
            r[self.D] = 0.0
        e = self.P[lvl] @ self._coarse_solve(lvl + 1, self.R[lvl] @ r)
        if lvl == 0:
            e[self.D] = 0.0
        x += e
        self._smooth(lvl, x, b, 1)
        return x

    def _coarse_solve(self, lvl, b):
        """An approximate A_l⁻¹ b on coarse level l: the coarsest level's pseudo-inverse, else two
        steps of flexible CG preconditioned by the level's cycle (the K-cycle; one cycle where the
        first step leaves nothing to do or A_l is not positive along it)."""
        if lvl == len(self.A) - 1:
            return self._coarse @ b
        A = self.A[lvl]
        c1 = self._cycle(lvl, b)
        v1 = A @ c1
        rho1 = float(c1 @ v1)
        if not rho1 > 0.0:
            return c1
        a1 = float(c1 @ b) / rho1
        r = b - a1 * v1
        c2 = self._cycle(lvl, r)
        v2 = A @ c2
        beta = float(c2 @ v1) / rho1
        d = c2 - beta * c1
        rho2 = float(d @ (v2 - beta * v1))
        if not rho2 > 0.0:
            return a1 * c1
        return a1 * c1 + (float(d @ r) / rho2) * d

    def __call__(self, v):
        self.calls += 1
        v = np.array(v, dtype=self.dtype)
        v[self.D] = 0.0
        out = self._cycle(0, v).astype(np.float64)
        out[self.D] = 0.0
        return out
