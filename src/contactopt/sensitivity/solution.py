"""The solve of one design as a value: the systems and contact states of every load case and step.

A design α is assembled once; the path prepares A(α) once and each load case adds its load vector
(``contactopt.sensitivity.cases``); on a load path (``contactopt.sensitivity.steps``) each
solve starts from the end of the one before. :func:`solve_design` returns a :class:`Solution`,
built once and never changed by what reads it: objectives, constraints and the subgradient are
functions of it. :class:`LastDesign` keeps the last one (as scipy's ``MemoizeJac`` keeps the last
point), so that Θ, ξ and the constraints at one design share one solve. A solution records the
contexts its solve started from (``start``), so that the same solve can be repeated bit for bit in
another process (a resumed run's outputs), and :class:`KeptDesign` keeps a solution without its
systems (the factorizations, the largest part) together with the responses' values evaluated on
it: a run's outputs at its initial design and at its optimum read them instead of solving again.

Contact conventions, on every path: per contact node m the order (t1, t2, ν) = (x1, x2, x3),
r the contact force on the body, λ = r_ν ≥ 0, τ = −r_t (paper (3.17)).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from .._threads import sequential_openblas
from ..contact.state import CLASS_CODES
from ..errors import SolverError


@dataclass
class Parts:
    """What the solve of every design uses: the ``model``, the solver ``path``, the load ``cases``,
    each case's load path ``steps`` (None: the static problem, one solve) and the ``contexts`` each
    solve carries from design to design (per case a list per solve, the first the case's own)."""

    model: object
    path: object
    cases: list
    steps: list
    contexts: list

    def label(self, k: int) -> str:
        """' of load case <name>' where the configuration has several cases, else ''."""
        return f" of load case {self.cases[k].name}" if len(self.cases) > 1 else ""

    def loads(self, k: int) -> tuple:
        """The load set of every solve of case k (one for the static problem)."""
        return (self.cases[k].loads,) if not self.steps[k] else tuple(s.loads for s in self.steps[k])

    def forces(self, k: int) -> tuple:
        """The force magnitude of a force-controlled obstacle at every solve of case k (None: no force control)."""
        return (self.model.force,) if not self.steps[k] else tuple(s.force for s in self.steps[k])


@dataclass(frozen=True)
class CaseSolution:
    """The ``systems`` and ``states`` of every solve of one load case (one: the static problem)."""

    systems: tuple
    states: tuple

    @property
    def system(self):
        """The system of the case's last solve (a load path's end)."""
        return self.systems[-1]

    @property
    def state(self):
        """The state of the case's last solve (a load path's end)."""
        return self.states[-1]


@dataclass(frozen=True)
class Solution:
    """The solve of design ``alpha`` by ``method``: a :class:`CaseSolution` per load case; ``cold``:
    solved without warm start, so that it answers a request without warm start (a run's final
    figures) independently of what was solved before."""

    alpha: np.ndarray
    method: str
    cold: bool
    cases: tuple
    start: list | None = None     # :func:`export_contexts` before the solve: the warm starts it began from

    @property
    def states(self) -> list:
        """The state of every load case (on a load path, that of its last solve)."""
        return [c.state for c in self.cases]

    @property
    def systems(self) -> list:
        return [c.system for c in self.cases]

    def answers(self, alpha: np.ndarray, method: str, warm_start: bool) -> bool:
        """Whether this solve is the one asked for (same α's bytes and method)."""
        return (self.alpha.tobytes(), self.method) == (alpha.tobytes(), method) and (warm_start or self.cold)

    def without_systems(self) -> Solution:
        """This solution with the states alone: the systems (factorizations, assembled matrices)
        dropped, so that keeping it costs the states' arrays only."""
        return replace(self, cases=tuple(replace(c, systems=()) for c in self.cases))


@dataclass(frozen=True)
class KeptDesign:
    """A design's :class:`Solution` (its systems dropped, unless it was solved for the purpose)
    and the values of the responses evaluated on it, by name; :meth:`LastDesign.restore` makes
    it the last design again, so that what reads the responses there reads these values."""

    solution: Solution
    values: dict

    @property
    def alpha(self) -> np.ndarray:
        return self.solution.alpha


def solve_design(parts: Parts, alpha: np.ndarray, *, method: str, warm_start: bool, tol: float) -> Solution:
    """The :class:`Solution` of design α (one assembly, one preparation by the path)."""
    path = parts.path
    out = []
    with sequential_openblas(), path.evaluation_threads():
        t0 = time.perf_counter()
        asm = path.assemble(alpha, parts.cases[0].loads)
        t1 = time.perf_counter()
        prepared = path.prepare(asm)
        prepared.timings = {"assembly": t1 - t0, **prepared.timings}
        systems = [prepared] + [_for_loads(parts, prepared, asm, case.loads) for case in parts.cases[1:]]
        shared = {}                    # what the cases of one design share (e.g. a factor of S)
        for k, system in enumerate(systems):
            if not parts.steps[k]:
                st = path.solve_state(system, parts.contexts[k][0], alpha, method=method, warm_start=warm_start,
                                      tol=tol, shared=shared, label=parts.label(k))
                out.append(CaseSolution((system,), (st,)))
                continue
            steps = tuple(_step_system(parts, system, system.assembled, step) for step in parts.steps[k])
            out.append(CaseSolution(steps, _solve_path(parts, k, steps, alpha, method, warm_start, tol, shared)))
    return Solution(np.array(alpha, copy=True), method, not warm_start, tuple(out))


def _solve_path(parts, k, systems, alpha, method, warm_start, tol, shared) -> tuple:
    """The states of case k's load path, each solve from the end of the one before (sensitivity/steps.py)."""
    n = parts.model.n_contact
    states, slip, slid = [], None, np.zeros((n, 2))
    for step, system, ctx in zip(parts.steps[k], systems, parts.contexts[k]):
        st = parts.path.solve_state(system, ctx, alpha, method=method, warm_start=warm_start, tol=tol,
                                    shared=shared, label=f"{parts.label(k)}, step {step.name} ({step.substep})",
                                    slip_ref=slip)
        st.step, st.substep = step.name, step.substep
        if st.slip_ref is None:              # the first step: slip from the unloaded body
            st.slip_ref = np.zeros((n, 2))
        sliding = np.isin(st.classes, [CLASS_CODES["M1"], CLASS_CODES["M2"]])
        slid = slid + np.where(sliding[:, None], st.slip_increment, 0.0)
        st.slip = slid                       # the accumulated slip along the path
        states.append(st)
        slip = st.u_c[:, :2].copy()
    return tuple(states)


def _step_system(parts, system, asm, step):
    """The system of one solve of a load path (sharing the case's prepared system)."""
    out = _for_loads(parts, system, asm, step.loads)
    if step.force is not None:       # a force-controlled obstacle: the step's force (paths/force.py)
        out = replace(out, force=step.force)
    return out


def _for_loads(parts, system, asm, loads):
    """The prepared ``system`` with the load vector of ``loads`` on the design of ``asm``."""
    t0 = time.perf_counter()
    L_full = parts.model.load_vector(asm.coords, loads)
    asm_k = replace(asm, L_full=L_full, L=parts.model.free_load(L_full))
    t1 = time.perf_counter()
    out = parts.path.for_load(system, asm_k)
    out.timings = {"assembly": t1 - t0, **out.timings}
    return out


class LastDesign:
    """The :class:`Solution` of the last design solved, given again for the same α and method, and
    the values of the responses evaluated at it (each by its name)."""

    def __init__(self, parts: Parts):
        self.parts = parts
        self.solution: Solution | None = None
        self.n_solves = 0          # designs solved (all cases at once)
        self._values = {}

    def __call__(self, alpha: np.ndarray, *, method: str, warm_start: bool, tol: float) -> Solution:
        if not np.all(np.isfinite(alpha)):
            raise SolverError("design contains NaN or infinite entries")
        if self.solution is None or not self.solution.answers(alpha, method, warm_start):
            self.clear()
            start = [[{k: np.array(v, copy=True) for k, v in ctx.items()} for ctx in row]
                     for row in export_contexts(self.parts)]
            self.solution = replace(solve_design(self.parts, alpha, method=method, warm_start=warm_start, tol=tol),
                                    start=start)
            self.n_solves += 1
        return self.solution

    def keep(self) -> KeptDesign:
        """The last design's solve, its systems dropped, with the values evaluated on it so far."""
        return KeptDesign(self.solution.without_systems(), dict(self._values))

    def restore(self, kept: KeptDesign) -> None:
        """Make ``kept`` the last design: requests at its α and method answer from it."""
        self.solution, self._values = kept.solution, dict(kept.values)

    def value(self, name: str, solution: Solution, evaluate):
        """The value of the response ``name`` at ``solution``: ``evaluate()`` once per solution."""
        if solution is not self.solution:
            return evaluate()
        if name not in self._values:
            self._values[name] = evaluate()
        return self._values[name]

    def clear(self) -> None:
        """Forget the last design (the next request solves anew)."""
        self.solution, self._values = None, {}


def export_contexts(parts: Parts) -> list:
    """What every solve carries from design to design: ``[k][j]`` the arrays of load case k at
    load step j (a checkpoint holds them)."""
    return [[parts.path.export_context(ctx) for ctx in row] for row in parts.contexts]


def import_contexts(parts: Parts, arrays: list, where: str) -> None:
    """Put back :func:`export_contexts` (read from a checkpoint ``where``)."""
    rows = parts.contexts
    for k, row in enumerate(rows):
        parts.path.import_context(row[0], arrays[k][0], where, others=[r[0] for r in rows[:k]])
        for j, ctx in enumerate(row[1:], 1):
            parts.path.import_context(ctx, arrays[k][j], where, others=[r[0] for r in rows] + [
                c for r in rows for c in r[1:] if c is not ctx])
