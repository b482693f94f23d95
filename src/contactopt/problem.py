"""The shape problem of a configuration: state solves and the oracle Θ(α), ∂Θ(α).

Data flow (docs/architecture.md): α → mesh → A(α), L(α) → a solver path (:mod:`contactopt.paths`)
→ a :class:`~contactopt.sensitivity.solution.Solution` (the contact state of every load case and
step) → responses, Θ and the constraints (:mod:`contactopt.sensitivity.responses`) → the adjoint
(4.15) → subgradient (``contactopt.sensitivity.subgradient``). :class:`ShapeProblem` builds
the parts and keeps the last design's solve; what it computes are functions of values.

Contact conventions, on every path: per contact node m the order (t1, t2, ν) = (x1, x2, x3),
r the contact force on the body, λ = r_ν ≥ 0, τ = −r_t (paper (3.17)).
"""

from __future__ import annotations

import copy
import logging
import time
from dataclasses import replace

import numpy as np

from ._threads import sequential_openblas
from .config import Config, load_config
from .contact.balance import check_held
from .contact.state import State, one_friction
from .fem import memory
from .fem.model import ElasticModel
from .io import reports
from .mesh.body import build_body
from .paths import PATHS, Start, make_path, path_estimates, select_path
from .sensitivity.cases import build_cases
from .sensitivity.objectives import make_constraints, warn_pressure_on_linear_tetrahedra
from .sensitivity.responses import Response, evaluate_response, max_combination
from .sensitivity.solution import KeptDesign, LastDesign, Parts, export_contexts, import_contexts
from .sensitivity.steps import build_path, step_choice, step_tables
from .sensitivity.subgradient import subgradient

log = logging.getLogger(__name__)


class ShapeProblem:
    """Discrete shape optimization problem (P̃) of a configuration.

    ``solve_state(alpha)`` returns the :class:`~contactopt.contact.state.State`;
    ``evaluate(alpha)`` returns (Θ(α), one Clarke subgradient) (:meth:`evaluate`).
    ``path``: the :class:`~contactopt.paths.base.SolverPath` the configuration runs on.

    A state is solved for any design that leaves the mesh valid, whatever ``[design]`` says of
    the admissible set U; ``optimizing=True`` (an optimization's set-up) also refuses a U unfit
    for one (``model.check_design_space()``: bounds that let admissible designs invert or distort
    an element) as soon as the model is built, as ``contactopt run`` does."""

    def __init__(self, config, *, method: str | None = None, optimizing: bool = False):
        self.config = config if isinstance(config, Config) else load_config(config)
        with self.config.assembly.named_as_written():      # a problem in the keys the model was written in
            body = build_body(self.config.face_body_designs())
            # pinned components on a foundation: fem.foundation checks they are clamped at their partners too
            name, library = select_path(self.config, memory.free_dofs(body), pinned=int(body.pinned_dofs.size),
                                        rigid=body.rigid, pinned_held=True)
            with PATHS[name].library_threads(self.config.linear_solver.threads):   # the morph weight's solve
                self.model = ElasticModel(self.config, body=body, memory_estimate=path_estimates(self.config, name, body),
                                          condensed=PATHS[name].condenses_counterparts)
            if optimizing:
                self.model.check_design_space()
            self.cases, self.combination = build_cases(self.config, self.model, self._design_lambda)
            self._selected = name, library
            self.path = make_path(self.config, self.model, name, library, Start(first_loads=self.cases[0].loads))
            self.method = method or self.path.settings.method
            self.tol = self.path.settings.tol
            if self.model.body.rigid is not None:
                self._check_held()
            self.constraints = make_constraints(self.config, self.model, self.cases, self._design_lambda)
            warn_pressure_on_linear_tetrahedra(self.config, self.model)
            contexts = [self.path.new_context() for _ in self.cases]
            self.steps = [build_path(self.model, case.loads, step_tables(self.config, k if self.has_load_cases else None),
                                     f"load_cases[{k}].steps" if self.has_load_cases and self.config.load_cases[k].steps
                                     is not None else "load_steps") for k, case in enumerate(self.cases)]
            self.step_choice = step_choice(self.config)
            self._use(self.path, contexts)
            self._objective = Response("objective", tuple(c.objective for c in self.cases), self.combination,
                                       self.step_choice)
            self.response = self._objective          # what evaluate and subgradient answer for

    def _use(self, path, contexts) -> None:
        """Solve on ``path``, each case from its context in ``contexts`` (a load path's later solves
        from new ones), with no last design."""
        self.path = path
        self.parts = Parts(self.model, path, self.cases, self.steps,
                           [[ctx] + [path.new_context() for _ in (steps or [None])[1:]]
                            for ctx, steps in zip(contexts, self.steps)])
        self._last = LastDesign(self.parts)

    def detached(self) -> ShapeProblem:
        """This problem on a solver path, contexts and last design of its own (the model shared): a
        side computation, such as a warning at another design, that leaves this problem's warm
        starts and kept factorizations as they are."""
        out = copy.copy(self)
        path = make_path(self.config, self.model, *self._selected, Start(first_loads=self.cases[0].loads))
        out._use(path, [path.new_context() for _ in self.cases])
        return out

    def _check_held(self) -> None:
        """A body held only by contact: ConfigError when no admissible contact force balances a
        case's load at the initial design (:mod:`contactopt.contact.balance`)."""
        m = self.model
        coords = m.mesh.coordinates(m.initial_design())
        loads = [("loads" if len(self.cases) == 1 else f"load case {c.name!r}", m.load_vector(coords, c.loads))
                 for c in self.cases]
        c = self.config
        # a load path's steps have loads and obstacle forces of their own: the obstacle's force is checked without them
        steps = bool(c.load_steps) or any(case.steps for case in c.load_cases)
        check_held(m.body.rigid, coords, m.contact_nodes, m.frames, self.friction, loads, c.source,
                   obstacle_force=None if steps else m.obstacle_force)

    def _design_lambda(self, alpha, case: int) -> np.ndarray:
        """λ of load case ``case`` at α, solved without warm start (a 'design' target)."""
        return self.solve_state(alpha, warm_start=False, case=case).lam.copy()

    # ------------------------------------------------------------------ the configuration's parts
    objective = property(lambda self: self.cases[0].objective, doc="The objective of the first load case.")
    has_load_cases = property(lambda self: bool(self.config.load_cases), doc="Whether [[load_cases]] are listed.")
    has_load_steps = property(lambda self: any(self.steps), doc="Whether a load case has a load path.")
    case_names = property(lambda self: self.combination.names)
    friction = property(lambda self: one_friction(self.path.friction), doc="F: a scalar if uniform, else (p,) per node.")
    contexts = property(lambda self: [row[0] for row in self.parts.contexts], doc="Each case's own context.")
    step_contexts = property(lambda self: self.parts.contexts, doc="Per case the context of every solve.")
    n_state_solves = property(lambda self: self._last.n_solves, doc="Designs solved (all cases at once).")
    # the first case's context under the names of a problem without cases
    next_zone = property(lambda self: self.contexts[0].next_zone,
                         lambda self, v: setattr(self.contexts[0], "next_zone", v))

    def for_constraint(self, j: int) -> ShapeProblem:
        """This problem with constraint j's response (its worst load case) in place of Θ: its
        :meth:`evaluate`, :meth:`subgradient` and ``evaluate_value`` answer for the constraint,
        sharing this problem's parts and its last design's solve."""
        con = self.constraints[j]
        out = copy.copy(self)
        out.response = Response(con.name, tuple(con.objectives), max_combination(self.combination),
                                con.steps if con.steps is not None else self.step_choice)
        return out

    # ------------------------------------------------------------------ systems and states
    def solution(self, alpha, *, method=None, warm_start=True, tol=None, resolve: bool = True):
        """The :class:`~contactopt.sensitivity.solution.Solution` at α (the last one if α and the
        method are those of the last solve). ``resolve``: first compute the objectives' 'design'
        targets, which solve a state of their own."""
        if resolve:
            self._objective.resolve()
        return self._last(self.model.surface.as_vector(alpha), method=method or self.method,
                          warm_start=warm_start, tol=tol or self.tol)

    def solve_state(self, alpha, *, method: str | None = None, warm_start: bool = True,
                    tol: float | None = None, case: int = 0) -> State:
        """Solve the discrete Coulomb problem (P) at α (α need not be in U, but the mesh must be
        valid) for every load case; returns the state of load case ``case``."""
        return self.solve_states(alpha, method=method, warm_start=warm_start, tol=tol)[case]

    def solve_states(self, alpha, *, method=None, warm_start=True, tol=None) -> list[State]:
        """The states of every load case at α (one assembly; see :meth:`solve_state`)."""
        return self.solution(alpha, method=method, warm_start=warm_start, tol=tol, resolve=False).states

    def clear_cache(self) -> None:
        """Forget the last design's states (the next solve_state solves anew)."""
        self._last.clear()

    def keep_design(self) -> KeptDesign:
        """The last design's solve, its systems dropped, and the values evaluated on it."""
        return self._last.keep()

    def use_design(self, kept: KeptDesign) -> None:
        """Make ``kept`` the last design (its values answer; no state is solved)."""
        self._objective.resolve()        # the 'design' targets first: they solve states of their own
        self._last.restore(kept)

    def cached_system(self, alpha, case: int = 0):
        """The path's system of load case ``case`` at α (solving the states if needed)."""
        return self.solution(alpha, resolve=False).cases[case].system

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

    def step_results(self, case: int = 0):
        """[(step name, substep, state)] of case ``case``'s load path at the last design solved
        (None without steps); a step end's state carries J there as its ``objective``."""
        solution = self._last.solution
        if not self.steps[case] or solution is None:
            return None
        self._objective.resolve()
        ends = self._last.value("objective", solution, lambda: evaluate_response(
            self._objective, solution, self.steps)).cases[case].ends
        return [(s.name, s.substep, replace(state, objective=ends.get(j))) for j, (s, state)
                in enumerate(zip(self.steps[case], solution.cases[case].states))]

    def step_values(self) -> list[float]:
        """J at the end of every step of every path at the last design solved (the order of
        :meth:`step_columns`)."""
        return [st.objective for k in range(len(self.cases)) for _, _, st in self.step_results(k) or []
                if st.objective is not None]

    # ------------------------------------------------------------------ checkpoints
    def export_contexts(self) -> list:
        """What the cases carry from design to design: ``[k][j]`` the arrays of load case k at load
        step j (:func:`~.sensitivity.solution.export_contexts`)."""
        return export_contexts(self.parts)

    def import_contexts(self, arrays: list, where: str) -> None:
        """Put back :meth:`export_contexts` (read from a checkpoint ``where``)."""
        import_contexts(self.parts, arrays, where)

    # ------------------------------------------------------------------ oracle
    def response_value(self, alpha, **kw):
        """This problem's response (Θ, or a constraint's: :meth:`for_constraint`) at α, a
        :class:`~contactopt.sensitivity.responses.ResponseValue` (``kw`` go to :meth:`solve_state`)."""
        solution = self.solution(alpha, **kw)
        return self._last.value(self.response.name, solution,
                                lambda: evaluate_response(self.response, solution, self.steps))

    def evaluate_value(self, alpha) -> float:
        """Θ(α) alone (one state solve per load case, combined as [objective] combine says)."""
        return self.evaluate_cases(alpha).value

    def evaluate_cases(self, alpha, **kw):
        """Θ_k of every load case and their combination at α: a
        ``contactopt.sensitivity.cases.Combined`` (``kw`` go to :meth:`solve_state`)."""
        return self.response_value(alpha, **kw).combined

    def evaluate(self, alpha):
        """(Θ(α), ξ) with ξ a Clarke subgradient from the adjoint system (4.15)."""
        with sequential_openblas():
            res = self.subgradient(alpha)
        return res.value, res.gradient

    def subgradient(self, alpha, *, choices=None):
        """Θ(α) and one Clarke subgradient of the combined load cases
        (``contactopt.sensitivity.adjoint.SubgradientResult``; paper Theorem 4.1,
        ``contactopt.sensitivity.subgradient``).

        OpenBLAS runs on one thread throughout, as in the state solve (``contactopt._threads``):
        its spinning threads would otherwise slow the next design's PARDISO factorization; MKL on
        the path's evaluation threads (``[linear_solver] threads``)."""
        with sequential_openblas(), self.path.evaluation_threads():
            self._objective.resolve()
            t0 = time.perf_counter()
            solution = self.solution(alpha)
            t1 = time.perf_counter()
            return subgradient(self.parts, solution, self.response_value(alpha), choices, {"state": t1 - t0})

    # ------------------------------------------------------------------ [[constraints]]
    def constraint_subgradients(self, alpha, *, choices=None) -> list:
        """One ``contactopt.sensitivity.adjoint.SubgradientResult`` per constraint at α:
        the response's value (the worst load case) and one Clarke subgradient, by the adjoint of
        the state solved for Θ (no other state solve)."""
        return [self.for_constraint(j).subgradient(alpha, choices=choices) for j in range(len(self.constraints))]

    def constraint_values(self, alpha, case: int | None = None, **kw) -> list[float]:
        """The responses of the constraints at α: the worst load case's, or load case ``case``'s
        (``kw`` go to :meth:`solve_state`)."""
        out = []
        for j in range(len(self.constraints)):
            comb = self.for_constraint(j).evaluate_cases(alpha, **kw)
            out.append(float(comb.value if case is None else comb.values[case]))
        return out

    # ------------------------------------------------------------------ reports (contactopt.io.reports)
    def objective_report(self, alpha, case: int | None = None, **kw) -> dict:
        return reports.objective_report(self, alpha, case, **kw)

    def constraint_report(self, alpha, case: int | None = None, **kw) -> dict:
        return reports.constraint_report(self, alpha, case, **kw)

    def step_reports(self, alpha, case: int = 0, **kw) -> list | None:
        return reports.step_reports(self, alpha, case, **kw)

    def term_names(self) -> list:
        return reports.term_names(self)

    def step_columns(self) -> list[str]:
        return reports.step_columns(self)
