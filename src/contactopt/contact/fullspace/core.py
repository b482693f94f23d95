"""What the two backends of the full-space method share (:mod:`contactopt.contact.fullspace`):
the start of a solve, the semismooth Newton iteration :func:`newton_loop` on a
:class:`NewtonBackend`, the one result type, and the set-up of the adjoint (4.15).

Conventions: per contact node the physical order (t1, t2, ν), r = (A u − L)_c the contact force
on the body (λ = r_ν ≥ 0, τ = −r_t); the contact law and warm starts in the FCLIB order
(N, T1, T2).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..._progress import progress, progress_level
from ...errors import ContactNotConverged, ProblemDataError, SolverError
from ..cones import siconos_error
from ..newton import alart_curnier
from ..state import FROM_FCLIB, TO_FCLIB, displacement_scale
from ..zone import missed_nodes, near_nodes

log = logging.getLogger(__name__)

OPEN, STICK, SLIDE = 0, 1, 2          # node classes of a Newton system
W_DIAG_FACTOR = 2.0                   # local part of tr(W_mm)/3 ≈ W_DIAG_FACTOR / mean(A_mm)
_TIGHT_BELOW = 0.01                   # error ≤ this·√tol and node classes as in the last step:
                                      # Newton is in its fast phase, the step solves to krylov_rtol
                                      # at once (saves the last, equilibrium-only step)
_STAGNATION_STEPS = 10                # no halving of the best error over this many steps:
_RESCALE, _MAX_RESCALES = 0.25, 3     # ρ times _RESCALE, at most _MAX_RESCALES times
_FORCING_STALL = 0.5                  # an error above this times the last one: the stall forcing


@dataclass
class FullSpaceResult:
    """A state solved in full space, on either backend (built by :func:`finish`, by keyword).

    ``r`` (p, 3) per contact node in FCLIB order (N, T1, T2) = (λ, −τ), zero outside the zone;
    ``u`` the backend's vector on the free DOFs (pyamg: an array; PETSc: the owned part, a Vec,
    the next warm start); ``u_all`` (PETSc) u on all PETSc DOFs, on every rank; ``u_c`` (p, 3)
    per node (t1, t2, ν); ``classes`` the node classes (OPEN, STICK, SLIDE) of the last Newton
    system; ``history`` the Siconos error of every iterate (``[0]`` the start);
    ``krylov_iterations`` (and on pyamg ``krylov_histories`` / ``krylov_rtol``) per Newton step
    (preceded by those of the start solve when no u0 was given); ``steps`` the line-search step
    lengths; ``timings`` in seconds per phase; ``hierarchy`` (pyamg) the AMG hierarchy to pass to
    the next solve; ``reason`` why Newton stopped without converging; ``fallback`` the path of
    the fallback chain that reached the state (None: the first attempt) after
    ``fallback_iterations`` Newton steps of the attempts before it."""

    r: np.ndarray
    u: object
    u_c: np.ndarray
    classes: np.ndarray
    converged: bool
    error: float
    equilibrium: float
    newton_steps: int
    krylov_iterations: list
    history: list
    steps: list
    zone: np.ndarray
    zone_growths: int
    timings: dict
    krylov_histories: list = field(default_factory=list)
    krylov_rtol: list = field(default_factory=list)
    hierarchy: object = None
    u_all: np.ndarray | None = None
    info: dict = field(default_factory=dict)
    reason: str = ""                 # why Newton stopped, when it did not converge
    fallback: str | None = None      # the fallback that reached the state (contactopt.contact.fallback), or None
    fallback_iterations: int = 0     # the Newton steps of the attempts before it

    @property
    def lam(self) -> np.ndarray:
        return self.r[:, 0].copy()

    @property
    def tau(self) -> np.ndarray:
        """τ = −r_t per node (t1, t2)."""
        return -self.r[:, 1:]


# ----------------------------------------------------------------------------- Newton pieces
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
                eta_max, eta_factor, zone_margin, timings, t_start, shift=None, polish_below=0.0,
                stall_forcing=None) -> NewtonOutcome:
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
    previous step; the tangential law acts on U_T = u_t − shift. ``polish_below``: an iterate that
    meets ``tol`` with its error or equilibrium above this takes one Newton step more (its system
    solved to krylov_rtol), so that a state ends at round-off rather than just below ``tol`` — where
    it stops there is a matter of where the iterates fall, and two backends' states (or a
    subgradient's central differences) would then differ by the tolerance; 0: none.
    ``stall_forcing`` = (eta_factor, eta_max): the forcing for the rest of the solve from the first
    step whose error is above _FORCING_STALL times the error before it with the node classes of
    the step before, or twice in a row (None: the one forcing throughout) — a loose forcing while
    Newton converges, a tight one where an inexact step stops making progress (a Krylov solve
    whose start already meets η·‖L‖ returns no step); one step that changes the classes may well
    not halve the error, and does not count alone. A step along which the line search finds no
    decrease is then solved again, to the stall forcing, before the solve gives up."""
    p = gap.size
    history, steps, recent = [], [], []
    growths = rescales = last_rescale = 0
    classes = np.zeros(p, dtype=np.int8)
    converged, reason = False, ""
    err = eq = np.inf
    polished = False
    stalled = slow = False
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
            if polished or not polish_below or max(err, eq) <= polish_below or len(history) > max_steps:
                converged = True
                break
            polished = True         # one step more: the Newton system solved to krylov_rtol below
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
        slow_before, slow = slow, len(history) > 1 and err > _FORCING_STALL * history[-2]
        if stall_forcing is not None and not stalled and slow and (settled or slow_before):
            # no halving of the error on the classes of the step before, or twice: too inexact a step
            stalled = True
            eta_factor, eta_max = stall_forcing
            log.debug("%s: error %.3e after %.3e: the forcing (%g, %g) from here on",
                      backend.label, err, history[-2], eta_factor, eta_max)
        eta = min(eta_max, max(krylov_rtol, eta_factor * err))
        if (settled and err <= _TIGHT_BELOW * np.sqrt(tol)) or polished:
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
            timings["newton"] += time.perf_counter() - t0
            if stall_forcing is not None and not stalled:
                # a direction too inexact to descend: the same step again, to the stall forcing
                stalled = True
                eta_factor, eta_max = stall_forcing
                history.pop(), recent.pop()          # (the iterate is evaluated again)
                log.debug("%s: no decrease along an inexact step: the forcing (%g, %g) from here on",
                          backend.label, eta_factor, eta_max)
                continue
            # the step past the tolerance found no decrease: the iterate that met it stands
            converged = polished and err <= tol and eq <= tol
            reason = "" if converged else "line search found no decrease of the merit ½‖Φ‖²"
            break
        u = backend.advance(u, t, du)
        steps.append(t)
        timings["newton"] += time.perf_counter() - t0
    return NewtonOutcome(u=u, zone=zone, classes=classes, converged=converged, reason=reason, error=err,
                         equilibrium=eq, history=history, steps=steps, zone_growths=growths,
                         rho_rescales=rescales)


# ----------------------------------------------------------------------------- start and end
@dataclass(frozen=True)
class Start:
    """What every solve starts from: ``mu`` (p,) the friction coefficients, ``krylov_rtol`` the
    tightest Krylov tolerance, ``zone`` the contact zone (sorted node indices) and ``timings``
    (seconds per phase, filled by the solve)."""

    mu: np.ndarray
    krylov_rtol: float
    zone: np.ndarray
    timings: dict


def start(friction, p: int, tol: float, krylov_rtol, zone) -> Start:
    """The :class:`Start` of a solve of p contact nodes (``krylov_rtol`` None: 0.1·tol; ``zone``
    None: every contact node)."""
    mu_all = np.broadcast_to(np.asarray(friction, dtype=np.float64), (p,)).copy()
    if np.any(mu_all < 0) or not np.all(np.isfinite(mu_all)):
        raise ProblemDataError("friction coefficients must be finite and ≥ 0")
    return Start(mu=mu_all, krylov_rtol=0.1 * tol if krylov_rtol is None else krylov_rtol,
                 zone=np.arange(p) if zone is None else np.unique(np.asarray(zone, dtype=np.int64)),
                 timings=dict.fromkeys(("amg_setup", "preconditioner", "krylov", "newton", "start"), 0.0))


def rho_of(diag_c: np.ndarray, compliance, rho_scale: float) -> np.ndarray:
    """The Alart–Curnier ρ_m = rho_scale / w̃_m, w̃_m ≈ tr(W_mm)/3: a local part W_DIAG_FACTOR /
    mean(A_mm) (``diag_c`` (p, 3) the diagonal of A at the contact DOFs) and ``compliance`` (p,),
    that of the body's global deformations (a coarse level of the hierarchy), or 0."""
    return rho_scale / (W_DIAG_FACTOR / diag_c.mean(axis=1) + compliance)


def overlap_force(diag_c: np.ndarray, gap: np.ndarray) -> float | None:
    """‖A_νν min(g, 0)‖ over the contact nodes: the scale of the forces an initial overlap makes
    (a press or shrink fit without load), or None without overlap. ``diag_c`` (p, 3) is the
    diagonal of A at the contact DOFs in the order (t1, t2, ν), ``gap`` (p,) the initial gaps,
    negative where a node starts inside its counterpart. A node's own stiffness times its overlap
    bounds its contact force from above, by about the inverse of the node's share of the body's
    stiffness."""
    f = diag_c[:, 2] * np.minimum(np.asarray(gap, dtype=np.float64), 0.0)
    return float(np.linalg.norm(f)) or None


def start_forces(r0, zone: np.ndarray, p: int) -> np.ndarray:
    """The warm start's contact forces (p, 3) per node (t1, t2, ν), zero outside the zone, from
    ``r0`` in FCLIB order (N, T1, T2)."""
    rz = np.zeros((p, 3))
    rz[zone] = np.asarray(r0, dtype=np.float64).reshape(p, 3)[zone][:, FROM_FCLIB]
    return rz


def finish(backend: NewtonBackend, out: NewtonOutcome, *, u_c, tol, t_start, timings, krylov_iterations,
           raise_on_failure=True, **fields) -> FullSpaceResult:
    """The :class:`FullSpaceResult` of a Newton loop's outcome ``out`` (``u_c`` (p, 3) its
    displacement at the contact DOFs, ``fields`` the backend's own: hierarchy, u_all, info ...);
    a failure raises :class:`~contactopt.errors.ContactNotConverged` with the error history unless
    ``raise_on_failure`` is False."""
    p = out.classes.size
    rphys = backend.contact_force(out.u)
    r = np.zeros((p, 3))
    r[out.zone] = rphys[out.zone][:, TO_FCLIB]
    timings["total"] = time.perf_counter() - t_start
    info = {"reason": out.reason, "rho_rescales": out.rho_rescales, **fields.pop("info", {})}
    result = FullSpaceResult(r=r, u=out.u, u_c=u_c, classes=out.classes, converged=out.converged, error=out.error,
                             equilibrium=out.equilibrium, newton_steps=len(out.steps),
                             krylov_iterations=krylov_iterations, history=out.history, steps=out.steps,
                             zone=out.zone, zone_growths=out.zone_growths, timings=timings, info=info,
                             reason=out.reason, **fields)
    if not out.converged and raise_on_failure:
        raise ContactNotConverged(f"{backend.label} did not converge: Siconos error {out.error:.3e}, "
                                  f"equilibrium {out.equilibrium:.3e} (tol {tol:.1e}) after {len(out.steps)} "
                                  f"steps ({out.reason})", out.history)
    return result


# ----------------------------------------------------------------------------- the adjoint
def sliding_frame(u_c, lam, slide: np.ndarray, friction):
    """(t, k, c) of the adjoint (4.15) at the sliding nodes ``slide`` (class M1) of a state:
    the transpose of its Newton system at the solution, with n = −â (â = u_t/‖u_t‖), μ = F and
    K_t = C = k t tᵀ, t ⊥ â, k = Fλ/‖u_t‖; c = −Fâ the friction coupling (per node (t1, t2)).
    ``friction`` F is a scalar or (p,) per node. Without friction a node in contact is M1 even
    where u_t = 0 (both tangential components pinned, or none moving): â and C = 0 there."""
    ut = np.asarray(u_c)[slide, :2]
    F = np.broadcast_to(np.asarray(friction, dtype=np.float64), np.shape(lam))[slide]
    nut = np.linalg.norm(ut, axis=1)
    if np.any((F > 0) & (nut <= 0)):
        raise SolverError("a sliding node (M1) without slip")
    safe = np.where(nut > 0, nut, 1.0)
    ahat = np.where(nut[:, None] > 0, ut / safe[:, None], 0.0)
    tvec = np.column_stack((-ahat[:, 1], ahat[:, 0]))
    return tvec, F * np.asarray(lam)[slide] / safe, -F[:, None] * ahat


def known_adjoint_part(p: int, stick: np.ndarray, slide: np.ndarray, y_lam) -> np.ndarray:
    """The known part v0 of the adjoint's ṽ at the contact DOFs (p, 3) per node (t1, t2, ν):
    (0, 0, y*_λ) on the nodes ``stick`` (M3+), y*_λ in the normal DOF of the nodes ``slide`` (M1)."""
    v0c = np.zeros((p, 3))
    v0c[stick, 2] = y_lam[stick]
    v0c[slide, 2] = y_lam[slide]
    return v0c
