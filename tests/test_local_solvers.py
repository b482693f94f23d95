"""Local contact solvers: Tresca (Kučera's Algorithm 1), fixed point (Cor. 3.9), Newton.

Test problems: the Delassus operator W = B K^{-1} B^T of a small 3D spring lattice with random
spring stiffnesses (top layer clamped, bottom layer = contact nodes), loads pressing one end
into contact and lifting the other, random shear: a mix of separated, sticking and sliding
contacts, like an elastic body on a foundation. References: Clarabel (interior point, QP for
frictionless and SOCP with cones ||r_T|| <= g for Tresca).
"""

from __future__ import annotations

import functools
import logging
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from contactopt.contact import LocalResult, solve_local, solve_tresca
from contactopt.contact.cones import (
    complementarity_violations,
    node_class,
    project_cone,
    project_tresca_set,
    siconos_error,
)
from contactopt.contact.fixed_point import solve_fixed_point
from contactopt.contact.newton import solve_newton
from contactopt.errors import ContactNotConverged, ProblemDataError

_OFFSETS = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1),
            (0, 1, 1), (0, 1, -1), (1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)]


@functools.lru_cache(maxsize=None)
def lattice_problem(nx, ny, nz=4, *, mu=0.3, seed=0, shear=0.4):
    """(W, q, mu) of an nx x ny x nz spring lattice; p = nx * ny contacts, order (N, T1, T2)."""
    rng = np.random.default_rng(seed)
    node = np.arange(nx * ny * nz).reshape(nz, ny, nx)
    xyz = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1)
    xyz = xyz.transpose(2, 1, 0, 3).reshape(-1, 3).astype(float)
    a_all, b_all = [], []
    for dx, dy, dz in _OFFSETS:
        lo = (max(0, -dz), max(0, -dy), max(0, -dx))
        hi = (nz - max(0, dz), ny - max(0, dy), nx - max(0, dx))
        a_all.append(node[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]].ravel())
        b_all.append(node[lo[0] + dz:hi[0] + dz, lo[1] + dy:hi[1] + dy,
                          lo[2] + dx:hi[2] + dx].ravel())
    a, b = np.concatenate(a_all), np.concatenate(b_all)
    e = xyz[b] - xyz[a]
    e /= np.linalg.norm(e, axis=1)[:, None]
    blk = rng.uniform(0.5, 2.0, a.size)[:, None, None] * e[:, :, None] * e[:, None, :]
    nn = nx * ny * nz
    rows, cols, vals = [], [], []
    for I, J, sgn in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
        rows.append(np.broadcast_to(3 * I[:, None, None] + np.arange(3)[:, None],
                                    blk.shape).ravel())
        cols.append(np.broadcast_to(3 * J[:, None, None] + np.arange(3), blk.shape).ravel())
        vals.append(sgn * blk.ravel())
    K = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(3 * nn, 3 * nn))
    top, bottom = node[-1].ravel(), node[0].ravel()
    free = (3 * np.setdiff1d(np.arange(nn), top)[:, None] + np.arange(3)).ravel()
    pos = -np.ones(3 * nn, dtype=int)
    pos[free] = np.arange(free.size)
    cdof = pos[(3 * bottom[:, None] + np.array([2, 0, 1])).ravel()]   # (z, x, y) = (N, T1, T2)
    lu = spla.splu(K[free][:, free].tocsc())
    E = np.zeros((free.size, cdof.size))
    E[cdof, np.arange(cdof.size)] = 1.0
    W = lu.solve(E)[cdof]
    W = 0.5 * (W + W.T)
    f = np.zeros(3 * nn)
    mid = node[1:-1].ravel()
    f[3 * mid + 2] = -1.0 + 1.5 * xyz[mid, 0] / max(nx - 1, 1)
    f[3 * mid + 0] = shear * rng.uniform(-1, 1) + 0.2 * rng.standard_normal(mid.size)
    f[3 * mid + 1] = shear * rng.uniform(-1, 1) + 0.2 * rng.standard_normal(mid.size)
    q = lu.solve(f[free])[cdof]
    q[0::3] += rng.uniform(0.0, 0.05, bottom.size)
    W.setflags(write=False)
    q.setflags(write=False)
    return np.ascontiguousarray(W), q, np.full(bottom.size, float(mu))


SIZES = [(6, 5), (10, 8), (12, 12)]          # 30, 80, 144 contacts


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# ---------------------------------------------------------------- Clarabel references
def _clarabel_settings(tol):
    import clarabel

    s = clarabel.DefaultSettings()
    s.verbose = False
    s.tol_gap_abs = s.tol_gap_rel = s.tol_feas = tol
    s.tol_ktratio = 1e-10
    s.max_iter = 300
    return s


def clarabel_frictionless(W, q):
    """QP min 1/2 r_N^T W_NN r_N + q_N^T r_N, r_N >= 0 (r_T = 0), by Clarabel."""
    import clarabel

    iN = np.arange(0, q.size, 3)
    p = iN.size
    P = sp.csc_matrix(np.triu(W[np.ix_(iN, iN)]))
    sol = clarabel.DefaultSolver(P, q[iN].copy(), sp.csc_matrix(-np.eye(p)), np.zeros(p),
                                 [clarabel.NonnegativeConeT(p)], _clarabel_settings(1e-11)).solve()
    assert str(sol.status) == "Solved"
    r = np.zeros(q.size)
    r[iN] = sol.x
    return r


def clarabel_tresca(W, q, g):
    """SOCP min 1/2 r^T W r + q^T r, r_N >= 0, (g_i, r_T,i) in SOC_3, by Clarabel."""
    import clarabel

    n, p = q.size, q.size // 3
    blocks = [sp.csr_matrix((-np.ones(p), (np.arange(p), 3 * np.arange(p))), shape=(p, n))]
    rhs = [np.zeros(p)]
    cones = [clarabel.NonnegativeConeT(p)]
    for i in range(p):
        blocks.append(sp.csr_matrix((-np.ones(2), ([1, 2], [3 * i + 1, 3 * i + 2])), shape=(3, n)))
        rhs.append(np.array([g[i], 0.0, 0.0]))
        cones.append(clarabel.SecondOrderConeT(3))
    sol = clarabel.DefaultSolver(sp.csc_matrix(np.triu(W)), q.copy(), sp.vstack(blocks).tocsc(),
                                 np.concatenate(rhs), cones, _clarabel_settings(1e-10)).solve()
    assert str(sol.status) in ("Solved", "AlmostSolved")
    return np.array(sol.x)


def polish_tresca(W, q, g, r):
    """Refine an interior-point Tresca solution on the smooth piece it identifies.

    Clarabel stops ~1e-8 away from the optimum of these SOCPs (its projected gradient is
    ~1e-8, ours 1e-13), so agreement to 1e-7 needs a polish. The piece is read off ``r``;
    normal and tangential parts are independent for Tresca: the normal is closed (u_N = 0) or
    open (r_N = 0); the tangent slides (||r_T|| = g, r_T = -g u_T/||u_T||), sticks (u_T = 0)
    or is frictionless (g = 0: r_T = 0). The square smooth system is solved by
    scipy.optimize.root from ``r``.
    """
    from scipy.optimize import root

    R = r.reshape(-1, 3)
    U = (W @ r + q).reshape(-1, 3)
    scale_r, scale_u = np.abs(R).max(), np.abs(U).max()
    closed = R[:, 0] > 1e-6 * scale_r
    sliding = (g > 0) & (np.hypot(R[:, 1], R[:, 2]) > (1 - 1e-6) * g) \
        & (np.hypot(U[:, 1], U[:, 2]) > 1e-6 * scale_u)
    sticking = (g > 0) & ~sliding

    def F(x):
        X = x.reshape(-1, 3)
        V = (W @ x + q).reshape(-1, 3)
        out = np.array(X)
        out[closed, 0] = V[closed, 0]
        out[sticking, 1:] = V[sticking, 1:]
        nv = np.hypot(V[sliding, 1], V[sliding, 2])
        out[sliding, 1:] = X[sliding, 1:] + g[sliding, None] * V[sliding, 1:] / nv[:, None]
        return out.ravel()

    sol = root(F, r, method="hybr", options={"xtol": 1e-15})
    assert np.linalg.norm(F(sol.x)) <= 1e-12 * max(scale_r, scale_u)
    return sol.x


def projected_gradient(W, q, g, r):
    return np.linalg.norm(r - project_tresca_set(r - (W @ r + q), g)) / np.linalg.norm(q)


# ---------------------------------------------------------------- cones
def test_cone_projection_is_moreau_decomposition():
    rng = np.random.default_rng(0)
    x = rng.standard_normal(3 * 200) * 3
    mu = rng.uniform(0, 1.5, 200)
    mu[:10] = 0.0
    P = project_cone(x, mu).reshape(-1, 3)
    D = (x - project_cone(x, mu)).reshape(-1, 3)
    # P in K_mu; x - P in the polar cone {mu ||t|| <= -n}; P orthogonal to x - P; idempotent.
    assert np.all(np.hypot(P[:, 1], P[:, 2]) <= mu * P[:, 0] + 1e-12)
    assert np.all(mu * np.hypot(D[:, 1], D[:, 2]) <= -D[:, 0] + 1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", P, D), 0.0, atol=1e-12)
    np.testing.assert_allclose(project_cone(P.ravel(), mu), P.ravel(), atol=1e-14)


def test_siconos_error_vanishes_only_at_solutions():
    # One contact, W = I: r = (1, 0.3, 0) with u = (0, 0, 0) is a sticking solution for mu = 0.5.
    W, q, mu = np.eye(3), np.array([-1.0, -0.3, 0.0]), 0.5
    r = np.array([1.0, 0.3, 0.0])
    assert siconos_error(r, W @ r + q, q, mu) == 0.0
    assert siconos_error(r + 0.01, W @ (r + 0.01) + q, q, mu) > 1e-3


def test_frictionless_cone_projects_a_separated_point_with_no_tangential_part_to_zero():
    # mu = 0: the cone is the half-line {r_T = 0, r_N >= 0}; (-1, 0, 0) lies in its polar cone
    assert np.array_equal(project_cone(np.array([-1.0, 0.0, 0.0]), 0.0), np.zeros(3))
    # one separated contact (u = (1, 0, 0), r = 0) and one in contact: an exact solution
    W, q = np.eye(6), np.array([1.0, 0.0, 0.0, -1.0, 0.0, 0.0])
    r = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    assert siconos_error(r, W @ r + q, q, 0.0) == 0.0


def test_frictionless_newton_converges_with_a_separated_contact_held_tangentially():
    # A contact node on two symmetry planes has u_T = 0 exactly; separated, it is solved
    # (r = 0, u_N > 0), and plain Newton must stop there, not run the proximal rounds into overflow.
    W, q = np.eye(6), np.array([1.0, 0.0, 0.0, -1.0, 0.0, 0.0])
    for dtype in (np.float64, np.float32):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            res = solve_newton(W.astype(dtype), q, 0.0, tol=1e-12)
        assert res.converged and res.stats["phase"] == "plain"
        np.testing.assert_allclose(res.r, [0, 0, 0, 1, 0, 0], atol=1e-12)


def test_proximal_parameter_stays_bounded_on_a_problem_without_solution():
    # W_NN < 0: u_N = -r_N - 1 < 0 for every r_N >= 0, no solution. The proximal rounds must stop
    # at the bound of alpha with that reason, without overflow.
    W = np.diag([-1.0, 1e-30, 1e-30])
    q = np.array([-1.0, 0.5, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = solve_newton(W, q, 0.3, tol=1e-10, max_iter=2000, raise_on_failure=False)
    assert not res.converged and res.stats["last_status"] == "alpha"
    assert max(res.stats["alphas"]) <= 1e8 * np.mean(np.abs(np.diag(W)))
    assert "proximal parameter reached its bound" in res.message


# ---------------------------------------------------------------- Tresca vs Clarabel
@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("seed", [0, 1])
def test_tresca_matches_clarabel_socp(size, seed):
    W, q, mu = lattice_problem(*size, seed=seed)
    g = np.random.default_rng(seed).uniform(0.0, 0.4, mu.size)
    res = solve_tresca(W, q, g, tol=1e-13)
    assert res.converged and projected_gradient(W, q, g, res.r) <= 1e-12
    assert min(res.steps.values()) > 0 or size == (6, 5)   # all three step types are used
    x_ipm = clarabel_tresca(W, q, g)
    x_ref = polish_tresca(W, q, g, x_ipm)
    assert rel(x_ref, x_ipm) <= 1e-5                        # the polish only refines
    assert rel(res.r, x_ref) <= 1e-7


@pytest.mark.parametrize("size", SIZES)
def test_frictionless_matches_clarabel_qp(size):
    W, q, _ = lattice_problem(*size, seed=3)
    x_ref = clarabel_frictionless(W, q)
    tres = solve_tresca(W, q, 0.0, tol=1e-13)
    assert rel(tres.r, x_ref) <= 1e-7
    for method in ("newton", "fixed-point"):
        res = solve_local(W, q, 0.0, method=method, tol=1e-12)
        assert res.converged and res.error <= 1e-12
        assert rel(res.r, x_ref) <= 1e-7, method


def test_tresca_warm_start_and_linear_operator():
    W, q, mu = lattice_problem(10, 8, seed=4)
    g = np.full(mu.size, 0.2)
    cold = solve_tresca(W, q, g, tol=1e-12)
    warm = solve_tresca(spla.aslinearoperator(W), q, g, r0=cold.r, tol=1e-12)
    assert warm.iterations <= 2 and rel(warm.r, cold.r) <= 1e-10


# ---------------------------------------------------------------- Coulomb
# (size, seed, mu, shear, some contacts stick); every case also has separated and sliding ones
COULOMB_CASES = [((6, 5), 0, 0.3, 0.4, False), ((10, 8), 1, 0.3, 0.1, True),
                 ((10, 8), 2, 0.5, 0.4, True), ((12, 12), 3, 0.3, 0.2, True),
                 ((12, 12), 4, 0.2, 0.6, False)]


@pytest.mark.parametrize("size,seed,mu,shear,sticking", COULOMB_CASES)
def test_coulomb_newton_and_fixed_point_agree(size, seed, mu, shear, sticking):
    W, q, mus = lattice_problem(*size, seed=seed, mu=mu, shear=shear)
    nt = solve_local(W, q, mus, method="newton", tol=1e-12)
    fp = solve_local(W, q, mus, method="fixed-point", tol=1e-11)
    assert isinstance(nt, LocalResult) and nt.converged and fp.converged
    assert rel(nt.r, fp.r) <= 1e-7
    classes = set(node_class(nt.r, nt.u, mus))
    assert "L" in classes and "M1" in classes                # separated and sliding contacts
    assert ("M3+" in classes) == sticking
    # Contact conditions at the Newton solution, relative to the force/displacement scales.
    sr, su = np.abs(nt.r).max(), np.abs(nt.u).max()
    v = complementarity_violations(nt.r, nt.u, mus)
    assert v["r_N>=0"] <= 1e-9 * sr and v["u_N>=0"] <= 1e-9 * su
    assert v["r_N*u_N"] <= 1e-9 * sr * su and v["cone"] <= 1e-9 * sr
    assert v["stick"] <= 1e-9 * sr * su and v["slip"] <= 1e-9 * sr * su
    R, U = nt.r.reshape(-1, 3), nt.u.reshape(-1, 3)
    ut = np.hypot(U[:, 1], U[:, 2])
    slide = (R[:, 0] > 1e-9 * sr) & (ut > 1e-6 * su)
    assert np.any(slide)
    expected = -(mus * R[:, 0])[slide, None] * U[slide, 1:] / ut[slide, None]
    np.testing.assert_allclose(R[slide, 1:], expected, rtol=0, atol=1e-9 * sr)
    np.testing.assert_allclose(nt.u, W @ nt.r + q, rtol=0, atol=1e-12 * su)


def test_newton_with_frictionless_and_frictional_contacts_mixed():
    # Per-contact mu with zeros: the Newton system then has every group of unknowns (sticking,
    # frictional sliding z_N and z_t, frictionless sliding d_N); the fixed point agrees.
    W, q, mus = lattice_problem(10, 8, seed=2, mu=0.5, shear=0.4)
    mus = mus.copy()
    mus[::3] = 0.0
    nt = solve_local(W, q, mus, method="newton", tol=1e-12)
    fp = solve_local(W, q, mus, method="fixed-point", tol=1e-11)
    assert nt.converged and fp.converged and rel(nt.r, fp.r) <= 1e-7
    R, U = nt.r.reshape(-1, 3), nt.u.reshape(-1, 3)
    sr, su = np.abs(R).max(), np.abs(U).max()
    touching = R[:, 0] > 1e-9 * sr
    sliding = np.hypot(U[:, 1], U[:, 2]) > 1e-6 * su
    assert np.any(touching & (mus == 0)) and np.any(touching & (mus > 0) & sliding)
    assert np.any(touching & (mus > 0) & ~sliding)
    assert np.abs(R[mus == 0, 1:]).max() <= 1e-9 * sr        # no friction force where mu = 0


def test_newton_warm_start_needs_few_steps():
    W, q, mu = lattice_problem(12, 12, seed=5)
    base = solve_newton(W, q, mu, tol=1e-10)
    rng = np.random.default_rng(0)
    for _ in range(3):
        q2 = q * (1.0 + 1e-3 * rng.standard_normal(q.size))
        warm = solve_newton(W, q2, mu, tol=1e-8, r0=base.r)
        assert warm.converged and warm.iterations <= 3, warm.history


def test_fixed_point_warns_when_not_contracting(caplog):
    # One contact, W_NT = 0.9 couples the tangential force into the normal gap. Sliding with
    # u_T < 0 gives Gamma(g) = max(0, 1 - 0.9 g), so g -> mu Gamma(g) oscillates 0, 2, 0, ...
    # for mu = 2 (|mu W_NT| > 1: no contraction), while the unique solution has r_N = 1/2.8.
    W = np.array([[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]])
    q = np.array([-1.0, -5.0, 0.0])
    with caplog.at_level(logging.WARNING, logger="contactopt.contact.fixed_point"):
        res = solve_fixed_point(W, q, 2.0, tol=1e-10, max_iter=30, raise_on_failure=False)
    assert not res.converged and res.stats["non_contracting"]
    assert any("not contracting" in rec.getMessage() for rec in caplog.records)
    nt = solve_newton(W, q, 2.0, tol=1e-12)
    np.testing.assert_allclose(nt.r, [1 / 2.8, 2 / 2.8, 0.0], atol=1e-12)


# ---------------------------------------------------------------- failures
@pytest.mark.parametrize("method", ["newton", "fixed-point"])
def test_non_convergence_raises_with_history(method):
    W, q, mu = lattice_problem(10, 8, seed=0)
    with pytest.raises(ContactNotConverged) as info:
        solve_local(W, q, mu, method=method, tol=1e-14, max_iter=2)
    assert len(info.value.history) == 2 and info.value.iterations == 2
    assert all(np.isfinite(info.value.history)) and info.value.history[-1] > 1e-14
    res = solve_local(W, q, mu, method=method, tol=1e-14, max_iter=2, raise_on_failure=False)
    assert not res.converged and res.iterations == 2 and len(res.history) == 2
    assert res.error == pytest.approx(min(res.history) if method == "newton" else res.history[-1])
    assert np.all(np.isfinite(res.r)) and "not converged" in res.message


def test_tresca_max_iter_raises():
    W, q, mu = lattice_problem(10, 8, seed=0)
    with pytest.raises(ContactNotConverged) as info:
        solve_tresca(W, q, 0.1, tol=1e-14, max_iter=3)
    assert len(info.value.history) == 3


def test_invalid_data_is_rejected():
    W, q, mu = lattice_problem(6, 5, seed=0)
    bad_q = q.copy()
    bad_q[4] = np.nan
    bad_W = W.copy()
    bad_W[0, 1] = np.inf
    for args in ((W, bad_q, mu), (bad_W, q, mu), (W, q[:-1], mu), (W, q, -0.1),
                 (W, q, mu[:-1]), (W[:-3, :-3], q, mu)):
        with pytest.raises(ProblemDataError):
            solve_local(*args)
    with pytest.raises(ProblemDataError):
        solve_local(W, q, mu, method="lemke")
    with pytest.raises(ProblemDataError):
        solve_local(spla.aslinearoperator(W), q, mu, method="newton")


def test_singular_W_uses_proximal_regularisation():
    # Two contacts sharing the same rigid-body-like W (rank 3 of 6): plain Newton's Jacobian
    # is singular; the proximal rounds must still converge.
    B = np.random.default_rng(1).standard_normal((3, 3))
    S = B @ B.T + np.eye(3)
    W = np.block([[S, S], [S, S]])
    q = np.array([-1.0, 0.2, 0.1, -0.5, 0.3, -0.2])
    res = solve_newton(W, q, 0.4, tol=1e-10)
    assert res.converged and res.stats["phase"] == "proximal" and res.outer_iterations >= 1
    v = complementarity_violations(res.r, res.u, 0.4)
    assert max(v.values()) <= 1e-8
