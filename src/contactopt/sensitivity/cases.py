"""Load cases and their combination into one objective Θ(α).

A configuration without ``[[load_cases]]`` has one case: the loads of ``[loads]`` and the
objective of ``[objective]``. With cases, case k acts with its own loads plus those written in
``[loads]`` and has its own objective Θ_k(α) = J_k(α, S_k(α)) (its own target, if it gives one).
The cases share A(α), its factorization, the Schur complement S and the Delassus data: only the
condensed load ℓ_k, the contact state and the adjoint are per case (:mod:`contactopt.problem`).

``[objective] combine`` joins them, with weights w_k ≥ 0 (default 1):

    "max":  Θ = max_k w_k Θ_k   (worst case; nonsmooth where two cases tie)
    "sum":  Θ = Σ_k w_k Θ_k

For the max, a Clarke subgradient is w_k ξ_k of an active case k (the first of largest value):
exact where one case alone is active (and none of its nodes is degenerate); where several are
active within ``active_tol`` (relative), ∂Θ is the convex hull of theirs, and the result names
every active case, as the adjoint names degenerate nodes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..fem.loadset import load_set
from .objectives import make_objective


@dataclass
class LoadCase:
    """One load case: ``loads`` a :class:`~contactopt.fem.loadset.LoadSet`, or None for the
    model's own ``[loads]`` (a configuration without cases); ``objective`` its J_k."""

    name: str
    loads: object
    objective: object
    weight: float = 1.0


@dataclass
class Combined:
    """Θ of the combined cases at one design.

    ``values`` Θ_k (unweighted, in case order), ``coefficients`` c_k with ξ = Σ_k c_k ξ_k
    (max: w_k at the chosen case, 0 elsewhere; sum: the weights), ``active`` indices of the
    cases active within the tolerance (max) or of positive weight (sum), ``case`` the index
    of the case whose subgradient the max uses (for the sum: the largest weighted term).
    """

    value: float
    values: np.ndarray
    coefficients: np.ndarray
    active: list = field(default_factory=list)
    case: int = 0


@dataclass
class Combination:
    """``[objective] combine``, ``weights`` and ``active_tol`` for the cases ``names``."""

    kind: str
    weights: np.ndarray
    active_tol: float
    names: tuple

    def combine(self, values) -> Combined:
        v = np.asarray(values, float)
        wv = self.weights * v
        k = int(np.argmax(np.where(self.weights > 0, wv, -np.inf)))   # a case of weight 0 never counts
        if self.kind == "sum":
            value = float(wv[0]) if v.size == 1 else float(np.sum(wv))
            return Combined(value, v, self.weights.copy(), [int(i) for i in np.flatnonzero(self.weights > 0)], k)
        top = float(wv[k])
        band = self.active_tol * max(abs(top), np.finfo(float).tiny)
        active = [int(i) for i in np.flatnonzero((wv >= top - band) & (self.weights > 0))]
        coef = np.zeros(v.size)
        coef[k] = self.weights[k]
        return Combined(top, v, coef, active, k)


def case_tables(config) -> list:
    """The ``[[load_cases]]`` of a configuration (:class:`~contactopt.config.LoadCase`); none:
    one case of ``[loads]``."""
    return list(config.load_cases)


def build_cases(config, model, solve=None) -> tuple[list[LoadCase], Combination]:
    """The load cases of a configuration and their combination; ``solve(alpha, case)`` returns λ
    of a design's state under a case's loads (the objectives' 'design' targets)."""
    tables = case_tables(config)
    obj = config.objective
    if not tables:
        cases = [LoadCase(config.name, None, make_objective(config, model, solve=solve))]
    else:
        cases = []
        for k, table in enumerate(tables):
            loads = model.loads + load_set(model.body, table.loads, where=f"load_cases[{k}]")
            # a case's own objective: a 'design' target is λ(α*) of the case's loads
            objective = make_objective(config, model, target=table.target, case=k, solve=solve, loads=loads)
            cases.append(LoadCase(table.name, loads, objective))
    names = tuple(c.name for c in cases)
    w = obj.weights
    if isinstance(w, dict):
        weights = np.array([float(w.get(n, 1.0)) for n in names])
    else:
        weights = np.array([float(x) for x in w]) if w else np.ones(len(cases))
    for c, wk in zip(cases, weights):
        c.weight = float(wk)
    return cases, Combination(obj.combine, weights, float(obj.active_tol), names)
