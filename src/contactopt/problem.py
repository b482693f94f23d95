"""The shape problem of a configuration: state solves and the oracle Θ(α), ∂Θ(α).

Data flow (docs/architecture.md): α → mesh → A(α), L(α) → a solver path (:mod:`contactopt.paths`)
→ the Coulomb contact state of each load case → objective → adjoint (4.15) → subgradient.

Contact conventions, on every path: per contact node m the order (t1, t2, ν) = (x1, x2, x3),
r the contact force on the body, λ = r_ν ≥ 0, τ = −r_t (paper (3.17)).

Load cases (:mod:`contactopt.sensitivity.cases`): A(α) and what the path builds from it do not
depend on the load, so a design is assembled and prepared once, and each case adds its load
vector L_k and its own contact solve. Each case carries its own context (warm start, contact
zone, what its path keeps) from design to design; a configuration without cases is the list of
one case.
"""

from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from ._threads import sequential_openblas
from .config import Config, load_config
from .contact.state import CLASS_CODES, State
from .errors import SolverError
from .fem import memory
from .fem.model import ElasticModel
from .mesh.body import build_body
from .paths import PATHS, Start, make_path, select_path

log = logging.getLogger(__name__)


@dataclass
class DesignCache:
    """The last design's solves: ``key`` α's bytes and ``method``; per load case its ``systems``
    and ``states`` (the last step's on a load path), and on a load path every step's
    (``step_systems``, ``step_states``: None for a case without steps); ``cold``: solved without
    warm start, so that a request without warm start (a run's final figures) is answered only by
    such solves and does not depend on what was solved before."""

    key: bytes
    method: str
    systems: list
    states: list
    step_systems: list
    step_states: list
    cold: bool = False


class ShapeProblem:
    """Discrete shape optimization problem (P̃) of a configuration.

    ``solve_state(alpha)`` returns the :class:`~contactopt.contact.state.State`;
    ``evaluate(alpha)`` returns (Θ(α), one Clarke subgradient) (:meth:`evaluate`).
    ``path``: the :class:`~contactopt.paths.base.SolverPath` the configuration runs on.
    """

    def __init__(self, config, *, method: str | None = None):
        self.config = config if isinstance(config, Config) else load_config(config)
        body = build_body(self.config)
        # pinned components on an elastic foundation: the foundation checks that they are clamped at
        # their partners too (fem.foundation), where the condensation takes them
        name, library = select_path(self.config, memory.free_dofs(body), pinned=int(body.pinned_dofs.size),
                                    rigid=body.rigid, pinned_held=True)
        with PATHS[name].library_threads(self.config.linear_solver.threads):   # the morph weight's solve
            self.model = ElasticModel(self.config, body=body, memory_estimate=PATHS[name].memory_estimate)
        self.n_state_solves = 0    # designs solved (all cases at once)
        self._cache = None         # DesignCache of the last design
        self._responding = None    # the constraint evaluated in place of the objective (_as_objective)
        from .sensitivity.cases import build_cases
        self.cases, self.combination = build_cases(self.config, self.model, self._design_lambda)
        self.path = make_path(self.config, self.model, name, library,
                              Start(first_loads=self.cases[0].loads))
        self.friction = self.path.settings.friction
        self.method = method or self.path.settings.method
        self.tol = self.path.settings.tol
        if body.rigid is not None:
            self._check_held()
        from .sensitivity.objectives import make_constraints
        self.constraints = make_constraints(self.config, self.model, self.cases, self._design_lambda)
        self.contexts = [self.path.new_context() for _ in self.cases]
        self._init_steps()

    def _check_held(self) -> None:
        """A body held only by contact: ConfigError when no admissible contact force balances a
        case's load at the initial design (:mod:`contactopt.contact.balance`)."""
        from .contact.balance import check_held
        m = self.model
        coords = m.mesh.coordinates(m.initial_design())
        loads = [("loads" if len(self.cases) == 1 else f"load case {c.name!r}", m.load_vector(coords, c.loads))
                 for c in self.cases]
        check_held(m.body.rigid, coords, m.contact_nodes, m.frames, self.friction, loads, self.config.source)

    def _init_steps(self) -> None:
        """The load path of every case (None: one step, the static problem; sensitivity/steps.py)
        and a context per solve of a path (the first is the case's own)."""
        from .sensitivity.steps import build_path, step_choice, step_tables
        self.steps = []
        for k, case in enumerate(self.cases):
            own = self.has_load_cases and self.config.load_cases[k].steps is not None
            where = f"load_cases[{k}].steps" if own else "load_steps"
            self.steps.append(build_path(self.model, case.loads,
                                         step_tables(self.config, k if self.has_load_cases else None), where))
        self.step_choice = step_choice(self.config)
        self.step_contexts = [[ctx] + [self.path.new_context() for _ in (steps or [None])[1:]]
                              for ctx, steps in zip(self.contexts, self.steps)]

    @property
    def has_load_steps(self) -> bool:
        return any(self.steps)

    def _design_lambda(self, alpha, case: int) -> np.ndarray:
        """λ of load case ``case`` at α, solved without warm start (a 'design' target)."""
        return self.solve_state(alpha, warm_start=False, case=case).lam.copy()

    # ------------------------------------------------------------------ load cases
    @property
    def objective(self):
        """The objective of the first load case (the objective, without cases)."""
        return self.cases[0].objective

    @property
    def has_load_cases(self) -> bool:
        """Whether the configuration lists [[load_cases]] (else one case of [loads])."""
        return bool(self.config.load_cases)

    @property
    def case_names(self) -> tuple:
        return self.combination.names

    # the first case's context under the names of a problem without cases
    next_zone = property(lambda self: self.contexts[0].next_zone,
                         lambda self, v: setattr(self.contexts[0], "next_zone", v))

    # ------------------------------------------------------------------ systems and states
    def _step_systems(self, system, asm, k: int) -> list:
        """The system of every solve of case k's load path (sharing the case's prepared system)."""
        out = []
        for step in self.steps[k]:
            system_k = self._for_loads(system, asm, step.loads)
            if step.force is not None:       # a force-controlled obstacle: the step's force (paths/force.py)
                system_k = replace(system_k, force=step.force)
            out.append(system_k)
        return out

    def _for_loads(self, system, asm, loads):
        """The prepared ``system`` with the load vector of ``loads`` on the design of ``asm``."""
        t0 = time.perf_counter()
        L_full = self.model.load_vector(asm.coords, loads)
        asm_k = replace(asm, L_full=L_full, L=self.model.free_load(L_full))
        t1 = time.perf_counter()
        system_k = self.path.for_load(system, asm_k)
        system_k.timings = {"assembly": t1 - t0, **system_k.timings}
        return system_k

    def _systems(self, alpha) -> list:
        """The system of every load case at α: assembled once, prepared by the path once."""
        t0 = time.perf_counter()
        asm = self.path.assemble(alpha, self.cases[0].loads)
        t1 = time.perf_counter()
        system = self.path.prepare(asm)
        system.timings = {"assembly": t1 - t0, **system.timings}
        out = [system]
        for case in self.cases[1:]:
            out.append(self._for_loads(system, asm, case.loads))
        return out

    def solve_state(self, alpha, *, method: str | None = None, warm_start: bool = True,
                    tol: float | None = None, case: int = 0) -> State:
        """Solve the discrete Coulomb problem (P) at α (α need not be in U, but the mesh must be
        valid) for every load case; returns the state of load case ``case``."""
        return self.solve_states(alpha, method=method, warm_start=warm_start, tol=tol)[case]

    def solve_states(self, alpha, *, method=None, warm_start=True, tol=None) -> list[State]:
        """The states of every load case at α (one assembly; see :meth:`solve_state`)."""
        alpha = self.model.surface.as_vector(alpha)
        if not np.all(np.isfinite(alpha)):
            raise SolverError("design contains NaN or infinite entries")
        key, method = alpha.tobytes(), method or self.method
        if (self._cache is not None and (self._cache.key, self._cache.method) == (key, method)
                and (warm_start or self._cache.cold)):
            return list(self._cache.states)
        step_systems, step_states = [None] * len(self.cases), [None] * len(self.cases)
        with sequential_openblas(), self.path.evaluation_threads():
            systems = self._systems(alpha)
            shared = {}                # what the cases of one design share (e.g. a factor of S)
            states = []
            for k, (system, ctx) in enumerate(zip(systems, self.contexts)):
                if not self.steps[k]:
                    states.append(self.path.solve_state(system, ctx, alpha, method=method, warm_start=warm_start,
                                                        tol=tol or self.tol, shared=shared, label=self._of(k)))
                    continue
                # a load path: each solve from the end of the one before (sensitivity/steps.py)
                step_systems[k] = self._step_systems(system, systems[k].assembled, k)
                step_states[k], slip, slid = [], None, np.zeros((self.model.n_contact, 2))
                for step, sys_j, ctx_j in zip(self.steps[k], step_systems[k], self.step_contexts[k]):
                    st = self.path.solve_state(sys_j, ctx_j, alpha, method=method, warm_start=warm_start,
                                               tol=tol or self.tol, shared=shared,
                                               label=f"{self._of(k)}, step {step.name} ({step.substep})",
                                               slip_ref=slip)
                    st.step, st.substep = step.name, step.substep
                    if st.slip_ref is None:              # the first step: slip from the unloaded body
                        st.slip_ref = np.zeros((self.model.n_contact, 2))
                    sliding = np.isin(st.classes, [CLASS_CODES["M1"], CLASS_CODES["M2"]])
                    slid = slid + np.where(sliding[:, None], st.slip_increment, 0.0)
                    st.slip = slid               # the accumulated slip along the path
                    step_states[k].append(st)
                    slip = st.u_c[:, :2].copy()
                systems[k], states = step_systems[k][-1], states + [step_states[k][-1]]
        self._cache = DesignCache(key=key, method=method, systems=systems, states=states,
                                  step_systems=step_systems, step_states=step_states, cold=not warm_start)
        self.n_state_solves += 1
        return list(states)

    def clear_cache(self) -> None:
        """Forget the last design's states (the next solve_state solves anew)."""
        self._cache = None

    def cached_system(self, alpha, case: int = 0):
        """The path's system of load case ``case`` at α (solving the states if needed)."""
        self.solve_states(alpha)
        return self._cache.systems[case]

    cached_condensed = cached_system

    def uniqueness_estimate(self, alpha):
        """(F0, None) of the bound (3.16) on F at α, or (None, the reason) where the path does
        not form the condensed stiffness S (:meth:`contactopt.paths.base.SolverPath.uniqueness_bound`)."""
        bound, reason = self.path.uniqueness_bound(self.cached_system(alpha))
        if reason:
            log.info("%s: not computed", reason)
        return bound, reason

    def uniqueness_bound(self, alpha) -> float:
        """F0 of :meth:`uniqueness_estimate`, NaN where it is not computed."""
        bound = self.uniqueness_estimate(alpha)[0]
        return float("nan") if bound is None else bound

    # ------------------------------------------------------------------ checkpoints
    def export_contexts(self) -> list:
        """What the cases carry from design to design: ``[k][j]`` the arrays of load case k at
        load step j (a checkpoint holds them)."""
        return [[self.path.export_context(ctx) for ctx in row] for row in self.step_contexts]

    def import_contexts(self, arrays: list, where: str) -> None:
        """Put back :meth:`export_contexts` (read from a checkpoint ``where``)."""
        for k, row in enumerate(self.step_contexts):
            self.path.import_context(row[0], arrays[k][0], where, others=self.contexts[:k])
            for j, ctx_j in enumerate(row[1:], 1):
                self.path.import_context(ctx_j, arrays[k][j], where, others=self.contexts + [
                    c for r in self.step_contexts for c in r[1:] if c is not ctx_j])

    # ------------------------------------------------------------------ oracle
    def evaluate_value(self, alpha) -> float:
        """Θ(α) alone (one state solve per load case, combined as [objective] combine says)."""
        return self.evaluate_cases(alpha).value

    def prepare_objectives(self) -> None:
        """Compute the targets of the cases' objectives now: a 'design' target solves a state at
        its own design, which must not come between a state and its adjoint."""
        for case in self.cases:
            case.objective.target  # noqa: B018 (read for its computation)

    def evaluate_cases(self, alpha, **kw):
        """Θ_k of every load case and their combination at α: a
        :class:`~contactopt.sensitivity.cases.Combined` (``kw`` go to :meth:`solve_state`)."""
        self.prepare_objectives()
        states = self.solve_states(alpha, **kw)
        systems = self._cache.systems
        values = [float(self._case_terms(k, states, systems)[0]) for k in range(len(self.cases))]
        return self.combination.combine(values)

    def _case_terms(self, k: int, states, systems):
        """(Θ_k, [(solve index or None, coefficient, objective part)]) of case k: its objective
        (part (J, ∂J/∂u, ∂J/∂λ, ∂J/∂α)), or on a load path the steps' objectives combined as
        ``[objective] steps`` says (part (J, {solve: (∂J/∂u, ∂J/∂λ, ∂J/∂α)}): the friction work
        depends on every solve up to the step's end; sensitivity/steps.py)."""
        case = self.cases[k]
        if not self.steps[k]:
            part = case.objective.evaluate(states[k], systems[k])
            return part[0], [(None, 1.0, part)]
        from .sensitivity.steps import step_objective
        step_systems, step_states = self._cache.step_systems[k], self._cache.step_states[k]
        memo, parts, terms = {}, {}, {}
        for j, step in enumerate(self.steps[k]):
            if step.end:
                parts[j] = step_objective(case.objective, self.steps[k], step_states, step_systems, j, memo)
                terms[j] = dict(getattr(case.objective, "last_terms", {}))
        if self._responding is None:          # a constraint's response is not the steps' objective
            for j, part in parts.items():
                step_states[j].objective = float(part[0])
        value, coef = self.step_choice.combine({j: (self.steps[k][j].name, parts[j][0]) for j in parts})
        if terms[max(terms)]:                 # the terms of Θ: combined over the steps as Θ is
            case.objective.last_terms = {name: float(sum(c * terms[j][name] for j, c in coef.items()))
                                         for name in terms[max(terms)]}
        return value, [(j, c, parts[j]) for j, c in coef.items()]

    def step_results(self, case: int = 0):
        """[(step name, substep, state)] of case ``case``'s load path at the last design solved
        (None without steps); a state's ``objective`` is J at the step's end."""
        if not self.steps[case] or self._cache is None:
            return None
        return [(st.name, st.substep, state) for st, state in zip(self.steps[case], self._cache.step_states[case])]

    def step_columns(self) -> list[str]:
        """The names of the steps' objective values (:meth:`step_values`): ``<step>``, with load
        cases ``<case>.<step>``; empty without load steps."""
        out = []
        for k, steps in enumerate(self.steps):
            pre = f"{self.cases[k].name}." if self.has_load_cases else ""
            out += [pre + s.name for s in steps or [] if s.end]
        return out

    def step_values(self) -> list[float]:
        """J at the end of every step of every path, at the last design evaluated (the order of
        :meth:`step_columns`)."""
        out = []
        for k, steps in enumerate(self.steps):
            out += [(np.nan if st.objective is None else st.objective) for s, st in zip(steps or [], self._cache.step_states[k] or [])
                    if s.end]
        return out

    def _path_adjoint(self, k: int, terms, choices):
        """(ξ_k, v_u, v_λ of the last solve with a term, degenerate nodes) backward through case
        k's load path (sensitivity/steps.py): each solve's adjoint (4.15) with the objective's
        right-hand side at that solve plus P_t(S v + y*_u) of the solve after it (with y*_u on
        every DOF, P_t((A ṽ)_c + y*_c): :meth:`~contactopt.paths.base.SolverPath.adjoint_carry`)."""
        from .sensitivity.objectives import add_terms
        from .sensitivity.steps import add_at_contact, tangential
        step_systems, step_states, ctxs = self._cache.step_systems[k], self._cache.step_states[k], self.step_contexts[k]
        rhs = {}                   # solve -> (c ∂J/∂u, c ∂J/∂λ, c ∂J/∂α) summed over the chosen steps
        for _, c, (_, parts) in terms:
            for i, (yu, yl, dJ_da) in parts.items():
                add_terms(rhs, i, c * yu, c * yl, c * dJ_da)
        last = max(rhs)
        pinned = self.model.contact_pinned_global.ravel()
        contact = (3 * self.model.contact_nodes[:, None] + np.arange(3)).ravel()
        xi, carry, nd, out = 0.0, None, 0, None
        for j in range(last, -1, -1):
            state, system = step_states[j], step_systems[j]
            p = state.lam.size
            y_u, y_lam = np.zeros(3 * p), np.zeros(p)
            if j in rhs:
                y_u, y_lam, dJ_da = rhs[j]
                xi = xi + dJ_da
            own = y_u                       # the objective's own ∂J/∂u at this solve
            if carry is not None:           # on every DOF: y_u's global components
                y_u = add_at_contact(y_u, carry if carry.size == y_u.size else self.path.global_contact(carry),
                                     contact)
            v_u, v_lam, v_full, krylov = self.path.adjoint(system, ctxs[j], state, y_u, y_lam, choices)
            if krylov is not None:
                state.stats.adjoint_krylov = krylov
            xi = xi + self.path.design_contraction(system, state.u, v_full, self.steps[k][j].loads) \
                + self.model.gap_matrix.T @ v_lam
            nd += state.n_degenerate
            if out is None:
                out = (v_u, v_lam)
            if j:
                carry = tangential(self.path.adjoint_carry(system, ctxs[j], v_u, v_full, y_u))
            if self.steps[k][j].force is not None:
                xi, carry = self._step_force(system, ctxs[j], state, v_lam, v_full, own, xi, carry, j,
                                             self.steps[k][j].loads)
            if j:
                carry[pinned] = 0.0          # u_t = 0 there in every step
        return xi, out[0], out[1], nd

    def _step_force(self, system, ctx, state, v_lam, v_full, own, xi, carry, j: int, loads):
        """(ξ, carry) of solve j of a load path with a force-controlled obstacle, its translation s_j
        following α and the previous solve's slip u_t^(j−1) (F_j(α, u_t^(j−1), s_j) = 0): with
        μ = (∂Θ/∂s)/(∂F/∂s), ξ gains −μ ∂F/∂α and the carry −μ P_t(S w_u + ∂F/∂u_c) of F's adjoint w
        (paths/force.py; sensitivity/steps.py)."""
        from .sensitivity.steps import tangential
        t = self.path.force_terms(system, ctx, state, v_lam, loads, v=v_full, y_u=own)
        if t.dF_ds == 0:
            return xi, carry
        xi = xi - t.dT_ds * t.dF_da / t.dF_ds
        if j:
            carry_F = tangential(self.path.adjoint_carry(system, ctx, t.adjoint.v_u, t.adjoint.v, t.y_F))
            carry = carry - t.dT_ds * carry_F / t.dF_ds
        return xi, carry

    def evaluate(self, alpha):
        """(Θ(α), ξ) with ξ a Clarke subgradient from the adjoint system (4.15)."""
        with sequential_openblas():
            res = self.subgradient(alpha)
        return res.value, res.gradient

    def subgradient(self, alpha, *, choices=None):
        """Θ(α) and one Clarke subgradient of the combined load cases
        (:class:`~contactopt.sensitivity.adjoint.SubgradientResult`; paper Theorem 4.1):

            ξ_k = ∂J/∂α + ṽᵀ(∂A/∂α ũ − ∂L_k/∂α) + v_λᵀ ∂g/∂α,

        ṽ the A-harmonic extension of the adjoint v_u, which the path returns; ξ = Σ_k c_k ξ_k over
        the cases of nonzero coefficient (the max: the chosen active case; the sum: every case).

        OpenBLAS runs on one thread throughout, as in the state solve (:mod:`contactopt._threads`):
        its spinning threads would otherwise slow the next design's PARDISO factorization; MKL on
        the path's evaluation threads (``[linear_solver] threads``)."""
        with sequential_openblas(), self.path.evaluation_threads():
            return self._subgradient(alpha, choices)

    def _subgradient(self, alpha, choices):
        from .sensitivity.adjoint import DEFAULT_CHOICES, SubgradientResult
        self.prepare_objectives()
        t0 = time.perf_counter()
        states = self.solve_states(alpha)
        systems = self._cache.systems
        t1 = time.perf_counter()
        parts = []
        for k in range(len(self.cases)):
            part = self._case_terms(k, states, systems)
            if not np.isfinite(part[0]):
                raise SolverError(f"objective{self._of(len(parts))} is not finite at this design ({part[0]})")
            parts.append(part)
        comb = self.combination.combine([part[0] for part in parts])
        t_adj = t_design = 0.0
        g, nd = None, 0
        for k in np.flatnonzero(comb.coefficients):
            t2 = time.perf_counter()
            state, system = states[k], systems[k]
            if self.steps[k]:
                xi, v_u_k, v_lam_k, nd_k = self._path_adjoint(k, parts[k][1], choices)
                g = comb.coefficients[k] * xi if g is None else g + comb.coefficients[k] * xi
                t_adj += time.perf_counter() - t2
                nd += nd_k
                if nd_k:
                    log.info("subgradient at a design with %d degenerate node(s) along the load path%s",
                             nd_k, self._of(k))
                if k == comb.case:
                    v_u, v_lam = v_u_k, v_lam_k
                continue
            _, y_u, y_lam, dJ_da = parts[k][1][0][2]
            v_u_k, v_lam_k, v_full, krylov = self.path.adjoint(system, self.contexts[k], state, y_u, y_lam, choices)
            if krylov is not None:
                state.stats.adjoint_krylov = krylov
            t3 = time.perf_counter()
            xi = dJ_da + self.path.design_contraction(system, state.u, v_full, self.cases[k].loads) \
                + self.model.gap_matrix.T @ v_lam_k
            xi = self.path.controlled_subgradient(system, self.contexts[k], state, v_u_k, v_lam_k, xi,
                                                  self.cases[k].loads, v=v_full, y_u=y_u)
            g = comb.coefficients[k] * xi if g is None else g + comb.coefficients[k] * xi
            t_adj, t_design = t_adj + t3 - t2, t_design + time.perf_counter() - t3
            nd += state.n_degenerate
            if state.n_degenerate:
                log.info("subgradient at a design with %d degenerate node(s)%s %s", state.n_degenerate,
                         self._of(k), state.counts)
            if k == comb.case:
                v_u, v_lam = v_u_k, v_lam_k
        if not np.all(np.isfinite(g)):
            raise SolverError("subgradient has non-finite entries")
        names = self.case_names
        active = tuple(names[i] for i in comb.active)
        if self.combination.kind == "max" and len(active) > 1:
            log.info("subgradient at a design where %d load cases are active (%s): the subgradient is "
                     "that of %s", len(active), ", ".join(active), names[comb.case])
        exact = nd == 0 and (self.combination.kind == "sum" or len(active) == 1)
        terms = dict(getattr(self.cases[comb.case].objective, "last_terms", {}))
        return SubgradientResult(value=comb.value, gradient=g, state=states[comb.case], v_u=v_u, v_lam=v_lam,
                                 n_degenerate=nd, exact=exact, choices={**DEFAULT_CHOICES, **(choices or {})},
                                 timings={"state": t1 - t0, "adjoint": t_adj, "design_terms": t_design},
                                 case_values=comb.values, case_names=names, active_cases=active,
                                 case=names[comb.case], states=states, terms=terms)

    # ------------------------------------------------------------------ [[constraints]]
    @contextmanager
    def _as_objective(self, j: int):
        """Constraint j's response in place of the objective of every case, the cases joined by the
        max (the limit holds in each) and on a load path the steps chosen by the constraint's
        ``steps``: the oracle's code then evaluates and differentiates it."""
        con = self.constraints[j]
        saved = [c.objective for c in self.cases], self.combination, self.step_choice
        from .sensitivity.cases import Combination
        for case, obj in zip(self.cases, con.objectives):
            case.objective = obj
        self.combination = Combination("max", np.ones(len(self.cases)), saved[1].active_tol, saved[1].names)
        if con.steps is not None:
            self.step_choice = con.steps
        self._responding = con
        try:
            yield con
        finally:
            self._responding = None
            for case, obj in zip(self.cases, saved[0]):
                case.objective = obj
            self.combination, self.step_choice = saved[1], saved[2]

    def constraint_subgradients(self, alpha, *, choices=None) -> list:
        """One :class:`~contactopt.sensitivity.adjoint.SubgradientResult` per constraint at α:
        the response's value (the worst load case) and one Clarke subgradient, by the adjoint of
        the state solved for Θ (no other state solve)."""
        out = []
        for j in range(len(self.constraints)):
            with self._as_objective(j):
                out.append(self.subgradient(alpha, choices=choices))
        return out

    def constraint_values(self, alpha, case: int | None = None, **kw) -> list[float]:
        """The responses of the constraints at α: the worst load case's, or load case ``case``'s
        (``kw`` go to :meth:`solve_state`)."""
        out = []
        for j in range(len(self.constraints)):
            with self._as_objective(j):
                comb = self.evaluate_cases(alpha, **kw)
                out.append(float(comb.value if case is None else comb.values[case]))
        return out

    def constraint_report(self, alpha, case: int | None = None, **kw) -> dict:
        """{name: {type, value, limit, margin}} at α (margin = limit − value ≥ 0 where the
        constraint holds; the worst load case, or load case ``case``), e.g. for state.json and
        summary.json; empty without [[constraints]]."""
        return {con.name: _limit(con, v) for con, v in zip(self.constraints, self.constraint_values(alpha, case, **kw))}

    def step_reports(self, alpha, case: int = 0, **kw) -> list | None:
        """[(step name, objective {type, value, terms}, constraints {name: {type, value, limit,
        margin}})] at the end of every step of load case ``case``'s path at α (None without steps):
        each value is the response at that step's end alone (the friction work from the start of
        the path up to it), before ``[objective] steps`` or a constraint's ``steps`` combine them."""
        from .sensitivity.steps import step_objective
        if not self.steps[case]:
            return None
        self.prepare_objectives()
        self.solve_states(alpha, **kw)
        steps = self.steps[case]
        states, systems = self._cache.step_states[case], self._cache.step_systems[case]
        ends = [j for j, s in enumerate(steps) if s.end]

        def at_ends(objective):
            memo, out = {}, []
            for j in ends:
                value = float(step_objective(objective, steps, states, systems, j, memo)[0])
                terms = {name: {"value": objective.last_terms[name], "weight": w}
                         for name, w, _ in getattr(objective, "terms", [])}
                out.append((value, terms))
            return out

        objective = at_ends(self.cases[case].objective)
        responses = [at_ends(con.objectives[case]) for con in self.constraints]
        out = []
        for n, j in enumerate(ends):
            value, terms = objective[n]
            cons = {con.name: _limit(con, r[n][0]) for con, r in zip(self.constraints, responses)}
            out.append((steps[j].name, {"type": self.config.objective.type, "value": value, "terms": terms}, cons))
        return out

    def term_names(self) -> list:
        """The names of the [[objective.terms]] (their type, numbered from the second of a type on)."""
        return [t[0] for t in getattr(self.objective, "terms", [])]

    def objective_report(self, alpha, case: int | None = None, **kw) -> dict:
        """{type, value, terms} of the objective at α, e.g. for state.json: the combined load
        cases' value (``case`` None; the terms of the case the combination picks) or load case
        ``case``'s own Θ_k and terms. ``terms`` maps each term's name to its value (unweighted)
        and weight; empty without [[objective.terms]]. ``kw`` go to :meth:`solve_state`."""
        comb = self.evaluate_cases(alpha, **kw)
        k = comb.case if case is None else case
        obj = self.cases[k].objective
        value = comb.value if case is None else float(comb.values[case])
        out = {"type": self.config.objective.type, "value": float(value), "terms": {}}
        for name, weight, _ in getattr(obj, "terms", []):
            out["terms"][name] = {"value": obj.last_terms[name], "weight": weight}
        return out

    def _of(self, k: int) -> str:
        return f" of load case {self.cases[k].name}" if len(self.cases) > 1 else ""


def _limit(con, value: float) -> dict:
    """{type, value, limit, margin} of constraint ``con`` with response ``value``."""
    return {"type": con.type, "value": float(value), "limit": con.limit, "margin": con.limit - float(value)}
