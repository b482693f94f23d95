"""Tests of the bundle-trust optimizer (contactopt.optimize.bundle) and its test problems."""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest

from contactopt.errors import ContactOptError, OptimizerError
from contactopt.optimize import BundleResult, BundleState, minimize_bundle
from contactopt.optimize._bundle_control import direction, update_metric
from contactopt.optimize._bundle_qp import Polyhedron
from contactopt.optimize.gallery import (
    PROBLEMS,
    goffin_problem,
    max_linear_problem,
    max_quadratics_problem,
    max_quadratics_reference,
    paper_admissible_set,
)

FEAS_TOL = 1e-9


class CheckedOracle:
    """Wraps a test problem: asserts that every evaluated point is feasible, counts calls."""

    def __init__(self, prob):
        self.prob = prob
        self.calls = 0
        self.points = []

    def __call__(self, x):
        viol = self.prob.max_violation(x)
        assert viol <= FEAS_TOL, f"{self.prob.name}: oracle called at a point {viol:.2e} outside U"
        self.calls += 1
        self.points.append(np.array(x))
        return self.prob(x)


def rel_error(f, f_star):
    return abs(f - f_star) / (abs(f_star) if f_star != 0 else 1.0)


# ------------------------------------------------------------------ the test problems themselves
@pytest.mark.parametrize("name", list(PROBLEMS))
def test_problem_value_at_x0_matches_report(name):
    prob = PROBLEMS[name]
    f, g = prob(prob.x0)
    assert g.shape == prob.x0.shape
    assert rel_error(f, prob.f_x0) < 1e-7, f"{name}: f(x0) = {f!r}, report {prob.f_x0!r}"
    assert prob.max_violation(prob.x0) == 0.0


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_problem_subgradient_matches_finite_differences(name):
    """At a random point the functions are smooth (a.s.); g must be their gradient there."""
    prob = PROBLEMS[name]
    rng = np.random.default_rng(3)
    x = prob.x0 + 0.01 * rng.normal(size=prob.n)
    if name == "EQUIL":
        x = np.abs(x) / np.abs(x).sum()
    if prob.lb is not None:                      # inside the domain (MAD4: log x2, x2 >= 0.01)
        x = np.maximum(x, prob.lb)
    f, g = prob(x)
    h = 1e-7
    fd = np.array([(prob(x + h * e)[0] - prob(x - h * e)[0]) / (2 * h) for e in np.eye(prob.n)])
    assert np.linalg.norm(fd - g) <= 1e-5 * max(1.0, np.linalg.norm(g))


# ------------------------------------------------------------------ acceptance: Lukšan–Vlček
# not solved to 1e-6 with a success verdict by the defaults (docs/stopping.md has the figures):
# Shell Dual, FILTER-124, HS114 and Dembo7 end above f*; HS78 and Dembo3 reach f* to 1e-8 but
# end "stalled" (no certificate at eps = 1e-7 before f stops decreasing)
UNSOLVED = {"Shell Dual", "FILTER-124", "HS114", "Dembo7", "HS78", "Dembo3"}
# runs of more than about two seconds here
LONG = {"Steiner2", "GOFFIN", "L1HILB", "Wong3", "Gill", "MAXABS-38"}


def _collection():
    for name in PROBLEMS:
        marks = []
        if name in UNSOLVED:
            marks = [pytest.mark.slow, pytest.mark.xfail(strict=True, reason="not yet solved to 1e-6 with the defaults (docs/stopping.md)")]
        elif name in LONG:
            marks = [pytest.mark.slow]
        yield pytest.param(name, marks=marks)


@pytest.mark.parametrize("name", list(_collection()))
def test_reaches_f_star_with_feasible_iterates(name):
    """The defaults (certified test at eps = 1e-7 relative, practical stop off): f* to 1e-6."""
    prob = PROBLEMS[name]
    oracle = CheckedOracle(prob)
    # the certificate alone (the f-change test and the metric choice off, as before they were
    # defaults; tests/test_bundle_defaults.py has the present defaults)
    res = minimize_bundle(oracle, prob.x0, max_iter=3000, tolf=0.0, metric="none", **prob.constraints())
    assert res.success, res.message
    assert res.status in (0, 5)       # certified, or no decrease above round-off after a restart
    err = rel_error(res.fun, prob.f_star)
    assert err <= 1e-6, f"{name}: f = {res.fun!r}, f* = {prob.f_star}, error {err:.2e}"
    assert prob.max_violation(res.x) <= FEAS_TOL
    assert res.nfev == oracle.calls
    assert res.nit == res.n_serious + res.n_null == len(res.history)
    fs = [h["f"] for h in res.history]
    assert all(b <= a for a, b in zip(fs, fs[1:])), "serious steps must decrease f"
    assert res.fun == pytest.approx(prob(res.x)[0], rel=0, abs=0)


# ------------------------------------------------------------------ acceptance: 32 variables
def test_paper_admissible_set_structure():
    cons = paper_admissible_set()
    assert cons["A_ub"].shape == (2 * (7 * 4 + 8 * 3), 32)
    x = np.full(32, 0.01)
    assert np.all(cons["A_ub"] @ x <= cons["b_ub"]) and cons["A_eq"] @ x == pytest.approx(0.32)
    alpha = np.zeros((8, 4))
    alpha[0, 0] = 0.5 * 2 / 7 + 1e-3          # violates |α_{2,1} − α_{1,1}| ≤ 1/7 only
    assert np.sum(cons["A_ub"] @ alpha.ravel() > cons["b_ub"]) == 1


def test_32_variable_paper_set_matches_clarabel():
    prob = max_quadratics_problem()
    pytest.importorskip("clarabel")
    x_ref, f_ref = max_quadratics_reference(prob)
    oracle = CheckedOracle(prob)
    # f convex: the certificate gives f(x) − f* ≤ eps·(1 + ‖x* − x‖), so eps = 1e-6 for 1e-6
    res = minimize_bundle(oracle, prob.x0, eps=1e-6, max_iter=2000, **prob.constraints())
    assert res.success, res.message
    assert rel_error(res.fun, f_ref) <= 1e-6, (res.fun, f_ref)
    assert res.fun >= f_ref - 1e-9 * abs(f_ref)       # the SOCP value is a lower bound on U
    # the minimiser is genuinely nonsmooth and constrained
    r = res.x[None, :] - prob.data["c"]
    pieces = 0.5 * np.einsum("ki,kij,kj->k", r, prob.data["Q"], r) + prob.data["b"]
    assert np.sum(pieces > res.fun - 1e-6) >= 2
    assert np.sum(prob.A_ub @ res.x > prob.b_ub - 1e-8) >= 1
    assert np.linalg.norm(res.x - x_ref) <= 1e-3


# ------------------------------------------------------------------ save / restore
def _record(prob, **kw):
    xs = []

    def cb(r):
        xs.append(r.x.copy())

    res = minimize_bundle(prob, prob.x0, callback=cb, **prob.constraints(), **kw)
    return xs, res


@pytest.mark.parametrize("name,fmt,metric", [("Shor", "npz", "diagonal"), ("MAD5", "json", "diagonal"),
                                             ("MAXQUAD-U32", "npz", "diagonal"),
                                             ("MAXQUAD-U32", "json", "bfgs")])
def test_restore_mid_run_gives_bit_identical_iterates(name, fmt, metric, tmp_path, bundle_state_roundtrip):
    prob = max_quadratics_problem() if name == "MAXQUAD-U32" else PROBLEMS[name]
    kw = dict(eps=1e-7, max_iter=60, metric=metric)
    xs_full, res_full = _record(prob, **kw)
    k = len(xs_full) // 2
    assert k >= 3
    saved = {}

    def stop_at_k(r):
        assert isinstance(r.state, BundleState)
        if r.nit == k:
            saved["state"] = r.state.to_dict()
            raise StopIteration

    first = minimize_bundle(prob, prob.x0, callback=stop_at_k, **prob.constraints(), **kw)
    assert not first.success and first.status == 2 and "callback" in first.message
    assert first.nit == k
    state = bundle_state_roundtrip(saved["state"], fmt)
    xs_rest = []
    res_rest = minimize_bundle(prob, None, state=state,
                               callback=lambda r: xs_rest.append(r.x.copy()),
                               **prob.constraints(), **kw)
    assert len(xs_rest) == len(xs_full) - k
    for a, b in zip(xs_rest, xs_full[k:]):
        assert np.array_equal(a, b)
    assert res_rest.fun == res_full.fun and res_rest.nfev == res_full.nfev
    assert res_rest.nit == res_full.nit and res_rest.message == res_full.message
    assert res_rest.history == res_full.history
    assert np.array_equal(res_rest.jac, res_full.jac)


def test_state_roundtrip_is_exact():
    prob = PROBLEMS["CB2"]
    res = minimize_bundle(prob, prob.x0, eps=1e-6, max_iter=5)
    d = res.state.to_dict()
    back = BundleState.from_dict(d).to_dict()
    assert d.keys() == back.keys()
    for key in d:
        assert np.array_equal(np.asarray(d[key]), np.asarray(back[key])), key


def test_invalid_state_raises():
    with pytest.raises(OptimizerError, match="invalid bundle state"):
        BundleState.from_dict({"version": 1, "x": [0.0]})


# ------------------------------------------------------------------ feasibility handling
def test_infeasible_start_is_projected_and_logged(caplog):
    prob = PROBLEMS["MAD1"]                      # x1 + x2 >= 0.5
    x0 = np.array([-1.0, -1.0])
    oracle = CheckedOracle(prob)
    with caplog.at_level(logging.WARNING, logger="contactopt.optimize.bundle"):
        res = minimize_bundle(oracle, x0, eps=1e-4, **prob.constraints())
    assert any("projection" in r.getMessage() for r in caplog.records)
    np.testing.assert_allclose(oracle.points[0], [0.25, 0.25], atol=1e-12)
    assert res.success and rel_error(res.fun, prob.f_star) <= 1e-4


def test_equality_and_bounds_projection():
    poly = Polyhedron(3, lb=0.0, ub=1.0, A_eq=np.ones((1, 3)), b_eq=[1.0])
    x = poly.project(np.array([2.0, -1.0, 0.5]))
    np.testing.assert_allclose(x, [1.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("kw", [
    dict(lb=np.zeros(2), A_ub=np.array([[1.0, 1.0]]), b_ub=np.array([-1.0])),
    dict(A_eq=np.array([[1.0, 1.0], [1.0, 1.0]]), b_eq=np.array([0.0, 1.0])),
    dict(lb=np.array([0.0, 2.0]), ub=np.array([1.0, 1.0])),
])
def test_empty_feasible_set_raises(kw):
    with pytest.raises(OptimizerError, match="empty") as info:
        minimize_bundle(PROBLEMS["CB2"], np.zeros(2), **kw)
    assert isinstance(info.value, ContactOptError)


def test_invalid_input_lists_every_problem():
    with pytest.raises(OptimizerError) as info:
        minimize_bundle(PROBLEMS["CB2"], np.zeros(2), lb=np.zeros(3), A_ub=np.ones((1, 2)))
    text = str(info.value)
    assert "lb has shape" in text and "A_ub and b_ub must be given together" in text


def test_unknown_and_invalid_options_raise():
    with pytest.raises(OptimizerError, match="unknown option"):
        minimize_bundle(PROBLEMS["CB2"], np.zeros(2), trust=1.0)
    with pytest.raises(OptimizerError, match="m1 < m2"):
        minimize_bundle(PROBLEMS["CB2"], np.zeros(2), m1=0.6, m2=0.5)


def test_nonfinite_oracle_at_start_raises():
    with pytest.raises(OptimizerError, match="non-finite"):
        minimize_bundle(lambda x: (np.nan, np.zeros(2)), np.zeros(2))


def test_nonfinite_value_at_trial_point_shrinks_the_step():
    """f = |x| + barrier that is inf beyond |x_i| > 3: the first long step must be retried."""
    def oracle(x):
        if np.any(np.abs(x) > 3):
            return np.inf, np.zeros(2)
        return float(np.abs(x).sum()), np.sign(x)

    res = minimize_bundle(oracle, np.array([2.5, -2.0]), eps=1e-6, t0=100.0)
    assert res.success and res.fun <= 1e-6


# ------------------------------------------------------------------ result, callback, messages
def test_result_object_and_messages():
    prob = PROBLEMS["QL"]
    res = minimize_bundle(prob, prob.x0, eps=1e-4)
    assert isinstance(res, BundleResult)
    assert re.fullmatch(r"converged: stationarity \d\.\de-\d\d < eps 1e-04", res.message)
    assert res.status == 0 and res.success and res.stationarity < 1e-4
    assert res.jac.shape == (2,) and res.x.shape == (2,)
    for h in res.history:
        assert set(h) == {"iteration", "f", "step", "t", "stationarity", "nfev"}
        assert h["step"] in ("serious", "null")
    short = minimize_bundle(prob, prob.x0, eps=1e-12, max_iter=3)
    assert not short.success and short.status == 1
    assert short.message == "max_iter reached (3 iterations)"


def test_callback_receives_each_iteration_and_can_stop():
    prob = PROBLEMS["Shor"]
    seen = []

    def cb(r):
        seen.append((r.nit, r.fun, r.state.nit))
        if r.nit == 4:
            raise StopIteration

    res = minimize_bundle(prob, prob.x0, callback=cb)
    assert [s[0] for s in seen] == [1, 2, 3, 4] and all(a == c for a, _, c in seen)
    assert res.status == 2 and not res.success and res.nit == 4
    assert res.message == "stopped by the callback after iteration 4"


def test_library_does_not_print(capsys):
    prob = PROBLEMS["CB3"]
    minimize_bundle(prob, prob.x0, eps=1e-4)
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""


# ------------------------------------------------------------------ the direction-finding QP
def _qp_reference(poly, x, G, alpha, t, W=None):
    clarabel = pytest.importorskip("clarabel")
    import scipy.sparse as sp

    n, m = poly.n, G.shape[0]
    H = np.zeros((n + 1, n + 1))
    H[:n, :n] = np.eye(n) / t if W is None else W / t
    P = sp.csc_matrix(np.triu(H))
    q = np.r_[np.zeros(n), 1.0]
    fin_u, fin_l = np.isfinite(poly.ub), np.isfinite(poly.lb)
    A_in = np.vstack([np.hstack([G, -np.ones((m, 1))]),
                      np.hstack([poly.A_ub, np.zeros((poly.n_ub, 1))]),
                      np.hstack([np.eye(n)[fin_u], np.zeros((fin_u.sum(), 1))]),
                      np.hstack([-np.eye(n)[fin_l], np.zeros((fin_l.sum(), 1))])])
    b_in = np.r_[alpha, poly.b_ub - poly.A_ub @ x, (poly.ub - x)[fin_u], (x - poly.lb)[fin_l]]
    A_eq = np.hstack([poly.A_eq, np.zeros((poly.n_eq, 1))])
    b_eq = poly.b_eq - poly.A_eq @ x
    s = clarabel.DefaultSettings()
    s.verbose = False
    s.tol_gap_abs = s.tol_gap_rel = s.tol_feas = 1e-12
    cones = [clarabel.ZeroConeT(poly.n_eq), clarabel.NonnegativeConeT(len(b_in))]
    sol = clarabel.DefaultSolver(P, q, sp.csc_matrix(np.vstack([A_eq, A_in])), np.r_[b_eq, b_in],
                                 cones, s).solve()
    return np.array(sol.x)[:n]


@pytest.mark.parametrize("seed", range(4))
def test_direction_qp_matches_clarabel(seed):
    rng = np.random.default_rng(seed)
    cons = paper_admissible_set()
    poly = Polyhedron(32, **cons)
    x = np.full(32, 0.01)
    G = rng.normal(size=(20, 32))
    G[5] = G[3]                                   # duplicate cut with a larger α
    alpha = np.abs(rng.normal(size=20)) * 0.1
    alpha[0] = 0.0
    alpha[5] = alpha[3] + 0.1
    t = 10.0 ** rng.uniform(-2, 1)
    qp = poly.direction(x, G, alpha, t)
    d_ref = _qp_reference(poly, x, G, alpha, t)
    phi = lambda d: np.max(G @ d - alpha) + d @ d / (2 * t)      # noqa: E731 (QP objective)
    assert phi(qp.d) == pytest.approx(phi(d_ref), rel=1e-7, abs=1e-10)
    assert np.linalg.norm(qp.d - d_ref) <= 1e-5 * (1 + np.linalg.norm(d_ref))
    assert qp.v + qp.d @ qp.d / (2 * t) == pytest.approx(phi(qp.d), rel=1e-7, abs=1e-12)
    assert qp.lam.sum() == pytest.approx(1.0, abs=1e-12) and np.all(qp.lam >= 0)
    assert qp.lam[5] == 0.0
    assert Polyhedron(32, **cons).violation(x + qp.d) <= 1e-10
    # KKT identity of the aggregate: −v = t‖p‖² + α_p + (μᵀC d ≥ 0)
    assert -qp.v >= t * qp.p @ qp.p + qp.lam @ alpha - 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_direction_qp_with_a_full_metric_matches_clarabel(seed):
    """min max_j(g_jᵀd − α_j) + dᵀWd/(2t) over x + d ∈ U, solved in e = Lᵀd (W = LLᵀ)."""
    rng = np.random.default_rng(10 + seed)
    cons = paper_admissible_set()
    poly = Polyhedron(32, **cons)
    x = np.full(32, 0.01)
    G = rng.normal(size=(15, 32))
    alpha = np.abs(rng.normal(size=15)) * 0.1
    alpha[0] = 0.0
    R = rng.normal(size=(32, 32))
    W = R @ R.T / 32 + 0.05 * np.eye(32)           # condition ~1e2, far from diagonal
    t = 10.0 ** rng.uniform(-3, -2)                # a step inside the box: W shapes it
    qp = direction(poly, x, G, alpha, t, W)
    d_ref = _qp_reference(poly, x, G, alpha, t, W)
    phi = lambda d: np.max(G @ d - alpha) + d @ W @ d / (2 * t)     # noqa: E731
    assert phi(qp.d) == pytest.approx(phi(d_ref), rel=1e-7, abs=1e-10)
    assert np.linalg.norm(qp.d - d_ref) <= 1e-5 * (1 + np.linalg.norm(d_ref))
    assert np.allclose(qp.p, -W @ qp.d / t, rtol=0, atol=1e-12 * (1 + np.abs(qp.p).max()))
    assert qp.lam.sum() == pytest.approx(1.0, abs=1e-12) and np.all(qp.lam >= 0)
    assert np.allclose(qp.xi, qp.lam @ G)
    assert poly.violation(x + qp.d) <= 1e-10
    assert np.linalg.norm(qp.d - direction(poly, x, G, alpha, t, None).d) > 1e-3   # W matters
    # a diagonal metric given as a matrix: the step of the diagonal (box-preserving) transform
    w = rng.uniform(0.1, 10.0, 32)
    a, b = direction(poly, x, G, alpha, t, w), direction(poly, x, G, alpha, t, np.diag(w))
    assert np.linalg.norm(a.d - b.d) <= 1e-8 * (1 + np.linalg.norm(a.d))


def test_bfgs_metric_is_a_secant_metric_and_stays_positive_definite():
    from types import SimpleNamespace

    rng = np.random.default_rng(3)
    n = 8
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    A = Q @ np.diag(np.linspace(0.5, 2.0, n)) @ Q.T          # f = ½xᵀAx: y = A s
    st = SimpleNamespace(x=np.zeros(n), w=None, S=None, Y=None)
    for _ in range(12):
        s = rng.normal(size=n)
        update_metric(st, s, A @ s, 20, 100.0, "bfgs")
    W = st.w
    assert W.shape == (n, n) and np.array_equal(W, W.T)
    ev = np.linalg.eigvalsh(W)
    assert ev.min() > 0 and abs(np.mean(np.log(ev))) < 1e-12        # geometric mean 1
    # the last secant equation W s = c·y holds, c the normalisation
    y = A @ s
    c = (W @ s) @ y / (y @ y)
    assert np.linalg.norm(W @ s - c * y) <= 1e-10 * np.linalg.norm(W @ s)
    # a pair with negative curvature (f not convex there) is damped: W stays positive definite
    update_metric(st, s, -3.0 * (A @ s), 20, 100.0, "bfgs")
    assert np.linalg.eigvalsh(st.w).min() > 0
    # the diagonal estimate stays a vector
    st2 = SimpleNamespace(x=np.zeros(n), w=None, S=None, Y=None)
    update_metric(st2, s, A @ s, 20, 100.0, "diagonal")
    assert st2.w.shape == (n,)


def test_direction_qp_survives_degenerate_bundles():
    """Near the minimum of MAXQ the cuts are almost dependent (DAQP alone may cycle)."""
    poly = Polyhedron(20)
    rng = np.random.default_rng(0)
    x = 1e-5 * rng.normal(size=20)
    G = np.zeros((23, 20))
    G[np.arange(20), np.arange(20)] = 2 * x
    G[20:] = G[:3] * (1 + 1e-13)
    alpha = np.r_[np.abs(x) ** 2, np.abs(x[:3]) ** 2] * 1e-3
    phi = lambda d, t: np.max(G @ d - alpha) + d @ d / (2 * t)   # noqa: E731 (QP objective)
    for t in (1e-3, 0.5, 1e3):
        qp = poly.direction(x, G, alpha, t)
        d_ref = _qp_reference(poly, x, G, alpha, t)
        # at these magnitudes (values ~1e-13) Clarabel's own answer is less accurate: ours must
        # be at least as good, and agree when the values are large enough to compare
        assert phi(qp.d, t) <= phi(d_ref, t) + 1e-6 * abs(phi(d_ref, t))
        assert qp.lam.sum() == pytest.approx(1.0, abs=1e-12)
        # optimality certificate: the dual value of λ is a lower bound of the QP value
        xi = qp.lam @ G
        dual = -0.5 * t * xi @ xi - qp.lam @ alpha
        assert phi(qp.d, t) - dual <= 1e-6 * abs(phi(qp.d, t))


# ------------------------------------------------------------------ defaults: both stopping tests
@pytest.mark.parametrize("name", list(_collection()))
def test_default_stopping_reaches_f_star(name):
    """With the built-in defaults every run ends in a success at f* to 1e-6, and the result
    names the test that fired."""
    prob = PROBLEMS[name]
    res = minimize_bundle(CheckedOracle(prob), prob.x0, max_iter=3000, tolf=0.0, metric="none",
                          **prob.constraints())       # the defaults before the f-change test
    assert res.success and res.status in (0, 4, 5), res.message
    assert res.criterion == {0: "stationarity", 4: "predicted_decrease", 5: "roundoff"}[res.status]
    assert rel_error(res.fun, prob.f_star) <= 1e-6, (res.fun, prob.f_star)


def test_converged_run_stops_before_max_iter_naming_criterion_and_value():
    prob = PROBLEMS["Shor"]
    # certified test: message names the measure and its value, which is the result's
    res = minimize_bundle(prob, prob.x0, eps=1e-4, max_iter=500, ftol=0.0)
    assert res.status == 0 and res.success and res.nit < 500
    m = re.fullmatch(r"converged: stationarity (\S+) < eps 1e-04", res.message)
    assert m and float(m.group(1)) == float(f"{res.stationarity:.1e}") and res.stationarity < 1e-4
    # practical stop: eps out of reach; the bundle model predicts a relative decrease of f
    # below ftol = 1e-6 right after a serious step (and after at least ftol_window of them)
    res = minimize_bundle(prob, prob.x0, eps=1e-12, max_iter=500, ftol=1e-6)
    assert res.status == 4 and res.success and res.criterion == "predicted_decrease"
    assert res.nit < 500 and res.history[-1]["step"] == "serious" and res.n_serious >= 5
    m = re.fullmatch(r"converged: the model predicts a relative decrease (\S+) < ftol 1e-06 "
                     r"\(stationarity (\S+), eps 1e-12\)", res.message)
    assert m, res.message
    assert res.predicted_decrease <= 1e-6
    assert float(m.group(1)) == float(f"{res.predicted_decrease:.1e}")
    # what the prediction promises: f within ftol·|f| of f* (Shor is convex)
    assert rel_error(res.fun, prob.f_star) <= 1e-6
    # neither: the result says how far each test was
    res = minimize_bundle(prob, prob.x0, eps=1e-12, max_iter=8, ftol=1e-12)
    assert res.status == 1 and not res.success and res.criterion == "max_iter"
    assert res.message == "max_iter reached (8 iterations)"
    assert res.stationarity > 1e-12 and res.relative_decrease >= 1e-12


# ------------------------------------------------------------------ proximity control
def test_t_grows_after_serious_steps_the_model_predicted():
    """f = ‖x‖₁ far from 0 is linear: every serious step realises the predicted decrease
    (ρ = 1), so t grows by t_factor = 10 from the second serious step on."""
    f = lambda x: (float(np.abs(x).sum()), np.sign(x))      # noqa: E731
    x0 = np.full(3, 1e3)
    kw = dict(eps=1e-6, t0=1e-3, t_max=1e5, max_iter=200)
    res = minimize_bundle(f, x0, **kw)
    assert res.success and res.fun <= 1e-6
    ts = [h["t"] for h in res.history]
    assert ts[:8] == pytest.approx([1e-3, 1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0, 1000.0])
    assert res.nfev <= 30
    fixed = minimize_bundle(f, x0, adapt_t=False, **kw)
    assert fixed.status == 1                      # 200 steps of length ≤ 1.7e-3 cannot get there


def test_t_shrinks_after_null_steps_where_f_rose():
    """A steep quadratic with t0 five times 2/curvature: the trial points are local but f
    rises there (ρ < 0); at the third such null step t comes down by the interpolation
    t/(2(1 − ρ)) and the run converges, where a fixed t makes no progress."""
    H = np.diag([1e3, 1.0])
    f = lambda x: (0.5 * float(x @ H @ x), H @ x)            # noqa: E731
    x0 = np.array([1.0, 1.0])
    kw = dict(eps=1e-6, ftol=0.0, tolf=0.0, t0=1e-2, max_iter=500, metric=False)   # t alone, no metric
    res = minimize_bundle(f, x0, **kw)
    assert res.status == 0, res.message
    steps = [h["step"] for h in res.history]
    ts = [h["t"] for h in res.history]
    assert steps[:3] == ["null"] * 3 and ts[:3] == [1e-2] * 3
    assert 1e-3 < ts[3] < 0.5e-2                  # t_int < t/2, and at most t/10
    assert res.nfev <= 80
    fixed = minimize_bundle(f, x0, adapt_t=False, **kw)
    assert fixed.status == 1


def test_line_search_extends_a_serious_step_along_its_direction():
    """f = ‖x‖₁ far from 0 is linear along the QP step d: the slope at x + d is the model's
    (ρ = 1, steeper than m2·v), so the line search tries x + 2d and x + 4d, both pass the
    descent test, and the first serious iterate is x0 + 4d; every trial point lies on the
    ray and is counted as an evaluation."""
    f = lambda x: (float(np.abs(x).sum()), np.sign(x))      # noqa: E731
    x0 = np.full(3, 1e3)
    points = []

    def oracle(x):
        points.append(np.array(x))
        return f(x)

    kw = dict(eps=1e-6, t0=1e-3, t_max=1e5, max_iter=200)
    res = minimize_bundle(oracle, x0, extrapolation=4.0, **kw)
    assert res.success and res.fun <= 1e-6
    d = points[1] - x0
    np.testing.assert_allclose(d, -1e-3, rtol=1e-9)          # the QP step −t·g, t = t0
    np.testing.assert_allclose(points[2], x0 + 2 * d, rtol=1e-15)
    np.testing.assert_allclose(points[3], x0 + 4 * d, rtol=1e-15)
    assert res.history[0]["step"] == "serious"
    assert res.history[0]["f"] == f(points[3])[0]
    assert res.nfev == len(points)
    off = minimize_bundle(f, x0, **kw)                       # extrapolation = 1: off (default)
    assert off.history[0]["f"] == f(points[1])[0]


def test_line_search_saves_evaluations_on_rosenbrock():
    """Rosenbrock (Lukšan–Vlček U1), smooth: 63 evaluations with the line search to the stop
    within 1e-6 of f*, 93 without (measured under the four OpenBLAS kernels)."""
    prob = PROBLEMS["Rosenbrock"]
    ls = minimize_bundle(prob, prob.x0, extrapolation=4.0)
    off = minimize_bundle(prob, prob.x0)
    for res in (ls, off):
        assert res.success and rel_error(res.fun, prob.f_star) <= 1e-6, res.message
    assert ls.nfev <= 0.8 * off.nfev


@pytest.mark.parametrize("name", ["Colville1", "MAXQ"])
def test_secant_cap_of_t_saves_evaluations(name):
    """t capped after serious steps by the secant step sᵀs/sᵀ(p⁺ − p) of the aggregate
    subgradients: Colville1 66 → 43 and MAXQ 192 → 146 evaluations to the stop within 1e-6 of
    f* (measured, the same under the Prescott, Haswell and SkylakeX kernels)."""
    prob = PROBLEMS[name]
    cap = minimize_bundle(prob, prob.x0, t_secant=True)
    off = minimize_bundle(prob, prob.x0)
    for res in (cap, off):
        assert res.success and rel_error(res.fun, prob.f_star) <= 1e-6, res.message
    assert cap.nfev <= 0.8 * off.nfev
    ts = [h["t"] for h in cap.history]
    assert min(b / a for a, b in zip(ts, ts[1:])) >= 0.1 - 1e-12    # at most t/t_factor per step


@pytest.mark.parametrize("fmt", ["json", "npz"])
def test_secant_cap_resumes_bit_for_bit(fmt, bundle_state_roundtrip):
    """The step and aggregate waiting for the next iteration are part of the state: a run
    stopped right after a serious step and restored repeats the uninterrupted run."""
    prob = PROBLEMS["Colville1"]
    kw = dict(max_iter=60, t_secant=True)
    full = minimize_bundle(prob, prob.x0, **kw)
    k = next(h["iteration"] for h in full.history[10:] if h["step"] == "serious")
    saved = {}

    def stop_at_k(r):
        if r.nit == k:
            assert r.state.pending_s is not None
            saved["state"] = r.state.to_dict()
            raise StopIteration

    minimize_bundle(prob, prob.x0, callback=stop_at_k, **kw)
    rest = minimize_bundle(prob, None, state=bundle_state_roundtrip(saved["state"], fmt), **kw)
    assert np.array_equal(rest.x, full.x) and rest.nfev == full.nfev
    assert rest.history == full.history


def test_invalid_extrapolation_is_named():
    with pytest.raises(OptimizerError, match="extrapolation >= 1"):
        minimize_bundle(PROBLEMS["CB2"], np.zeros(2), extrapolation=0.5)
    with pytest.raises(OptimizerError, match="t_secant must be True or False"):
        minimize_bundle(PROBLEMS["CB2"], np.zeros(2), t_secant="yes")


# ------------------------------------------------------------------ polyhedral, n >= 50
def test_goffin_50_needs_and_gets_room_for_n_cuts():
    """GOFFIN (Lukšan–Vlček), n = 50, a maximum of 50 linear pieces with f* = 0: solved with
    the defaults (the bundle holds n + 3 elements)."""
    prob = goffin_problem()
    res = minimize_bundle(prob, prob.x0, eps=1e-4, max_iter=2000)
    assert res.success, res.message
    assert res.fun <= 1e-6
    assert res.state.G.shape[0] <= prob.n + 3


def test_max_linear_60_to_1e6():
    """Own construction with known sharp minimum f* = 1 at x*: f to 1e-6, x to 1e-6."""
    prob = max_linear_problem(60)
    f0, _ = prob(prob.x0)
    assert f0 > prob.f_star + 1 and prob(prob.data["x_star"])[0] == prob.f_star
    res = minimize_bundle(prob, prob.x0, eps=1e-8, ftol=0.0, max_iter=2000)    # defaults
    # which test certifies the stop (eps: status 0, or f's change: status 4) is a trajectory detail
    # that moves with the BLAS kernel (Prescott stops by f's change at |f − f*| = 5e-15)
    assert res.success, res.message
    assert abs(res.fun - prob.f_star) <= 1e-6
    assert np.abs(res.x - prob.data["x_star"]).max() <= 1e-6


# ------------------------------------------------------------------ options and old states
def test_new_options_are_validated_together():
    with pytest.raises(OptimizerError) as info:
        minimize_bundle(PROBLEMS["CB2"], np.zeros(2), ftol=-1.0, ftol_window=0, t_factor=1.0,
                        m_r=2.0, adapt_t="yes", metric="newton")
    text = str(info.value)
    for key in ("ftol <", "ftol_window", "t_factor", "m_r", "adapt_t", "metric must be one of"):
        assert key in text, key


def test_the_run_sets_gamma_from_what_the_cuts_show():
    """Default γ (None): a polyhedral f gets its affine pieces recognised (exact cuts at any
    distance), a max-type nonconvex f (Crescent) raises γ above its floor and reaches f*."""
    prob = goffin_problem()
    res = minimize_bundle(prob, prob.x0, eps=1e-6, max_iter=2000)
    assert res.status == 0 and res.fun <= 1e-6 and res.state.affine is not None
    prob = PROBLEMS["Crescent"]
    gammas = []
    res = minimize_bundle(prob, prob.x0, eps=1e-6, max_iter=2000, tolf=0.0, metric="none",
                          callback=lambda r: gammas.append(r.gamma))
    # certified, or (status 5) no decrease above round-off from a bundle rebuilt at x
    assert res.status in (0, 5) and res.success and rel_error(res.fun, prob.f_star) <= 1e-6
    # the cuts showed nonconvexity and γ rose above its floor; whether it is still there when the
    # run stops is a trajectory detail that moves with the BLAS kernel (back at 0 under Prescott)
    assert res.state.nonconvex == 1 and gammas[0] == 0.0 and max(gammas) > 1.0
    with pytest.raises(OptimizerError) as info:
        minimize_bundle(prob, prob.x0, gamma=-1.0, gamma_t0=float("nan"), gamma_factor=0.5)
    for key in ("gamma >= 0", "gamma_t0", "gamma_factor"):
        assert key in str(info.value), key


def test_version_1_state_resumes():
    prob = PROBLEMS["CB2"]
    d = minimize_bundle(prob, prob.x0, max_iter=3).state.to_dict()
    d["version"] = 1
    del d["i_t"], d["eps_v"]
    st = BundleState.from_dict(d)
    assert st.i_t == 0 and st.eps_v == np.inf
    res = minimize_bundle(prob, None, state=st, eps=1e-4)
    assert res.success and rel_error(res.fun, prob.f_star) <= 1e-4


# ------------------------------------------------------------------ verdicts independent of the run
def _verdicts(names, threads):
    """(status, reached f* to 1e-6 relative) of each problem with the defaults (eps = 1e-6)."""
    from threadpoolctl import threadpool_limits

    out = {}
    with threadpool_limits(limits=threads, user_api="blas"):
        for name in names:
            prob = PROBLEMS[name]
            res = minimize_bundle(prob, prob.x0, eps=1e-6, max_iter=1500, **prob.constraints())
            out[name] = (res.status, rel_error(res.fun, prob.f_star) <= 1e-6)
    return out


@pytest.mark.slow
def test_collection_verdicts_do_not_depend_on_order_or_threads():
    """The whole collection in the table's order with one BLAS thread, then shuffled with two:
    every problem gets the same verdict (the problems are pure functions and the method keeps
    no state between runs; a verdict that moved would mean a tie broken by round-off)."""
    names = list(PROBLEMS)
    first = _verdicts(names, 1)
    shuffled = list(np.random.default_rng(34).permutation(names))
    assert shuffled != names
    second = _verdicts(shuffled, 2)
    assert second == first
