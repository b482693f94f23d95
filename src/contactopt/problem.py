"""The shape problem of a configuration: state solves and the oracle Θ(α), ∂Θ(α).

Data flow (DESIGN.md §8): α → mesh → A(α), L(α) → Schur complement S, ℓ on the contact DOFs →
Coulomb contact state → objective → adjoint (4.15) → subgradient.

Condensed contact system (paper (3.17)), per contact node m in the order (t1, t2, ν) = (x1, x2, x3):
    r = S u_c − ℓ  is the contact force on the body, λ = r_ν ≥ 0, τ = −r_t,
    u_ν + g ≥ 0, λ(u_ν + g) = 0, ‖τ‖ ≤ Fλ, u_t ≠ 0 ⇒ τ = Fλ u_t/‖u_t‖.
It is handed to the local solvers in the FCLIB convention (normal first): with W = S⁻¹,
    u_loc = P(u_c) + (g, 0, 0) = W_loc r_loc + q,   W_loc = P W Pᵀ,  q = P W ℓ + (g, 0, 0),
where P reorders each node's (t1, t2, ν) to (ν, t1, t2); the FCLIB friction law r_T = −μ r_N u_T/‖u_T‖
is exactly the Coulomb law above. The local problem is solved on the contact zone, the nodes near
the foundation, with W_loc the zone's block of W (:mod:`contactopt.contact.zone`; ``[state] zone``).
Newton builds its matrices from the block W_loc of an earlier design, kept in single precision,
while products W_loc r are exact (triangular solves in double precision with the zone's Cholesky
factor), so the block is formed only when it has drifted from the current one
(``[state] reuse_delassus``; :meth:`ShapeProblem._solve_local`).

Load cases (:mod:`contactopt.sensitivity.cases`): A(α), its factorization and S do not depend on
the load, so a design is assembled and condensed once, and each case adds its load vector L_k,
ℓ_k and its own contact solve. Each case carries its own warm start, contact zone and kept
Delassus block from design to design (:class:`CaseContext`); a configuration without cases is
the list of one case.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from ._threads import sequential_openblas
from .config import Config, load_config
from .contact import zone as zone_rules
from .contact.state import State, classify_nodes, contact_conditions_violation, displacement_scale
from .errors import SolverError
from .fem.model import Assembled, ElasticModel

log = logging.getLogger(__name__)

REUSE_MAX_STEPS = 12   # a solve with a kept Delassus block that needs more steps drops it
REUSE_MAX_GAP = 0.2      # kept blocks farther than this from the new W_Z (relative) are not used
FULLSPACE_TOL = 1e-10    # the full-space Newton's Siconos error and equilibrium residual (at
                         # least): its GMRES then runs to 1e-11, near the AMG V-cycle's floor
HIERARCHY_SEED = 20090101   # NumPy's global generator while pyamg builds a hierarchy
CHORD_MIN_GAP = 1e-3     # below this gap Newton is nearly quadratic: no chord steps
JACOBIAN_DTYPE = np.float32  # a kept block only builds Newton matrices, and is 1e-3–0.2 off the
                             # current W_Z anyway: single precision halves the memory traffic of
                             # those matrices and the time of their LU
DELASSUS_NEW_NODES = 24  # Delassus path: new nodes whose exact columns (3 sparse solves each, as
                         # one block) extend a kept block; 72 columns ≈ 1.5–2 factorizations at
                         # 113k DOFs, about the cost of the zone's Schur complement
ADJOINT_MAX_NEW = 0.1    # the adjoint's preconditioner takes exact columns for at most this
                         # fraction of nodes outside the kept block, else the zone's Schur complement
REUSE_TOL_FACTOR = 0.1   # and it iterates to this times tol: exact Newton's last, quadratic
                         # step usually overshoots far below tol; an inexact Jacobian converges
                         # linearly and would otherwise stop just below it


@dataclass
class Condensed:
    """The condensed system of one design (see the module docstring).

    On the Delassus path (large meshes, ``[linear_solver] backend = "delassus"``) nothing is
    condensed: ``factor`` is the sparse Cholesky factorization of A(α), ``S`` and ``ell`` are None,
    and ``x0`` = A(α)⁻¹L(α) (free DOFs) is the displacement without contact forces, so that
    W = S⁻¹ = B A⁻¹ Bᵀ and S⁻¹ℓ = (x0)_c (:class:`~contactopt.contact.zone.DelassusZoneProblem`)."""

    assembled: Assembled
    factor: object           # contactopt.fem.linsolve condensed factorization (or Factorization)
    S: np.ndarray | None     # (3p, 3p), per node (t1, t2, ν)
    ell: np.ndarray | None   # (3p,)
    gap: np.ndarray          # (p,)
    timings: dict
    x0: np.ndarray | None = None   # Delassus path: A⁻¹L on the free DOFs
    path: str = "schur"            # "schur", "delassus" or "amg" (full space: nothing factorized)

    @property
    def delassus(self) -> bool:
        """Whether this design is on the Delassus path (no S, a sparse factorization of A)."""
        return self.path == "delassus"


@dataclass
class CaseContext:
    """What one load case carries from design to design: ``warm`` its last contact forces
    ((p, 3) per node (N, T1, T2)), ``next_zone`` the zone of its next state solve,
    ``jacobian`` (alpha, zone, W_Z) of its kept Delassus block."""

    warm: np.ndarray | None
    next_zone: np.ndarray
    jacobian: tuple | None = None
    u_free: np.ndarray | None = None   # full-space path: the last displacement (free DOFs)


def spd_inverse(S: np.ndarray) -> np.ndarray:
    """Inverse of a dense SPD matrix by Cholesky (see :func:`contactopt.fem.dense.spd_inverse`)."""
    from .fem.dense import spd_inverse as inverse
    return inverse(S)


def _on_factor(zp, ell: np.ndarray, zone: np.ndarray):
    """The zone problem of another load ℓ and zone on the Cholesky factor of S that ``zp`` holds
    in S's own order (``ordered=False``): that factor depends on neither, so the load cases of a
    design share it. The same numbers as ``ZoneProblem(S, ell, zone, ordered=False)``."""
    out = object.__new__(zone_rules.ZoneProblem)
    out.p, out._S, out._L, out._order, out._start, out._parent = zp.p, zp._S, zp._L, None, 0, None
    out._set_zone(np.asarray(zone), None, out.solve(ell))
    return out


class ShapeProblem:
    """Discrete shape optimization problem (P̃) of a configuration.

    ``solve_state(alpha)`` returns the :class:`~contactopt.contact.state.State`;
    ``evaluate(alpha)`` returns (Θ(α), one Clarke subgradient) — see
    :mod:`contactopt.sensitivity.adjoint`.
    """

    def __init__(self, config, *, method: str | None = None, backend: str | None = None):
        self.config = config if isinstance(config, Config) else load_config(config)
        self.model = ElasticModel(self.config)
        self.friction = float(self.config["friction"]["coefficient"])
        st = self.config["state"]
        self.method = method or st["method"]
        self.tol = st["tol"]
        self.max_iter = st["max_iter"]
        from .fem.model import _legacy
        self.backend = backend or _legacy(self.config["linear_solver"])
        from .fem.linsolve import linear_path
        # "schur" (dense S on all contact DOFs), "delassus" (sparse Cholesky of A, products by
        # solves) or "amg" (full space): [linear_solver] backend, "auto" by the size of the mesh
        # and the memory available (the model's choice)
        if backend is None and self.model.path == "schur":
            self.path = "schur"
            self.backend = self.backend if self.backend in ("pardiso", "scipy") else "auto"
        else:
            self.path, self.backend = linear_path(backend or self.model.path, self.model.assembler.n_free,
                                                  self.config["objective"]["type"],
                                                  self.config["linear_solver"]["crossover"])
        self.use_zone = bool(st["zone"])
        self.zone_margin = float(st["zone_margin"])
        self.reuse_delassus = bool(st["reuse_delassus"])
        self.n_delassus = 0        # Delassus blocks W_Z formed (the others were reused)
        p = self.model.n_contact
        self._all_nodes = np.arange(p)
        self.n_zone_misses = 0     # zone problems solved again on a grown zone
        # (alpha bytes, Condensed, State of case 0, (Condensed per case, State per case))
        self._cache = None
        self._factor = None        # the condensation, refactored in place for each new design
        self._slot = None          # Delassus path: the factorization a design's solves go through
        self._keep_cholesky = True
        if self.path == "delassus":
            from .fem.memory import keeps_cholesky
            self._keep_cholesky = keeps_cholesky(self.model)
        self._hierarchy = None     # full-space path: the AMG hierarchy of an earlier A(α) ...
        self._hierarchy_alpha = None   # ... built at this design (checkpoints rebuild it)
        self.n_state_solves = 0    # designs solved (all cases at once)
        from .sensitivity.cases import build_cases
        self.cases, self.combination = build_cases(self.config, self)
        self.contexts = [CaseContext(None, self._all_nodes) for _ in self.cases]

    # ------------------------------------------------------------------ load cases
    @property
    def objective(self):
        """The objective of the first load case (the objective, without cases)."""
        return self.cases[0].objective

    @property
    def has_load_cases(self) -> bool:
        """Whether the configuration lists [[load_cases]] (else one case of [loads])."""
        return bool(self.config.data.get("load_cases"))

    @property
    def case_names(self) -> tuple:
        return self.combination.names

    # the first case's context under the names of a problem without cases
    _warm = property(lambda self: self.contexts[0].warm,
                     lambda self, v: setattr(self.contexts[0], "warm", v))
    next_zone = property(lambda self: self.contexts[0].next_zone,
                         lambda self, v: setattr(self.contexts[0], "next_zone", v))
    _jacobian = property(lambda self: self.contexts[0].jacobian,
                         lambda self, v: setattr(self.contexts[0], "jacobian", v))

    # ------------------------------------------------------------------ condensation
    def condensed_system(self, alpha) -> Condensed:
        from .fem.linsolve import condense
        t0 = time.perf_counter()
        asm = self.model.assemble(alpha, self.cases[0].loads)
        t1 = time.perf_counter()
        if self.path == "delassus":
            return self._factorized_system(asm, t1 - t0)
        if self.path == "amg":        # full space: A(α) is used as it is
            return Condensed(asm, None, None, None, asm.gap, {"assembly": t1 - t0}, path="amg")
        # the sparsity pattern never changes with α: reuse PARDISO's ordering and analysis
        fac = self._factor
        if fac is not None and hasattr(fac, "refactor"):
            fac.refactor(asm.A, trusted=True)     # symmetric, positive diagonal: assembled
        else:
            fac = condense(asm.A, self.model.contact_dofs, backend=self.backend)
            self._factor = fac
        t2 = time.perf_counter()
        ell = fac.condense_load(asm.L)
        return Condensed(asm, fac, fac.S, ell, asm.gap, {"assembly": t1 - t0, "schur": t2 - t1})

    def _factorized_system(self, asm, t_assembly: float) -> Condensed:
        """The Delassus path's system of a design: the sparse Cholesky factorization of A(α),
        numerical only after the first design (the pattern never changes with α), and x0 = A⁻¹L."""
        from .fem.linsolve import Factorization, SolverSlot
        t0 = time.perf_counter()
        fac = self._factor
        if fac is None:           # the first design, or the Cholesky was released (_zone_block)
            fac = self._factor = Factorization(asm.A, self.backend)
        else:
            fac.refactor(asm.A)
        if self._slot is None:
            self._slot = SolverSlot()
        self._slot.set(fac)       # releases the last design's zone condensation, if any
        t1 = time.perf_counter()
        x0 = fac.solve(asm.L)
        return Condensed(asm, self._slot, None, None, asm.gap,
                         {"assembly": t_assembly, "factor": t1 - t0, "load_solve": time.perf_counter() - t1},
                         x0=x0, path="delassus")

    def _zone_block(self, A):
        """``dofs -> S_D``: the dense Schur complement of A onto the DOFs ``dofs`` (in their
        order), by a factorization that eliminates them last (Delassus path: W_Z = S_D⁻¹).

        Where both factors would not fit in memory together (:func:`contactopt.fem.memory.keeps_cholesky`;
        at 371k DOFs: 4.5 GB and 7 GB), the Cholesky factorization of A is released first; the
        condensation then serves the design's remaining solves
        (:class:`~contactopt.fem.linsolve.SolverSlot`), and the next design factorizes anew
        (ordering included) instead of numerically only."""
        from .fem.linsolve import condense

        def block(dofs):
            t0 = time.perf_counter()
            slot = self._slot
            released = (not self._keep_cholesky and self._factor is not None
                        and slot.current is self._factor)
            if released:
                self._factor.close()
                self._factor = None
            fac = condense(A, dofs, backend=self.backend)
            S = fac.S
            if released:
                slot.current = fac
            else:
                fac.close()
            log.debug("Schur complement onto %d zone DOFs: %.2f s", len(dofs), time.perf_counter() - t0)
            return S
        return block

    def _case_condensed(self, cond: Condensed, k: int) -> Condensed:
        """The condensed system of load case k: ``cond`` (of case 0) with L_k and ℓ_k (on the
        Delassus path: x0_k = A⁻¹L_k)."""
        if k == 0:
            return cond
        t0 = time.perf_counter()
        asm = cond.assembled
        L_full = self.model.load_vector(asm.coords, self.cases[k].loads)
        L = L_full[self.model.assembler.free]
        t1 = time.perf_counter()
        asm_k = replace(asm, L_full=L_full, L=L)
        if cond.path == "amg":
            return replace(cond, assembled=asm_k, timings={"assembly": t1 - t0})
        if cond.delassus:
            return replace(cond, assembled=asm_k, x0=cond.factor.solve(L),
                           timings={"assembly": t1 - t0, "load_solve": time.perf_counter() - t1})
        ell = cond.factor.condense_load(L)
        return replace(cond, assembled=asm_k, ell=ell,
                       timings={"assembly": t1 - t0, "schur": time.perf_counter() - t1})

    # ------------------------------------------------------------------ state
    def solve_state(self, alpha, *, method: str | None = None, warm_start: bool = True,
                    tol: float | None = None, case: int = 0) -> State:
        """Solve the discrete Coulomb problem (P) at α (α need not be in U, but the mesh must be
        valid) for every load case; returns the state of load case ``case``."""
        with sequential_openblas():
            return self._solve_state(alpha, method, warm_start, tol)[case]

    def solve_states(self, alpha, **kw) -> list[State]:
        """The states of every load case at α (one condensation; see :meth:`solve_state`)."""
        self.solve_state(alpha, **kw)
        return list(self._cache[3][1])

    def _solve_state(self, alpha, method, warm_start, tol) -> list[State]:
        alpha = self.model.surface.as_vector(alpha)
        if not np.all(np.isfinite(alpha)):
            raise SolverError("design contains NaN or infinite entries")
        key = alpha.tobytes()
        method = method or self.method
        if self._cache is not None and self._cache[0] == key and self._cache[2].method == method:
            return self._cache[3][1]
        cond = self.condensed_system(alpha)
        conds = [self._case_condensed(cond, k) for k in range(len(self.cases))]
        shared = {}                # S's Cholesky factor in its own order, for every case
        states = [self._solve_case(k, ck, alpha, method, warm_start, tol, shared) for k, ck in enumerate(conds)]
        self._cache = (key, cond, states[0], (conds, states))
        self.n_state_solves += 1
        return states

    def _solve_case(self, k, cond, alpha, method, warm_start, tol, shared) -> State:
        """The contact state of load case k on its condensed system ``cond``, warm-started from
        the case's own context (warm start, zone, kept Delassus block)."""
        ctx = self.contexts[k]
        if cond.path == "amg":
            return self._solve_case_fullspace(k, cond, alpha, warm_start, tol)
        timings = dict(cond.timings, delassus=0.0, contact=0.0)
        zone = ctx.next_zone if self.use_zone else self._all_nodes
        warm = ctx.warm if warm_start else None
        misses = 0
        reused = []
        t0 = time.perf_counter()
        # a kept Delassus block will most likely serve Newton: the products need no W_Z
        reuse = method == "newton" and self.reuse_delassus and ctx.jacobian is not None
        if cond.delassus:
            if warm is None and self.use_zone and zone.size == self._all_nodes.size:
                zone = self._predicted_zone(cond)
            if "zone" in shared:
                zp = shared["zone"].with_load(cond.x0, zone)
            else:
                zp = shared["zone"] = zone_rules.DelassusZoneProblem(
                    cond.factor, self.model.contact_dofs, cond.x0, zone, self._zone_block(cond.assembled.A))
        elif reuse and "zone" in shared:
            zp = _on_factor(shared["zone"], cond.ell, zone)
        else:
            zp = zone_rules.ZoneProblem(cond.S, cond.ell, zone, ordered=not reuse)
            if reuse:
                shared["zone"] = zp
        t1 = time.perf_counter()
        while True:
            res, t_inv, how = self._solve_local(zp, cond, warm, method, tol, alpha, ctx)
            reused.append(how)
            u3 = zp.displacements(res.r)
            timings["delassus"] += t1 - t0 + t_inv
            timings["contact"] += time.perf_counter() - t1 - t_inv
            clearance = u3[:, 2] + cond.gap
            u_scale = displacement_scale(u3, cond.gap)
            missed = zone_rules.missed_nodes(zone, clearance, u_scale)
            if missed.size == 0:
                break
            misses += 1
            lam_all = np.zeros(cond.gap.size)
            lam_all[zone] = res.r[0::3]
            log.debug("contact zone of %d nodes missed %d node(s) closing their gap; solving again",
                      zone.size, missed.size)
            t0 = time.perf_counter()
            zp = zp.grow(np.union1d(missed, zone_rules.near_nodes(lam_all, clearance, u_scale,
                                                                 self.zone_margin)))
            t1 = time.perf_counter()
            warm = self._zone_warm(res.r, zone)
            zone = zp.zone
        t3 = time.perf_counter()
        if cond.delassus:
            u_free = zp.free_displacement(res.r)
        else:
            u_free = cond.factor.recover(cond.assembled.L, u3.ravel())
        u = self.model.assembler.to_full(u_free)
        timings["recovery"] = time.perf_counter() - t3
        p = self.model.n_contact
        r = np.zeros((p, 3))                      # per node (t1, t2, ν)
        r[zone] = res.r.reshape(-1, 3)[:, [1, 2, 0]]
        lam, tau = r[:, 2].copy(), -r[:, :2]
        # with nothing in contact, forces count as zero against the load (ℓ; on the Delassus
        # path, without ℓ, the load on the contact DOFs' stiffness scale: |S u0| ≈ |L| there)
        load = cond.ell if not cond.delassus else cond.assembled.L
        fscale = max(np.abs(lam).max(initial=0.0), np.abs(load).max(initial=0.0))
        classes = classify_nodes(u3, lam, tau, cond.gap, self.friction,
                                 force_scale=fscale if lam.max(initial=0) <= 0 else None)
        timings["total"] = sum(timings.values())
        state = State(alpha=alpha, coords=cond.assembled.coords, u=u, u_c=u3, lam=lam, tau=tau,
                      gap=cond.gap, classes=classes, friction=self.friction, method=method,
                      iterations=res.iterations, residual=res.error,
                      complementarity=contact_conditions_violation(u3, lam, tau, cond.gap, self.friction),
                      converged=res.converged, timings=timings,
                      info={"backend": getattr(cond.factor, "backend", "?"), "path": self.path,
                            "zone_nodes": int(zone.size),
                            "zone_misses": misses, "delassus": reused[-1],
                            **({"sparse_solves": zp.n_solves} if cond.delassus else {})})
        ctx.warm = self._zone_warm(res.r, zone)
        if self.use_zone:
            ctx.next_zone = zone_rules.near_nodes(lam, clearance, u_scale, self.zone_margin)
        self.n_zone_misses += misses
        log.debug("state%s: %s %d it, residual %.2e, zone %d/%d nodes, %.3f s",
                  f" of load case {self.cases[k].name}" if len(self.cases) > 1 else "", method,
                  res.iterations, res.error, zone.size, p, timings["total"])
        return state

    def _solve_case_fullspace(self, k, cond, alpha, warm_start, tol) -> State:
        """The contact state of load case k in full space (``[linear_solver] backend = "amg"``):
        :func:`contactopt.contact.fullspace.solve_fullspace`, a semismooth Newton method on all
        free DOFs with AMG-preconditioned GMRES, warm-started from the case's last forces and
        displacement, the AMG hierarchy of an earlier design reused (``self._hierarchy``)."""
        from .contact.fullspace import solve_fullspace
        ctx = self.contexts[k]
        asm = cond.assembled
        model = self.model
        t0 = time.perf_counter()
        warm = ctx.warm if warm_start else None
        u0 = ctx.u_free if warm_start and warm is not None else None
        t_setup = 0.0
        if self._hierarchy is None:
            self._hierarchy = self._build_hierarchy(alpha, asm)
            self._hierarchy_alpha = np.array(alpha, dtype=float)
            t_setup = time.perf_counter() - t0
        res = solve_fullspace(asm.A, asm.L, model.contact_dofs, cond.gap, self.friction, coords=asm.coords,
                              free=model.assembler.free, r0=warm, u0=u0, hierarchy=self._hierarchy,
                              tol=max(tol or self.tol, FULLSPACE_TOL), zone=ctx.next_zone if self.use_zone else None,
                              zone_margin=self.zone_margin)
        self._hierarchy = res.hierarchy
        timings = dict(cond.timings, **{f"fullspace_{key}": v for key, v in res.timings.items() if key != "total"})
        timings["fullspace_amg_setup"] += t_setup
        timings["contact"] = time.perf_counter() - t0
        u3, lam, tau = res.u_c, res.lam, res.tau
        fscale = max(np.abs(lam).max(initial=0.0), np.abs(asm.L).max(initial=0.0))
        classes = classify_nodes(u3, lam, tau, cond.gap, self.friction,
                                 force_scale=fscale if lam.max(initial=0) <= 0 else None)
        timings["total"] = sum(timings.values())
        state = State(alpha=alpha, coords=asm.coords, u=model.assembler.to_full(res.u), u_c=u3, lam=lam,
                      tau=tau, gap=cond.gap, classes=classes, friction=self.friction, method="fullspace",
                      iterations=res.newton_steps, residual=res.error,
                      complementarity=contact_conditions_violation(u3, lam, tau, cond.gap, self.friction),
                      converged=res.converged, timings=timings,
                      info={"backend": "pyamg", "path": "amg", "zone_nodes": int(res.zone.size),
                            "zone_misses": int(res.zone_growths), "delassus": "none",
                            "krylov_iterations": int(sum(res.krylov_iterations))})
        ctx.warm, ctx.u_free = res.r.copy(), res.u
        if self.use_zone:
            clearance = u3[:, 2] + cond.gap
            ctx.next_zone = zone_rules.near_nodes(lam, clearance, displacement_scale(u3, cond.gap),
                                                  self.zone_margin)
        log.debug("state%s: full-space Newton %d steps, %d GMRES iterations, error %.2e, %.2f s",
                  f" of load case {self.cases[k].name}" if len(self.cases) > 1 else "", res.newton_steps,
                  sum(res.krylov_iterations), res.error, timings["total"])
        return state

    def _build_hierarchy(self, alpha, asm=None):
        """The AMG hierarchy of A(α) (:class:`~contactopt.contact.fullspace.ContactHierarchy`).

        pyamg estimates spectral radii from random start vectors of NumPy's global generator: it
        is seeded here (and its state restored), and OpenBLAS runs on one thread, so that the same
        design gives the same hierarchy bit for bit — a resumed run rebuilds it from the
        checkpoint's design and repeats the uninterrupted one."""
        import scipy.sparse as sp
        from .contact.fullspace import ContactHierarchy
        from .fem.iterative import rigid_body_modes
        if asm is None:
            asm = self.model.assemble(self.model.surface.as_vector(alpha), self.cases[0].loads)
        A = sp.csr_matrix(asm.A)
        if not A.has_sorted_indices:
            A = A.copy()
            A.sort_indices()
        saved = np.random.get_state()
        np.random.seed(HIERARCHY_SEED)
        try:      # one OpenBLAS thread, as inside a state solve: the same round-off either way
            with sequential_openblas():
                return ContactHierarchy(A, rigid_body_modes(asm.coords, self.model.assembler.free),
                                        contact_dofs=self.model.contact_dofs)
        finally:
            np.random.set_state(saved)

    def adjoint_fullspace(self, k: int, cond: Condensed, state: State, y_u, y_lam, choices=None):
        """The adjoint (4.15) of load case k in full space
        (:func:`contactopt.sensitivity.adjoint_fullspace.solve_adjoint_fullspace`): (v_u, v_λ, ṽ)."""
        from .sensitivity.adjoint_fullspace import solve_adjoint_fullspace
        adj = solve_adjoint_fullspace(cond.assembled.A, self.model.contact_dofs, state.classes, state.u_c,
                                      state.lam, y_u, y_lam, self.friction, hierarchy=self._hierarchy,
                                      choices=choices)
        state.info["adjoint_krylov"] = int(adj.iterations)
        return adj.v_u, adj.v_lam, adj.v

    def _new_columns(self, nodes, fraction: float = 0.25) -> dict:
        """``max_new`` of :meth:`ZoneProblem.block_from` for a zone ``nodes``: a kept block takes exact
        columns for at most this fraction of new nodes — on the Delassus path, where a column costs
        a sparse solve, for at most DELASSUS_NEW_NODES (beyond that the zone's Schur complement is
        cheaper)."""
        if self.path == "delassus":
            fraction = min(fraction, DELASSUS_NEW_NODES / max(len(nodes), 1))
        return {"max_new": fraction}

    def _predicted_zone(self, cond) -> np.ndarray:
        """A first contact zone without a warm start (Delassus path): the nodes whose
        displacement without contact forces, x0, closes the gap to within the margin — the zone
        grows by every node it misses, so the state does not depend on this guess, and W_Z is
        not formed on all contact DOFs at the first design."""
        u0 = cond.x0[self.model.contact_dofs].reshape(-1, 3)
        clearance = u0[:, 2] + cond.gap
        return zone_rules.near_nodes(np.zeros(cond.gap.size), clearance,
                                     displacement_scale(u0, cond.gap), self.zone_margin)

    def _solve_local(self, zp, cond, warm, method, tol, alpha, ctx):
        """The zone's local problem u = W r + q, q = (S⁻¹ℓ)_Z + (g, 0, 0), in the FCLIB convention.

        Returns (result, time spent forming W_Z, how W_Z entered: "formed" or "reused"). With
        ``reuse_delassus``, Newton first runs with the Delassus block of an earlier design as its
        matrix and exact products W_Z r by triangular solves (:meth:`ZoneProblem.product`), to
        REUSE_TOL_FACTOR·tol, so the state is exact either way; W_Z is formed (and kept for later
        designs) when that solve fails, and the kept block is dropped when it needed more than
        REUSE_MAX_STEPS steps.
        """
        from .contact.local import solve_local
        from .contact.newton import solve_newton
        q = zp.q0.copy()
        q[0::3] += cond.gap[zp.zone]
        r0 = warm[zp.zone].ravel() if warm is not None else None
        tol = tol or self.tol
        if method == "newton" and self.reuse_delassus and not zp.has_W:
            W_old = None if ctx.jacobian is None else zp.block_from(*ctx.jacobian[1:], **self._new_columns(zp.zone))
            # Delassus path: measured on the warm start, whose product Newton needs first anyway
            eta = np.inf if W_old is None else zp.relative_gap(W_old, r0 if cond.delassus else None)
            if eta <= REUSE_MAX_GAP:
                # (Delassus path: to tol itself — each step costs a sparse solve there)
                res = solve_newton(W_old, q, self.friction, tol=tol * (1.0 if cond.delassus else REUSE_TOL_FACTOR),
                                   max_iter=self.max_iter, r0=r0, product=zp.product,
                                   chord=eta > CHORD_MIN_GAP, raise_on_failure=False)
                # on the Delassus path forming W_Z costs more than a factorization: a solve that
                # reached tol itself (if not REUSE_TOL_FACTOR·tol, a round-off floor) is accepted
                if res.converged or (cond.delassus and res.error <= tol):
                    if res.iterations > REUSE_MAX_STEPS:
                        ctx.jacobian = None                # stale: form W_Z at the next design
                    return res, 0.0, "reused"
                log.debug("Newton with the Delassus block of an earlier design stopped at %.2e "
                          "after %d steps; forming W_Z", res.error, res.iterations)
                r0 = res.r
        t0 = time.perf_counter()
        keep = method == "newton" and self.reuse_delassus
        # a kept block must be what restore_jacobian(alpha, zone) rebuilds, bit for bit (a
        # resumed run repeats the uninterrupted one): the zone's own factorization, not the
        # grown block (equal up to round-off). Zones grow rarely.
        W = self._own_block(cond, zp.zone) if keep and zp.grown else zp.W
        t_inv = time.perf_counter() - t0
        self.n_delassus += 1
        if keep:
            self._keep_block(alpha, zp.zone, W, ctx)
        res = solve_local(W, q, self.friction, method=method, tol=tol, max_iter=self.max_iter, r0=r0)
        return res, t_inv, "formed"

    def adjoint_delassus(self, k: int, cond: Condensed, state: State, y_u, y_lam, choices=None):
        """The adjoint (4.15) of load case k on the Delassus path
        (:func:`contactopt.sensitivity.adjoint.solve_adjoint_delassus`): products W s by sparse
        solves, preconditioned by the case's kept Delassus block on the nodes in contact (exact
        columns for nodes outside it; the zone's Schur complement when there is no kept block)."""
        from .sensitivity.adjoint import _effective_classes, _check_choices, solve_adjoint_delassus
        from .contact.state import CLASS_CODES
        contact = self.model.contact_dofs
        n = cond.x0.size

        def apply(s):
            f = np.zeros(n)
            f[contact] = s
            x = cond.factor.solve(f)
            return x[contact], x

        eff = _effective_classes(state.classes, _check_choices(choices))
        K = np.flatnonzero(eff != CLASS_CODES["L"])
        zpK = zone_rules.DelassusZoneProblem(cond.factor, contact, cond.x0, K, self._zone_block(cond.assembled.A))
        jac = self.contexts[k].jacobian
        W = None
        if jac is not None and K.size:
            W = zpK.block_from(jac[1], jac[2], **self._new_columns(K, ADJOINT_MAX_NEW))
        if W is None:
            W = zpK.W if K.size else np.zeros((0, 0))
        perm = (3 * np.arange(K.size)[:, None] + np.array([1, 2, 0])).ravel()   # FCLIB -> (t1, t2, ν)
        W = W[np.ix_(perm, perm)]
        t0 = time.perf_counter()
        v_u, v_lam, v_free, res = solve_adjoint_delassus(apply, W, state, y_u, y_lam, choices)
        if res is not None:
            log.debug("adjoint (4.15) in W-form on %d nodes: %d GMRES iterations, %.2f s",
                      K.size, res.iterations, time.perf_counter() - t0)
            state.info["adjoint_krylov"] = int(res.iterations)
        return v_u, v_lam, v_free, res

    def jacobian_design(self, case: int = 0):
        """(alpha, zone) of load case ``case``'s kept Delassus block, or None: with them
        :meth:`restore_jacobian` rebuilds the same block (checkpoints)."""
        if self.path == "amg":      # the design of the AMG hierarchy, with the case's zone
            a = self._hierarchy_alpha
            return None if a is None else (a, self.contexts[case].next_zone)
        jac = self.contexts[case].jacobian
        return None if jac is None else (jac[0], jac[1])

    def restore_jacobian(self, alpha, zone, case: int = 0) -> None:
        """Form and keep the Delassus block W_Z at design ``alpha`` for the nodes ``zone`` as
        load case ``case``'s (W_Z does not depend on the load)."""
        alpha = np.array(alpha, dtype=float)
        zone = np.asarray(zone, dtype=np.int64)
        if self.path == "amg":      # full space: the AMG hierarchy of A(alpha), shared by the cases
            if self._hierarchy_alpha is None or not np.array_equal(self._hierarchy_alpha, alpha):
                self._hierarchy = self._build_hierarchy(alpha)
                self._hierarchy_alpha = alpha
            return
        for other in self.contexts:           # cases that kept the same block share it
            j = other.jacobian
            if j is not None and np.array_equal(j[0], alpha) and np.array_equal(j[1], zone):
                self.contexts[case].jacobian = j
                return
        with sequential_openblas():       # the same round-off as inside a state solve
            cond = self.condensed_system(self.model.surface.as_vector(alpha))
            self._keep_block(alpha, zone, self._own_block(cond, zone), self.contexts[case])

    def _own_block(self, cond, zone):
        """W_Z of ``zone`` from the zone's own (N, Z)-ordered factorization of S (Delassus path:
        the inverse of the Schur complement of A onto the zone's DOFs)."""
        if cond.delassus:
            zp = zone_rules.DelassusZoneProblem(cond.factor, self.model.contact_dofs, cond.x0, zone,
                                                self._zone_block(cond.assembled.A))
            return zp.W
        return zone_rules.ZoneProblem(cond.S, cond.ell, zone).W

    @staticmethod
    def _keep_block(alpha, zone, W, ctx):
        """Keep W_Z (in JACOBIAN_DTYPE) as the Newton matrix of the case's later designs."""
        ctx.jacobian = (alpha, zone, W.astype(JACOBIAN_DTYPE))

    def _zone_warm(self, r_loc: np.ndarray, zone: np.ndarray) -> np.ndarray:
        """Contact forces of a zone solve as a (p, 3) warm start, per node (N, T1, T2)."""
        w = np.zeros((self.model.n_contact, 3))
        w[zone] = r_loc.reshape(-1, 3)
        return w

    def cached_condensed(self, alpha, case: int = 0) -> Condensed:
        """The condensed system of load case ``case`` at α (solving the states if needed)."""
        alpha = self.model.surface.as_vector(alpha)
        self.solve_state(alpha)
        return self._cache[3][0][case]

    def uniqueness_bound(self, alpha) -> float:
        """Estimate of the bound (3.16) on F applied to the condensed system: F0 = γ/‖S‖.

        With A := S (the condensed Coulomb problem (3.17)), N and T select components so β = ‖T‖ = 1
        and (3.16) reads F < λ_min(S)/λ_max(S). Known to be very pessimistic.
        """
        from scipy.sparse.linalg import eigsh
        cond = self.cached_condensed(alpha)
        if cond.S is None:
            log.info("the uniqueness bound (3.16) needs the condensed stiffness S on all contact "
                     "DOFs, which the Delassus path does not form: not computed")
            return float("nan")
        lmax = eigsh(cond.S, k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        wmax = eigsh(spd_inverse(cond.S), k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        return float((1.0 / wmax) / lmax)

    # ------------------------------------------------------------------ oracle
    def evaluate_value(self, alpha) -> float:
        """Θ(α) alone (one state solve per load case, combined as [objective] combine says)."""
        return self.evaluate_cases(alpha).value

    def prepare_objectives(self) -> None:
        """Compute the targets of the cases' objectives now: a 'design' target solves a state at
        its own design, which must not come between a state and its adjoint."""
        for case in self.cases:
            getattr(case.objective, "target", None)

    def evaluate_cases(self, alpha, **kw):
        """Θ_k of every load case and their combination at α: a
        :class:`~contactopt.sensitivity.cases.Combined` (``kw`` go to :meth:`solve_state`)."""
        self.prepare_objectives()
        self.solve_state(alpha, **kw)
        conds, states = self._cache[3]
        values = [float(c.objective.evaluate(st, cd)[0]) for c, st, cd in zip(self.cases, states, conds)]
        return self.combination.combine(values)

    def evaluate(self, alpha):
        """(Θ(α), ξ) with ξ a Clarke subgradient from the adjoint system (4.15)."""
        from .sensitivity.adjoint import subgradient
        with sequential_openblas():
            res = subgradient(self, alpha)
        return res.value, res.gradient
