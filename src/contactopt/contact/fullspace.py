"""Full-space semismooth Newton for the discrete Coulomb problem, with AMG-preconditioned Krylov
solves: the state solver for meshes where no factorization of A(α) fits (issue #16, ≥ 900k DOFs).

Problem (paper (3.17)/(3.18), the same as the condensation path's, :mod:`contactopt.paths.condensation`).
On the free DOFs, with B selecting the contact DOFs (``contact_dofs``: per contact node m the DOFs
(t1, t2, ν) = (x1, x2, x3); the foundation x3 ≤ 0 has normal e3),

    A u = L + Bᵀ r,     r per node (t1, t2, ν) the contact force on the body,
    λ = r_ν ≥ 0,  τ = −r_t,  u_ν + g ≥ 0,  λ(u_ν + g) = 0,  ‖τ‖ ≤ Fλ,  u_t ≠ 0 ⇒ τ = Fλ u_t/‖u_t‖.

Nothing is condensed: the unknown is u on all free DOFs, and r is *defined* by the equilibrium of
the contact rows, r := B(A u − L); the other rows must satisfy (A u − L)_j = 0. The contact law is
written in the FCLIB convention of :mod:`contactopt.contact.newton` (normal first): per node
R = (r_ν, r_t1, r_t2) = (λ, −τ) and U = (u_ν + g, u_t1, u_t2), friction law R_T = −μ R_N U_T/‖U_T‖;
the Alart–Curnier function (:func:`contactopt.contact.newton.alart_curnier`)

    x_N = R_N − ρ U_N,  x_T = R_T − ρ U_T,  Φ_N = R_N − max(0, x_N),  Φ_T = R_T − P_{D(μ max(0, x_N))}(x_T)

vanishes exactly at the solutions. Nodes outside the contact zone (default: none — in full space a
node without contact costs nothing, its rows are natural boundary rows) carry r = 0.

Newton step. On each smooth piece of Φ, the Newton equation Φ + Φ'·(Δu) = 0 is *linear in the new
iterate* u⁺ (the piece's data ρ, n, c frozen at the current iterate), per node class:

* open (x_N ≤ 0): R⁺ = 0 — the node's rows are plain equilibrium rows (natural boundary);
* stick (x_N > 0, ‖x_T‖ ≤ μ x_N): U⁺ = 0, i.e. u⁺_c = (0, 0, −g): three Dirichlet DOFs;
* slide (x_N > 0, ‖x_T‖ > μ x_N), in the frame (n, t) of the tangent plane with n = x_T/‖x_T‖,
  t ⊥ n, c = μ x_N/‖x_T‖ < 1: u⁺_ν = −g (Dirichlet), R⁺_n = μ R⁺_N (the friction force of the
  normal reaction, along n) and (1 − c) R⁺_t + c ρ U⁺_t = 0, a Robin condition
  R⁺_t = −k U⁺_t with k = cρ/(1 − c) ≥ 0 (at the solution k = Fλ/‖u_t‖, the C of the adjoint).

With D the Dirichlet DOFs (three per sticking node, the normal one per sliding node) and I the
others, substituting R⁺ = B(A u⁺ − L) into the rows I gives one linear system for u⁺_I,

    G u⁺ = L − μ N L  on I,   u⁺_D prescribed,   G = A + K_t − μ N A,

where K_t adds k t tᵀ on the tangential DOFs of a sliding node and N copies the normal row of a
sliding node, times n, into its tangential rows. G is non-symmetric (the friction coupling μ N A)
and sparse (A plus a few rows): it is applied as A x + K_t x (K_t: 2×2 blocks at the sliding
nodes) with a correction of the sliding tangential rows. Each step is solved by right-
preconditioned restarted GMRES (flexible: it keeps the preconditioned directions), warm-started at
the current iterate, to a relative residual η_k (inexact Newton: 0.1·error while the error is
large, ``krylov_rtol`` once it is below 0.01·√tol and the node classes have settled),
preconditioned by a V-cycle of H = A + K_t restricted to I:

* the smoothed-aggregation hierarchy (pyamg, rigid-body modes as near-null space) of an A(α_ref)
  — of this design, or of an earlier one: :class:`ContactHierarchy`, reused over Newton steps and
  nearby designs, never rebuilt inside a solve;
* the fine level smooths H itself by Gauss–Seidel on the rows I only (x_D = 0 kept);
* the coarse operators are the Galerkin products (Π P)ᵀ H (Π P) of the prolongation with the D
  rows removed (Π), obtained from the stored ones of A(α_ref) by sparse updates supported near D
  and the sliding nodes (the fine matrix differs from A(α_ref) only there, up to the design
  change), so no full triple product is redone per step (docs/large_meshes.md: as few
  iterations as a fresh hierarchy of the constrained matrix).

Globalization: Armijo backtracking on the merit ½‖Φ‖² along u + t(u⁺ − u) (non-monotone over the
last four values, as in :mod:`contactopt.contact.newton`); r is affine in u, so a trial step costs
one product with the contact rows of A. ρ per node is ``rho_scale`` / w̃_m with w̃_m ≈ 2/mean(A_mm)
an estimate of the Delassus diagonal tr(W_mm)/3 (docs/large_meshes.md).

Convergence: the Siconos error ‖R − P_K(R − Ũ)‖ / max(‖R‖, ‖U‖) on the zone ≤ ``tol`` and the
equilibrium of the other rows ‖(A u − L)_other‖ / ‖L‖ ≤ ``tol``. A Newton or Krylov failure raises
:class:`contactopt.errors.ContactNotConverged` / :class:`contactopt.fem.krylov.KrylovNotConverged`
(both SolverErrors) with their histories, never an inaccurate state. With a zone smaller than all
contact nodes, a converged state whose outside nodes close their gap grows the zone (as
:mod:`contactopt.contact.zone` does) and Newton continues from the current iterate.

The iteration itself (stopping test, zone growth, ρ rescaling, forcing term, line search) is
:func:`newton_loop`, shared with the PETSc path (:mod:`contactopt.contact.fullspace_petsc`):
each path gives it a backend (:class:`NewtonBackend`) for the residual, the Newton system and
the update, here :class:`_PyamgBackend` on NumPy/SciPy arrays.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import scipy.sparse as sp

from .._progress import progress, progress_level
from .._threads import sequential_openblas
from ..errors import ContactNotConverged, ProblemDataError, SolverError
from ..fem.amg import ContactHierarchy, block_positions, rigid_body_modes
from ..fem.krylov import KrylovNotConverged, gmres
from .cones import siconos_error
from .newton import alart_curnier
from .state import FROM_FCLIB, TO_FCLIB, displacement_scale
from .zone import missed_nodes, near_nodes

__all__ = ["solve_fullspace", "FullSpaceResult", "NewtonSystem", "newton_loop", "NewtonBackend",
           "NewtonOutcome", "OPEN", "STICK", "SLIDE"]

log = logging.getLogger(__name__)

OPEN, STICK, SLIDE = 0, 1, 2          # node classes of a Newton system
W_DIAG_FACTOR = 2.0                   # local part of tr(W_mm)/3 ≈ W_DIAG_FACTOR / mean(A_mm)
_TIGHT_BELOW = 0.01                   # error ≤ this·√tol and node classes as in the last step:
                                      # Newton is in its fast phase, the step solves to krylov_rtol
                                      # at once (saves the last, equilibrium-only step)
_STAGNATION_STEPS = 10                # no halving of the best error over this many steps:
_RESCALE, _MAX_RESCALES = 0.25, 3     # ρ times _RESCALE, at most _MAX_RESCALES times
# ----------------------------------------------------------------------------- Newton system
class NewtonSystem:
    """The linear system of one smooth piece of the full-space Newton method (module docstring),
    per contact node (t1, t2, ν) DOFs ``cd``: Dirichlet DOFs D (all three of a sticking node, the
    normal one of a sliding node), the Robin blocks K_t = k t tᵀ on the sliding nodes' tangential
    DOFs, and the friction coupling c = μ n of a sliding node's normal row into its tangential
    rows, so that on the rows I outside D

        G = (I − C_N)(A + K_t),   (C_N y)_t = c y_ν.

    :meth:`apply` is G (the state's Newton step), :meth:`apply_transpose` its transpose on I (the
    adjoint (4.15), :mod:`contactopt.sensitivity.adjoint_fullspace`): the tangential unknowns
    enter the normal DOF through −c."""

    def __init__(self, A, cd, stick, slide, tvec, k, coupling):
        n = A.shape[0]
        self.A = A
        self.dirichlet = np.zeros(n, dtype=bool)
        self.dirichlet[cd[stick].ravel()] = True
        self.dirichlet[cd[slide, 2]] = True
        self.D = np.flatnonzero(self.dirichlet)
        self.rows = np.repeat(cd[slide, :2], 2, axis=1).ravel()        # (t1,t1),(t1,t2),(t2,t1),(t2,t2)
        self.cols = np.tile(cd[slide, :2], (1, 2)).ravel()
        self.blk = (k[:, None, None] * tvec[:, :, None] * tvec[:, None, :]).reshape(-1)
        self.kt = sp.csr_matrix((self.blk, (self.rows, self.cols)), shape=(n, n))
        self.T1, self.T2, self.Nsl = cd[slide, 0], cd[slide, 1], cd[slide, 2]
        self.c1, self.c2 = coupling[:, 0], coupling[:, 1]

    def stiffness(self, x):
        """(A + K_t) x."""
        y = self.A @ x
        if self.kt.nnz:
            y += self.kt @ x
        return y

    def couple(self, y):
        """(I − C_N) y in place: a sliding node's normal row, times c, out of its tangential rows."""
        y[self.T1] -= self.c1 * y[self.Nsl]
        y[self.T2] -= self.c2 * y[self.Nsl]
        return y

    def apply(self, x):
        """G x on the rows I (zero on D)."""
        y = self.couple(self.stiffness(x))
        y[self.D] = 0.0
        return y

    def lift(self, x):
        """x with the normal DOF of every sliding node set from its tangential ones, −cᵀx_t."""
        w = x.copy()
        w[self.Nsl] = -(self.c1 * x[self.T1] + self.c2 * x[self.T2])
        return w

    def apply_transpose(self, x):
        """Gᵀ x on the rows I, for x zero on D."""
        y = self.stiffness(self.lift(x))
        y[self.D] = 0.0
        return y

    def fine_matrix(self, hierarchy):
        """A + K_t for the V-cycle's smoother (a fresh copy)."""
        H = hierarchy.fine_matrix(self.A)
        H.data[block_positions(self.A, self.rows, self.cols)] += self.blk
        return H


@dataclass
class FullSpaceResult:
    """A state solved in full space.

    ``r`` (p, 3) per contact node in FCLIB order (N, T1, T2) = (λ, −τ), zero outside the zone;
    ``u`` on the free DOFs; ``u_c`` (p, 3) per node (t1, t2, ν); ``classes`` the node classes
    (OPEN, STICK, SLIDE) of the last Newton system; ``history`` the Siconos error of every
    iterate (``[0]`` the start); ``krylov_iterations`` / ``krylov_histories`` / ``krylov_rtol``
    per Newton step (preceded by those of the start solve when no u0 was given); ``steps`` the
    line-search step lengths; ``timings`` in seconds per phase; ``hierarchy`` the AMG hierarchy
    to pass to the next solve."""

    r: np.ndarray
    u: np.ndarray
    u_c: np.ndarray
    classes: np.ndarray
    converged: bool
    error: float
    equilibrium: float
    newton_steps: int
    krylov_iterations: list
    krylov_histories: list
    krylov_rtol: list
    history: list
    steps: list
    zone: np.ndarray
    zone_growths: int
    timings: dict
    hierarchy: ContactHierarchy
    info: dict = field(default_factory=dict)

    @property
    def lam(self) -> np.ndarray:
        return self.r[:, 0].copy()

    @property
    def tau(self) -> np.ndarray:
        """τ = −r_t per node (t1, t2)."""
        return -self.r[:, 1:]


# ----------------------------------------------------------------------------- solver
def piece_classes(piece, z, classes, rho, mu, steps: int):
    """The node classes of the current piece of the Alart–Curnier map on the zone ``z``, written
    into ``classes`` (all contact nodes; OPEN off the piece's active set), and what the Newton
    system of that piece needs: (settled — the zone's classes as at the last step, from the second
    step on —, stick nodes, slide nodes, tangential directions t ⊥ n (per slide node, (t1, t2)
    order), k = cρ/(1 − c), the friction coupling μn (per slide node))."""
    cls = np.where(piece.active, np.where(piece.slip, SLIDE, STICK), OPEN).astype(np.int8)
    settled = bool(np.array_equal(classes[z], cls)) and steps > 1
    classes[:] = OPEN
    classes[z] = cls
    lsl = np.flatnonzero(cls == SLIDE)
    nvec = piece.nvec[lsl]
    c = piece.c[lsl]
    return (settled, z[cls == STICK], z[cls == SLIDE], np.column_stack((-nvec[:, 1], nvec[:, 0])),
            c * rho[lsl] / (1.0 - c), mu[lsl, None] * nvec)


# ----------------------------------------------------------------------------- the Newton loop
class NewtonBackend(Protocol):
    """What :func:`newton_loop` asks of a linear-algebra backend (the pyamg path's arrays, the
    PETSc path's distributed Vecs). ``u`` and the directions are the backend's own vectors on the
    free DOFs; everything per contact node is a (p, 3) array (on every rank) in the physical
    order (t1, t2, ν), r = (A u − L)_c the contact force on the body (λ = r_ν ≥ 0, τ = −r_t); the
    loop forms the FCLIB-order R, U from them. The rows "other" are those outside the contact
    DOFs of the zone of the last :meth:`residual`."""

    label: str          # the start of the progress lines: "full-space Newton", "... (PETSc)"
    n: int              # unknowns (the progress level)

    def residual(self, u, z):
        """(r(u) (p, 3), u_c (p, 3), e_other = (A u − L)_other, ½‖e_other‖², ‖e_other‖ / ‖L‖),
        the rows "other" now those outside the contact DOFs of the nodes ``z``."""

    def newton_step(self, u, uc, stick, slide, tvec, k, coupling, eta, step):
        """(du = u⁺ − u, seconds per ``timings`` key) of the Newton system of the current piece
        (:func:`piece_classes`): u⁺_c = (0, 0, −g) at the nodes ``stick``, u⁺_ν = −g at the nodes
        ``slide`` with per sliding node the direction t (t1, t2) ⊥ n, the Robin k and the coupling
        μn; solved to a residual ≤ eta·‖L‖ from ``u`` and ``uc`` = u_c (p, 3), ``step`` naming the
        Newton step in a Krylov failure. Records its Krylov iterations."""

    def line(self, du, e_other):
        """((A du)_c (p, 3), du_c (p, 3), t ↦ ½‖e_other + t·de_other‖² with de_other = (A du)_other)
        for the line search along u + t du (r is affine in u: r(u + t du) = r(u) + t (A du)_c)."""

    def advance(self, u, t, du):
        """The next iterate u + t du (the pyamg backend: a new array; PETSc: u updated in place)."""

    def max_abs(self, u) -> float:
        """max |u| over all free DOFs (on every rank)."""


@dataclass
class NewtonOutcome:
    """How :func:`newton_loop` ended: the last iterate ``u`` (the backend's vector), the contact
    ``zone`` (grown or as given), the ``classes`` (OPEN, STICK, SLIDE per contact node) of the last
    Newton system, ``converged`` or the failure ``reason``, the Siconos ``error`` and relative
    ``equilibrium`` of the last iterate, ``history`` (the Siconos error of every iterate, ``[0]``
    the start), the line-search ``steps``, ``zone_growths`` and ``rho_rescales``."""

    u: object
    zone: np.ndarray
    classes: np.ndarray
    converged: bool
    reason: str
    error: float
    equilibrium: float
    history: list
    steps: list
    zone_growths: int
    rho_rescales: int


def newton_loop(backend: NewtonBackend, u, zone, *, gap, mu_all, rho_all, tol, max_steps, krylov_rtol,
                eta_max, eta_factor, zone_margin, timings, t_start, shift=None) -> NewtonOutcome:
    """The full-space semismooth Newton iteration from ``u`` on the contact ``zone`` (node
    indices), the same for the pyamg and the PETSc path: only the linear algebra is the
    ``backend``'s (:class:`NewtonBackend`). Per contact node ``gap`` (p,) the initial gap,
    ``mu_all`` (p,) the friction coefficient, ``rho_all`` (p,) the Alart–Curnier ρ (scaled in
    place on stagnation); the contact law in the FCLIB order (normal, t1, t2) on the zone:
    R = (λ, −τ), U = (u_ν + g, u_t1, u_t2).

    Per iterate: the Siconos error and equilibrium ‖(A u − L)_other‖ / ‖L‖ against ``tol`` (a
    converged state whose outside nodes close their gap grows the zone and goes on); ρ times
    _RESCALE when the error has not halved over _STAGNATION_STEPS steps (at most _MAX_RESCALES
    times); the Newton system of the current piece solved to η = clip(eta_factor · error,
    krylov_rtol, eta_max), krylov_rtol once the classes have settled below _TIGHT_BELOW·√tol;
    the nonmonotone Armijo search on ½‖Φ‖² + ½‖e_other‖² (reference the largest of the last four
    merits, 30 halvings). Adds its seconds to ``timings`` ("newton" and the backend's phases) and
    logs progress against ``t_start``. ``shift`` (p, 2): in a load step, u_t at the end of the
    previous step; the tangential law acts on U_T = u_t − shift."""
    p = gap.size
    history, steps, recent = [], [], []
    growths = rescales = last_rescale = 0
    classes = np.zeros(p, dtype=np.int8)
    converged, reason = False, ""
    err = eq = np.inf
    while True:
        t0 = time.perf_counter()
        z = zone
        mu, rho = mu_all[z], rho_all[z]
        rphys, uc, e_other, theta_other, eq = backend.residual(u, z)
        R = rphys[z][:, TO_FCLIB]
        U = uc[z][:, TO_FCLIB]
        U[:, 0] += gap[z]
        if shift is not None:
            U[:, 1:] -= shift[z]
        Phi, piece = alart_curnier(R.ravel(), U.ravel(), mu, rho)
        theta_phi = 0.5 * float(Phi @ Phi)
        err = siconos_error(R.ravel(), U.ravel(), U.ravel(), mu)
        # merit ½‖Φ‖² + ½‖(A u − L)_other‖² (both in force units): the equilibrium of the rows
        # outside the contact zone is part of the nonsmooth system, and a start that is not
        # in equilibrium (u0 of another design, or forces outside the zone) must not be hidden
        theta = theta_phi + theta_other
        history.append(err)
        recent.append(theta)
        timings["newton"] += time.perf_counter() - t0
        progress.log(progress_level(backend.n, t_start), backend.label + " %d: error %.3e, equilibrium %.3e, "
                     "zone %d, %.1f s", len(history) - 1, err, eq, z.size, time.perf_counter() - t_start)
        if err <= tol and eq <= tol:
            # nodes outside the zone must end with an open gap
            if z.size < p:
                clearance = uc[:, 2] + gap
                # against the whole displacement's scale, as the node classes count a gap closed
                u_scale = displacement_scale(uc, gap, backend.max_abs(u))
                missed = missed_nodes(z, clearance, u_scale)     # the zone rule of the zone paths
                if missed.size:
                    lam_all = np.zeros(p)
                    lam_all[z] = R[:, 0]
                    near = near_nodes(lam_all, clearance, u_scale, zone_margin, min_nodes=0)
                    zone = np.union1d(np.union1d(z, missed), near)
                    growths += 1
                    log.debug("%s: %d node(s) outside the zone close their gap; zone %d -> %d nodes",
                              backend.label, missed.size, z.size, zone.size)
                    continue
            converged = True
            break
        if len(history) > max_steps:
            reason = f"{max_steps} Newton steps used"
            break
        if (len(history) - last_rescale > _STAGNATION_STEPS and rescales < _MAX_RESCALES
                and min(history[-_STAGNATION_STEPS:]) > 0.5 * min(history[:-_STAGNATION_STEPS])):
            # no progress: ρ too large for this body (the active-set decisions follow u rather
            # than r and cycle); a smaller ρ, the merit of the new Φ from here on
            rho_all *= _RESCALE
            rescales += 1
            last_rescale = len(history)
            recent = []
            history.pop()                   # the iterate is evaluated again with the new ρ
            log.debug("%s: no progress over %d steps, ρ scaled by %g", backend.label, _STAGNATION_STEPS, _RESCALE)
            continue
        # -- the Newton system of the current piece
        t0 = time.perf_counter()
        settled, st, sl, tvec, k, coupling = piece_classes(piece, z, classes, rho, mu, len(history))
        eta = min(eta_max, max(krylov_rtol, eta_factor * err))
        if settled and err <= _TIGHT_BELOW * np.sqrt(tol):
            eta = krylov_rtol
        timings["newton"] += time.perf_counter() - t0
        du, spent = backend.newton_step(u, uc, st, sl, tvec, k, coupling, eta, len(history))
        for key, seconds in spent.items():
            timings[key] += seconds
        # -- line search on the merit (r is affine in u)
        t0 = time.perf_counter()
        dr, duc, theta_other_at = backend.line(du, e_other)
        dR, dU = dr[z][:, TO_FCLIB].ravel(), duc[z][:, TO_FCLIB].ravel()
        R0, U0 = R.ravel(), U.ravel()
        ref = max(recent[-4:])
        t = 1.0
        for _ in range(30):
            Phi_t, _ = alart_curnier(R0 + t * dR, U0 + t * dU, mu, rho)
            if 0.5 * float(Phi_t @ Phi_t) + theta_other_at(t) <= ref - 2e-4 * t * theta:
                break
            t *= 0.5
        else:
            reason = "line search found no decrease of the merit ½‖Φ‖²"
            timings["newton"] += time.perf_counter() - t0
            break
        u = backend.advance(u, t, du)
        steps.append(t)
        timings["newton"] += time.perf_counter() - t0
    return NewtonOutcome(u=u, zone=zone, classes=classes, converged=converged, reason=reason, error=err,
                         equilibrium=eq, history=history, steps=steps, zone_growths=growths,
                         rho_rescales=rescales)


class _PyamgBackend:
    """:class:`NewtonBackend` on NumPy/SciPy arrays: the Newton systems as :class:`NewtonSystem`,
    solved by GMRES preconditioned by a V-cycle of the hierarchy's H = A + K_t (module
    docstring). Per contact node ``cd`` the free DOFs (t1, t2, ν); r = (A u − L)_c is the
    contact force on the body. Appends each step's Krylov iterations, residual history and
    tolerance to the lists given (those of the start solve before them)."""

    label = "full-space Newton"

    def __init__(self, A, L, cd, gap, hierarchy, H, Lnorm, restart, max_krylov, krylov_its, krylov_hist,
                 krylov_eta, shift=None):
        self.A, self.L, self.cd, self.gap, self.hierarchy, self.H = A, L, cd, gap, hierarchy, H
        self.shift = shift        # (p, 2) a load step's reference u_t: sticking u_t = shift, Robin on u_t − shift
        self.n, p = A.shape[0], cd.shape[0]
        self.Lnorm, self.restart, self.max_krylov = Lnorm, restart, max_krylov
        self.krylov_its, self.krylov_hist, self.krylov_eta = krylov_its, krylov_hist, krylov_eta
        # positions of the tangential 2×2 blocks of every contact node in A.data (Robin blocks)
        tt_rows = np.repeat(cd[:, :2], 2, axis=1).ravel()      # (t1,t1),(t1,t2),(t2,t1),(t2,t2)
        tt_cols = np.tile(cd[:, :2], (1, 2)).ravel()
        self.tt_pos = block_positions(A, tt_rows, tt_cols).reshape(p, 4)
        self.other = np.ones(self.n, dtype=bool)    # rows that must be in plain equilibrium
        self.touched = np.zeros(0, dtype=np.int64)  # entries of H holding the last Robin blocks

    def contact_force(self, u, Au_L=None):
        """r(u) = (A u − L)_c per node (t1, t2, ν), from ``Au_L`` = A u − L where given."""
        if Au_L is None:
            Au_L = self.A @ u - self.L
        return Au_L[self.cd.ravel()].reshape(-1, 3)

    def residual(self, u, z):
        other = self.other
        other[:] = True
        other[self.cd[z].ravel()] = False
        Au_L = self.A @ u - self.L
        rphys = self.contact_force(u, Au_L)
        e_other = Au_L[other]
        return rphys, u[self.cd], e_other, 0.5 * float(e_other @ e_other), float(np.linalg.norm(e_other)) / self.Lnorm

    def max_abs(self, u) -> float:
        return float(np.abs(u).max(initial=0.0))

    def newton_step(self, u, uc, stick, slide, tvec, k, coupling, eta, step):
        A, L, cd, gap, H = self.A, self.L, self.cd, self.gap, self.H
        t0 = time.perf_counter()
        system = NewtonSystem(A, cd, stick, slide, tvec, k, coupling)
        dirichlet, kt, D, Nsl = system.dirichlet, system.kt, system.D, system.Nsl
        # H = A + K_t: restore the blocks of the last step, add the new ones
        if self.touched.size:
            H.data[self.touched] = A.data[self.touched]
        pos = self.tt_pos[slide].ravel()
        H.data[pos] += system.blk
        self.touched = pos
        if self.shift is None:
            b = system.couple(L.copy())
        else:                     # the Robin rows of sliding nodes: K_t (u − shift)
            s_full = np.zeros(A.shape[0])
            s_full[cd[:, :2].ravel()] = self.shift.ravel()
            b = system.couple(L + system.kt @ s_full)
        b[D] = 0.0
        x0 = u.copy()
        x0[cd[stick, 0]] = 0.0 if self.shift is None else self.shift[stick, 0]
        x0[cd[stick, 1]] = 0.0 if self.shift is None else self.shift[stick, 1]
        x0[cd[stick, 2]] = -gap[stick]
        x0[Nsl] = -gap[slide]
        y0 = system.couple(A @ x0 + kt @ x0)    # b − G x0 on the rows I
        rhs = b - y0
        rhs[D] = 0.0
        t1 = time.perf_counter()
        Mv = self.hierarchy.preconditioner(H, dirichlet, kt)
        t2 = time.perf_counter()
        try:
            kres = gmres(system.apply, rhs, Mv, atol=eta * self.Lnorm, restart=self.restart,
                         max_iter=self.max_krylov, scale=self.Lnorm)
        except KrylovNotConverged as exc:
            exc.args = (f"full-space Newton step {step}: {exc.args[0]}",)
            raise
        t3 = time.perf_counter()
        self.krylov_its.append(kres.iterations), self.krylov_hist.append(kres.history), self.krylov_eta.append(eta)
        if self.hierarchy.reference_iterations is None:
            self.hierarchy.reference_iterations = kres.iterations
        return x0 + kres.x - u, {"newton": t1 - t0, "preconditioner": t2 - t1, "krylov": t3 - t2}

    def line(self, du, e_other):
        Adu = self.A @ du                           # r is affine in u: its contact rows give dr
        dr = Adu[self.cd.ravel()].reshape(-1, 3)
        de_other = Adu[self.other]

        def theta_other(t):
            e_t = e_other + t * de_other
            return 0.5 * float(e_t @ e_t)
        return dr, du[self.cd], theta_other

    def advance(self, u, t, du):
        return u + t * du


def solve_fullspace(A, L, contact_dofs, gap, friction, *, coords, free, r0=None, u0=None,
                    tol: float = 1e-10, hierarchy: ContactHierarchy | None = None, zone=None,
                    rho_scale: float = 0.5, max_steps: int = 50, krylov_rtol: float | None = None,
                    eta_max: float = 1e-2, eta_factor: float = 0.1, restart: int = 60,
                    max_krylov: int = 400, zone_margin: float = 0.1, amg: dict | None = None,
                    raise_on_failure: bool = True, slip_ref=None) -> FullSpaceResult:
    """Solve the discrete Coulomb problem A u = L + Bᵀ r with the contact law on the contact nodes
    (module docstring) by a full-space semismooth Newton method with AMG-preconditioned GMRES.

    Parameters
    ----------
    A, L : stiffness (sparse SPD) and load on the free DOFs, as ``ElasticModel.assemble`` gives.
    contact_dofs : (3p,) free-DOF indices, per contact node (t1, t2, ν).
    gap : (p,) initial gaps g; friction : F (scalar or per node).
    coords, free : node coordinates (N, 3) and the free DOFs' full indices (rigid-body modes).
    r0 : (p, 3) warm start, FCLIB order (N, T1, T2) (e.g. the forces of the previous design).
    u0 : warm start of u (free DOFs); without it u0 solves A u0 = L + Bᵀ r0 (one Krylov solve).
    tol : Siconos error and relative equilibrium residual to reach.
    hierarchy : a :class:`ContactHierarchy` of an earlier A (reused); built from A if None.
    zone : node indices of the contact zone (default: all contact nodes).
    rho_scale : Alart–Curnier ρ_m = rho_scale / w̃_m, w̃_m = W_DIAG_FACTOR / mean(A_mm) + the
        coarse compliance of node m (:meth:`ContactHierarchy.coarse_compliance`), an estimate
        of tr(W_mm)/3 within 0.5–1.7 × on Example 1 and the bracket.
    max_steps : Newton steps.  krylov_rtol : the tightest Krylov tolerance (default 0.1·tol);
    the step k uses η_k = clip(eta_factor · error_k, krylov_rtol, eta_max) relative to ‖L‖, and
    krylov_rtol once error_k ≤ 0.01·√tol with the node classes of the step before.
    restart, max_krylov : GMRES restart length and iteration limit per Newton step.
    amg : keyword arguments of pyamg's smoothed_aggregation_solver when a hierarchy is built.
    raise_on_failure : raise ContactNotConverged on a Newton failure (else return converged=False).
    slip_ref : (p, 2) in a load step, u_t at the end of the previous step (the tangential law on
        u_t − slip_ref, :mod:`contactopt.sensitivity.steps`); None: the static problem.

    OpenBLAS runs sequentially inside (:func:`contactopt._threads.sequential_openblas`): the dense
    work here is the GMRES basis products, memory-bound, and its threads competed with the sparse
    kernels (3–4× slower on the shared 2-core machine).
    """
    with sequential_openblas():
        return _solve_fullspace(A, L, contact_dofs, gap, friction, coords, free, r0, u0, tol, hierarchy,
                                zone, rho_scale, max_steps, krylov_rtol, eta_max, eta_factor, restart,
                                max_krylov, zone_margin, amg, raise_on_failure, slip_ref)


def _solve_fullspace(A, L, contact_dofs, gap, friction, coords, free, r0, u0, tol, hierarchy, zone,
                     rho_scale, max_steps, krylov_rtol, eta_max, eta_factor, restart, max_krylov,
                     zone_margin, amg, raise_on_failure, slip_ref=None):
    t_start = time.perf_counter()
    timings = dict.fromkeys(("amg_setup", "preconditioner", "krylov", "newton", "start"), 0.0)
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.copy()
        A.sort_indices()
    n = A.shape[0]
    L = np.asarray(L, dtype=np.float64)
    cd = np.asarray(contact_dofs, dtype=np.int64).reshape(-1, 3)
    p = cd.shape[0]
    gap = np.asarray(gap, dtype=np.float64)
    if L.shape != (n,) or gap.shape != (p,):
        raise ProblemDataError(f"L of shape {L.shape} / gap of shape {gap.shape} do not match A ({n}) "
                               f"and {p} contact nodes")
    mu_all = np.broadcast_to(np.asarray(friction, dtype=np.float64), (p,)).copy()
    if np.any(mu_all < 0) or not np.all(np.isfinite(mu_all)):
        raise ProblemDataError("friction coefficients must be finite and ≥ 0")
    krylov_rtol = 0.1 * tol if krylov_rtol is None else krylov_rtol
    zone = np.arange(p) if zone is None else np.unique(np.asarray(zone, dtype=np.int64))
    Lnorm = float(np.linalg.norm(L)) or 1.0

    # -- the hierarchy (reused when given)
    if hierarchy is None:
        t0 = time.perf_counter()
        hierarchy = ContactHierarchy(A, rigid_body_modes(coords, free), contact_dofs=cd.ravel(),
                                     **(amg or {}))
        timings["amg_setup"] = time.perf_counter() - t0
    elif hierarchy.n != n:
        raise SolverError(f"the AMG hierarchy is of a matrix with {hierarchy.n} rows, A has {n}")

    diagA = A.diagonal()
    # ρ_m = rho_scale / w̃_m, w̃_m ≈ tr(W_mm)/3: a local part W_DIAG_FACTOR / mean(A_mm) and the
    # compliance of the body's global deformations from a coarse level of the hierarchy
    w_est = W_DIAG_FACTOR / diagA[cd].mean(axis=1) + hierarchy.coarse_compliance(cd.ravel())
    rho_all = rho_scale / w_est
    H = hierarchy.fine_matrix(A)                # A + K_t for the smoother, changed in place per step

    # -- the start
    t0 = time.perf_counter()
    krylov_its, krylov_hist, krylov_eta = [], [], []
    if u0 is None:
        f = L.copy()
        if r0 is not None:
            r0 = np.asarray(r0, dtype=np.float64).reshape(p, 3)
            rz = np.zeros((p, 3))
            rz[zone] = r0[zone][:, FROM_FCLIB]          # r = 0 outside the zone
            f[cd.ravel()] += rz.ravel()
        M0 = hierarchy.preconditioner(H, np.zeros(n, dtype=bool))
        eta0 = max(krylov_rtol, 1e-6)
        res = gmres(A.dot, f, M0, atol=eta0 * np.linalg.norm(f), restart=restart, max_iter=max_krylov,
                    scale=np.linalg.norm(f))
        u = res.x
        krylov_its.append(res.iterations), krylov_hist.append(res.history), krylov_eta.append(eta0)
        if hierarchy.reference_iterations is None:
            hierarchy.reference_iterations = res.iterations
    else:
        u = np.array(u0, dtype=np.float64)
        if u.shape != (n,):
            raise ProblemDataError(f"u0 of shape {u.shape}, expected ({n},)")
    timings["start"] = time.perf_counter() - t0

    shift = None if slip_ref is None else np.asarray(slip_ref, dtype=np.float64).reshape(p, 2)
    backend = _PyamgBackend(A, L, cd, gap, hierarchy, H, Lnorm, restart, max_krylov, krylov_its, krylov_hist,
                            krylov_eta, shift)
    out = newton_loop(backend, u, zone, gap=gap, mu_all=mu_all, rho_all=rho_all, tol=tol, max_steps=max_steps,
                      krylov_rtol=krylov_rtol, eta_max=eta_max, eta_factor=eta_factor, zone_margin=zone_margin,
                      timings=timings, t_start=t_start, shift=shift)
    u, zone, classes, converged, err, eq = out.u, out.zone, out.classes, out.converged, out.error, out.equilibrium

    rphys = backend.contact_force(u)
    r = np.zeros((p, 3))
    r[zone] = rphys[zone][:, TO_FCLIB]
    timings["total"] = time.perf_counter() - t_start
    result = FullSpaceResult(
        r=r, u=u, u_c=u[cd].copy(), classes=classes, converged=converged, error=err, equilibrium=eq,
        newton_steps=len(out.steps), krylov_iterations=krylov_its, krylov_histories=krylov_hist,
        krylov_rtol=krylov_eta, history=out.history, steps=out.steps, zone=zone, zone_growths=out.zone_growths,
        timings=timings, hierarchy=hierarchy,
        info={"levels": hierarchy.sizes(), "operator_complexity": hierarchy.operator_complexity,
              "class_counts": {"open": int(np.sum(classes == OPEN)), "stick": int(np.sum(classes == STICK)),
                               "slide": int(np.sum(classes == SLIDE))},
              "start_solve": u0 is None, "reason": out.reason, "rho_rescales": out.rho_rescales})
    if not converged and raise_on_failure:
        raise ContactNotConverged(f"full-space Newton did not converge: Siconos error {err:.3e}, "
                                  f"equilibrium {eq:.3e} (tol {tol:.1e}) after {len(out.steps)} steps "
                                  f"({out.reason})", out.history)
    return result
