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
inverse of S. Without a foundation (C = 0) nothing of this is formed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..contact import zone as zone_rules
from ..fem import memory
from ..fem.model import Assembled
from .zone_paths import ZonePath


@dataclass
class CondensedSystem:
    """One design's condensed system: ``factor`` the condensation (S, ℓ and the recovery of
    the interior DOFs), ``S`` (3p, 3p) and ``ell`` (3p,) per node (t1, t2, ν), ``gap`` (p,)."""

    assembled: Assembled
    factor: object
    S: np.ndarray
    ell: np.ndarray
    gap: np.ndarray
    timings: dict
    coupling: object = None            # on an elastic foundation: fem.foundation.Coupling, S_eff ...
    ell_eff: np.ndarray | None = None  # ... and ℓ_eff = S_eff (S⁻¹ℓ − Π q_f) (module docstring)

    @property
    def S_eff(self):
        return None if self.coupling is None else self.coupling.S_eff

    @property
    def contact_S(self) -> np.ndarray:
        """The stiffness of the contact law's displacement: S, or S_eff on an elastic foundation."""
        return self.S if self.S_eff is None else self.S_eff

    @property
    def contact_ell(self) -> np.ndarray:
        return self.ell if self.ell_eff is None else self.ell_eff


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

    def __init__(self, model, settings):
        super().__init__(model, settings)
        self._factor = None      # the condensation, refactored in place for each new design

    @classmethod
    def memory_estimate(cls, body, **kw):
        est = memory.estimate_evaluation(body, memory.condensation_parts)
        foundation = getattr(body, "foundation", None)       # a model's elastic foundation
        return est if foundation is None else est.with_parts(foundation.memory_parts)

    def prepare(self, asm) -> CondensedSystem:
        from ..fem.linsolve import condense
        t1 = time.perf_counter()
        fac = self._factor
        if fac is not None and hasattr(fac, "refactor"):
            fac.refactor(asm.A, trusted=True)     # symmetric, positive diagonal: assembled
        else:
            fac = self._factor = condense(asm.A, self.model.contact_dofs, backend=self.library)
        system = CondensedSystem(asm, fac, fac.S, fac.condense_load(asm.L), asm.gap, {})
        if self.foundation is not None:
            from ..fem.foundation import Coupling
            system.coupling = Coupling(system.S, self.foundation)
            system.ell_eff = system.coupling.ell_eff(system.ell)
        system.timings["schur"] = time.perf_counter() - t1
        return system

    @property
    def foundation(self):
        return getattr(self.model, "foundation", None)

    def for_load(self, system, asm) -> CondensedSystem:
        t1 = time.perf_counter()
        ell = system.factor.condense_load(asm.L)
        out = replace(system, assembled=asm, ell=ell, timings={})
        if out.coupling is not None:
            out.ell_eff = out.coupling.ell_eff(ell)
        out.timings["schur"] = time.perf_counter() - t1
        return out

    def zone_problem(self, system, zone, warm, reuse, shared):
        if reuse and "zone" in shared:
            return on_factor(shared["zone"], system.contact_ell, zone), zone
        zp = zone_rules.ZoneProblem(system.contact_S, system.contact_ell, zone, ordered=not reuse)
        if reuse:
            shared["zone"] = zp
        return zp, zone

    def free_displacement(self, system, zp, r_loc, u_body):
        return system.factor.recover(system.assembled.L, u_body)

    def body_contact_displacement(self, system, u_c, r):
        """On a foundation u_c is the relative displacement w; the body's own is w + Π u_f."""
        if system.coupling is None:
            return np.ravel(u_c)
        return system.coupling.body_displacement(u_c, r)

    def contact_info(self, system, u_c, r, u_body) -> dict:
        """On a foundation: the body's contact displacement and its partners' (p, 3) per node
        (t1, t2, ν); w = u_c − partner is the state's ``u_c``."""
        if system.coupling is None:
            return {}
        body = u_body.reshape(-1, 3)
        return {"foundation": True, "u_body_c": body, "u_partner": body - u_c,
                "foundation_u": self.foundation.displacement(r)}

    def load_scale(self, system):
        return system.contact_ell

    def own_block(self, system, zone):
        return zone_rules.ZoneProblem(system.contact_S, system.contact_ell, zone).W

    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None):
        """(v_u, v_λ, ṽ) of (4.15); on a foundation (4.15) is solved with S_eff and ṽ extends
        z = S⁻¹ S_eff v_u (module docstring)."""
        from ..sensitivity.adjoint import solve_adjoint
        v_u, v_lam = solve_adjoint(system.contact_S, state, y_u, y_lam, choices)
        z = v_u if system.coupling is None else system.coupling.adjoint_z(v_u)
        return v_u, v_lam, self.model.assembler.to_full(system.factor.extend(z))

    def adjoint_force(self, system, ctx, v_u):
        return system.contact_S @ v_u

    def uniqueness_bound(self, system):
        """F0 = λ_min(S)/λ_max(S) of the bound (3.16) applied to the condensed system: with A := S,
        N and T select components so β = ‖T‖ = 1. Known to be very pessimistic."""
        from scipy.sparse.linalg import eigsh

        from ..fem.dense import spd_inverse
        S = system.contact_S
        keep = ~self.model.contact_pinned.ravel()
        if not np.all(keep):           # pinned DOFs: decoupled diagonal entries, no contact law
            S = np.ascontiguousarray(S[np.ix_(keep, keep)])
        lmax = eigsh(S, k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        wmax = eigsh(spd_inverse(S), k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        return float((1.0 / wmax) / lmax), None
