"""A Coulomb coefficient per contact node (``ElasticModel.contact_friction``, several contact pairs).

A uniform array gives the scalar run's state and subgradient to the bit; a coefficient that is 0 on
part of the face and 0.4 on the rest (a block 2 × 1 × 1 under a top and a side traction, so that
nodes stick and slide) gives the same state and subgradient on the condensation, Delassus and
full-space paths, a state in which every node satisfies its own Coulomb law, and a subgradient
that central differences confirm.
"""

import json

import numpy as np
import pytest

from contactopt._mpi import petsc_missing
from contactopt.config import load_config
from contactopt.contact.balance import check_held
from contactopt.contact.state import CLASS_CODES, classify_nodes, contact_conditions_violation
from contactopt.errors import ConfigError, ProblemDataError
from contactopt.fem.linsolve import pardiso_available
from contactopt.io.statefiles import read_state_npz, write_state
from contactopt.problem import ShapeProblem
from contactopt.runner import uniqueness_warnings
from contactopt.sensitivity.check import check_gradient

F = 0.4
PATHS = ["condensation", pytest.param("delassus", marks=pytest.mark.skipif(
    not pardiso_available(), reason="the Delassus path needs MKL PARDISO")), "fullspace"]


def block(path="condensation", friction=F, **updates):
    """Example 1's block (a = 2, b = 1) on an 8 × 4 × 3 mesh under the top traction and a side
    traction 0.05 along x1: at the flat design 0.01 the contact nodes at x1 ≥ 1.25 touch, the row
    x1 = 1.5 sticks and the others slide."""
    cfg = {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "linear_solver": {"path": path},
           "state": {"method": "newton", "tol": 1e-12}, "friction": {"coefficient": friction},
           "loads": {"right_traction": [5e-2, 0.0, 0.0]}, **updates}
    return ShapeProblem(load_config("example1").with_updates(cfg))


def split(problem):
    """F = 0 on the contact nodes with x1 < 0.7 a, F = 0.4 on the others."""
    x1 = problem.model.mesh.contact_points()[:, 0]
    return np.where(x1 < 0.7 * problem.config.geometry.a, 0.0, F)


def flat(problem):
    return np.full(problem.model.n_design, 0.01)


def designs(problem):
    a0 = problem.model.initial_design()
    return a0, a0 + 1e-3 * np.cos(np.arange(a0.size))


@pytest.mark.parametrize("path", PATHS)
def test_a_uniform_array_is_the_scalar_to_the_bit(path):
    scalar = block(path)
    # the configuration's coefficient is another: the array decides
    array = block(path, friction=0.1)
    array.model.contact_friction = np.full(array.model.n_contact, F)
    assert array.friction == F and isinstance(array.friction, float)
    for alpha in designs(scalar):
        (v1, xi1), (v2, xi2) = scalar.evaluate(alpha), array.evaluate(alpha)
        s1, s2 = scalar.solve_state(alpha), array.solve_state(alpha)
        assert s1.counts["M1"] > 0 and s1.counts["M3+"] > 0
        np.testing.assert_array_equal(s2.friction, np.full(s1.lam.size, F))
        if path == "condensation":
            assert v1 == v2
            np.testing.assert_array_equal(xi1, xi2)
            np.testing.assert_array_equal(s1.lam, s2.lam)
            np.testing.assert_array_equal(s1.tau, s2.tau)
        else:
            assert v2 == pytest.approx(v1, rel=1e-12)
            np.testing.assert_allclose(xi2, xi1, rtol=0, atol=1e-12 * np.abs(xi1).max())
            np.testing.assert_allclose(s2.lam, s1.lam, rtol=0, atol=1e-12 * s1.lam.max())
            np.testing.assert_allclose(s2.tau, s1.tau, rtol=0, atol=1e-12 * s1.lam.max())


_states = {}


def split_solution(path):
    """(problem, μ per node, state, Θ, ξ) of the split coefficient at the flat design, per path."""
    if path not in _states:
        problem = block(path)
        mu = split(problem)
        problem.model.contact_friction = mu
        alpha = flat(problem)
        res = problem.subgradient(alpha)
        _states[path] = problem, mu, res.state, res.value, res.gradient
    return _states[path]


@pytest.mark.parametrize("path", PATHS)
def test_each_node_satisfies_its_own_coulomb_law(path):
    problem, mu, st, _, _ = split_solution(path)
    np.testing.assert_array_equal(st.friction, mu)
    assert isinstance(problem.friction, np.ndarray)
    lam, tau_norm = st.lam, np.linalg.norm(st.tau, axis=1)
    fs = lam.max()
    touch = lam > 1e-8 * fs
    # both coefficients are in contact: F = 0 nodes slide freely, F = 0.4 nodes stick and slide
    assert np.sum(touch & (mu == 0)) >= 5 and np.sum(touch & (mu > 0)) >= 10
    fric = mu > 0
    assert np.sum(st.classes[fric] == CLASS_CODES["M3+"]) >= 5
    assert np.sum(st.classes[fric] == CLASS_CODES["M1"]) >= 5
    assert np.all(st.classes[touch & (mu == 0)] == CLASS_CODES["M1"])
    # ‖τ_m‖ ≤ F_m λ_m; at equality where node m slides (F = 0: τ = 0)
    assert np.max(tau_norm - mu * lam) <= 1e-10 * fs
    assert np.max(tau_norm[mu == 0]) <= 1e-10 * fs
    slide = fric & (st.classes == CLASS_CODES["M1"])
    np.testing.assert_allclose(tau_norm[slide], mu[slide] * lam[slide], rtol=1e-9)
    stick = fric & (st.classes == CLASS_CODES["M3+"])
    assert np.all(tau_norm[stick] < 0.99 * mu[stick] * lam[stick])
    assert st.complementarity <= 1e-9


@pytest.mark.parametrize("path", [p for p in PATHS if p != "condensation"])
def test_the_paths_agree_with_a_split_coefficient(path):
    _, _, ref, v_ref, xi_ref = split_solution("condensation")
    _, mu, st, value, xi = split_solution(path)
    np.testing.assert_array_equal(st.friction, mu)
    fs = ref.lam.max()
    np.testing.assert_allclose(st.lam, ref.lam, rtol=0, atol=1e-8 * fs)
    np.testing.assert_allclose(st.tau, ref.tau, rtol=0, atol=1e-8 * fs)
    np.testing.assert_array_equal(st.classes, ref.classes)
    assert value == pytest.approx(v_ref, rel=1e-8)
    np.testing.assert_allclose(xi, xi_ref, rtol=0, atol=1e-8 * np.abs(xi_ref).max())


def test_the_split_state_is_neither_uniform_coefficient():
    """The split coefficient's state lies between the frictionless and the uniform F = 0.4 ones:
    its tangential forces are not those of either."""
    _, mu, st, _, _ = split_solution("condensation")
    alpha = flat(block())
    for uniform in (0.0, F):
        other = block(friction=uniform).solve_state(alpha)
        assert np.abs(other.tau - st.tau).max() > 1e-3 * st.lam.max()


def test_the_subgradient_with_a_split_coefficient_matches_central_differences():
    problem = block()
    mu = split(problem)
    problem.model.contact_friction = mu
    alpha = flat(problem)
    rep = check_gradient(problem, alpha, seed=1, n_directions=8)
    assert rep.n_degenerate == 0
    assert rep.counts["M1"] > 0 and rep.counts["M3+"] > 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9
    st = problem.solve_state(alpha)
    assert np.max(np.linalg.norm(st.tau, axis=1)[mu == 0]) == 0.0 < st.lam[mu == 0].max()


@pytest.mark.skipif(petsc_missing() is not None, reason=f"PETSc path: {petsc_missing()}")
def test_the_petsc_path_with_a_split_coefficient():
    _, _, ref, v_ref, xi_ref = split_solution("fullspace")
    _, mu, st, value, xi = split_solution("petsc")
    np.testing.assert_array_equal(st.friction, mu)
    fs = ref.lam.max()
    np.testing.assert_allclose(st.lam, ref.lam, rtol=0, atol=1e-8 * fs)
    np.testing.assert_allclose(st.tau, ref.tau, rtol=0, atol=1e-8 * fs)
    assert value == pytest.approx(v_ref, rel=1e-8)
    np.testing.assert_allclose(xi, xi_ref, rtol=0, atol=1e-8 * np.abs(xi_ref).max())


# ----------------------------------------------------------------------------- the parts
def test_classes_and_contact_conditions_per_node():
    # three nodes in contact, none moving tangentially, each with |τ| = 0.5 λ
    u_c = np.zeros((3, 3))
    lam = np.ones(3)
    tau = np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 0.0]])
    gap = np.zeros(3)
    mu = np.array([0.0, 1.0, 0.5])
    codes = classify_nodes(u_c, lam, tau, gap, mu)
    # F = 0: sticking counts as sliding; slack 0.5: strict stick; slack 0: the degenerate stick
    assert list(codes) == [CLASS_CODES["M1"], CLASS_CODES["M3+"], CLASS_CODES["M3-"]]
    assert contact_conditions_violation(u_c, lam, tau, gap, mu) == 0.0
    # node 0 carries τ with F = 0: violated by 0.3 (relative to the force scale 1)
    tau[0] = [0.3, 0.0]
    assert contact_conditions_violation(u_c, lam, tau, gap, mu) == pytest.approx(0.3)
    # a sliding node m must have τ_m = F_m λ_m u_t/‖u_t‖: with F = (0, 1, 0.5) and u_t = (1, 0)
    u_c[:, 0] = 1.0
    tau = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 0.0]])
    assert contact_conditions_violation(u_c, lam, tau, gap, mu) == 0.0


def test_a_wrong_coefficient_array_is_refused_by_name():
    problem = block()
    p = problem.model.n_contact
    problem.model.contact_friction = np.full(p + 1, F)
    with pytest.raises(ProblemDataError, match=rf"one coefficient per contact node, shape \({p},\)"):
        problem.solve_state(flat(problem))
    mu = np.full(p, F)
    mu[3] = -0.1
    problem.model.contact_friction = mu
    with pytest.raises(ProblemDataError, match="finite and ≥ 0: 1 contact node.* the first 3 with F = -0.1"):
        problem.solve_state(flat(problem))


def test_state_files_hold_the_coefficient_per_node(tmp_path):
    problem, mu, st, _, _ = split_solution("condensation")
    write_state(tmp_path, problem.model, st)
    back = read_state_npz(tmp_path / "state.npz")
    np.testing.assert_array_equal(back.friction, mu)
    doc = json.loads((tmp_path / "state.json").read_text())
    assert doc["summary"]["friction"] == mu.tolist()
    scalar = block().solve_state(flat(problem))
    assert scalar.summary()["friction"] == F
    write_state(tmp_path / "scalar", problem.model, scalar)
    with np.load(tmp_path / "scalar" / "state.npz") as z:
        assert z["friction"].shape == () and z["friction"].dtype == np.float64 and float(z["friction"]) == F
    assert read_state_npz(tmp_path / "scalar" / "state.npz").friction == F


class _Problem:
    """What the uniqueness warning reads of a problem."""

    def __init__(self, friction, bound):
        self.friction, self.bound = friction, bound

    def uniqueness_bound(self, alpha):
        return self.bound


def test_the_uniqueness_warning_compares_the_largest_coefficient():
    assert uniqueness_warnings(_Problem(np.array([0.0, 0.2]), 0.3), None) == []
    (msg,) = uniqueness_warnings(_Problem(np.array([0.0, 0.5, 0.2]), 0.3), None)
    assert msg.startswith("the largest friction coefficient F = 0.5 exceeds the uniqueness estimate (3.16) F0 ≈ 0.3")
    (msg,) = uniqueness_warnings(_Problem(0.5, 0.3), None)
    assert msg.startswith("friction coefficient F = 0.5 exceeds")


def test_a_free_body_is_held_by_each_node_s_cone():
    """The free block of tests/test_rigid.py (no clamp) under the top traction 0.1 and a side
    traction 0.07: F = 0.3 holds 0.06, F = 0.4 holds 0.08; per node the same decisions."""
    cfg = {"friction": {"coefficient": 0.4}, "linear_solver": {"path": "condensation"},
           "loads": {"top_traction": [0.0, 0.0, -0.1], "right_traction": [0.07, 0.0, 0.0]},
           "design": {"degree": [3, 2], "initial": 0.0, "C2": 0.0}, "geometry": {"a": 2.0, "b": 1.0, "c": 1.0},
           "mesh": {"nx": 8, "ny": 4, "nz": 3}, "body": {"clamped": []}}
    m = ShapeProblem(load_config("example1").with_updates(cfg)).model
    coords = m.mesh.coordinates(m.initial_design())
    loads = [("loads", m.load_vector(coords, m.loads))]
    p = m.n_contact

    def held(mu):
        check_held(m.body.rigid, coords, m.contact_nodes, m.frames, mu, loads, "block")

    held(np.full(p, 0.4))
    with pytest.raises(ConfigError, match="exceeds the largest F × the normal load 0.3 × 0.2 = 0.06"):
        held(np.full(p, 0.3))
    with pytest.raises(ConfigError, match="not held: without friction"):
        held(np.zeros(p))
