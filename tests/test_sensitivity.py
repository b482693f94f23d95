"""Subgradients from the adjoint (4.15) against finite differences and an independent adjoint."""

import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient
from contactopt.sensitivity.check import check_gradient


def small_problem(friction=0.3, objective="target_normal_force", mesh=(8, 4, 3), **extra):
    upd = {"mesh": {"nx": mesh[0], "ny": mesh[1], "nz": mesh[2]},
           "state": {"method": "newton", "tol": 1e-12},
           "friction": {"coefficient": friction}, "objective": {"type": objective}}
    upd.update(extra)
    return ShapeProblem(load_config("example1").with_updates(upd))


def wavy(problem, amp=0.005, phase=0.0):
    a = problem.model.initial_design() + amp * np.sin(np.arange(problem.model.n_design) + phase)
    return a + 0.01 - a.mean()


@pytest.mark.parametrize("friction,objective", [(0.3, "target_normal_force"), (1.0, "target_normal_force"),
                                                (0.6, "compliance"), (0.3, "pressure_uniformity")])
def test_subgradient_matches_central_differences(friction, objective):
    pr = small_problem(friction, objective)
    alpha = wavy(pr)
    assert pr.model.admissible.is_feasible(alpha)
    rep = check_gradient(pr, alpha, seed=1, n_directions=10)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9
    if friction >= 1.0:
        assert rep.counts["M3+"] > 0 and rep.counts["M1"] > 0    # sticking and sliding both exercised


def signorini_adjoint_gradient(pr, alpha):
    """Independent frictionless gradient: the active-set KKT system S u − ℓ = E_A λ_A, E_Aᵀu = −g_A."""
    state = pr.solve_state(alpha)
    cond = pr.cached_condensed(alpha)
    p = state.lam.size
    active = np.flatnonzero(state.lam > 1e-9 * state.lam.max())
    nA = active.size
    E = np.zeros((3 * p, nA))
    E[3 * active + 2, np.arange(nA)] = 1.0
    K = np.block([[cond.S, -E], [E.T, np.zeros((nA, nA))]])
    dJ_dlam = pr.objective.evaluate(state, cond).derivatives.dlam
    rhs = np.concatenate([np.zeros(3 * p), dJ_dlam[active]])
    adj = np.linalg.solve(K.T, -rhs)            # multipliers of the two equation blocks
    mu, eta = adj[:3 * p], adj[3 * p:]
    model = pr.model
    v_full = model.assembler.to_full(cond.factor.extend(mu))
    g = model.design_contraction(cond.assembled.coords, state.u, v_full)
    g += model.gap_matrix[active].T @ eta
    return g


def test_frictionless_matches_differentiable_signorini_adjoint():
    pr = small_problem(0.0)
    alpha = wavy(pr, phase=1.0)
    res = subgradient(pr, alpha)
    assert res.n_degenerate == 0
    ref = signorini_adjoint_gradient(pr, alpha)
    assert np.linalg.norm(res.gradient - ref) <= 1e-8 * np.linalg.norm(ref)


def test_degenerate_node_gives_a_one_sided_gradient():
    """At a class change along a line, ξ lies in the hull of the gradients from either side."""
    pr = small_problem(0.3, mesh=(6, 3, 2))
    a0, d = wavy(pr, 0.004), np.cos(np.arange(pr.model.n_design))
    d -= d.mean()

    def classes(s):
        return pr.solve_state(a0 + s * d).classes.copy()

    lo, hi = 0.0, 0.004
    c_lo = classes(lo)
    assert np.any(classes(hi) != c_lo), "no class change on the search interval"
    # bisection on "still the classes of lo"; the degenerate window between the two stable classes
    # is reached when a midpoint has a degenerate node
    s_star = None
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        state = pr.solve_state(a0 + mid * d)
        if state.n_degenerate:
            s_star = mid
            break
        if np.array_equal(state.classes, c_lo):
            lo = mid
        else:
            hi = mid
    assert s_star is not None, "bisection did not reach a degenerate node"
    alpha_star = a0 + s_star * d
    res = subgradient(pr, alpha_star)
    assert res.n_degenerate >= 1 and not res.exact
    delta = 1e-6
    g_minus = subgradient(pr, alpha_star - delta * d).gradient
    g_plus = subgradient(pr, alpha_star + delta * d).gradient
    # one-sided gradients checked by finite differences in the same direction
    for g, sgn in ((g_minus, -1), (g_plus, 1)):
        base = alpha_star + sgn * delta * d
        h = 2e-7
        fd = (pr.evaluate_value(base + h * d) - pr.evaluate_value(base - h * d)) / (2 * h)
        assert abs(g @ d - fd) <= 1e-4 * abs(fd)
    # distance of ξ to the segment [g_minus, g_plus]
    seg = g_plus - g_minus
    t = np.clip((res.gradient - g_minus) @ seg / max(seg @ seg, 1e-300), 0.0, 1.0)
    dist = np.linalg.norm(res.gradient - (g_minus + t * seg))
    assert dist <= 1e-3 * np.linalg.norm(g_minus), (dist, np.linalg.norm(seg))


def test_class_codes_cover_table_4_1():
    assert set(CLASS_CODES) == {"L", "M1", "M2", "M3+", "M3-", "M4"}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["example1", "example2", "example3"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_paper_examples_subgradient_vs_finite_differences(name, seed):
    """Examples 1–3 at α0 (seed 0) and at random admissible designs: 10 directions, 1e-6, rate ≥ 1.9."""
    from scipy.optimize import linprog
    pr = ShapeProblem(name)
    U = pr.model.admissible
    a0 = pr.model.initial_design()
    alpha = a0
    if seed:
        c = np.random.default_rng(seed).standard_normal(pr.model.n_design)
        v = linprog(c, A_ub=U.A_ub, b_ub=U.b_ub, A_eq=U.A_eq, b_eq=U.b_eq, bounds=list(zip(U.lb, U.ub))).x
        alpha = a0 + 0.02 * (v - a0)
    assert U.is_feasible(alpha)
    rep = check_gradient(pr, alpha, seed=seed, n_directions=10)
    assert rep.n_degenerate == 0
    assert rep.rel_errors.max() <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9
