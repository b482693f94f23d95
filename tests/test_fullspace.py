"""The full-space semismooth Newton with AMG-preconditioned GMRES (contact/fullspace/) against
today's condensed path (ShapeProblem.solve_state: S on the contact DOFs, the zone's local Newton).

Both solve the same discrete Coulomb problem A u = L + Bᵀ r with the contact law (paper (3.17)):
λ, τ and u_c must agree to 1e-8 relative (to max |λ| and max |u_c|) and the node classes of
Table 4.1 must be the same, at the example's initial design (cold start) and at a perturbed design
(warm start from the first design's forces, displacement and AMG hierarchy); the adjoint (4.15)
in full space gives the condensed path's v_u, v_λ and subgradient. A solve that cannot converge
raises a SolverError with its history, never an inaccurate state.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.config import load_config, validate
from contactopt.contact.fullspace import OPEN, SLIDE, STICK, solve_fullspace
from contactopt.contact.state import CLASS_CODES, classify_nodes
from contactopt.errors import ContactNotConverged, SolverError
from contactopt.fem.krylov import KrylovNotConverged, gmres
from contactopt.mesh.block import block_mesh
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient
from contactopt.sensitivity.adjoint_fullspace import ADJOINT_RTOL, subgradient_fullspace

TOL = 1e-8
NEWTON_CLASS = {OPEN: CLASS_CODES["L"], STICK: CLASS_CODES["M3+"], SLIDE: CLASS_CODES["M1"]}


class Case:
    """One example: the problem, two designs, today's states and the data of the full space."""

    def __init__(self, name, step):
        self.problem = pb = ShapeProblem(name)
        m = pb.model
        self.a0 = m.initial_design()
        d = np.random.default_rng(7).standard_normal(m.n_design)
        d -= d.mean()
        self.a1 = self.a0 + step * d / np.abs(d).max()
        assert m.admissible.is_feasible(self.a1)
        self.states = [pb.solve_state(a, warm_start=False) for a in (self.a0, self.a1)]
        self.asm = [m.assemble(a, pb.cases[0].loads) for a in (self.a0, self.a1)]

    def solve(self, k, **kw):
        asm, m = self.asm[k], self.problem.model
        return solve_fullspace(asm.A, asm.L, m.contact_dofs, asm.gap, self.problem.friction,
                               coords=asm.coords, free=m.assembler.free, **kw)


@pytest.fixture(scope="module", params=[("example1", 2e-3), ("example2", 2e-3)], ids=["example1", "example2"])
def case(request):
    return Case(*request.param)


def assert_same_state(res, st, friction):
    lscale = np.abs(st.lam).max()
    uscale = np.abs(st.u_c).max()
    assert lscale > 0
    assert np.abs(res.lam - st.lam).max() <= TOL * lscale
    assert np.abs(res.tau - st.tau).max() <= TOL * lscale
    assert np.abs(res.u_c - st.u_c).max() <= TOL * uscale
    classes = classify_nodes(res.u_c, res.lam, res.tau, st.gap, friction)
    assert np.array_equal(classes, st.classes)
    # the classes of the last Newton system are those of Table 4.1 (no degenerate node here)
    assert st.n_degenerate == 0
    assert np.array_equal(np.vectorize(NEWTON_CLASS.get)(res.classes), st.classes)


def test_agrees_with_the_condensed_path(case):
    first = case.solve(0, tol=1e-11)                  # cold start: r = 0, AMG built here
    assert first.converged and first.error <= 1e-11 and first.equilibrium <= 1e-11
    assert first.info["start_solve"] and first.timings["amg_setup"] > 0
    assert_same_state(first, case.states[0], case.problem.friction)
    # the next design: warm from the first one's forces, displacement and hierarchy
    nxt = case.solve(1, tol=1e-11, r0=first.r, u0=first.u, hierarchy=first.hierarchy)
    assert nxt.hierarchy is first.hierarchy and nxt.timings["amg_setup"] == 0.0
    assert_same_state(nxt, case.states[1], case.problem.friction)
    assert nxt.newton_steps < first.newton_steps
    assert len(nxt.krylov_iterations) == nxt.newton_steps
    assert len(nxt.history) == nxt.newton_steps + 1 and nxt.history[-1] <= 1e-11
    # the whole equilibrium A u = L + Bᵀ r holds, r the returned forces
    asm, cd = case.asm[1], case.problem.model.contact_dofs.reshape(-1, 3)
    f = asm.L.copy()
    f[cd.ravel()] += nxt.r[:, [1, 2, 0]].ravel()
    assert np.linalg.norm(asm.A @ nxt.u - f) <= 1e-10 * np.linalg.norm(asm.L)


def test_warm_start_from_forces_only_and_a_small_zone(case):
    """r0 alone (u0 by one Krylov solve) and a zone of a few nodes that must grow."""
    st = case.states[1]
    start = np.zeros((st.lam.size, 3))
    start[:, 0] = case.states[0].lam
    start[:, 1:] = -case.states[0].tau
    zone = np.argsort(st.gap + st.u_c[:, 2])[:5]         # far too small: nodes in contact outside
    res = case.solve(1, tol=1e-11, r0=start, zone=zone)
    assert res.info["start_solve"]
    assert res.zone_growths >= 1 and res.zone.size > zone.size
    assert_same_state(res, st, case.problem.friction)
    assert np.all(res.r[np.setdiff1d(np.arange(st.lam.size), res.zone)] == 0.0)


@pytest.mark.parametrize("friction", [0.0, 0.6])
def test_frictionless_and_mostly_sticking(friction):
    """F = 0 (sliding nodes with a zero Robin block, no friction coupling) and F = 0.6 (most
    nodes in contact stick: three Dirichlet DOFs each) on Example 1 at 16×8×5."""
    pb = ShapeProblem(load_config("example1").with_updates({"friction": {"coefficient": friction},
                                                             "mesh": {"nx": 16, "ny": 8, "nz": 5}}))
    m = pb.model
    a = m.initial_design()
    st = pb.solve_state(a)
    asm = m.assemble(a, pb.cases[0].loads)
    res = solve_fullspace(asm.A, asm.L, m.contact_dofs, asm.gap, friction, coords=asm.coords,
                          free=m.assembler.free, tol=1e-11)
    assert_same_state(res, st, friction)
    assert np.sum(res.classes == STICK) == (0 if friction == 0 else st.counts["M3+"])


@pytest.mark.parametrize("config", ["bracket.toml", "round_pad.toml"])
def test_flexible_body_and_tetrahedra(config):
    """The L-shaped bracket (a flexible foot: the Delassus diagonal is 5–48 times 1/A_mm, so ρ
    needs the coarse compliance of the hierarchy; with the local estimate alone Newton cycled)
    and the round pad (ten-node tetrahedra, almost all nodes sticking), cold starts."""
    root = Path(__file__).resolve().parents[1] / "examples"
    pb = ShapeProblem(root / config)
    m = pb.model
    a = m.initial_design()
    st = pb.solve_state(a)
    asm = m.assemble(a, pb.cases[0].loads)
    res = solve_fullspace(asm.A, asm.L, m.contact_dofs, asm.gap, pb.friction, coords=asm.coords,
                          free=m.assembler.free, tol=1e-11, max_steps=20)
    assert_same_state(res, st, pb.friction)


def test_newton_failure_raises_with_its_history(case):
    with pytest.raises(ContactNotConverged) as info:
        case.solve(0, tol=1e-11, max_steps=2)
    assert isinstance(info.value, SolverError)
    assert len(info.value.history) == 3 and info.value.history[-1] > 1e-11
    res = case.solve(0, tol=1e-11, max_steps=2, raise_on_failure=False)
    assert not res.converged and res.newton_steps == 2


def test_the_stall_forcing_takes_over_where_inexact_steps_stop_halving_the_error(case):
    """A forcing so loose (10·error, at most 1) that its Krylov solves stop after one or two
    iterations, and the stall forcing (1e-3·error, at most 1e-4) behind it: the Krylov tolerances
    the solve used, read back, are the loose ones up to a step whose error is above half the one
    before, the tight ones from there (1e-12 at the end: the classes settled or the step past the
    tolerance), and the state is the condensed path's. The loose forcing alone stalls on Example 2
    (its error stays at 7.8e-2) and reaches the same state on Example 1."""
    kw = dict(tol=1e-11, krylov_rtol=1e-12, polish_below=1e-13, eta_factor=10.0, eta_max=1.0, max_steps=40)

    def loose(h):
        return min(1.0, max(1e-12, 10.0 * h))

    def tight(h):
        return min(1e-4, max(1e-12, 1e-3 * h))
    res = case.solve(0, stall_forcing=(1e-3, 1e-4), **kw)
    h, etas = res.history, res.krylov_rtol[1:]                # (the start solve's first)
    assert res.converged and len(etas) == len(h) - 1 and etas[-1] == 1e-12
    first = next(k for k, (e, x) in enumerate(zip(etas, h)) if e != loose(x) and e != 1e-12)
    assert first > 1 and h[first] > 0.5 * h[first - 1]
    assert all(e == loose(x) for e, x in zip(etas[:first], h))
    assert all(e in (1e-12, tight(x)) for e, x in zip(etas[first:], h[first:]))
    assert_same_state(res, case.states[0], case.problem.friction)
    plain = case.solve(0, raise_on_failure=False, **kw)
    assert all(e in (1e-12, loose(x)) for e, x in zip(plain.krylov_rtol[1:], plain.history))
    if plain.converged:
        assert_same_state(plain, case.states[0], case.problem.friction)
    else:
        assert plain.error > 1e-2


def test_krylov_failure_raises_with_its_history(case):
    with pytest.raises(KrylovNotConverged) as info:
        case.solve(0, tol=1e-11, max_krylov=2)
    assert isinstance(info.value, SolverError)
    assert len(info.value.history) >= 2 and info.value.history[-1] > 0


def test_adjoint_in_full_space_agrees_with_the_condensed_one(case):
    """(4.15) on the full space with the state's hierarchy: v_u, v_λ and ξ as the condensed path."""
    pb, m = case.problem, case.problem.model
    ref = subgradient(pb, case.a1)
    res = case.solve(1, tol=1e-11)
    value, xi, state, adj, _ = subgradient_fullspace(m, pb.cases[0].objective, case.a1, case.asm[1], res,
                                                     pb.friction)
    assert np.array_equal(state.classes, ref.state.classes)
    assert value == pytest.approx(ref.value, rel=1e-9)
    assert adj.history[-1] <= ADJOINT_RTOL
    # measured 1e-10 and 1e-8 (the two designs): the state's tolerance 1e-11 limits them, not GMRES
    assert np.abs(adj.v_u - ref.v_u).max() <= 1e-7 * np.abs(ref.v_u).max()
    assert np.abs(adj.v_lam - ref.v_lam).max() <= 1e-7 * np.abs(ref.v_lam).max()
    assert np.abs(xi - ref.gradient).max() <= 1e-8 * np.abs(ref.gradient).max()
    assert adj.iterations == len(adj.history) - 1


def test_gmres_on_a_nonsymmetric_system():
    rng = np.random.default_rng(3)
    n = 200
    G = sp.random(n, n, density=0.05, random_state=4) + sp.diags(np.linspace(1.0, 10.0, n))
    b = rng.standard_normal(n)
    d = G.diagonal()
    res = gmres(G.dot, b, lambda v: v / d, atol=1e-12 * np.linalg.norm(b), restart=15)
    assert np.linalg.norm(G @ res.x - b) <= 1e-12 * np.linalg.norm(b)
    assert res.history[0] == pytest.approx(1.0) and res.history[-1] <= 1e-12
    assert res.iterations == len(res.history) - 1
    with pytest.raises(KrylovNotConverged) as info:
        gmres(G.dot, b, atol=1e-14 * np.linalg.norm(b), restart=5, max_iter=7)
    assert len(info.value.history) == 8


# ------------------------------------------------------------------ a press fit without load
def plane_press_fit(tmp_path, path, friction):
    """A block 2 × 1 × 1 (8 × 4 × 3 hexahedra) clamped on its top whose underside starts below the
    plane x3 = 0 by about 1e-3 (``initial_gap = "mesh"``, ``interference = true``), E = 1, no load."""
    m = block_mesh(2.0, 1.0, 1.0, 8, 4, 3)
    pts = m.points.copy()
    pts[:, 2] -= 1e-3 * (1.0 + 0.2 * np.sin(pts[:, 0]))
    meshio.write(tmp_path / "fit.vtu", meshio.Mesh(pts, [("hexahedron", m.cells)]))
    return validate({"name": "plane-fit", "material": {"E": 1.0, "nu": 0.3}, "friction": {"coefficient": friction},
                     "body": {"mesh": str(tmp_path / "fit.vtu"), "contact": {"box": [[-1, 3], [-1, 2], [-0.01, 0.0]]},
                              "clamped": {"box": [[-1, 3], [-1, 2], [0.9, 1.1]]}, "initial_gap": "mesh",
                              "interference": True},
                     "loads": {"body_force": [0.0, 0.0, 0.0]}, "design": {"degree": [2, 1], "initial": 0.0, "C2": 0.0},
                     "state": {"method": "newton", "tol": 1e-12}, "linear_solver": {"path": path}}, "plane-fit")


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_a_press_fit_on_the_plane_without_load_equals_the_condensation(tmp_path, friction):
    # L = 0: the residuals against the overlap's force (the fit's forces are ~1e-3, not 1)
    cond, full = (ShapeProblem(plane_press_fit(tmp_path, path, friction)) for path in ("condensation", "fullspace"))
    assert full.path.name == "fullspace"
    alpha = cond.model.initial_design()
    sc, sf = cond.solve_state(alpha), full.solve_state(alpha)
    assert sf.converged and np.array_equal(sc.classes, sf.classes)
    assert np.abs(sf.lam - sc.lam).max() <= TOL * sc.lam.max()
    assert np.abs(sf.tau - sc.tau).max() <= TOL * sc.lam.max()
    assert np.abs(sf.u - sc.u).max() <= TOL * np.abs(sc.u).max()
