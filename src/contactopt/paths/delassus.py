"""The Delassus path: a sparse Cholesky factorization of A(α) per design, nothing condensed.

W = S⁻¹ = B A⁻¹ Bᵀ (B selects the contact DOFs) is applied by sparse solves, S⁻¹ℓ = (A⁻¹L)_c
= (x0)_c, and the zone's block W_Z, when Newton needs it, is the inverse of the Schur complement
of A onto the zone's DOFs (:class:`~contactopt.contact.zone.DelassusZoneProblem`). The local
problem and its conventions are those of :mod:`.zone_paths`. For meshes where the dense S on all
contact DOFs would not fit (docs/large_meshes.md).

Where the Cholesky factor and a zone's Schur-mode factorization would not fit in memory together
(:func:`contactopt.fem.memory.keeps_cholesky`), the Cholesky is released while the zone block is
formed; the condensation then serves the design's remaining solves
(:class:`~contactopt.fem.linsolve.SolverSlot`), and the next design factorizes anew.

On a rigid obstacle other than the plane the contact DOFs are the local components of each node's
frame R_m = (t1, t2, n): W = Qᵀ B A⁻¹ Bᵀ Q, Q = diag(R_m), by rotating the forces before each
sparse solve and the displacements after it (:class:`~contactopt.contact.zone.FramedDelassusZoneProblem`);
the W-form adjoint's products rotate the same way, and an obstacle's tangential translation shifts q
as on the condensation path (:mod:`.condensation`; on the plane in the axes' frames). The translation
is a field of the system, so that a force-controlled obstacle (:mod:`.force`) moves it per trial.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from ..contact import zone as zone_rules
from ..contact.state import CLASS_CODES, FROM_FCLIB, displacement_scale
from ..fem import memory
from ..fem.linsolve import Factorization, SolverSlot
from ..fem.model import Assembled
from ..sensitivity.adjoint import check_choices, effective_classes, solve_adjoint_delassus
from .base import Adjoint, Capabilities, SystemParts
from .force import normal_stiffness
from .transforms import from_frames, to_frames
from .zone_paths import ZonePath

log = logging.getLogger(__name__)

NEW_NODES = 24          # new nodes whose exact columns (3 sparse solves each, as one block) extend
                        # a kept block; 72 columns ≈ 1.5–2 factorizations at 113k DOFs, about the
                        # cost of the zone's Schur complement
ADJOINT_MAX_NEW = 0.1   # the adjoint's preconditioner takes exact columns for at most this
                        # fraction of nodes outside the kept block, else the zone's Schur complement


@dataclass
class FactorizedSystem(SystemParts):
    """One design's system on the Delassus path: ``factor`` the slot holding the sparse
    factorization of A(α) (free DOFs), ``x0`` = A(α)⁻¹L(α) the displacement without contact
    forces, ``gap`` (p,)."""

    assembled: Assembled
    factor: object
    x0: np.ndarray
    gap: np.ndarray
    timings: dict
    shift: np.ndarray | None = None    # an obstacle's tangential translation (3p, per node frame), or None
    force: float | None = None         # a load step's |f| of a force-controlled obstacle (None: the model's)


class DelassusPath(ZonePath):
    """``[linear_solver] path = "delassus"`` (module docstring)."""

    name = "delassus"
    capabilities = Capabilities(obstacle=True, pinned=True, whole_displacement=True,
                                load_steps=True, auto="large", auto_order=1, auto_libraries=("pardiso",), auto_avoids=("obstacle",))
    reuse_tol_factor = 1.0    # each Newton step costs a sparse solve here: to tol itself
    accept_at_tol = True      # forming W_Z costs more than a factorization
    probe_warm = True         # the warm start's product Newton needs first anyway

    def __init__(self, model, settings, start=None):
        super().__init__(model, settings, start)
        self._factor = None       # the Cholesky factorization of A(α), numerical only after the first
        self._slot = None         # the factorization a design's solves go through
        self._keep_cholesky = memory.keeps_cholesky(model)

    @classmethod
    def memory_estimate(cls, body, counterparts=None, keep_cholesky=None):    # (no counterparts on this path)
        if keep_cholesky is None:
            keep_cholesky = memory.keeps_cholesky(body)
        return memory.estimate_evaluation(body, memory.delassus_parts, keep_cholesky=keep_cholesky)

    def prepare(self, asm) -> FactorizedSystem:
        t0 = time.perf_counter()
        fac = self._factor
        if fac is None:           # the first design, or the Cholesky was released (_zone_block)
            fac = self._factor = Factorization(asm.A, self.library)
        else:
            fac.refactor(asm.A)
        if self._slot is None:
            self._slot = SolverSlot()
        self._slot.set(fac)       # releases the last design's zone condensation, if any
        t1 = time.perf_counter()
        x0 = fac.solve(asm.L)
        shift = self.mechanics.shift
        return FactorizedSystem(asm, self._slot, x0, asm.gap,
                                {"factor": t1 - t0, "load_solve": time.perf_counter() - t1},
                                None if shift is None else shift.vector)

    def for_load(self, system, asm) -> FactorizedSystem:
        t1 = time.perf_counter()
        return replace(system, assembled=asm, x0=system.factor.solve(asm.L),
                       timings={"load_solve": time.perf_counter() - t1})

    def _zone_block(self, A):
        """``dofs -> S_D``: the dense Schur complement of A onto the DOFs ``dofs`` (in their
        order), by a factorization that eliminates them last (W_Z = S_D⁻¹)."""
        from ..fem.linsolve import condense

        def block(dofs):
            t0 = time.perf_counter()
            slot = self._slot
            released = not self._keep_cholesky and self._factor is not None and slot.current is self._factor
            if released:
                self._factor.close()
                self._factor = None
            fac = condense(A, dofs, backend=self.library)
            S = fac.S
            if released:
                slot.current = fac
            else:
                fac.close()
            log.debug("Schur complement onto %d zone DOFs: %.2f s", len(dofs), time.perf_counter() - t0)
            return S
        return block

    @property
    def frames(self):
        """(p, 3, 3) contact frames on an obstacle other than the plane (columns (t1, t2, n)), else None:
        W, forces and contact displacements are then per node in its frame (:class:`~contactopt.contact.
        zone.FramedDelassusZoneProblem`)."""
        return self.mechanics.frames

    def law_frames(self, system):
        """The frames of the zone problems: :attr:`frames`, or the axes on the plane translated
        tangentially (the shift acts per node frame), else None."""
        if self.frames is None and system.shift is not None:
            return np.broadcast_to(np.eye(3), (self.model.n_contact, 3, 3))
        return self.frames

    def _problem(self, system, zone):
        R = self.law_frames(system)
        if R is not None:
            return zone_rules.FramedDelassusZoneProblem(system.factor, self.model.contact_dofs, system.x0, zone,
                                                        self._zone_block(system.assembled.A), R, system.shift)
        return zone_rules.DelassusZoneProblem(system.factor, self.model.contact_dofs, system.x0, zone,
                                              self._zone_block(system.assembled.A))

    def body_contact_displacement(self, system, u_c, r):
        """On an obstacle u_c is per node in its frame, relative to a translated obstacle: the body's is
        Q (u_c + shift)."""
        R = self.law_frames(system)
        if R is None:
            return np.ravel(u_c)
        u = np.ravel(u_c) if system.shift is None else np.ravel(u_c) + system.shift
        return from_frames(u, R)

    # ------------------------------------------------------------------ a force-controlled obstacle (.force)
    def translated(self, system, s, c, e):
        shift = system.shift
        if np.any(e):
            shift = s * e if shift is None else shift + s * e
        return replace(system, gap=system.gap - s * c, shift=shift)

    def normal_stiffness(self, system):
        return normal_stiffness(system.assembled.A, self.model.contact_dofs, self.frames)

    def zone_problem(self, system, zone, warm, reuse, shared):
        if warm is None and self.settings.use_zone and zone.size == self.all_nodes.size:
            zone = self.predicted_zone(system)
        if "zone" in shared:
            zp = shared["zone"]
            if isinstance(zp, zone_rules.FramedDelassusZoneProblem):   # the shift of this system
                return zp.with_load(system.x0, zone, system.shift), zone
            return zp.with_load(system.x0, zone), zone
        zp = shared["zone"] = self._problem(system, zone)
        return zp, zone

    def predicted_zone(self, system) -> np.ndarray:
        """A first contact zone without a warm start: the nodes whose displacement without contact
        forces, x0, closes the gap to within the margin — the zone grows by every node it misses,
        so the state does not depend on this guess, and W_Z is not formed on all contact DOFs."""
        u0 = system.x0[self.model.contact_dofs]
        R = self.law_frames(system)
        if R is not None:
            u0 = to_frames(u0, R) - (0.0 if system.shift is None else system.shift)
        u0 = u0.reshape(-1, 3)
        clearance = u0[:, 2] + system.gap
        return zone_rules.near_nodes(np.zeros(system.gap.size), clearance, displacement_scale(u0, system.gap),
                                     self.settings.zone_margin)

    def free_displacement(self, system, zp, r_loc, u_body):
        return zp.free_displacement(r_loc)

    def load_scale(self, system):
        # without ℓ: the load on the contact DOFs' stiffness scale (|S u0| ≈ |L| there)
        return system.assembled.L

    def solve_counts(self, zp) -> dict:
        return {"sparse_solves": zp.n_solves}

    def max_new(self, nodes, fraction):
        # a column costs a sparse solve here: at most NEW_NODES (beyond that the zone's Schur
        # complement is cheaper)
        return {"max_new": min(fraction, NEW_NODES / max(len(nodes), 1))}

    def own_block(self, system, zone):
        return self._problem(system, zone).W

    def adjoint_force(self, system, ctx, v_u):
        """S v_u: the unknown s of the last W-form adjoint of ``ctx`` (v_u = W s)."""
        return ctx.adjoint_s

    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None):
        """(4.15) in W-form (:func:`contactopt.sensitivity.adjoint.solve_adjoint_delassus`): products
        W s by sparse solves, preconditioned by the case's kept Delassus block on the nodes in
        contact (exact columns for nodes outside it; the zone's Schur complement without one)."""
        contact = self.model.contact_dofs
        n = system.x0.size
        R = self.frames
        rot, back = (lambda v: v, lambda v: v) if R is None else (lambda v: to_frames(v, R), lambda v: from_frames(v, R))

        def apply(s):
            f = np.zeros(n)
            f[contact] = back(s)
            x = system.factor.solve(f)
            return rot(x[contact]), x

        eff = effective_classes(state.classes, check_choices(choices))
        K = np.flatnonzero(eff != CLASS_CODES["L"])
        zpK = self._problem(system, K)
        jac = ctx.jacobian
        W = None
        if jac is not None and K.size:
            W = zpK.block_from(jac.zone, jac.W, **self.max_new(K, ADJOINT_MAX_NEW))
        if W is None:
            W = zpK.W if K.size else np.zeros((0, 0))
        perm = (3 * np.arange(K.size)[:, None] + FROM_FCLIB).ravel()   # FCLIB -> (t1, t2, ν)
        W = W[np.ix_(perm, perm)]
        t0 = time.perf_counter()
        shift, out = None, {}
        if self.is_full(y_u):          # ∂J/∂u on every DOF: ṽ = A⁻¹(Bᵀs − g₀), v_u = W s + d
            g = np.asarray(y_u, float)[self.model.assembler.free]
            g0 = g.copy()
            g0[contact] = 0.0
            d_full = -system.factor.solve(g0)
            shift, y_u = (rot(d_full[contact]), d_full), rot(g[contact])
        v_u, v_lam, v_free, res = solve_adjoint_delassus(apply, W, state, y_u, y_lam, choices, shift=shift,
                                                     out=out)
        ctx.adjoint_s = out["force"]       # S v_u, for the previous load step (adjoint_force)
        if res is not None:
            log.debug("adjoint (4.15) in W-form on %d nodes: %d GMRES iterations, %.2f s",
                      K.size, res.iterations, time.perf_counter() - t0)
        return Adjoint(v_u, v_lam, self.model.assembler.to_full(v_free),
                       None if res is None else int(res.iterations))
