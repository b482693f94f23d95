"""One Clarke subgradient of a response from a solution and the response's partial derivatives.

For each load case of nonzero coefficient c_k (``contactopt.sensitivity.cases``) the adjoint
runs backward through the case's solves (a static problem: its one solve; a load path:
``contactopt.sensitivity.steps``), each solve's adjoint (4.15) with the response's right-hand
side at that solve plus what the solve after it passes down, P_t(S v + y*_u) (with y*_u on every
DOF, P_t((A ṽ)_c + y*_c): :meth:`~contactopt.paths.base.SolverPath.adjoint_carry`), and

    ξ_k = Σ_solves [∂J/∂α + ṽᵀ(∂A/∂α u − ∂L/∂α) + v_λᵀ ∂g/∂α],     ξ = Σ_k c_k ξ_k,

ṽ the A-harmonic extension of the adjoint v_u (paper Theorem 4.1). A force-controlled obstacle
adds the dependence of its translation on α at every solve (:mod:`contactopt.paths.force`).
The same code serves Θ and every constraint: a response is data (:mod:`.responses`).

Conventions: per contact node the order (t1, t2, ν), λ = r_ν ≥ 0, τ = −r_t (paper (3.17)).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ..errors import SolverError
from .adjoint import DEFAULT_CHOICES, SubgradientResult
from .partials import FULL
from .steps import add_at_contact, tangential

log = logging.getLogger(__name__)


def subgradient(parts, solution, value, choices=None, timings=None) -> SubgradientResult:
    """Θ and one Clarke subgradient of the response ``value`` (a
    :class:`~contactopt.sensitivity.responses.ResponseValue` at ``solution``); ``parts`` the
    problem's :class:`~contactopt.sensitivity.solution.Parts`, ``choices`` those of the degenerate
    classes (``contactopt.sensitivity.adjoint``), ``timings`` more timings to report."""
    for k, case in enumerate(value.cases):
        if not np.isfinite(case.value):
            raise SolverError(f"objective{parts.label(k)} is not finite at this design ({case.value})")
    comb = value.combined
    t_adj = t_design = 0.0
    g, nd, v_u, v_lam = None, 0, None, None
    for k in np.flatnonzero(comb.coefficients):
        xi, v_u_k, v_lam_k, nd_k, t = case_subgradient(parts, k, solution.cases[k], value.cases[k].solves, choices)
        g = comb.coefficients[k] * xi if g is None else g + comb.coefficients[k] * xi
        t_adj, t_design, nd = t_adj + t[0], t_design + t[1], nd + nd_k
        if nd_k:
            where = " along the load path" if parts.steps[k] else ""
            log.info("subgradient at a design with %d degenerate node(s)%s%s %s", nd_k, where, parts.label(k),
                     solution.cases[k].state.counts)
        if k == comb.case:
            v_u, v_lam = v_u_k, v_lam_k
    if not np.all(np.isfinite(g)):
        raise SolverError("subgradient has non-finite entries")
    names = tuple(c.name for c in parts.cases)
    active = tuple(names[i] for i in comb.active)
    if value.kind == "max" and len(active) > 1:
        log.info("subgradient at a design where %d load cases are active (%s): the subgradient is "
                 "that of %s", len(active), ", ".join(active), names[comb.case])
    exact = nd == 0 and (value.kind == "sum" or len(active) == 1)
    return SubgradientResult(value=comb.value, gradient=g, state=solution.states[comb.case], v_u=v_u, v_lam=v_lam,
                             n_degenerate=nd, exact=exact, choices={**DEFAULT_CHOICES, **(choices or {})},
                             timings={**(timings or {}), "adjoint": t_adj, "design_terms": t_design},
                             case_values=comb.values, case_names=names, active_cases=active,
                             case=names[comb.case], states=solution.states, terms=dict(value.cases[comb.case].terms))


def case_subgradient(parts, k: int, case, rhs: dict, choices):
    """(ξ_k, v_u, v_λ of the last solve, degenerate nodes, (adjoint time, design-term time)) of load
    case k, backward through its solves; ``rhs`` {solve: Derivatives} the response's partials."""
    path, model = parts.path, parts.model
    loads, forces, ctxs = parts.loads(k), parts.forces(k), parts.contexts[k]
    pinned = model.contact_pinned.ravel()      # per row of the law, in its frame (t1, t2, ν), as the carry
    contact = (3 * model.contact_nodes[:, None] + np.arange(3)).ravel()
    xi, carry, nd, out, t_adj, t_design = None, None, 0, None, 0.0, 0.0
    for j in range(max(rhs), -1, -1):
        t0 = time.perf_counter()
        state, system = case.states[j], case.systems[j]
        p = state.lam.size
        y_u, y_lam = np.zeros(3 * p), np.zeros(p)
        if j in rhs:
            d = rhs[j]
            y_u, y_lam = d.du, d.dlam
            xi = d.dalpha if xi is None else xi + d.dalpha
        own = y_u                       # the response's own ∂J/∂u at this solve
        late = {}                       # a carry that joins the adjoint after ∂J/∂u's map
        if carry is not None:           # on every DOF: y_u's global components
            full = j in rhs and rhs[j].space == FULL
            if full and system.relative:    # on a foundation: ∂/∂w, not ∂/∂u_c of the body
                late = {"carry": carry}
            else:
                y_u = add_at_contact(y_u, path.global_contact(carry) if full else carry, contact, full)
        v_u, v_lam, v_full, krylov = path.adjoint(system, ctxs[j], state, y_u, y_lam, choices, **late)
        if krylov is not None:
            state.stats.adjoint_krylov = krylov
        t1 = time.perf_counter()
        xi = xi + path.design_contraction(system, state.u, v_full, loads[j]) + model.gap_matrix.T @ v_lam
        nd += state.n_degenerate
        if out is None:
            out = (v_u, v_lam)
        if j:
            passed = path.adjoint_carry(system, ctxs[j], v_u, v_full, y_u)
            carry = tangential(passed + late["carry"] if late else passed)
        if forces[j] is not None:
            xi, carry = _force(path, system, ctxs[j], state, v_lam, v_full, own, xi, carry, j, loads[j])
        if j:
            carry[pinned] = 0.0          # u_t = 0 there in every step
        t_adj, t_design = t_adj + t1 - t0, t_design + time.perf_counter() - t1
    return xi, out[0], out[1], nd, (t_adj, t_design)


def _force(path, system, ctx, state, v_lam, v_full, own, xi, carry, j: int, loads):
    """(ξ, carry) of solve j with a force-controlled obstacle, its translation s_j following α and
    the previous solve's slip u_t^(j−1) (F_j(α, u_t^(j−1), s_j) = 0): with μ = (∂Θ/∂s)/(∂F/∂s), ξ
    gains −μ ∂F/∂α and the carry −μ P_t(S w_u + ∂F/∂u_c) of F's adjoint w (paths/force.py)."""
    t = path.force_terms(system, ctx, state, v_lam, loads, v=v_full, y_u=own)
    if t.dF_ds == 0:
        return xi, carry
    xi = xi - t.dT_ds * t.dF_da / t.dF_ds
    if j:
        carry_F = tangential(path.adjoint_carry(system, ctx, t.adjoint.v_u, t.adjoint.v, t.y_F))
        carry = carry - t.dT_ds * carry_F / t.dF_ds
    return xi, carry
