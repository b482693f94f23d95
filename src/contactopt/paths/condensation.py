"""The condensation path: the Schur complement S of A(α) onto all contact DOFs, dense.

Condensed contact system (paper (3.17)), per contact node m in the order (t1, t2, ν) = (x1, x2, x3):
    r = S u_c − ℓ  is the contact force on the body, λ = r_ν ≥ 0, τ = −r_t,
    u_ν + g ≥ 0, λ(u_ν + g) = 0, ‖τ‖ ≤ Fλ, u_t ≠ 0 ⇒ τ = Fλ u_t/‖u_t‖,
handed to the local solvers on the contact zone with W = S⁻¹ (:mod:`.zone_paths`). A(α), its
factorization and S do not depend on the load: a design is condensed once (PARDISO's ordering and
analysis reused from design to design, the pattern never changes with α), and each load case adds
ℓ_k. The adjoint (4.15) is the dense system of :func:`contactopt.sensitivity.adjoint.solve_adjoint`.

On an elastic foundation (:mod:`contactopt.fem.foundation`, docs/foundation.md) the contact law
acts on the relative displacement w = u_c − Π u_f of a contact node and its partner,
w = W r + S⁻¹ℓ − Π q_f with W = S⁻¹ + C. With

    S_eff = W⁻¹,   ℓ_eff = S_eff (S⁻¹ℓ − Π q_f)   (w = S_eff⁻¹(ℓ_eff + r)),

the zone problems are those of the rigid foundation on (S_eff, ℓ_eff) — the state's ``u_c`` is
w, its node classes those of w, the gap ϑ_α as before — and the body's own contact
displacement is u_c = S⁻¹(ℓ + r) = w + Π q_f − C r. The adjoint (4.15) is solved with S_eff;
differentiating S_eff w − ℓ_eff at fixed w gives S_eff S⁻¹(∂S u_c − ∂ℓ), so the design terms take
z = S⁻¹ S_eff v_u in place of v_u: ṽ is the A-harmonic extension of z. S_eff and both
transfers come from the Woodbury identity (:class:`contactopt.fem.foundation.Coupling`), with no
inverse of S. Where the body and every counterpart are held by their clamps
(:attr:`CondensedSystem.compliant`) none of S_eff, ℓ_eff is formed: the zone's problem is that of
the compliance W = S⁻¹ + C on the factor of S (:class:`contactopt.contact.zone.CoupledZoneProblem`),
with the free displacement W ℓ_eff = S⁻¹ℓ − Π q_f, and (4.15) is solved in W-form for
s = S_eff v_u, so that z = S⁻¹ s (:func:`contactopt.sensitivity.adjoint.solve_adjoint_compliant`).
Without a foundation (C = 0) nothing of this is formed.

On a rigid obstacle other than the plane (``[obstacle]``, :mod:`contactopt.mesh.obstacle`) each
contact node m has a frame R_m with columns (t1, t2, n): the contact DOFs are the local
components u_loc = R_mᵀ u_c, so the system is S_loc = Qᵀ S Q, ℓ_loc = Qᵀ ℓ with Q = diag(R_m),
the state's ``u_c`` and forces are per node (t1, t2, n) in the node's frame, the interior is
recovered from Q u_loc, and the adjoint's design terms extend Q v_u. On the plane nothing is rotated.

A force-controlled obstacle (``control = "force"``) translates by s f̂ along its force: the gap
falls by s c and the law's load by S s e (:func:`shifted`); s and its subgradient are those of
:mod:`.force`, shared with the Delassus and full-space paths.

A body held only by contact (clamps that leave rigid motions free) keeps this condensation exact
with a singular S; its state comes from an anchored problem iterated until the anchor carries no
force, and its adjoint is solved with the singular S (:mod:`.rigid`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from scipy.sparse.linalg import eigsh

from ..contact import zone as zone_rules
from ..contact.state import CLASS_CODES, FROM_FCLIB, FoundationState
from ..contact.zone import CoupledZoneProblem
from ..errors import SolverError
from ..fem import memory
from ..fem.dense import mkl_threads, spd_inverse
from ..fem.faces import FacesCoupling
from ..fem.foundation import Coupling
from ..fem.model import Assembled
from ..sensitivity.adjoint import solve_adjoint, solve_adjoint_compliant
from .base import Adjoint, Capabilities, SystemParts, counterpart_sizes
from .rigid import Anchor, anchor, held_state, with_contact_diagonal
from .zone_paths import ZonePath


@dataclass
class CondensedSystem(SystemParts):
    """One design's condensed system: ``factor`` the condensation (S, ℓ and the recovery of
    the interior DOFs), ``S`` (3p, 3p) and ``ell`` (3p,) per node (t1, t2, ν), ``gap`` (p,)."""

    assembled: Assembled
    factor: object
    S: np.ndarray
    ell: np.ndarray
    gap: np.ndarray
    timings: dict
    coupling: Coupling | None = None   # on an elastic foundation: W = S⁻¹ + C, S_eff = W⁻¹ ...
    ell_eff: np.ndarray | None = None  # ... and ℓ_eff = S_eff (S⁻¹ℓ − Π q_f) (module docstring; None: not formed yet)
    shift: np.ndarray | None = None    # an obstacle's tangential translation (3p,) per node frame: ℓ_eff = ℓ − S shift
    rigid: Anchor | None = None        # a body held only by contact: the kernel of S (module docstring)
    beta: np.ndarray | None = None     # ... and the anchor's position β of this solve
    force: float | None = None         # a load step's |f| of a force-controlled obstacle (None: the model's)
    moved: float = 0.0                 # the force search's translation s of the counterpart (.force)
    basis: object = None               # the transformed basis of quadratic faces (transforms.Basis): u_c = Vᵀ û
    counterpart_terms: tuple | None = None   # (ṽ, the designed counterparts' design terms) of its last adjoint

    @property
    def law_S(self) -> np.ndarray:
        """The stiffness the zone's local problems are built on: S_γ = S + γQQᵀ of a body held only
        by contact (S itself is singular there), else :attr:`contact_S`."""
        return self.contact_S if self.rigid is None else self.rigid.S

    @property
    def law_ell(self) -> np.ndarray:
        """ℓ_eff + γQβ of a body held only by contact, else :attr:`contact_ell`."""
        if self.rigid is None:
            return self.contact_ell
        return self.contact_ell + self.rigid.gamma * (self.rigid.Q @ self.beta)

    @property
    def S_eff(self):
        return None if self.coupling is None else self.coupling.S_eff

    @property
    def contact_S(self) -> np.ndarray:
        """The stiffness of the contact law's displacement: S, or S_eff on an elastic foundation."""
        return self.S if self.S_eff is None else self.S_eff

    @property
    def contact_ell(self) -> np.ndarray:
        """The load of the contact law's displacement: ℓ, ℓ − S shift on a translated obstacle, or
        ℓ_eff on an elastic foundation (formed on first use: the zone and the adjoint of a
        :attr:`compliant` system need only W ℓ_eff)."""
        if self.ell_eff is None:
            if self.coupling is None:
                return self.ell
            self.ell_eff = self.coupling.ell_eff(self.ell)
        return self.ell_eff

    @property
    def compliant(self) -> bool:
        """Whether the contact law is that of a foundation or held counterparts on a body held by
        its clamps: the zone and the adjoint then work with W = S⁻¹ + C and the factor of S alone
        (:class:`~contactopt.contact.zone.CoupledZoneProblem`), never with S_eff."""
        return self.coupling is not None and self.coupling.compliant

    @property
    def law_offset(self) -> np.ndarray:
        """``offset`` of W ℓ_eff = S⁻¹ℓ − offset (:attr:`compliant` systems): the partners'
        displacement under no contact force, plus an obstacle's tangential translation."""
        offset = self.coupling.offset
        return offset if self.shift is None else offset + self.shift


def on_factor(zp, ell: np.ndarray, zone: np.ndarray):
    """The zone problem of another load ℓ and zone on the Cholesky factor of S that ``zp`` holds
    in S's own order (``ordered=False``): that factor depends on neither, so the load cases of a
    design share it. The same numbers as ``ZoneProblem(S, ell, zone, ordered=False)``."""
    out = object.__new__(zone_rules.ZoneProblem)
    out.p, out._S, out._L, out._order, out._start, out._parent = zp.p, zp._S, zp._L, None, 0, None
    out._set_zone(np.asarray(zone), None, out.solve(ell))
    return out


class CondensationPath(ZonePath):
    """``[linear_solver] path = "condensation"`` (module docstring)."""

    name = "condensation"
    capabilities = Capabilities(foundation=True, pairs=True, counterpart_force=True, obstacle=True, obstacle_steps=True,
                                held_by_contact=True, pinned=True,
                                compliance=True,
                                whole_displacement=True, load_steps=True, auto="small")

    def __init__(self, model, settings, start=None):
        super().__init__(model, settings, start)
        self._factor = None      # the condensation, refactored in place for each new design

    @classmethod
    def memory_estimate(cls, body, counterparts=None, **kw):
        return memory.condensation_estimate(body, counterpart_sizes(body, counterparts))

    def prepare(self, asm) -> CondensedSystem:
        from ..fem.linsolve import condense
        t1 = time.perf_counter()
        fac = self._factor
        A, shift_c = asm.A, 0.0
        mech = self.mechanics
        if mech.anchor is not None:          # A singular: condense A + γ_A I_c (rigid.py)
            A, shift_c = with_contact_diagonal(A, self.model.contact_dofs)
        if fac is not None and hasattr(fac, "refactor"):
            fac.refactor(A, trusted=True)     # symmetric, positive diagonal: assembled
        else:
            fac = self._factor = condense(A, self.model.contact_dofs, backend=self.library)
        S, ell = fac.S, fac.condense_load(asm.L)
        if shift_c:
            S = S - shift_c * np.eye(S.shape[0])
        if mech.rotate is not None:
            S, ell = mech.rotate.matrix(S), mech.rotate.vector(ell)
        if mech.basis is not None:
            S, ell = mech.basis.matrix(S), mech.basis.vector(ell)
        system = CondensedSystem(asm, fac, S, ell, asm.gap, {}, basis=mech.basis)
        if mech.shift is not None:
            system = shifted(system, mech.shift.vector)
        couple = mech.couple
        if couple is not None and self.model.cp_designs is not None:   # designed counterparts: formed at α
            couple = self.model.cp_designs.foundation_at(asm.alpha)
        if couple is not None:
            # faces on several bodies: S_eff of the face body's rows and the others' (fem.faces)
            kind = Coupling if couple.face_rows is None else FacesCoupling
            system.coupling = kind(system.S, couple, anchored=mech.anchor is not None)
        extra = None if couple is None else couple.kernel()   # counterparts held by contact
        if mech.anchor is not None or extra is not None:
            system.rigid = anchor(self.model, mech.anchor, asm, system.contact_S, mech.frames, mech.basis, extra)
        system.timings["schur"] = time.perf_counter() - t1
        return system

    @classmethod
    def library_threads(cls, threads: int):
        """MKL on ``threads`` threads (1: bit for bit a single-threaded run's results;
        :func:`contactopt.fem.dense.mkl_threads`)."""
        return mkl_threads(threads)

    @property
    def foundation(self):
        """The elastic foundation of the model (the couple of :mod:`.transforms`), or None."""
        return self.mechanics.couple

    def for_load(self, system, asm) -> CondensedSystem:
        t1 = time.perf_counter()
        ell = system.factor.condense_load(asm.L)
        if self.mechanics.rotate is not None:
            ell = self.mechanics.rotate.vector(ell)
        if self.mechanics.basis is not None:
            ell = self.mechanics.basis.vector(ell)
        out = replace(system, assembled=asm, ell=ell, ell_eff=None, timings={}, counterpart_terms=None)
        if out.shift is not None:
            out = shifted(out, out.shift)
        out.timings["schur"] = time.perf_counter() - t1
        return out

    def translated(self, system, s, c, e):
        """The obstacle translated by s f̂ (:mod:`.force`): the gap falls by s c, the law's load
        by S s e (:func:`shifted`)."""
        moved = replace(system, gap=system.gap - s * c, moved=s)
        return shifted(moved, s * e) if np.any(e) else moved

    def normal_stiffness(self, system):
        return np.diag(system.contact_S)[2::3]

    def fixed_state(self, system, ctx, alpha, **kw):
        """The zone's state; of a body held only by contact, by the anchor's iteration (:mod:`.rigid`)."""
        if system.rigid is None:
            return self.zone_state(system, ctx, alpha, **kw)
        return held_state(lambda sys: self.zone_state(sys, ctx, alpha, **kw), system,
                          kw.get("tol") or self.settings.tol, kw.get("method", self.settings.method))

    def zone_problem(self, system, zone, warm, reuse, shared):
        if system.compliant:
            return self._coupled_zone(system, zone, reuse, shared), zone
        if reuse and "zone" in shared:
            return on_factor(shared["zone"], system.law_ell, zone), zone
        zp = zone_rules.ZoneProblem(system.law_S, system.law_ell, zone, ordered=not reuse)
        if reuse:
            shared["zone"] = zp
        return zp, zone

    def _coupled_zone(self, system, zone, reuse: bool = False, shared: dict | None = None) -> CoupledZoneProblem:
        """The zone problem of a :attr:`~CondensedSystem.compliant` system: the factor of S ordered
        (N, Z) serves the state's products and W_Z, which the adjoint then needs (its block on the
        nodes in contact); the load cases of a design share it (``reuse``). Kept on the coupling
        for the adjoint."""
        if reuse and shared is not None and "zone" in shared:
            zp = shared["zone"].on_load(system.ell, system.law_offset, zone)
        else:
            zp = CoupledZoneProblem(system.S, system.coupling.foundation.C, system.ell, system.law_offset, zone)
            if reuse and shared is not None:
                shared["zone"] = zp
        system.coupling.zone_problem = zp
        return zp

    def free_displacement(self, system, zp, r_loc, u_body):
        return system.factor.recover(system.assembled.L, u_body)

    def body_contact_displacement(self, system, u_c, r):
        """On a foundation u_c is the relative displacement w; the body's own is w + Π u_f. On an
        obstacle u_c is in the nodes' frames: the body's is Q u_c."""
        if system.shift is not None:
            u_c = np.ravel(u_c) + system.shift
        if system.coupling is not None:      # (in the nodes' frames on a curved face)
            u_c = system.coupling.body_displacement(u_c, r, system.ell)
        if self.mechanics.basis is not None:
            return self.mechanics.basis.back(u_c)
        if self.mechanics.rotate is not None:
            return self.mechanics.rotate.back(np.ravel(u_c))
        return np.ravel(u_c)

    def foundation_state(self, system, u_c, r, u_body):
        """On a foundation: the body's contact displacement and its partners' (p, 3) per node
        (t1, t2, ν) — w = u_c − partner is the state's ``u_c`` — and the foundation's own."""
        if system.coupling is None:
            return None
        rot, basis = self.mechanics.rotate, self.mechanics.basis
        if isinstance(system.coupling, FacesCoupling):    # every row's face side: the face body's and the others'
            u = np.ravel(u_c) + (0.0 if system.shift is None else system.shift)
            body = system.coupling.face_displacement(u, system.ell).reshape(-1, 3)
            return FoundationState(u_body_c=body, u_partner=body - np.reshape(u_c, (-1, 3)),
                                   displacement=self._foundation_displacement(system, u_c, r))
        body = (u_body if rot is None else rot.vector(np.ravel(u_body))).reshape(-1, 3)
        if basis is not None:
            body = basis.displacement(body).reshape(-1, 3)
        partner = body - np.reshape(u_c, (-1, 3))
        if system.moved:         # a force-controlled foundation: u_c's normal part omits the translation's
            partner = partner + system.moved * self.model.obstacle_force.gap_rate[:, None] * [0.0, 0.0, 1.0]
        return FoundationState(u_body_c=body, u_partner=partner,
                               displacement=self._foundation_displacement(system, u_c, r))

    def _foundation_displacement(self, system, u_c, r):
        """The foundation's displacement of a state as a function of no arguments, computed when an
        output reads it (:class:`~contactopt.contact.state.FoundationState`): it holds only the
        run's foundation and a few contact vectors (the counterparts' support displacement o,
        formed here), not the design's factorizations."""
        f = system.coupling.foundation
        if f.ell_o is None:            # one foundation: its own solve under −Πᵀr
            return partial(f.displacement, np.array(r), system.moved)
        o = system.coupling.support_displacement(np.ravel(u_c), system.ell, r)
        return lambda: np.concatenate(f.recovered(o, system.moved))

    def load_scale(self, system):
        return system.contact_ell

    def own_block(self, system, zone):
        if system.compliant:
            return CoupledZoneProblem(system.S, system.coupling.foundation.C, system.ell, system.law_offset, zone).W
        return zone_rules.ZoneProblem(system.law_S, system.law_ell, zone).W

    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None, carry=None):
        """(v_u, v_λ, ṽ) of (4.15); on a foundation (4.15) is solved with S_eff and ṽ extends
        z = S⁻¹ S_eff v_u (module docstring).

        ∂J/∂u on every DOF of the body (g) on a foundation: J depends on the state's w through
        the body's u_c = w + Π q_f − C r, r = S_eff w − ℓ_eff, so u_c = S⁻¹S_eff w + … and with
        y_c = g_c − A_ci A_ii⁻¹ g_i (4.15) takes y*_u = S_eff S⁻¹ y_c; at fixed w, r and with it
        u_c move with α: g·δu gains −y_cᵀC δr = −(S⁻¹S_eff C y_c)ᵀ(∂A u − ∂L)… extended, so
        z = S⁻¹S_eff (v_u − C y_c) (docs/foundation.md). ``carry`` (3p, per node (t1, t2, ν)), with
        g on every DOF on a foundation: what a later load step passes down, a derivative with
        respect to w itself (the next step's slip reference is w_t), which joins y*_u after that
        map, not g (:meth:`SolverPath.adjoint`).

        A :attr:`~CondensedSystem.compliant` system with ∂J/∂u on the contact DOFs solves (4.15)
        in W-form instead (:meth:`_compliant_adjoint`): the same v_u, v_λ without S_eff."""
        if system.compliant and not self.is_full(y_u):
            return self._compliant_adjoint(system, ctx, state, y_u, y_lam, choices)
        zhat = y_c = None
        if self.is_full(y_u):          # ∂J/∂u on every DOF (SolverPath.adjoint): ẑ = (0, A_ii⁻¹g_i)
            fac, asm = system.factor, self.model.assembler
            g = np.asarray(y_u, float)[asm.free]
            zhat = np.zeros(g.size)
            zhat[fac.interior] = fac.solve_interior(g[fac.interior])
            y_u = g[fac.c] - (system.assembled.A @ zhat)[fac.c]
            if self.mechanics.rotate is not None:   # global components at the contact nodes: into their frames
                y_u = self.mechanics.rotate.vector(y_u)
            if self.mechanics.basis is not None:    # ... and into the transformed basis
                y_u = self.mechanics.basis.vector(y_u)
            if isinstance(system.coupling, FacesCoupling):
                raise SolverError("an objective of the body's whole displacement is not taken with faces on several "
                                  "bodies so far (contacts: a pair's face off the face body)")
            if system.coupling is not None:  # ∂J/∂w of the body's contact displacement
                y_c, y_u = y_u, system.coupling.to_eff(y_u)
                if carry is not None:
                    y_u = y_u + carry
        v_u, v_lam = solve_adjoint(system.contact_S, state, y_u, y_lam, choices)
        if system.coupling is None:
            z = v_u
        else:
            C = system.coupling.foundation.C
            if y_c is not None and C is None:
                raise SolverError("an objective of the body's whole displacement needs the compliance of its "
                                  "counterparts, and a counterpart held only by its contacts has none")
            z = system.coupling.adjoint_z(v_u if y_c is None else v_u - C @ y_c)
        if self.mechanics.basis is not None:
            z = self.mechanics.basis.back(z)
        if self.mechanics.rotate is not None:
            z = self.mechanics.rotate.back(z)
        v = system.factor.extend(z)
        if zhat is not None:
            v = v - zhat
        out = Adjoint(v_u, v_lam, self.model.assembler.to_full(v))
        if self.model.cp_designs is not None:      # the adjoint's contact force s = S_eff v_u (fem.cpdesigns)
            s = system.contact_S @ v_u if y_c is None else system.contact_S @ (v_u - C @ y_c) + y_c
            self._counterpart_terms(system, state, s, out.v)
        return out

    def _compliant_adjoint(self, system, ctx, state, y_u, y_lam, choices) -> Adjoint:
        """(4.15) in W-form, solved directly (:func:`~contactopt.sensitivity.adjoint.solve_adjoint_compliant`):
        its unknown s = S_eff v_u on the nodes in contact K, v_u = W s = S⁻¹s + C s, and the design
        terms' z = S⁻¹ S_eff v_u = S⁻¹ s, all with the factor of S of the state's zone problem, whose
        block W_Z holds W_KK (K lies in the zone: every node outside it is of class L)."""
        coupling = system.coupling
        zp = coupling.zone_problem
        if zp is None:                 # no state solved on this design's factor here
            zp = self._coupled_zone(system, np.flatnonzero(state.classes != CLASS_CODES["L"]))
        C = coupling.foundation.C

        def apply(s):
            x = zp.body_solve(s)
            return x + C @ s, x

        def block(K):
            src = zp if np.all(np.isin(K, zp.zone, assume_unique=True)) else zp.grow(K)
            pos = np.searchsorted(src.zone, K)
            dof = (3 * pos[:, None] + FROM_FCLIB).ravel()        # FCLIB -> (t1, t2, ν)
            return src.W[np.ix_(dof, dof)]

        v_u, v_lam, s, z = solve_adjoint_compliant(block, apply, state, y_u, y_lam, choices)
        ctx.adjoint_s = (v_u, s)           # S_eff v_u, for the previous load step (adjoint_force)
        if self.mechanics.basis is not None:
            z = self.mechanics.basis.back(z)
        if self.mechanics.rotate is not None:
            z = self.mechanics.rotate.back(z)
        out = Adjoint(v_u, v_lam, self.model.assembler.to_full(system.factor.extend(z)))
        if self.model.cp_designs is not None:
            self._counterpart_terms(system, state, s, out.v)
        return out

    def _counterpart_terms(self, system, state, s: np.ndarray, v_full: np.ndarray) -> None:
        """The design terms of the counterparts' designs at this adjoint (s its contact force per
        node frame), kept on the system for :meth:`design_contraction` (fem.cpdesigns)."""
        r = np.column_stack([-state.tau, state.lam])
        cp = self.model.cp_designs
        system.counterpart_terms = (v_full, cp.design_terms(system.coupling.foundation, r, s, self.model.n_design))

    def design_contraction(self, system, u_full, v_full, loads=None) -> np.ndarray:
        """The face body's design terms, plus the counterparts' designs' of the adjoint ``v_full``."""
        out = super().design_contraction(system, u_full, v_full, loads)
        kept = system.counterpart_terms
        if kept is not None and kept[0] is v_full:
            out = out + kept[1]
        return out

    def law_extension(self, system, x: np.ndarray) -> np.ndarray:
        """The A-harmonic extension, on every DOF, of the body's contact displacement that the
        law's displacement x (3p, per node frame) gives at fixed forces: S⁻¹ S_eff x on a
        foundation (:meth:`~contactopt.fem.foundation.Coupling.adjoint_z`), x itself elsewhere."""
        z = x if system.coupling is None else system.coupling.adjoint_z(x)
        if self.mechanics.rotate is not None:
            z = self.mechanics.rotate.back(z)
        return self.model.assembler.to_full(system.factor.extend(z))

    def adjoint_force(self, system, ctx, v_u):
        kept = getattr(ctx, "adjoint_s", None)      # the W-form adjoint's s = S_eff v_u
        if kept is not None and kept[0] is v_u:
            return kept[1]
        return system.contact_S @ v_u

    def global_contact(self, v):
        """A contact vector conjugate to u_c (a force, ∂J/∂u_c) in global components: Q v in the
        nodes' frames, V⁻¹ v in the transformed basis."""
        if self.mechanics.basis is not None:
            v = self.mechanics.basis.force(v)
        rot = self.mechanics.rotate
        return v if rot is None else rot.back(np.asarray(v))

    def adjoint_carry(self, system, ctx, v_u, v_full, y_u):
        """As :meth:`SolverPath.adjoint_carry`, in the nodes' frames on an obstacle (the load
        steps' tangential reference is per node frame)."""
        out = super().adjoint_carry(system, ctx, v_u, v_full, y_u)
        if self.mechanics.rotate is not None and self.is_full(y_u):
            out = self.mechanics.rotate.vector(out)
        if self.mechanics.basis is not None and self.is_full(y_u):
            out = self.mechanics.basis.vector(out)
        return out

    def uniqueness_bound(self, system):
        """F0 = λ_min(S)/λ_max(S) of the bound (3.16) applied to the condensed system: with A := S,
        N and T select components so β = ‖T‖ = 1. Known to be very pessimistic."""

        if system.rigid is not None:
            return None, ("the body is held only by contact: its condensed stiffness S is singular, and the "
                          "bound (3.16) needs λ_min(S) > 0")
        S = system.contact_S
        keep = ~self.model.contact_pinned.ravel()
        if not np.all(keep):           # pinned DOFs: decoupled diagonal entries, no contact law
            S = np.ascontiguousarray(S[np.ix_(keep, keep)])
        lmax = eigsh(S, k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        wmax = eigsh(spd_inverse(S), k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        return float((1.0 / wmax) / lmax), None


def shifted(system: CondensedSystem, shift: np.ndarray) -> CondensedSystem:
    """The system whose contact law sees the displacement relative to an obstacle translated
    tangentially by ``shift`` (3p, per node frame, normal parts 0): w = u_c − shift, so
    S w − ℓ_eff = r with ℓ_eff = ℓ − S shift; the body's own u_c is w + shift. On an elastic
    foundation translated by a force (:mod:`.force`) the law's w is relative to the partners and
    its stiffness S_eff: ℓ_eff = S_eff (S⁻¹ℓ − Π q_f) − S_eff shift."""
    if system.coupling is None:
        return replace(system, shift=shift, ell_eff=system.ell - system.S @ shift)
    return replace(system, shift=shift, ell_eff=system.coupling.ell_eff(system.ell) - system.S_eff @ shift)
