"""Load paths: quasi-static load steps and Coulomb friction on the slip of each step.

A load path is a sequence of steps k = 1…N, each giving the total loads at its end (``[[load_steps]]``,
or a case's ``[[load_cases.steps]]``), from the unloaded body u⁰ = 0. A step of ``substeps`` = n is
n equal increments, linear in the loads, from the previous step's loads (the first from zero). Step
k is the static problem (paper (3.17)) with the tangential law on the slip increment
Δu_t^k = u_t^k − u_t^(k−1):

    ‖τ^k‖ ≤ Fλ^k,   Δu_t^k ≠ 0 ⇒ τ^k = Fλ^k Δu_t^k/‖Δu_t^k‖,   the normal law on the total u^k.

With z = u_c − s_k, s_k = (u_t^(k−1), 0) per node (t1, t2, ν), it is the static problem in z with
the load ℓ_k − S s_k: in the local (FCLIB) form the same W and q shifted by −s_k. The node classes
of Table 4.1 are taken with the slip increment. One step is the static problem, bit for bit.

Subgradient. The residual of step k is S z_k + S s_k − ℓ_k at the unknown y_k = (z_k, λ_k), so the
adjoint (4.15) of step k with right-hand side y*_k gives y*_kᵀ dy_k = v_kᵀ(∂S u_k − ∂ℓ_k + S ds_k):
the design terms are those of the static problem at the total u_k, and s_k = P_t u_(k−1) (P_t the
tangential components) couples the steps. Backward, with a_k the derivative of J with respect to
u_k (its own ∇_{u_k}J plus what the later steps pass down),

    a_N = ∇_{u_N}J,   v_k from (4.15) of step k with y*_u = a_k, y*_λ = ∇_{λ_k}J,
    a_(k−1) = ∇_{u_(k−1)}J + P_t(S v_k + a_k),   ξ = ∇_α J + Σ_k [ṽ_kᵀ(∂A u_k − ∂L_k) + v_λ,kᵀ ∂g].

``[objective] steps`` chooses Θ from the named steps' J: "last" (default), "max", "sum", or a
list of step names (the worst of them). An objective of the whole displacement (the peak stress)
gives y*_u on every DOF; what it passes down is then P_t((A ṽ_k)_c + y*_c), the same S v_k + ∂J/∂u_c.
On an elastic foundation the state's u_c is the relative w (the slip reference w_t^(k−1)): what a
step passes down is a derivative with respect to w, which joins a solve's y*_u on every DOF after
the map of the body's ∂J/∂u to w (:meth:`contactopt.paths.condensation.CondensationPath.adjoint`).
The friction work is a sum over the solves, J at the end of solve j = Σ_{i≤j} τ^i·Δu_t^i: each
increment's derivatives act on its own solve and, through Δu_t^i's reference u_t^(i−1), on the
solve before it (−τ^i on the tangential contact DOFs).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fem.loadset import LoadSet, load_set


@dataclass
class Step:
    """One solve of a load path: ``loads`` the total loads at its end, ``name`` the user's step
    it ends or belongs to, ``end`` whether it ends that step (its state is the step's state)."""

    name: str
    loads: object
    end: bool
    index: int = 0          # the user's step (0-based)
    substep: int = 1        # 1…substeps within it
    force: float | None = None   # |f| of a force-controlled obstacle at its end (None: no force control)


def step_tables(config, case: int | None) -> tuple:
    """The load steps (:class:`~contactopt.config.LoadStep`) of a load case (``case`` None: the
    configuration without cases); empty: no load path."""
    cases = config.load_cases
    own = cases[case].steps if case is not None and case < len(cases) else None
    return own if own is not None else config.load_steps


def build_path(model, base_loads, tables, where: str) -> list[Step] | None:
    """The solves of a load path: every substep of every step, in order; None without steps."""
    if not tables:
        return None
    base = base_loads if base_loads is not None else model.loads
    out, previous = [], LoadSet()
    force = model.force          # |f| of a force-controlled obstacle, else None
    f_prev = 0.0
    for n, table in enumerate(tables):
        loads = base + load_set(model.body, table.loads, where=f"{where}[{n}]")
        f_end = force if force is None or table.obstacle_force is None else float(np.linalg.norm(table.obstacle_force))
        m = int(table.substeps)
        for j in range(1, m + 1):
            now = loads if j == m else previous.scaled(1.0 - j / m) + loads.scaled(j / m)
            f_now = f_end if j == m or force is None else f_prev * (1.0 - j / m) + f_end * (j / m)
            out.append(Step(table.name, now, j == m, n, j, f_now))
        previous, f_prev = loads, f_end
    return out


@dataclass
class StepChoice:
    """``[objective] steps`` on one path: Θ of the named steps' values and its coefficients."""

    kind: str                 # "last", "max", "sum" or "list"
    names: tuple = ()

    @property
    def spec(self):
        """The choice as configured: "last", "max", "sum" or the list of step names."""
        return list(self.names) if self.kind == "list" else self.kind

    def combine(self, values: dict) -> tuple[float, dict]:
        """(Θ, {solve index: coefficient}) from ``values`` {solve index: (step name, J)} of the
        steps' ends in order."""
        items = list(values.items())
        if self.kind == "last":
            i, (_, v) = items[-1]
            return v, {i: 1.0}
        if self.kind == "sum":
            return float(sum(v for _, (_, v) in items)), {i: 1.0 for i, _ in items}
        pool = items if self.kind == "max" else [(i, nv) for i, nv in items if nv[0] in self.names]
        vals = np.array([v for _, (_, v) in pool])
        k = int(np.argmax(vals))
        return float(vals[k]), {pool[k][0]: 1.0}


def step_choice(config) -> StepChoice:
    """The choice of ``[objective] steps``."""
    return choice_of(config.objective.steps)


def choice_of(steps) -> StepChoice:
    """The :class:`StepChoice` of a ``steps`` value ("last", "max", "sum" or a list of step names)."""
    return StepChoice("list", tuple(steps)) if isinstance(steps, (list, tuple)) else StepChoice(steps)


def step_objective(objective, steps, states, systems, j: int, memo: dict):
    """The :class:`~contactopt.sensitivity.partials.Partials` of J at the end of solve j of a load
    path, keyed by solve: an objective of the state at solve j alone, the friction work summed over
    the solves up to j (:meth:`contactopt.sensitivity.objectives.Objective.evaluate_path`)."""
    return objective.evaluate_path(states[:j + 1], systems[:j + 1], [s.loads for s in steps[:j + 1]], memo)


def add_at_contact(y_u: np.ndarray, carry: np.ndarray, contact: np.ndarray, full: bool) -> np.ndarray:
    """y_u + carry with ``carry`` on the contact DOFs (3p, per node (t1, t2, ν)) and y_u on the
    contact DOFs (``full`` False) or on every DOF (``contact`` the full indices of the contact DOFs)."""
    if not full:
        return y_u + carry
    out = np.array(y_u, dtype=float, copy=True)
    out[contact] += carry
    return out


def tangential(x: np.ndarray) -> np.ndarray:
    """P_t x: the tangential components (t1, t2) of a contact vector (3p per node (t1, t2, ν))."""
    out = np.array(x, dtype=float, copy=True).reshape(-1, 3)
    out[:, 2] = 0.0
    return out.ravel()
