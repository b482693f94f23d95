"""The contact zone (contact/zone.py) and the dense kernels behind it (fem/dense.py).

The zone's local problem must be the whole problem restricted exactly: W_Z is the block of
S⁻¹, the displacements of the other nodes solve their rows with zero force, and a state solved
on a zone that misses nodes (they close their gap) must equal the state on all contact nodes.
"""

from __future__ import annotations

import ctypes
import os

import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.contact.zone import ZoneProblem, missed_nodes, near_nodes
from contactopt.errors import ConfigError, SolverError
from contactopt.fem import _pardiso, dense
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient

BACKENDS = ["mkl", "scipy"] if _pardiso.available() else ["scipy"]


@pytest.fixture(params=BACKENDS)
def lapack_backend(request, monkeypatch):
    if request.param == "scipy":
        monkeypatch.setattr(_pardiso, "available", lambda: False)
    return request.param


def random_spd(n, seed=0, cond=1e4):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (Q * np.logspace(0, np.log10(cond), n)) @ Q.T


@pytest.mark.parametrize("n", [1, 7, 130, 301])
def test_cholesky_and_trailing_inverse(lapack_backend, n):
    S = random_spd(n, seed=n)
    L = dense.cholesky_lower(np.array(S))
    Lt = np.tril(L)
    assert np.allclose(Lt @ Lt.T, S, rtol=0, atol=1e-12 * np.abs(S).max())
    for start in {0, n // 3, n - 1}:
        inv = dense.inverse_from_cholesky(np.array(L), start)
        ref = np.linalg.inv(S)[start:, start:]
        assert np.array_equal(inv, inv.T)
        assert np.abs(inv - ref).max() <= 1e-9 * np.abs(ref).max()
    assert np.abs(dense.spd_inverse(S) - np.linalg.inv(S)).max() <= 1e-9 * np.abs(np.linalg.inv(S)).max()


def test_cholesky_rejects_an_indefinite_matrix(lapack_backend):
    A = random_spd(20)
    A[5, 5] = -1.0
    with pytest.raises(SolverError, match="not positive definite"):
        dense.cholesky_lower(A)


@pytest.mark.parametrize("n", [1, 2, 127, 129, 300])
def test_symmetrize_lower(n):
    a = np.random.default_rng(n).standard_normal((n, n))
    out = dense.symmetrize_lower(a.copy())
    ref = np.tril(a) + np.tril(a, -1).T
    assert np.array_equal(out, ref)


def test_lu_factor_solves_and_estimates_the_condition(lapack_backend):
    rng = np.random.default_rng(3)
    M = rng.standard_normal((90, 90)) + 10 * np.eye(90)
    b = rng.standard_normal(90)
    lu = dense.LUFactor(np.array(M))
    assert lu.info == 0
    x = lu.solve(b)
    assert np.linalg.norm(M @ x - b) <= 1e-12 * np.linalg.norm(b) * np.linalg.cond(M)
    kappa = np.linalg.norm(M, np.inf) * np.linalg.norm(np.linalg.inv(M), np.inf)
    rc = lu.rcond(np.linalg.norm(M, np.inf))
    assert 0.1 / kappa <= rc <= 10 / kappa          # LAPACK's estimate is within a small factor
    sing = dense.LUFactor(np.zeros((4, 4)))
    assert sing.info > 0
    assert 1e-3 < lu.pivot_ratio() <= 1.0
    near = M.copy()
    near[:, -1] = near[:, 0] + 1e-14 * rng.standard_normal(90)   # rank-deficient up to 1e-14
    assert dense.LUFactor(near).pivot_ratio() < 1e-10


def test_single_precision_lu_solves_to_its_precision(lapack_backend):
    rng = np.random.default_rng(8)
    M = rng.standard_normal((120, 120)) + 12 * np.eye(120)
    b = rng.standard_normal(120)
    x64 = dense.LUFactor(np.array(M)).solve(b)
    lu = dense.LUFactor(M.astype(np.float32))
    assert lu.info == 0 and lu.dtype == np.float32
    x = lu.solve(b)
    assert x.dtype == np.float64
    err = np.linalg.norm(x - x64) / np.linalg.norm(x64)
    assert 1e-12 < err < 1e-5        # single precision: not exact, but to ~κ·6e-8
    kappa = np.linalg.norm(M, np.inf) * np.linalg.norm(np.linalg.inv(M), np.inf)
    assert 0.1 / kappa <= lu.rcond(np.linalg.norm(M, np.inf)) <= 10 / kappa
    assert dense.LUFactor(np.zeros((4, 4), dtype=np.float32)).info > 0
    with pytest.raises(SolverError, match="float64 or float32"):
        dense.LUFactor(M.astype(np.float16))


@pytest.mark.skipif(not _pardiso.available(), reason="MKL's thread count is MKL's")
def test_sequential_lu_is_the_one_thread_factor_and_restores_the_threads():
    """LUFactor(sequential=True) factorizes as MKL on one thread does, bit for bit, and leaves the
    calling thread's MKL thread count as it found it."""
    lib, _ = _pardiso._load()
    set_local, get_max = lib.MKL_Set_Num_Threads_Local, lib.MKL_Get_Max_Threads
    set_local.restype, get_max.restype = ctypes.c_int, ctypes.c_int
    set_local.argtypes = [ctypes.c_int]
    rng = np.random.default_rng(11)
    M = (rng.standard_normal((400, 400)) + 40 * np.eye(400)).astype(np.float32)
    b = rng.standard_normal(400)
    before = get_max()
    with dense.mkl_sequential():
        assert get_max() == 1
        one = dense.LUFactor(M.copy())
        x_one, rc_one = one.solve(b), one.rcond(float(np.abs(M).sum(axis=1).max()))
    assert get_max() == before
    lu = dense.LUFactor(M.copy(), sequential=True)
    assert get_max() == before
    assert np.array_equal(lu.a, one.a) and np.array_equal(lu.piv, one.piv)
    assert np.array_equal(lu.solve(b), x_one)
    assert lu.rcond(float(np.abs(M).sum(axis=1).max())) == rc_one
    assert np.linalg.norm(M.astype(np.float64) @ x_one - b) <= 1e-4 * np.linalg.norm(b)


@pytest.mark.parametrize("zone", [np.arange(40), np.array([0, 3, 4, 17, 39]), np.array([22])])
def test_zone_problem_is_the_exact_restriction(lapack_backend, zone):
    p = 40
    S = random_spd(3 * p, seed=1, cond=1e3)
    ell = np.random.default_rng(2).standard_normal(3 * p)
    zp = ZoneProblem(S, ell, zone)
    local = (3 * zone[:, None] + np.array([2, 0, 1])).ravel()      # FCLIB order per node
    W = np.linalg.inv(S)
    assert np.abs(zp.W - W[np.ix_(local, local)]).max() <= 1e-10 * np.abs(W).max()
    r_loc = np.random.default_rng(4).standard_normal(local.size)
    u = zp.displacements(r_loc).ravel()
    r_full = np.zeros(3 * p)
    r_full[local] = r_loc
    # S u − ℓ = r with r = 0 off the zone: the condensed equations hold for every node
    assert np.linalg.norm(S @ u - ell - r_full) <= 1e-10 * np.linalg.norm(ell)
    assert np.allclose(zp.q0 + zp.W @ r_loc, u[local], rtol=0, atol=1e-12 * np.abs(u).max())


def test_growing_a_zone_equals_building_the_larger_zone(lapack_backend):
    p = 30
    S = random_spd(3 * p, seed=5, cond=1e3)
    ell = np.random.default_rng(6).standard_normal(3 * p)
    small = ZoneProblem(S, ell, np.array([2, 9, 10, 25]))
    grown = small.grow(np.array([0, 9, 17, 29]))
    ref = ZoneProblem(S, ell, np.array([0, 2, 9, 10, 17, 25, 29]))
    assert np.array_equal(grown.zone, ref.zone)
    assert np.abs(grown.W - ref.W).max() <= 1e-12 * np.abs(ref.W).max()
    assert np.array_equal(grown.W, grown.W.T)
    assert np.abs(grown.q0 - ref.q0).max() <= 1e-12 * np.abs(ref.q0).max()
    r = np.random.default_rng(7).standard_normal(ref.W.shape[0])
    assert np.abs(grown.displacements(r) - ref.displacements(r)).max() <= 1e-11 * np.abs(ref.displacements(r)).max()
    assert small.grow(np.array([9])).W is small.W          # nothing new: same problem


def test_zone_rules():
    clearance = np.array([0.0, 1e-12, 5e-3, 2e-2, -1e-3, 1.0])
    lam = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    zone = np.array([0, 2])
    # closed (or violated) gaps outside the zone are misses; open ones and zone nodes are not
    assert list(missed_nodes(zone, clearance, 1.0)) == [1, 4]
    near = near_nodes(lam, clearance, 1.0, 0.01)
    assert set(near) >= {0, 1, 2, 4} and 5 in near          # fewer than MIN_ZONE: smallest added
    big = np.linspace(0.0, 1.0, 101)
    assert list(near_nodes(np.zeros(101), big, 1.0, 0.105)) == list(range(11))


def small_problem(**state):
    upd = {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "state": {"tol": 1e-12, **state}}
    return ShapeProblem(load_config("example1").with_updates(upd))


def wavy(pr, amp=0.004, phase=0.0):
    a = pr.model.initial_design() + amp * np.sin(np.arange(pr.model.n_design) + phase)
    return a + 0.01 - a.mean()


@pytest.mark.parametrize("method", ["newton", "fixed-point"])
def test_a_missing_zone_grows_to_the_state_on_all_contact_nodes(method):
    full, zoned = small_problem(zone=False), small_problem(zone_margin=0.0)
    alpha = wavy(full)
    ref = full.solve_state(alpha, method=method)
    in_contact = np.flatnonzero(ref.lam > 0)
    assert 3 <= in_contact.size < ref.lam.size - 3
    zoned.next_zone = in_contact[: in_contact.size // 2]          # half of the contact nodes only
    st = zoned.solve_state(alpha, method=method)
    assert st.info["zone_misses"] >= 1 and zoned.path.n_zone_misses >= 1
    scale = ref.lam.max()
    assert np.abs(st.lam - ref.lam).max() <= 1e-9 * scale
    assert np.abs(st.tau - ref.tau).max() <= 1e-9 * scale
    assert np.abs(st.u - ref.u).max() <= 1e-9 * np.abs(ref.u).max()
    assert np.array_equal(st.classes, ref.classes)
    assert st.complementarity <= 1e-9
    # the next zone covers the contact nodes; nodes left out carry no force and are of class L
    assert np.all(np.isin(in_contact, zoned.next_zone))
    out = np.setdiff1d(np.arange(st.lam.size), zoned.next_zone)
    assert np.all(st.classes[out] == CLASS_CODES["L"])


def test_subgradient_does_not_depend_on_the_zone():
    full, zoned = small_problem(zone=False), small_problem(zone_margin=0.0)
    alpha = wavy(full, phase=1.0)
    zoned.next_zone = np.array([0, 1])
    g_full = subgradient(full, alpha).gradient
    res = subgradient(zoned, alpha)
    assert res.state.info["zone_misses"] >= 1
    assert np.linalg.norm(res.gradient - g_full) <= 1e-8 * np.linalg.norm(g_full)


def test_zone_settings_are_validated():
    with pytest.raises(ConfigError) as err:
        load_config("example1").with_updates({"state": {"zone": "yes", "zone_margin": -1.0,
                                                        "reuse_delassus": 1}})
    text = str(err.value)
    assert "state.zone" in text and "state.zone_margin" in text and "state.reuse_delassus" in text


def _check_contact_data(where, warm, zone, n_contact, jacobian=None, n_design=0):
    """A checkpoint's arrays of one load case put back by a zone path with a mesh of
    ``n_contact`` contact nodes and ``n_design`` design variables; returns the warm start."""
    from types import SimpleNamespace

    from contactopt.paths.base import Settings
    from contactopt.paths.zone_paths import ZonePath
    path = ZonePath(SimpleNamespace(n_contact=n_contact, n_design=n_design),
                    Settings(0.3, "newton", 1e-12, 10, True, 0.1, False, "auto"))
    ctx = path.new_context()
    arrays = {"warm": warm if warm is not None else np.zeros(0)}
    if zone is not None:
        arrays["zone"] = zone
    if jacobian is not None:
        arrays.update(jacobian_alpha=jacobian[0], jacobian_zone=jacobian[1])
    path.import_context(ctx, arrays, f"checkpoint {where}")
    return ctx.warm


def test_checkpoint_contact_data_is_checked(tmp_path):
    from contactopt.errors import CheckpointError
    _check_contact_data(tmp_path, np.zeros((5, 3)), np.array([0, 2, 4]), 5)
    assert _check_contact_data(tmp_path, np.zeros(15), None, 5).shape == (5, 3)   # flat, as stored before
    for bad in (np.zeros(14), np.zeros((3, 5, 1))):
        with pytest.raises(CheckpointError, match="warm start"):
            _check_contact_data(tmp_path, bad, None, 5)
    for bad in (np.array([0, 5]), np.array([2, 1]), np.array([], dtype=int), np.array([-1, 0])):
        with pytest.raises(CheckpointError, match="contact zone"):
            _check_contact_data(tmp_path, None, bad, 5)


# ---------------------------------------------------------------- Delassus reuse
def test_newton_with_an_approximate_W_and_the_exact_product_solves_the_exact_problem():
    # W perturbed by 2 % (as the block of a nearby design is) builds the Newton matrices; the
    # exact product keeps u, the line search and the stopping test exact.
    from contactopt.contact.newton import solve_newton
    p = 30
    S = random_spd(3 * p, seed=4, cond=1e2)
    W = np.linalg.inv(S)
    rng = np.random.default_rng(5)
    q = rng.standard_normal(3 * p) * 0.1
    q[0::3] -= 0.05                                        # most contacts pressed
    exact = solve_newton(W, q, 0.3, tol=1e-13)
    E = rng.standard_normal(W.shape)
    W_old = W + 0.02 * np.abs(W).max() * (E + E.T) / 2
    res = solve_newton(W_old, q, 0.3, tol=1e-13, product=W.dot)
    assert res.converged and res.iterations > exact.iterations       # linear, not quadratic
    assert np.abs(res.r - exact.r).max() <= 1e-9 * np.abs(exact.r).max()
    np.testing.assert_allclose(res.u, W @ res.r + q, rtol=0, atol=1e-12 * np.abs(res.u).max())
    # the same block in single precision (as a state solve keeps it): same solution
    single = solve_newton(W_old.astype(np.float32), q, 0.3, tol=1e-13, product=W.dot)
    assert single.converged
    assert np.abs(single.r - exact.r).max() <= 1e-9 * np.abs(exact.r).max()
    assert abs(single.iterations - res.iterations) <= 2
    from contactopt.errors import ProblemDataError
    with pytest.raises(ProblemDataError, match="product"):
        solve_newton(W, q, 0.3, product=np.eye(3))
    # without the exact product a float32 W is the problem's W: taken in double precision
    from contactopt.contact.local import check_problem
    assert check_problem(W.astype(np.float32), q, 0.3)[0].dtype == np.float64
    assert check_problem(W.astype(np.float32), q, 0.3, single=True)[0].dtype == np.float32


@pytest.mark.parametrize("ordered", [True, False])
def test_zone_product_and_columns_are_those_of_W(ordered):
    # ordered=False: the factor of S in its own order serves the products, W_Z is then formed
    # from a second, ordered factorization; both give the same operator
    p = 20
    S = random_spd(3 * p, seed=6, cond=1e3)
    zp = ZoneProblem(S, np.zeros(3 * p), np.array([1, 4, 5, 11, 19]), ordered=ordered)
    v = np.random.default_rng(7).standard_normal(15)
    assert not zp.has_W and not zp.grown
    assert np.abs(zp.product(v) - zp.W @ v).max() <= 1e-12 * np.abs(zp.W @ v).max()
    g = zp.grow(np.array([2, 11]))
    assert g.grown and not g.has_W
    assert np.abs(g.columns(np.array([2, 19])) - g.W[:, [3, 4, 5, 15, 16, 17]]).max() <= 1e-12 * np.abs(g.W).max()
    assert np.abs(g.W - ZoneProblem(S, np.zeros(3 * p), g.zone).W).max() <= 1e-10 * np.abs(g.W).max()
    W_ref = np.linalg.inv(S)[np.ix_(zp._dof_z, zp._dof_z)]
    assert np.abs(zp.W - W_ref).max() <= 1e-9 * np.abs(W_ref).max()
    ell = np.random.default_rng(9).standard_normal(3 * p)
    z_ref = np.linalg.solve(S, ell)
    assert np.abs(ZoneProblem(S, ell, zp.zone, ordered=ordered).q0 - z_ref[zp._dof_z]).max() \
        <= 1e-9 * np.abs(z_ref).max()


def design_path(pr, n, step=2e-3):
    return [wavy(pr, amp=0.004 + step * k, phase=0.3 * k) for k in range(n)]


def test_reused_delassus_gives_the_states_of_formed_ones():
    reuse, formed = small_problem(), small_problem(reuse_delassus=False)
    how = []
    for alpha in design_path(reuse, 6):
        a, b = reuse.solve_state(alpha), formed.solve_state(alpha)
        how.append(a.info["delassus"])
        assert b.info["delassus"] == "formed"
        assert np.abs(a.lam - b.lam).max() <= 1e-9 * b.lam.max()
        assert np.abs(a.tau - b.tau).max() <= 1e-9 * b.lam.max()
        assert np.abs(a.u - b.u).max() <= 1e-9 * np.abs(b.u).max()
        assert np.array_equal(a.classes, b.classes) and a.complementarity <= 1e-9
        assert np.linalg.norm(subgradient(reuse, alpha).gradient - subgradient(formed, alpha).gradient) \
            <= 1e-7 * np.linalg.norm(subgradient(formed, alpha).gradient)
    assert how[0] == "formed" and how.count("reused") >= 3
    assert reuse.path.n_delassus < formed.path.n_delassus
    assert reuse.contexts[0].jacobian[2].dtype == np.float32        # the kept block is single precision


def test_restored_delassus_repeats_the_solve_bit_for_bit():
    # what a resumed run relies on: (alpha, zone) of the kept block rebuild it exactly, also
    # when it was formed on a grown zone
    pr = small_problem(zone_margin=0.0)
    path = design_path(pr, 5)
    pr.solve_state(path[0])
    pr.next_zone = np.flatnonzero(pr.solve_state(path[1]).lam > 0)[:3]   # will miss and grow
    pr.contexts[0].jacobian = None
    st = pr.solve_state(path[2])
    assert st.info["zone_misses"] >= 1 and st.info["delassus"] == "formed"
    saved = [[{k: np.array(v) for k, v in step.items()} for step in case]     # what a checkpoint holds
             for case in pr.export_contexts()]
    a = pr.solve_state(path[3])
    again = small_problem(zone_margin=0.0)
    again.import_contexts(saved, "a checkpoint")
    b = again.solve_state(path[3])
    assert a.info["delassus"] == b.info["delassus"] == "reused"
    assert np.array_equal(a.lam, b.lam) and np.array_equal(a.u, b.u)


def test_checkpoint_delassus_design_is_checked(tmp_path):
    from contactopt.errors import CheckpointError
    good = (np.zeros(4), np.array([0, 3]))
    _check_contact_data(tmp_path, None, None, 5, good, 4)
    for bad in ((np.zeros(3), np.array([0, 3])), (np.full(4, np.nan), np.array([0, 3]))):
        with pytest.raises(CheckpointError, match="Delassus design"):
            _check_contact_data(tmp_path, None, None, 5, bad, 4)
    for zone in (np.array([0, 5]), np.array([3, 1]), np.array([], dtype=np.int64)):
        with pytest.raises(CheckpointError, match="Delassus zone"):
            _check_contact_data(tmp_path, None, None, 5, (np.zeros(4), zone), 4)


def test_warm_start_after_a_small_design_change_needs_at_most_three_steps():
    # a kept block within 1e-3 of the new one: no chord steps, nearly quadratic as with a formed one
    steps = {}
    for reuse in (True, False):
        pr = small_problem(reuse_delassus=reuse)
        a0 = pr.model.initial_design()
        pr.solve_state(a0)
        d = np.sin(np.arange(pr.model.n_design))
        st = pr.solve_state(a0 + 1e-4 * (d - d.mean()))
        steps[reuse] = st.iterations
        assert st.info["delassus"] == ("reused" if reuse else "formed")
    assert steps[True] <= 3 and steps[False] <= 3


@pytest.mark.skipif(not _pardiso.available() or (os.cpu_count() or 1) < 2,
                    reason="MKL's threads on a machine with two cores or more")
def test_one_mkl_thread_makes_evaluations_those_of_a_single_threaded_run():
    """[linear_solver] threads = 1 (the default): Θ and ξ along a few designs are those of a process
    whose MKL runs on one thread, bit for bit, while MKL's own pool has two; with threads = 0 two
    MKL threads sum in another order (so the comparison can tell)."""
    lib, _ = _pardiso._load()
    set_global, get_max = lib.MKL_Set_Num_Threads, lib.MKL_Get_Max_Threads
    set_global.argtypes, get_max.restype = [ctypes.c_int], ctypes.c_int
    set_local = lib.MKL_Set_Num_Threads_Local
    set_local.argtypes, set_local.restype = [ctypes.c_int], ctypes.c_int
    before = get_max()
    # this thread on MKL's global count: a threadpoolctl limit that ended earlier in this process
    # leaves a thread-local count behind (it restores the count it read, not "the global one")
    local_before = set_local(0)

    def evaluations(threads, mkl):
        set_global(mkl)
        cfg = load_config("example1").with_updates({"mesh": {"nx": 16, "ny": 8, "nz": 5},
                                                    "linear_solver": {"threads": threads}})
        pr = ShapeProblem(cfg)
        a0 = pr.model.initial_design()
        return [pr.evaluate(a0 + 0.002 * k) for k in range(3)]

    try:
        one = evaluations(1, 1)
        pinned = evaluations(1, 2)
        free = evaluations(0, 2)
    finally:
        set_global(before)
        set_local(local_before)
    assert all(f == g and np.array_equal(x, y) for (f, x), (g, y) in zip(one, pinned))
    assert any(f != g or not np.array_equal(x, y) for (f, x), (g, y) in zip(one, free))
    assert max(abs(f - g) / abs(f) for (f, _), (g, _) in zip(one, free)) < 1e-12   # round-off only
