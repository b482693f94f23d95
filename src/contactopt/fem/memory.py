"""Up-front estimate of the peak memory of one evaluation, and the check that refuses a mesh
that would not fit (issue #16).

An evaluation on today's path (:mod:`contactopt.fem.linsolve`, PARDISO Schur mode) holds at once

* the sparse system: A(α) in CSR (12 bytes per entry), its upper triangle handed to PARDISO and
  the assembly's value arrays — about ``SPARSE_COPIES`` × 12 bytes per entry of A;
* PARDISO's memory for the Schur-mode factorization: ``PARDISO_BYTES`` per entry of the factor,
  whose size is nnz(L) = fill(n)·nnz(A) with a fill that grows like n^FILL_EXPONENT on 3D meshes
  of the block (nested dissection: nnz(L) ~ n^(4/3) on a cube);
* dense matrices on all 3p contact DOFs: the condensed stiffness S, its Cholesky factor, the
  Delassus block of the zone and the adjoint's matrix — ``DENSE_COPIES`` × (3p)² doubles;
* the element layer (per-element arrays of the assembly and of the design contraction) and the
  interpreter with its libraries: ``BASE_BYTES`` plus ``CELL_BYTES`` per element.

The constants are calibrated against measured peak RSS (``benchmarks/bench_scale.py``, which
prints estimate and measurement side by side) on refinements of Example 1 (Q1 hexahedra): BASE
and DENSE_COPIES fitted to the peaks 0.42 GB (15k DOFs) and 3.30 GB (113k DOFs), PARDISO_BYTES
from PARDISO's own report of its memory, the fill from nnz(L) at those two sizes. On
other element types the number of entries of A is counted from the mesh, the fill is that of the
block. The estimate is for the PARDISO backend (SciPy's SuperLU needs several times more). It
decides whether a run can start, not how much memory to reserve.

The check compares the estimate with ``MemAvailable`` of /proc/meminfo (memory the kernel can
hand out without swapping) and raises :class:`InsufficientMemoryError` (a ContactOptError: exit
code 2 from the CLI) naming the estimate, its parts and what to do, instead of letting the system
kill the run mid-factorization.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import ContactOptError

log = logging.getLogger(__name__)

GB = 2.0**30

BASE_BYTES = 0.20 * GB        # interpreter, NumPy/SciPy/MKL, the model's design-independent data
CELL_BYTES = 2.0e3            # element work arrays per cell (assembly, design contraction), Q1
SPARSE_COPIES = 3.0           # A, its upper triangle for PARDISO, assembly values
FILL_REF = (15360, 8.0)       # measured nnz(L)/nnz(A) of the Schur-mode factor at n = 15360 DOFs
FILL_EXPONENT = 0.372         # ... and 16.8 at n = 113088: fill ∝ n^0.372
PARDISO_BYTES = 10.0          # PARDISO's memory per entry of the factor (its iparm[15]+[16]: 9.7–11.6)
DENSE_COPIES = 5.3            # S (PARDISO's and ours), its Cholesky factor, W_Z, the adjoint's matrix
# The Delassus path (``[linear_solver] path = "delassus"``): the Cholesky factor of A (nnz(L)
# 97.1M at 113k, 503M at 371k DOFs: CHOLESKY_FILL of the Schur-mode factor's) is kept, and when a
# contact zone's Delassus block is formed, the Schur-mode factorization onto the zone's DOFs is
# held beside it with dense zone matrices (S_Z, W_Z, the adjoint's) — ZONE_FRACTION of the contact
# DOFs at most (the zone is the nodes near the foundation).
CHOLESKY_FILL = 0.64
ZONE_FRACTION = 1.0       # the first design's zone (predicted from A⁻¹L) can hold every contact node
# The full-space path (``path = "fullspace"``): no factorization; A, its modified copy H, the AMG
# hierarchy (operator complexity ≈ 1.16) and GMRES's Krylov basis (restart 60).
AMG_SPARSE_COPIES = 6.0
KRYLOV_VECTORS = 130
# ... with elastic counterparts in its Newton system (paths/coupled.py): the products Tᵀ diag(A, K_f) T
# formed per design beside diag(A, K_f), a system denser than the bodies' blocks and a hierarchy of
# operator complexity ≈ 1.9 (six near-null vectors per body): COUPLED_SPARSE_COPIES × 12 bytes per
# entry of every body's stiffness, fitted to the peaks of Example 1 on its slab since the system is
# formed as diag(A, K_f) + Δ (docs/foundation.md, "Memory"): 0.44, 2.16, 3.71 and 9.53 GB at 26k, 191k,
# 360k and 977k DOFs against 0.44, 2.12, 3.87 and 10.30 GB estimated (10.8 before: 10.65 GB at 977k)
COUPLED_SPARSE_COPIES = 10.4
# An elastic foundation (``[foundation]``, condensation path): K_f and the Schur-mode factor of it
# onto the m free top-face DOFs that carry partners, held once per run, with dense S_f, W_f, M and
# its Cholesky factor (m × m), C and S_eff (3p × 3p) and the products between them (3p × m).
FOUNDATION_DENSE_M = 5.0
FOUNDATION_DENSE_C = 3.0
FOUNDATION_DENSE_CM = 3.0


class InsufficientMemoryError(ContactOptError):
    """The estimated peak memory of an evaluation exceeds the memory available.

    ``estimate`` is the :class:`MemoryEstimate`, ``available_gb`` what /proc/meminfo offered.
    """

    def __init__(self, message, estimate=None, available_gb=None):
        self.estimate = estimate
        self.available_gb = available_gb
        super().__init__(message)


@dataclass
class MemoryEstimate:
    """Estimated peak memory (bytes) of one evaluation, by part; sizes it was computed from."""

    n_dofs: int
    n_contact_dofs: int
    n_cells: int
    nnz_A: int
    nnz_factor: int
    parts: dict

    @property
    def total(self) -> float:
        return float(sum(self.parts.values()))

    @property
    def total_gb(self) -> float:
        return self.total / GB

    def with_parts(self, extra: dict) -> "MemoryEstimate":
        """The estimate with more parts held at the same time (an elastic foundation's)."""
        return MemoryEstimate(self.n_dofs, self.n_contact_dofs, self.n_cells, self.nnz_A, self.nnz_factor,
                              {**self.parts, **extra})

    def describe(self) -> str:
        parts = ", ".join(f"{k} {v / GB:.2f}" for k, v in self.parts.items())
        return (f"{self.total_gb:.1f} GB for {self.n_dofs} DOFs and {self.n_contact_dofs} contact DOFs "
                f"({parts} GB)")


@dataclass(frozen=True)
class PathEstimates:
    """The memory estimate of the solver path that will run (``run``, a function of a body and,
    keyword ``counterparts``, its elastic counterparts' sizes) and ``others``: {path: its
    estimate} of the other paths that take the model, which a refusal names; ``name`` the path
    that will run, which the estimate's log line and a refusal name (None: not said)."""

    run: object
    others: dict = field(default_factory=dict)
    name: str | None = None


def fill_factor(n_dofs: int) -> float:
    """nnz(L)/nnz(A) of PARDISO's Schur-mode factor, extrapolated from the block's measurements."""
    n0, f0 = FILL_REF
    return f0 * (max(n_dofs, 1) / n0) ** FILL_EXPONENT


def matrix_entries(cells: np.ndarray, n_nodes: int, free_per_node=None) -> int:
    """Entries of the stiffness matrix on the free DOFs, from the mesh only: a pair of nodes
    sharing a cell (or a node with itself) gives f_a·f_b entries, f the free components of a node
    (3 unless ``free_per_node`` says otherwise)."""
    cells = np.asarray(cells)
    n_cells, k = cells.shape
    C = sp.csr_matrix((np.ones(cells.size, dtype=np.float32), cells.ravel(),
                       np.arange(0, cells.size + 1, k)), shape=(n_cells, n_nodes))
    G = (C.T @ C).tocsr()
    G.data[:] = 1.0
    f = np.full(n_nodes, 3.0) if free_per_node is None else np.asarray(free_per_node, dtype=float)
    return int(round(f @ (G @ f)))


def condensation_parts(n_dofs: int, n_contact_dofs: int, nnz_A: int) -> tuple[dict, int]:
    """(parts, nnz of the factor) of the condensation path: the Schur-mode factor of A and dense
    matrices on all contact DOFs (see the module docstring for the model)."""
    nnz_L = int(fill_factor(n_dofs) * nnz_A)
    return {"factor": PARDISO_BYTES * nnz_L, "dense": DENSE_COPIES * 8.0 * float(n_contact_dofs) ** 2}, nnz_L


def delassus_parts(n_dofs: int, n_contact_dofs: int, nnz_A: int, keep_cholesky: bool = False) -> tuple[dict, int]:
    """The Delassus path: the Cholesky of A, and (beside it, or with it released: ``keep_cholesky``
    False) the Schur-mode factor onto a zone (upper bound: onto all contact DOFs) with the zone's
    dense matrices."""
    nz = ZONE_FRACTION * n_contact_dofs
    zone_L = int(fill_factor(n_dofs) * nnz_A)
    nnz_L = int(CHOLESKY_FILL * zone_L)
    factor = nnz_L + zone_L if keep_cholesky else max(nnz_L, zone_L)
    return {"factor": PARDISO_BYTES * factor, "dense": DENSE_COPIES * 8.0 * nz ** 2}, nnz_L


def fullspace_parts(n_dofs: int, n_contact_dofs: int, nnz_A: int) -> tuple[dict, int]:
    """The full-space path: no factorization; A, its modified copy, the AMG hierarchy and the
    Krylov basis."""
    return {"sparse": AMG_SPARSE_COPIES * 12.0 * nnz_A, "krylov": KRYLOV_VECTORS * 8.0 * n_dofs}, 0


@dataclass(frozen=True)
class CounterpartSize:
    """What an estimate counts of an elastic counterpart body, from its mesh (before K_f is
    assembled): its free DOFs, the entries of K_f on them, its free support DOFs that carry
    partners and the contact DOFs of its pairs."""

    n_dofs: int
    nnz: int
    n_support_dofs: int
    n_contact_dofs: int


def coupled_parts(n_dofs: int, n_contact_dofs: int, nnz_A: int, counterparts=()) -> tuple[dict, int]:
    """The full-space path with the elastic ``counterparts`` (:class:`CounterpartSize`) in its
    Newton system: every body's stiffness in the products with T, the system and its AMG
    hierarchy (COUPLED_SPARSE_COPIES), every body's DOFs in the Krylov basis; the counterparts'
    share under "foundation". Without counterparts :func:`fullspace_parts`."""
    if not counterparts:
        return fullspace_parts(n_dofs, n_contact_dofs, nnz_A)
    nnz_K = sum(c.nnz for c in counterparts)
    n_f = sum(c.n_dofs for c in counterparts)
    return {"sparse": COUPLED_SPARSE_COPIES * 12.0 * nnz_A, "krylov": KRYLOV_VECTORS * 8.0 * n_dofs,
            "foundation": COUPLED_SPARSE_COPIES * 12.0 * nnz_K + KRYLOV_VECTORS * 8.0 * n_f}, 0


def condensed_counterparts(counterparts) -> dict:
    """The condensation path's part of the elastic ``counterparts``: each one's
    :func:`foundation_parts`, held for the whole run ({} without counterparts)."""
    if not counterparts:
        return {}
    return {"foundation": sum(foundation_parts(c.n_dofs, c.nnz, c.n_support_dofs, c.n_contact_dofs)["foundation"]
                              for c in counterparts)}


def condensation_estimate(body, counterparts=()) -> MemoryEstimate:
    """The condensation path's estimate of a body and its elastic counterparts (sizes)."""
    return estimate_evaluation(body, condensation_parts).with_parts(condensed_counterparts(counterparts))


def foundation_parts(n_dofs: int, nnz_K: int, n_support_dofs: int, n_contact_dofs: int) -> dict:
    """The elastic foundation's part (bytes), held for the whole run beside an evaluation's: its
    sparse K_f and Schur-mode factor (``n_dofs`` free DOFs, ``nnz_K`` entries) and the dense
    matrices on its ``n_support_dofs`` free top-face DOFs and the body's contact DOFs."""
    m, c = float(n_support_dofs), float(n_contact_dofs)
    factor = PARDISO_BYTES * fill_factor(n_dofs) * nnz_K + SPARSE_COPIES * 12.0 * nnz_K
    dense = 8.0 * (FOUNDATION_DENSE_M * m * m + FOUNDATION_DENSE_C * c * c + FOUNDATION_DENSE_CM * c * m)
    return {"foundation": factor + dense}


def estimate_counts(n_dofs: int, n_contact_dofs: int, n_cells: int, nnz_A: int,
                    parts=condensation_parts, **kw) -> MemoryEstimate:
    """The estimate from the sizes alone, with the parts of a solver path (``parts``: one of
    :func:`condensation_parts`, :func:`delassus_parts`, :func:`fullspace_parts`; ``kw`` go to it)."""
    out = {"base": BASE_BYTES + CELL_BYTES * n_cells, "sparse": SPARSE_COPIES * 12.0 * nnz_A}
    own, nnz_L = parts(n_dofs, n_contact_dofs, nnz_A, **kw)
    out.update(own)
    return MemoryEstimate(n_dofs, n_contact_dofs, n_cells, nnz_A, nnz_L, out)


def estimate_evaluation(body, parts=condensation_parts, **kw) -> MemoryEstimate:
    """Estimated peak memory of one evaluation with a path's ``parts`` (the condensation's by
    default) for a :class:`~contactopt.mesh.body.Body` (or anything with a ``.body``, such as an
    :class:`~contactopt.fem.model.ElasticModel`): from the mesh alone, before anything is
    assembled or solved on it."""
    body = getattr(body, "body", body)
    n_free, nnz_A = _sizes(body)
    return estimate_counts(n_free, 3 * len(body.contact_nodes), len(body.reference.cells), nnz_A, parts, **kw)


def free_dofs(body) -> int:
    """Free DOFs of a body, counted from its mesh (before anything is assembled)."""
    return _sizes(getattr(body, "body", body))[0]


def _sizes(body) -> tuple:
    """(free DOFs, entries of the stiffness on them) of a body, from its mesh; counted once per
    body (the path choice, the memory check and the run log all ask)."""
    out = body.sizes
    if out is None:
        ref = body.reference
        free = np.ones(3 * ref.n_nodes, dtype=bool)
        free[np.asarray(body.fixed_dofs, dtype=np.int64)] = False
        out = (int(free.sum()), matrix_entries(ref.cells, ref.n_nodes, free.reshape(-1, 3).sum(axis=1)))
        body.sizes = out              # kept on the body itself
    return out


def keeps_cholesky(body, *, margin: float = 0.7) -> bool:
    """Whether the Delassus path may keep the Cholesky factor of A while a zone's Schur-mode
    factorization is formed beside it (both estimated, with the dense zone matrices, within
    ``margin`` × the available memory). When not, the Cholesky is released meanwhile and the next
    design factorizes anew, ordering included (:class:`contactopt.paths.delassus.DelassusPath`)."""
    return estimate_evaluation(body, delassus_parts, keep_cholesky=True).total <= margin * available_memory()


def available_memory() -> float:
    """Bytes the kernel can give without swapping (``MemAvailable`` of /proc/meminfo); inf when
    unknown (not Linux)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return float("inf")


def check_memory(body, *, margin: float = 0.9, estimate=None, counterparts=(), alternatives=None,
                 path: str | None = None) -> MemoryEstimate:
    """Refuse (:class:`InsufficientMemoryError`) a body (or model) whose evaluation would need
    more than ``margin`` × the available memory; returns the estimate otherwise (logged at INFO).
    ``estimate``: the estimate of the solver path that will run, a function of the body and of
    its elastic ``counterparts`` (:class:`CounterpartSize`, those built so far; the condensation's
    by default). ``alternatives``: {path: its estimate} of the other paths that take the model,
    whose estimates a refusal names (those that fit first); ``path``: the name of the path that
    will run, said in the log line and the refusal."""
    est = _estimate(estimate or condensation_estimate, body, counterparts)
    avail = available_memory()
    on = f" on the '{path}' path" if path else ""
    if est.total > margin * avail:
        raise InsufficientMemoryError(
            f"the mesh is too large for the memory available: one evaluation{on} needs about "
            f"{est.describe()}, and {avail / GB:.1f} GB are available (MemAvailable). "
            f"{_other_paths(body, counterparts, alternatives, margin * avail)}Use a coarser "
            f"[mesh] (the factor grows like n^{1 + FILL_EXPONENT:.2f}, the dense contact matrices like "
            f"(contact DOFs)²), free memory on this machine, or set [linear_solver] memory_check = false "
            f"to try anyway", est, avail / GB)
    log.info("memory estimate of an evaluation%s: %s; %.1f GB available", on, est.describe(), avail / GB)
    return est


def _estimate(estimate, body, counterparts) -> MemoryEstimate:
    return estimate(body, counterparts=list(counterparts)) if counterparts else estimate(body)


def _other_paths(body, counterparts, alternatives, limit: float) -> str:
    """The sentence of a refusal on the other paths that take the model: those whose estimate
    fits within ``limit`` bytes, else each one's estimate."""
    if not alternatives:
        return ""
    totals = {name: _estimate(f, body, counterparts).total for name, f in alternatives.items()}
    fit = sorted((t, name) for name, t in totals.items() if t <= limit)
    if fit:
        t, name = fit[0]
        return (f"The '{name}' path would fit (about {t / GB:.1f} GB): set [linear_solver] path = '{name}'. ")
    said = ", ".join(f"'{name}' {t / GB:.1f} GB" for name, t in totals.items())
    return f"No other path that takes this model fits either ({said}). "
