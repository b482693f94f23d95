"""The condensation path: the Schur complement S of A(α) onto all contact DOFs, dense.

Condensed contact system (paper (3.17)), per contact node m in the order (t1, t2, ν) = (x1, x2, x3):
    r = S u_c − ℓ  is the contact force on the body, λ = r_ν ≥ 0, τ = −r_t,
    u_ν + g ≥ 0, λ(u_ν + g) = 0, ‖τ‖ ≤ Fλ, u_t ≠ 0 ⇒ τ = Fλ u_t/‖u_t‖,
handed to the local solvers on the contact zone with W = S⁻¹ (:mod:`.zone_paths`). A(α), its
factorization and S do not depend on the load: a design is condensed once (PARDISO's ordering and
analysis reused from design to design, the pattern never changes with α), and each load case adds
ℓ_k. The adjoint (4.15) is the dense system of :func:`contactopt.sensitivity.adjoint.solve_adjoint`.
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
        return memory.estimate_evaluation(body, memory.condensation_parts)

    def prepare(self, asm) -> CondensedSystem:
        from ..fem.linsolve import condense
        t1 = time.perf_counter()
        fac = self._factor
        if fac is not None and hasattr(fac, "refactor"):
            fac.refactor(asm.A, trusted=True)     # symmetric, positive diagonal: assembled
        else:
            fac = self._factor = condense(asm.A, self.model.contact_dofs, backend=self.library)
        t2 = time.perf_counter()
        return CondensedSystem(asm, fac, fac.S, fac.condense_load(asm.L), asm.gap, {"schur": t2 - t1})

    def for_load(self, system, asm) -> CondensedSystem:
        t1 = time.perf_counter()
        ell = system.factor.condense_load(asm.L)
        return replace(system, assembled=asm, ell=ell, timings={"schur": time.perf_counter() - t1})

    def zone_problem(self, system, zone, warm, reuse, shared):
        if reuse and "zone" in shared:
            return on_factor(shared["zone"], system.ell, zone), zone
        zp = zone_rules.ZoneProblem(system.S, system.ell, zone, ordered=not reuse)
        if reuse:
            shared["zone"] = zp
        return zp, zone

    def free_displacement(self, system, zp, r_loc, u_c):
        return system.factor.recover(system.assembled.L, u_c.ravel())

    def load_scale(self, system):
        return system.ell

    def own_block(self, system, zone):
        return zone_rules.ZoneProblem(system.S, system.ell, zone).W

    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None):
        from ..sensitivity.adjoint import solve_adjoint
        v_u, v_lam = solve_adjoint(system.S, state, y_u, y_lam, choices)
        return v_u, v_lam, self.model.assembler.to_full(system.factor.extend(v_u))

    def uniqueness_bound(self, system):
        """F0 = λ_min(S)/λ_max(S) of the bound (3.16) applied to the condensed system: with A := S,
        N and T select components so β = ‖T‖ = 1. Known to be very pessimistic."""
        from scipy.sparse.linalg import eigsh

        from ..fem.dense import spd_inverse
        lmax = eigsh(system.S, k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        wmax = eigsh(spd_inverse(system.S), k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        return float((1.0 / wmax) / lmax), None
