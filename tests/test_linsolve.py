"""Condensation onto the contact DOFs (contactopt.fem.linsolve) against dense references."""

from __future__ import annotations

import gc
import logging

import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.errors import SolverError
from contactopt.fem import _pardiso, linsolve
from contactopt.fem.linsolve import condense, factorize
from contactopt.verification.brick import EXAMPLE1, brick, hex_stiffness

HAVE_PARDISO = _pardiso.available()
BACKENDS = [pytest.param("pardiso", marks=pytest.mark.skipif(not HAVE_PARDISO,
                                                             reason="MKL PARDISO not loadable")),
            "scipy"]


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.fixture(scope="module")
def small():
    """6x3x3 brick (288 free DOFs, 72 Schur DOFs) with c shuffled, and dense references."""
    b = brick(6, 3, 3)
    c = np.random.default_rng(3).permutation(b.c)
    Ad = b.A.toarray()
    Ainv = np.linalg.inv(Ad)
    return b.A, c, Ad, Ainv


@pytest.fixture(scope="module", params=BACKENDS)
def fac(request, small):
    A, c, _, _ = small
    f = condense(A, c, backend=request.param)
    yield f
    f.close()


# ------------------------------------------------------------------------------ test matrix

def test_brick_sizes_match_the_paper_example_1():
    b = brick(*EXAMPLE1)
    assert b.A.shape == (15360, 15360)
    assert len(b.c) == 1536 and len(np.unique(b.c)) == 1536


def test_hex_stiffness_has_exactly_the_six_rigid_modes():
    Ke = hex_stiffness(np.array([0.5, 0.3, 0.2]))
    ev = np.linalg.eigvalsh(Ke)
    assert np.all(np.abs(ev[:6]) < 1e-12 * ev[-1]) and ev[6] > 1e-4 * ev[-1]
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                        [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]) * [0.5, 0.3, 0.2]
    rot = np.cross([0.0, 0.0, 1.0], corners).ravel()        # infinitesimal rotation about z
    assert np.abs(Ke @ rot).max() < 1e-12 * np.abs(Ke).max()


# ------------------------------------------------------------------- condensation vs dense

def test_S_is_the_inverse_of_the_cc_block_of_A_inverse(fac, small):
    _, c, _, Ainv = small
    W = Ainv[np.ix_(c, c)]                       # Delassus operator W = B A⁻¹ Bᵀ
    assert fac.S.shape == (len(c), len(c))
    assert rel(fac.S, np.linalg.inv(W)) < 1e-10
    assert rel(fac.S @ W, np.eye(len(c))) < 1e-10
    assert np.array_equal(fac.S, fac.S.T)


def test_S_matches_the_block_formula(fac, small):
    _, c, Ad, _ = small
    i = fac.interior
    S_ref = Ad[np.ix_(c, c)] - Ad[np.ix_(c, i)] @ np.linalg.solve(Ad[np.ix_(i, i)], Ad[np.ix_(i, c)])
    assert rel(fac.S, S_ref) < 1e-10
    assert np.array_equal(i, np.setdiff1d(np.arange(Ad.shape[0]), c))


def test_condensed_load_gives_the_contact_part_of_the_full_solution(fac, small):
    A, c, Ad, Ainv = small
    rng = np.random.default_rng(7)
    L = rng.standard_normal((A.shape[0], 3))
    ell = fac.condense_load(L)
    assert ell.shape == (len(c), 3)
    u = Ainv @ L                                  # A u = L  =>  S u_c = ℓ
    assert rel(fac.S @ u[c], ell) < 1e-10
    i = fac.interior
    ell_ref = L[c] - Ad[np.ix_(c, i)] @ np.linalg.solve(Ad[np.ix_(i, i)], L[i])
    assert rel(fac.condense_load(L[:, 0]), ell_ref[:, 0]) < 1e-10


def test_recover_solves_the_interior_equations(fac, small):
    A, c, Ad, Ainv = small
    rng = np.random.default_rng(8)
    L = rng.standard_normal(A.shape[0])
    u_c = rng.standard_normal(len(c))
    u = fac.recover(L, u_c)
    assert np.array_equal(u[c], u_c)
    r = A @ u - L
    assert np.linalg.norm(r[fac.interior]) <= 1e-10 * np.linalg.norm(L)
    # with the contact values of the unconstrained solution, recover gives A⁻¹L
    u_free = Ainv @ L
    assert rel(fac.recover(L, np.linalg.solve(fac.S, fac.condense_load(L))), u_free) < 1e-10


def test_extend_is_the_discrete_harmonic_extension(fac, small):
    A, c, _, _ = small
    rng = np.random.default_rng(9)
    v_c = rng.standard_normal((len(c), 2))
    v = fac.extend(v_c)
    assert np.array_equal(v[c], v_c)
    Av = A @ v
    assert np.linalg.norm(Av[fac.interior]) <= 1e-10 * np.linalg.norm(Av)
    # energy identity ṽᵀAṽ = v_cᵀ S v_c
    assert np.allclose(v.T @ Av, v_c.T @ fac.S @ v_c, rtol=1e-10)
    assert rel(fac.extend(v_c[:, 1]), v[:, 1]) < 1e-13


def test_solve_interior_one_and_several_rhs(fac, small):
    _, _, Ad, _ = small
    i = fac.interior
    Aii = Ad[np.ix_(i, i)]
    rng = np.random.default_rng(10)
    B = rng.standard_normal((len(i), 4))
    X = fac.solve_interior(B)
    assert X.shape == B.shape
    assert np.linalg.norm(Aii @ X - B) <= 1e-10 * np.linalg.norm(B)
    x = fac.solve_interior(B[:, 2])
    assert np.linalg.norm(Aii @ x - B[:, 2]) <= 1e-10 * np.linalg.norm(B[:, 2])


def test_backends_agree_on_a_medium_mesh():
    if not HAVE_PARDISO:
        pytest.skip("MKL PARDISO not loadable")
    b = brick(12, 6, 4)
    rng = np.random.default_rng(11)
    c = rng.permutation(b.c)
    L = rng.standard_normal(b.A.shape[0])
    with condense(b.A, c, "pardiso") as fp, condense(b.A, c, "scipy") as fs:
        assert fp.backend == "pardiso" and fs.backend == "scipy"
        assert rel(fp.S, fs.S) < 1e-11
        assert rel(fp.condense_load(L), fs.condense_load(L)) < 1e-11
        u_c = rng.standard_normal(len(c))
        assert rel(fp.recover(L, u_c), fs.recover(L, u_c)) < 1e-11
        assert set(fp.timings) == set(fs.timings) == {"analyze", "factor_schur"}


@pytest.mark.parametrize("backend", BACKENDS)
def test_factorize_solves(backend, small):
    A, _, _, _ = small
    rng = np.random.default_rng(12)
    B = rng.standard_normal((A.shape[0], 3))
    with factorize(A, backend) as f:
        assert f.backend == backend
        X = f.solve(B)
        assert np.linalg.norm(A @ X - B) <= 1e-10 * np.linalg.norm(B)
        x = f.solve(B[:, 0])
        assert np.linalg.norm(A @ x - B[:, 0]) <= 1e-10 * np.linalg.norm(B[:, 0])
        assert set(f.timings) == {"analyze", "factor"}


# ----------------------------------------------------------------------- refactor, memory

@pytest.mark.parametrize("backend", BACKENDS)
def test_refactor_reuses_the_analysis(backend, small):
    A, c, _, _ = small
    with condense(A, c, backend) as f:
        S1 = f.S
        assert f.refactor(2.5 * A) is f
        assert rel(f.S, 2.5 * S1) < 1e-12
        if backend == "pardiso":
            assert f.timings["analyze"] == 0.0
        L = np.ones(A.shape[0])
        u = f.recover(L, np.zeros(len(c)))
        assert np.linalg.norm((2.5 * A @ u - L)[f.interior]) < 1e-10 * np.linalg.norm(L)
        A2 = A.tolil()
        A2[0, A.shape[0] - 1] = A2[A.shape[0] - 1, 0] = 1e-3
        with pytest.raises(SolverError, match="same sparsity pattern"):
            f.refactor(A2.tocsr())
        # trusted (an assembled stiffness): the same factorization; symmetry is not re-checked,
        # finiteness and the pattern still are
        assert rel(f.refactor(2.0 * A, trusted=True).S, 2.0 * S1) < 1e-12
        skew = (A + sp.triu(A, 1) * 1e-3).tocsr()
        with pytest.raises(SolverError, match="not symmetric"):
            f.refactor(skew)
        bad = A.copy()
        bad.data[3] = np.nan
        with pytest.raises(SolverError, match="non-finite"):
            f.refactor(bad, trusted=True)
        with pytest.raises(SolverError, match="same sparsity pattern"):
            f.refactor(A2.tocsr(), trusted=True)


@pytest.mark.skipif(not HAVE_PARDISO, reason="MKL PARDISO not loadable")
def test_pardiso_memory_released_on_close_and_on_garbage_collection(small):
    A, c, _, _ = small
    f = condense(A, c, "pardiso")
    fin = f._ps._finalizer
    assert fin.alive
    f.close()
    assert not fin.alive
    with pytest.raises(SolverError, match="released"):
        f.condense_load(np.ones(A.shape[0]))
    f = condense(A, c, "pardiso")
    fin = f._ps._finalizer
    del f
    gc.collect()
    assert not fin.alive


@pytest.mark.skipif(not HAVE_PARDISO, reason="MKL PARDISO not loadable")
def test_auto_prefers_pardiso_and_falls_back_to_scipy(small, monkeypatch, caplog):
    A, c, _, _ = small
    with caplog.at_level(logging.INFO, logger="contactopt.fem.linsolve"):
        with condense(A, c) as f:
            assert f.backend == "pardiso"
        monkeypatch.setattr(_pardiso, "available", lambda: False)
        with condense(A, c, "auto") as f:
            assert f.backend == "scipy"
    assert "backend: pardiso" in caplog.text and "backend: scipy" in caplog.text


# ------------------------------------------------------------------------------ bad input

@pytest.mark.parametrize("bad_c, match", [
    (lambda c, n: np.r_[c, c[:1]], "duplicate"),
    (lambda c, n: np.r_[c, n], "out of range"),
    (lambda c, n: np.r_[c, -1], "out of range"),
    (lambda c, n: c.astype(float), "integer"),
    (lambda c, n: np.array([], dtype=int), "empty"),
    (lambda c, n: np.arange(n), "no interior"),
    (lambda c, n: c.reshape(-1, 3), "1-D"),
])
def test_bad_schur_dofs_raise(small, bad_c, match):
    A, c, _, _ = small
    with pytest.raises(SolverError, match=match):
        condense(A, bad_c(c, A.shape[0]), "scipy")


@pytest.mark.parametrize("backend", BACKENDS)
def test_bad_matrices_raise(backend, small):
    A, c, Ad, _ = small
    n = A.shape[0]
    with pytest.raises(SolverError, match="square"):
        condense(A[:, :-1], c, backend)
    A_nan = A.copy()
    A_nan.data[5] = np.nan
    with pytest.raises(SolverError, match="non-finite"):
        condense(A_nan, c, backend)
    A_uns = A.tolil()
    A_uns[0, 1] += 1.0
    with pytest.raises(SolverError, match="not symmetric"):
        condense(A_uns.tocsr(), c, backend)
    # positive diagonal but indefinite: shift past the 6th eigenvalue
    lam = np.linalg.eigvalsh(Ad)[5]
    A_ind = (A - lam * sp.identity(n)).tocsr()
    with pytest.raises(SolverError, match="not positive definite"):
        condense(A_ind, c, backend)
    if backend == "pardiso":                    # SuperLU solves indefinite systems too
        with pytest.raises(SolverError, match="not positive definite"):
            factorize(A_ind, backend)
    with pytest.raises(SolverError, match="unknown backend"):
        condense(A, c, "umfpack")


def test_wrong_vector_sizes_raise(fac, small):
    A, c, _, _ = small
    with pytest.raises(SolverError, match="length"):
        fac.condense_load(np.ones(A.shape[0] - 1))
    with pytest.raises(SolverError, match="len\\(c\\)"):
        fac.recover(np.ones(A.shape[0]), np.ones(len(c) + 1))
    with pytest.raises(SolverError, match="interior"):
        fac.solve_interior(np.ones(3))


def test_pardiso_error_codes_are_decoded():
    assert "not positive definite" in _pardiso.PARDISO_ERRORS[-4]
    assert "memory" in _pardiso.PARDISO_ERRORS[-2]
    assert set(range(-13, 0)) <= set(_pardiso.PARDISO_ERRORS)


def test_missing_library_gives_a_clear_error(monkeypatch):
    monkeypatch.setattr(_pardiso, "_lib", None)
    monkeypatch.setattr(_pardiso, "_load_error", None)
    monkeypatch.setattr(_pardiso, "_candidate_paths", lambda: iter(["/nonexistent/libmkl_rt.so"]))
    assert not _pardiso.available()
    with pytest.raises(SolverError, match="MKL PARDISO is not available"):
        linsolve.condense(sp.identity(4, format="csr"), [0], "pardiso")
