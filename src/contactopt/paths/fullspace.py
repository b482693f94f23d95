"""The full-space path: a semismooth Newton method on all free DOFs, nothing factorized.

The state is :func:`contactopt.contact.fullspace.solve_fullspace` (AMG-preconditioned GMRES on
A(α) plus the contact rows), the adjoint (4.15) is its transposed Newton system
(:func:`contactopt.sensitivity.adjoint_fullspace.solve_adjoint_fullspace`) with the same V-cycle.
For meshes no factorization fits (docs/large_meshes.md). Contact conventions as everywhere:
per node (t1, t2, ν), λ = r_ν ≥ 0 on the body, warm starts per node (N, T1, T2).

The AMG hierarchy of an earlier A(α) serves every later design and every load case; it is
rebuilt from its design at a resume (the checkpoint holds that design), with NumPy's global
generator seeded and OpenBLAS on one thread, so the same design gives the same hierarchy bit for
bit.

On a rigid obstacle other than the plane the unknowns at the contact nodes are the components in
each node's frame R_m = (t1, t2, n): the Newton method solves TᵀA T u_loc = TᵀL with T the
orthogonal change of basis (the identity but the 3 × 3 blocks R_m at the contact DOFs), so its
Dirichlet and Robin rows act in the frames unchanged; u = T u_loc, the AMG near-null space is Tᵀ
times the rigid-body modes, the adjoint is solved on TᵀA T and its extension returned as T ṽ_loc.
An obstacle's tangential translation is the slip's reference (``slip_ref``), as a load step's is;
it is a field of the system, so that a force-controlled obstacle (:mod:`.force`) moves it per trial.

With elastic counterparts (an elastic ``[foundation]``, the counterpart bodies of several pairs)
their DOFs join the Newton system by the change of unknowns of :mod:`.coupled` (the contact DOFs
then hold the law's relative displacement), nothing condensed; the system's ``couple`` holds it.
A rigid counterpart of one of several pairs adds no DOFs: its pair's contact nodes have no
partners (their rows of Π are zero), their gaps and frames are its geometry's and its prescribed
translation is in the offset q.

:class:`FullSpaceCommon` is what this path and the PETSc path (:mod:`.petsc`), the two backends of
one method, share: the options of a solve, the state of its result, and the arrays of a
checkpoint (the last displacement on the free DOFs and the design of the hierarchy, the same on
both, so that a checkpoint of either resumes on the other).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np
import scipy.sparse as sp

from .._threads import sequential_openblas
from ..contact.fullspace import solve_fullspace, solve_fullspace_with_fallbacks
from ..contact.fullspace.core import overlap_force
from ..contact.fullspace.pyamg import sorted_csr
from ..contact.state import FoundationState, RigidAnchor
from ..errors import CheckpointError, ConfigError, SolverError
from ..fem import memory
from ..fem.amg import ContactHierarchy, rigid_body_modes
from ..fem.model import Assembled
from ..sensitivity.adjoint_fullspace import solve_adjoint_fullspace
from .base import Adjoint, Capabilities, Context, SolverPath, SystemParts, check_design, counterpart_sizes
from .coupled import FullSpaceCouple, with_contact_blocks
from .coupled import force_terms as coupled_force_terms
from .floating import first_anchored_solve, floating_anchor, iterate_anchor
from .force import normal_stiffness
from .transforms import frame_rotation

log = logging.getLogger(__name__)

FULLSPACE_TOL = 1e-10     # the Newton's Siconos error and equilibrium residual (at least): its
                          # GMRES then runs to 1e-11, near the AMG V-cycle's floor
HIERARCHY_SEED = 20090101  # NumPy's global generator while pyamg builds a hierarchy
# the unanchored Newton steps from the anchored state of counterparts held only by their contacts
# (.floating) before the anchor's iteration takes over: a chain of three bodies held in x1 by friction
# alone (tests/test_petsc_chains.py) needs 13 on the PETSc backend after a stiffer anchor, whose
# iteration then stalls at 3.5e-3 of the load unbalanced after 200 steps (with 10 it came to that)
FREE_NEWTON_STEPS = 30
# the Newton steps of the first anchored solve (a soft anchor, .floating) before a stiffer anchor takes
# over: those that converge on the examples take 7 to 16
SOFT_ANCHOR_STEPS = 25
# the inexact Newton's forcing term with elastic counterparts: the one body's η_k = clip(0.1·error_k, 1e-13,
# 1e-2) while the error falls below half the one before, clip(1e-3·error_k, 1e-13, 1e-4) from the first step
# that does not (``stall_forcing``, contact.fullspace.core.newton_loop). The loose forcing alone stalls Lamé's
# shrink fit on meshes that do not match (mortar partners, hub 96 × 384): its Krylov solves start below
# η·‖L‖ and return no step, at an error of 4.4e-5; the tight one alone took 61 Krylov iterations of the
# state where the pair takes 44 (Example 1's elastic slab at 80k DOFs; docs/scaling.md)
# ... and a state that meets the tolerance above 1e-12 takes one Newton step more: the friction work's ξ
# along a load path on a slab moved 5e-9 between two hierarchies whose last iterates fell at 7e-11 and
# 6e-14 (the PETSc and pyamg backends must agree to 1e-9)
COUPLED_FORCING = MappingProxyType({"eta_factor": 0.1, "eta_max": 1e-2, "stall_forcing": (1e-3, 1e-4),
                                     "krylov_rtol": 1e-13, "polish_below": 1e-12})


@dataclass
class FullSystem(SystemParts):
    """One design's system in full space: A(α), L(α) in ``assembled`` as they are, ``gap`` (p,);
    on an obstacle other than the plane also ``T`` and the rotated ``A``, ``L`` (:class:`Frames`)."""

    assembled: Assembled
    gap: np.ndarray
    timings: dict
    T: object = None
    A: object = None
    L: np.ndarray | None = None
    shift: np.ndarray | None = None    # an obstacle's tangential translation (p, 2) per node frame, or None
    force: float | None = None         # a load step's |f| of a force-controlled obstacle (None: the model's)
    couple: FullSpaceCouple | None = None   # an elastic foundation: both bodies in one system (.coupled)
    moved: float = 0.0                 # a force-controlled foundation's translation s (.force)
    anchor: object = None              # counterparts held only by their contacts (.floating), or None
    anchored_A: object = None          # ... and the Newton system's A + γ N Nᵀ

    @property
    def law_A(self):
        """The matrix the Newton method sees: Tᵀ A T on an obstacle, else A(α)."""
        return self.assembled.A if self.T is None else self.A

    @property
    def law_L(self):
        return self.assembled.L if self.T is None else self.L


@dataclass
class FullContext(Context):
    """Also ``u_free``: the case's last displacement (free DOFs), Newton's warm start;
    ``adjoint_rhs_c`` the contact DOFs' part of the last adjoint's right-hand side in u_loc (an
    elastic foundation, :meth:`FullSpacePath.adjoint_carry`)."""

    u_free: np.ndarray | None = None
    adjoint_rhs_c: np.ndarray | None = None


class FullSpaceCommon(SolverPath):
    """What the full-space paths share (module docstring). A subclass keeps the design of its
    hierarchy in ``hierarchy_alpha`` and implements :meth:`last_displacement` and
    :meth:`restore`."""

    hierarchy_alpha = None        # the design of the hierarchy (an instance's, once built)

    @classmethod
    def memory_estimate(cls, body, counterparts=None, **kw):
        """Every body of the Newton system: the body's and its elastic counterparts' (a model's,
        or those ``counterparts`` given; :func:`~contactopt.fem.memory.coupled_parts`)."""
        return memory.estimate_evaluation(body, memory.coupled_parts, counterparts=counterpart_sizes(body, counterparts))

    def newton_options(self, ctx, tol, warm_start) -> dict:
        """The tolerance (at least :data:`FULLSPACE_TOL`), the case's zone when warm-started, and
        the zone margin of a solve."""
        s = self.settings
        return {"tol": max(tol or s.tol, FULLSPACE_TOL), "zone": ctx.next_zone if s.use_zone and warm_start else None,
                "zone_margin": s.zone_margin}

    def fit_scale(self, load_norm: float, diag_c, gap, held: bool = False) -> float | None:
        """The force scale of a press or shrink fit without load: with ``[body] interference``, or
        for a body held only by its contacts (``held``) pressed by an overlap or by a counterpart's
        prescribed translation (its q in the gaps), and L = 0 (``load_norm``), the overlap's force
        ‖A_νν min(g, 0)‖ (``diag_c()`` gives the (p, 3) diagonal of the Newton method's A at the
        contact DOFs, per node (t1, t2, ν); ``gap`` (p,) the gaps the law sees, negative inside
        the counterpart); else None (or without overlap), so that the Newton method measures its
        residuals against ‖L‖, or 1 as before. Without it such a fit's forces (E δ per unit area,
        1e-4 for E = 1 and δ = 1e-3) would be measured against 1, and its Krylov solves would stop
        before they begin; a held body's anchored solve then makes no progress at all (the lap
        joint's preload by the bolt head's displacement)."""
        if load_norm or not (self.model.config.body.interference or held):
            return None
        return overlap_force(diag_c(), gap)

    def local_contraction(self, system, state, z_loc, loads=None) -> np.ndarray:
        """The design term of (T z_loc) on the body, z_loc in the unknowns of all bodies (a hook of
        :func:`.coupled.force_terms`)."""
        z = self.model.assembler.to_full(system.couple.split(np.asarray(z_loc, float))[0])
        return self.design_contraction(system, state.u, z, loads)

    def translated(self, system, s, c, e):
        """As :meth:`SolverPath.translated`: the system's gaps g − s c, its shift (the slip's
        reference) plus s e, and s itself (both backends' systems hold ``gap``, ``shift`` and ``moved``)."""
        shift = system.shift
        if np.any(e):
            e2 = e.reshape(-1, 3)[:, :2]
            shift = s * e2 if shift is None else shift + s * e2
        return replace(system, gap=system.gap - s * c, shift=shift, moved=s)

    @staticmethod
    def law_displacement(state) -> np.ndarray:
        """(p, 3) the friction law's displacement of a state: u_c, in a load step with the slip
        increment in t1, t2 (the adjoint's sliding frames)."""
        if state.slip_ref is None:
            return state.u_c
        u_law = state.u_c.copy()
        u_law[:, :2] = state.slip_increment
        return u_law

    @property
    def n_unknowns(self) -> int:
        """The Newton system's unknowns (a checkpoint's displacement): the body's free DOFs."""
        return self.model.assembler.n_free

    def state_of(self, ctx, system, alpha, res, *, u_free, t0, t_setup, stats, label, slip_ref=None, u_c=None,
                 foundation=None):
        """The :class:`~contactopt.contact.state.State` of a full-space result ``res``
        (:class:`~contactopt.contact.fullspace.FullSpaceResult`; ``u_free`` its displacement on
        the model's free DOFs; ``u_c`` the contact nodes' displacement where it is not the
        result's own, e.g. in the world frame on an obstacle), begun at ``t0`` with ``t_setup``
        seconds of hierarchy set-up; the case's warm start is set from it."""
        timings = dict(system.timings, **{f"fullspace_{k}": v for k, v in res.timings.items() if k != "total"})
        timings["fullspace_amg_setup"] += t_setup
        timings["contact"] = time.perf_counter() - t0
        r = np.column_stack((res.r[:, 1:], res.r[:, 0]))           # per node (t1, t2, ν): (−τ, λ)
        asm = system.assembled
        state = self.finish_state(ctx, alpha=alpha, coords=asm.coords, u=self.model.assembler.to_full(u_free),
                                  u_c=res.u_c if u_c is None else u_c, r=r, gap=system.gap, load=asm.L, method="fullspace",
                                  outcome=(res.newton_steps, res.error, res.converged), timings=timings,
                                  stats={**stats, "zone_nodes": int(res.zone.size), "zone_misses": int(res.zone_growths),
                                        "delassus": "none", "krylov_iterations": int(sum(res.krylov_iterations))},
                                  slip_ref=slip_ref, foundation=foundation)
        ctx.warm = res.r.copy()
        log.debug("state%s: %s %d steps, %d GMRES iterations, error %.2e, %.2f s", label, self.newton_label,
                  res.newton_steps, sum(res.krylov_iterations), res.error, timings["total"])
        return state

    def _foundation_state(self, couple, u_free, u_f, w, moved=0.0):
        """The :class:`~contactopt.contact.state.FoundationState` of a two-body solve: the body's
        contact displacement and its partners' per node (t1, t2, ν) (their difference the law's
        w) and the foundation's whole displacement."""
        if couple.n_pinned or couple.cd.size > self.model.contact_dofs.size:    # faces on several bodies
            u_c = couple.face_side(u_free, u_f)
        else:
            u_c = u_free[self.model.contact_dofs].reshape(-1, 3)
            if self.mechanics.frames is not None:
                u_c = np.einsum("mij,mi->mj", self.mechanics.frames, u_c)
        return FoundationState(u_body_c=u_c, u_partner=couple.partner(u_f, moved),
                               displacement=couple.foundation_displacement(u_f, moved))

    # ------------------------------------------------------------------ checkpoints
    def last_displacement(self, ctx) -> np.ndarray | None:
        """The case's last displacement on the free DOFs (None before its first state)."""
        raise NotImplementedError

    def restore(self, ctx, arrays: dict, u_free, alpha, where: str) -> None:
        """Put back a checked displacement ``u_free`` and hierarchy design ``alpha`` (either None)."""
        raise NotImplementedError

    def export_context(self, ctx) -> dict:
        out = super().export_context(ctx)
        a = self.hierarchy_alpha       # the design of the hierarchy, shared by the cases
        out["jacobian_alpha"] = np.asarray(a if a is not None else np.zeros(0), dtype=float)
        out["jacobian_zone"] = np.asarray(ctx.next_zone if a is not None else np.zeros(0), dtype=np.int64)
        u = self.last_displacement(ctx)
        if u is not None:
            out["u_free"] = np.asarray(u)
        return out

    def import_context(self, ctx, arrays: dict, where: str, others=()) -> None:
        """Also the case's last displacement, and the hierarchy rebuilt at its design."""
        super().import_context(ctx, arrays, where, others)
        n_free = self.n_unknowns
        u = arrays.get("u_free")
        if u is not None and (u.shape != (n_free,) or not np.all(np.isfinite(u))):
            raise CheckpointError(f"{where}: its displacement does not fit the mesh ({u.shape[0] if u.ndim else 0} "
                                  f"values for {n_free} free DOFs) or is not finite")
        a = arrays.get("jacobian_alpha")
        alpha = check_design(a, self.model.n_design, where, "AMG design") if a is not None and a.size else None
        self.restore(ctx, arrays, u, alpha, where)


class FullSpacePath(FullSpaceCommon):
    """``[linear_solver] path = "fullspace"`` (module docstring)."""

    name = "fullspace"
    capabilities = Capabilities(foundation=True, pairs=True, counterpart_force=True, obstacle=True, pinned=True, whole_displacement=True,
                                load_steps=True, held_by_contact=True, libraries=("pyamg",), sparse="pyamg", auto="large", auto_order=0,
                                auto_avoids=("obstacle",))
    condenses_counterparts = False      # an elastic foundation joins the Newton system (.coupled)

    def __init__(self, model, settings, start=None):
        super().__init__(model, settings, start)
        self.library = "pyamg"
        self._hierarchy = None          # the AMG hierarchy of an earlier A(α) ...
        self.hierarchy_alpha = None     # ... built at this design (checkpoints rebuild it)
        self._couple = None             # an elastic foundation's change of unknowns (.coupled)
        refuse_counterparts(model, self.name)

    newton_label = "full-space Newton"

    def new_context(self) -> FullContext:
        return FullContext(None, self.all_nodes)

    @property
    def frames(self):
        """(p, 3, 3) contact frames on an obstacle other than the plane, else None."""
        return self.mechanics.frames

    @property
    def couple(self) -> FullSpaceCouple | None:
        """The change of unknowns of an elastic foundation (:mod:`.coupled`), built once; None without one."""
        if self.model.foundation is None:
            return None
        if self._couple is None:
            self._couple = FullSpaceCouple(self.model.foundation, self.model.contact_dofs, self.model.assembler.n_free,
                                           self.frames)
        return self._couple

    @property
    def law_dofs(self) -> np.ndarray:
        """The Newton system's contact DOFs (3p), per row (t1, t2, ν): the body's contact DOFs, and
        with faces on several bodies those of rows b on their carriers (:mod:`.coupled`)."""
        return self.model.contact_dofs if self.couple is None else self.couple.cd

    @property
    def n_unknowns(self) -> int:
        """The Newton system's unknowns: the body's free DOFs, and the foundation's."""
        return self.model.assembler.n_free if self.couple is None else self.couple.n

    def prepare(self, asm) -> FullSystem:
        shift = None if self.mechanics.shift is None else self.mechanics.shift.tangential
        face = self.model if self.mechanics.anchor is not None else None     # the face body held only by contact
        if self.couple is not None:
            A, L = self.couple.system(asm.A, asm.L)
            anchor = floating_anchor(self.couple, A.diagonal(), face)
            return FullSystem(asm, asm.gap, {}, self.couple.T, A, L, shift, couple=self.couple, anchor=anchor,
                              anchored_A=None if anchor is None else anchor.anchored(A))
        if self.frames is None:
            system = FullSystem(asm, asm.gap, {}, shift=shift)
        else:
            T = frame_rotation(self.model.contact_dofs, self.frames, self.model.assembler.n_free)
            # the product drops exact zeros (of pinned rows, or where a frame's zero meets the design's
            # values): keep every contact node's 3×3 block in the pattern (the Robin blocks are added there)
            A = with_contact_blocks(sp.csr_matrix(T.T @ asm.A @ T), self.model.contact_dofs)
            A.sort_indices()
            system = FullSystem(asm, asm.gap, {}, T, A, T.T @ asm.L, shift)
        if face is None:
            return system
        anchor = floating_anchor(None, system.law_A.diagonal(), face)
        return replace(system, anchor=anchor, anchored_A=anchor.anchored(system.law_A))

    # ------------------------------------------------------------------ a force-controlled obstacle (.force)
    def normal_stiffness(self, system):
        if system.couple is not None:       # the Newton system's own rows, in the nodes' frames
            return normal_stiffness(system.law_A, self.law_dofs, None)
        return normal_stiffness(system.assembled.A, self.model.contact_dofs, self.frames)

    def force_terms(self, system, ctx, state, v_lam, loads=None, *, v=None, y_u=None):
        """As :meth:`SolverPath.force_terms`; a foundation pressed by a force in the two bodies'
        unknowns (:func:`.coupled.force_terms`)."""
        if system.couple is None:
            return super().force_terms(system, ctx, state, v_lam, loads, v=v, y_u=y_u)
        return coupled_force_terms(self, system, ctx, state, v_lam, loads, y_u)

    def for_load(self, system, asm) -> FullSystem:
        out = replace(system, assembled=asm, timings={})
        if out.couple is not None:
            return replace(out, L=out.T.T @ out.couple.load(asm.L))
        return out if out.T is None else replace(out, L=out.T.T @ asm.L)

    def contact_diagonal(self, system) -> np.ndarray:
        """(p, 3) the diagonal of the Newton method's A at the contact DOFs, per node (t1, t2, ν)."""
        return system.law_A.diagonal()[self.law_dofs.reshape(-1, 3)]

    def build_hierarchy(self, alpha, asm=None, system=None):
        """The AMG hierarchy of A(α) (:class:`~contactopt.fem.amg.ContactHierarchy`), of the Newton
        system ``system`` of that design where the caller holds it (not formed a second time: with
        elastic counterparts the hierarchy's set-up is an evaluation's peak, and a second copy of
        the two bodies' system there took it from 8.60 to 9.53 GB at 977k DOFs).

        pyamg estimates spectral radii from random start vectors of NumPy's global generator: it
        is seeded here (and its state restored), and OpenBLAS runs on one thread, so that the same
        design gives the same hierarchy bit for bit."""
        if system is None:
            if asm is None:
                asm = self.model.assemble(alpha, self.first_loads)
            system = self.prepare(asm)
        return self.hierarchy_of(system, system.law_A if system.anchor is None else system.anchored_A,
                                 system.assembled.coords)

    def hierarchy_of(self, system, A, coords):
        """The AMG hierarchy of the matrix ``A`` of ``system`` (its near-null space the bodies'
        rigid modes at ``coords``), seeded as :meth:`build_hierarchy` says."""
        A = sorted_csr(A)
        saved = np.random.get_state()
        np.random.seed(HIERARCHY_SEED)
        try:
            with sequential_openblas():
                body_modes, transform = None, None
                if system.couple is not None:
                    modes = system.couple.modes(coords, self.model.assembler.free)
                    body_modes = 6 if modes.shape[1] > 6 else None     # six columns per body with DOFs
                    if body_modes:
                        transform = (system.couple.T, system.couple.inverse())
                else:
                    modes = rigid_body_modes(coords, self.model.assembler.free)
                    if system.T is not None:
                        modes = np.asarray(system.T.T @ modes)
                return ContactHierarchy(A, modes, contact_dofs=self.law_dofs, body_modes=body_modes,
                                        transform=transform)
        finally:
            np.random.set_state(saved)

    def solve_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None):
        """The state through the transforms of the contact system (:meth:`transformed_state`)."""
        return self.transformed_state(system, ctx, alpha, method=method, warm_start=warm_start, tol=tol,
                                      shared=shared, label=label, slip_ref=slip_ref)

    def fixed_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None):
        """The state with the obstacle where ``system`` puts it (:meth:`solve_state`, :mod:`.force`),
        warm-started from the case's last forces, displacement and contact zone, on the AMG
        hierarchy of an earlier design; without ``warm_start`` from nothing the case carries (on
        all contact nodes), so that two such solves of one design agree bit for bit."""
        asm = system.assembled
        t0 = time.perf_counter()
        warm = ctx.warm if warm_start else None
        u0 = ctx.u_free if warm_start and warm is not None else None
        t_setup = 0.0
        if self._hierarchy is None:
            self._hierarchy = self.build_hierarchy(alpha, asm, system)
            self.hierarchy_alpha = np.array(alpha, dtype=float)
            t_setup = time.perf_counter() - t0
        # on an obstacle: the contact DOFs in the nodes' frames (A → TᵀAT), and a tangential translation
        # as the reference of the slip (the law's displacement is w = u_c − shift, as on the condensation path)
        shift, gap = system.shift, system.gap
        if system.couple is not None:     # the foundation's translation q: gap g − q_ν, the slip's reference q_t
            q = system.couple.offset
            gap = gap - q[:, 2]
            if np.any(q[:, :2]):
                shift = q[:, :2] if shift is None else shift + q[:, :2]
        law_ref = slip_ref if shift is None else (shift if slip_ref is None else slip_ref + shift)
        load_norm = float(np.linalg.norm(system.law_L))
        options = dict(coords=asm.coords, free=self.model.assembler.free, slip_ref=law_ref,
                       force_scale=self.fit_scale(load_norm, lambda: self.contact_diagonal(system), gap,
                                                  held=system.anchor is not None),
                       **self.newton_options(ctx, tol, warm_start),
                       **(COUPLED_FORCING if system.couple is not None or system.anchor is not None else {}))
        held = None
        if system.anchor is None:
            res = solve_fullspace_with_fallbacks(system.law_A, system.law_L, self.law_dofs, gap,
                                                 self.friction, r0=warm, u0=u0, hierarchy=self._hierarchy, **options)
        else:
            res, held = self.held_solve(system, gap, warm, u0, load_norm or options["force_scale"] or 1.0,
                                        options)
        self._hierarchy = res.hierarchy
        ctx.u_free = res.u
        u_free, u_c, found = res.u, None, None
        if system.couple is not None:
            u_free, u_f = system.couple.split(res.u)
            u_c = res.u_c - system.couple.offset          # the law's w
            found = self._foundation_state(system.couple, u_free, u_f, u_c, system.moved)
        elif system.T is not None:
            u_free = system.T @ res.u
        if system.shift is not None:
            u_c = (res.u_c if u_c is None else u_c).copy()
            u_c[:, :2] -= system.shift
        state = self.state_of(ctx, system, alpha, res, u_free=u_free, u_c=u_c, t0=t0, t_setup=t_setup,
                              stats={"backend": "pyamg", **({"fallback": res.fallback} if res.fallback else {})},
                              label=label, slip_ref=slip_ref, foundation=found)
        if held is not None:
            state.rigid = held
        return state

    def held_solve(self, system, gap, warm, u0, load_norm, options):
        """The full-space result of a model with counterparts held only by their contacts
        (:mod:`.floating`): the anchored problem at β₀ = Nᵀu₀ (its start solve and first Newton
        systems regular whatever holds the body), then from its state the Newton method on the
        unanchored system, whose Newton systems the contact now holds (at most
        :data:`FREE_NEWTON_STEPS` steps); where that does not converge, the anchor's iteration
        β ← Nᵀu on. Returns (the result, its ``krylov_iterations`` and ``newton_steps`` those of
        every solve; the
        :class:`~contactopt.contact.state.RigidAnchor`: the anchored solves, the unbalanced load
        relative to ‖L‖)."""
        n, cd = system.law_A.shape[0], self.law_dofs
        current = {"anchor": system.anchor, "A": system.anchored_A, "hierarchy": None}
        shared = self._hierarchy          # (the hierarchy of the soft anchor, kept for later solves)

        def solve(beta, last, fallbacks=True):
            kw = dict(options, r0=warm, u0=u0, hierarchy=current["hierarchy"] or self._hierarchy)
            if last is not None:
                kw.update(r0=last.r, u0=last.u, zone=last.zone, hierarchy=current["hierarchy"] or last.hierarchy)
            L = system.law_L + current["anchor"].load(beta, n)
            if not fallbacks:
                kw.update(max_steps=SOFT_ANCHOR_STEPS, raise_on_failure=False)
                return solve_fullspace(current["A"], L, cd, gap, self.friction, **kw)
            return solve_fullspace_with_fallbacks(current["A"], L, cd, gap, self.friction, **kw)
        an = system.anchor
        beta0 = an.position(u0) if u0 is not None else np.zeros(an.N.shape[1])

        def stiffen():
            # its own hierarchy, for its solves only (the shared one, the soft anchor's, stays:
            # a resume rebuilds that one from the design)
            current["anchor"] = current["anchor"].stiffer()
            current["A"] = current["anchor"].anchored(system.law_A)
            current["hierarchy"] = self.hierarchy_of(system, current["A"], options["coords"])
        first = first_anchored_solve(solve, beta0, stiffen)
        first.hierarchy = shared
        an = current["anchor"]
        try:
            free = solve_fullspace(system.law_A, system.law_L, cd, gap, self.friction,
                                   **dict(options, r0=first.r, u0=first.u, zone=first.zone, hierarchy=first.hierarchy,
                                          max_steps=FREE_NEWTON_STEPS, raise_on_failure=False))
        except SolverError as exc:          # a Newton system the contact does not hold: singular
            log.debug("counterpart held only by its contacts: the unanchored Newton method stopped (%s)", exc)
            free = None
        if free is not None and free.converged:
            free.krylov_iterations = list(first.krylov_iterations) + list(free.krylov_iterations)
            free.newton_steps += first.newton_steps
            free.fallback = first.fallback
            return free, RigidAnchor(iterations=1, residual=float(free.equilibrium))
        res, held, iterations, steps = iterate_anchor(solve, an, (beta0, first), load_norm, options["tol"])
        spent = [] if free is None else list(free.krylov_iterations)     # (the unanchored attempt's)
        res.krylov_iterations, res.newton_steps = iterations + spent, steps + (0 if free is None else free.newton_steps)
        res.hierarchy = shared
        return res, held

    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None, carry=None):
        """As :meth:`SolverPath.adjoint`; with an elastic foundation (:mod:`.coupled`) in the
        unknowns u_loc of both bodies, ``carry`` (∂J/∂w of a later load step, with ∂J/∂u on every
        DOF of the body) joining at the contact DOFs, which hold w."""
        full = self.is_full(y_u)
        if full:                       # ∂J/∂u on every DOF: the free DOFs' part
            y_u = np.asarray(y_u, float)[self.model.assembler.free]
        if system.couple is not None and full:
            y_u = system.couple.extend(y_u)   # ∂J/∂u of the body into both bodies' u_loc
            ctx.adjoint_rhs_c = y_u[self.law_dofs].copy()
            if carry is not None:
                y_u[self.law_dofs] += carry
        elif system.T is not None and np.asarray(y_u).size == system.T.shape[0]:
            y_u = system.T.T @ y_u        # ∂J/∂u on the free DOFs into the nodes' frames
        return self.local_adjoint(system, ctx, state, y_u, y_lam, choices)

    def local_adjoint(self, system, ctx, state, y_u, y_lam, choices=None):
        """The adjoint of the Newton system's own unknowns: ``y_u`` on the contact DOFs (3p) or on
        every unknown of the system (in the nodes' frames, both bodies' with a foundation)."""
        u_law = self.law_displacement(state)
        adj = solve_adjoint_fullspace(system.law_A, self.law_dofs, state.classes, u_law,
                                      state.lam, y_u, y_lam, self.friction, hierarchy=self._hierarchy,
                                      choices=choices)
        ctx.adjoint_v = adj.v
        v = adj.v if system.T is None else system.T @ adj.v
        if system.couple is not None:
            v = v[:self.model.assembler.n_free]       # ∂A/∂α touches the body's block only
        return Adjoint(adj.v_u, adj.v_lam, self.model.assembler.to_full(v), int(adj.iterations))

    # the hooks of :func:`.coupled.force_terms`
    def law_product(self, system, x) -> np.ndarray:
        return system.law_A @ x

    def last_adjoint(self, system, ctx) -> np.ndarray:
        return ctx.adjoint_v

    def adjoint_force(self, system, ctx, v_u):
        """S v_u = (A ṽ)_c: ṽ, the last adjoint's A-harmonic extension of v_u, has A ṽ = Bᵀ S v_u."""
        return (system.law_A @ ctx.adjoint_v)[self.law_dofs]

    def adjoint_carry(self, system, ctx, v_u, v_full, y_u):
        """As :meth:`SolverPath.adjoint_carry`; with an elastic foundation in u_loc, where the
        contact DOFs hold w: (Tᵀ diag(A, K_f) T ṽ_loc)_c + (Tᵀ(g, 0))_c for ∂J/∂u = g on every DOF."""
        if system.couple is None or not self.is_full(y_u):
            return super().adjoint_carry(system, ctx, v_u, v_full, y_u)
        return self.adjoint_force(system, ctx, v_u) + ctx.adjoint_rhs_c

    # ------------------------------------------------------------------ checkpoints
    def last_displacement(self, ctx):
        return ctx.u_free

    def restore(self, ctx, arrays, u_free, alpha, where):
        if u_free is not None:
            ctx.u_free = u_free
        if alpha is not None and (self.hierarchy_alpha is None or not np.array_equal(self.hierarchy_alpha, alpha)):
            self._hierarchy = self.build_hierarchy(alpha)
            self.hierarchy_alpha = alpha


def _pairs_whose(counterparts, test) -> list:
    """``contacts[k]`` of every pair whose counterpart body passes ``test`` (none without counterparts)."""
    if counterparts is None:
        return []
    return [f"contacts[{k}]" for part, pairs in zip(counterparts.parts, counterparts.pairs) if test(part)
            for k in pairs]


def refuse_counterparts(model, path: str) -> None:
    """ConfigError naming the counterparts that the full-space form (:mod:`.coupled`) does not take
    so far, on ``path`` (the pyamg or the PETSc backend): mortar partners on six-node triangles.
    (A counterpart held only by its contacts is anchored on both, :mod:`.floating`.)"""
    if model.foundation is not None and model.foundation.basis is not None:
        raise ConfigError([f"{model.config.source}: linear_solver.path = {path!r}: an elastic [foundation] "
                           "with mortar partners on six-node triangles (a transformed basis) is solved on the "
                           "'condensation' path only so far; use path 'condensation' or partner = 'point'"])
