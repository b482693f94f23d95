"""The Krylov candidates kept with the benchmarks (``_iterative.py``: conjugate gradients with a
reused factorization or AMG, the Delassus operator by solves), checked against the direct solvers of
contactopt.fem.linsolve on Example 1 coarsened to 16×8×5. They live here, beside the code they check:
the package's tests do not import benchmarks/."""

from __future__ import annotations

import numpy as np
import pytest

import _iterative as iterative
from contactopt.config import load_config
from contactopt.errors import SolverError
from contactopt.fem.linsolve import factorize
from contactopt.fem.model import ElasticModel


@pytest.fixture(scope="module")
def small():
    """A(α0), A(α0 + 1e-3·d), L of Example 1 coarsened to 16×8×5 (about 2.5k DOFs)."""
    m = ElasticModel(load_config("example1").with_updates({"mesh": {"nx": 16, "ny": 8, "nz": 5}}))
    a0 = m.initial_design()
    d = np.sin(np.arange(m.n_design) + 1.0)
    d -= d.mean()
    asm0, asm1 = m.assemble(a0), m.assemble(a0 + 1e-3 * d / np.abs(d).max())
    return m, asm0, asm1


def test_pcg_with_reused_factorization_agrees_with_direct(small):
    _, asm0, asm1 = small
    x_direct = factorize(asm1.A).solve(asm1.L)
    solver = iterative.ReusedFactorSolver(asm0.A, rtol=1e-12, refactor_after=50)
    res = solver.solve(asm1.A, asm1.L)
    assert np.linalg.norm(res.x - x_direct) <= 1e-10 * np.linalg.norm(x_direct)
    assert 1 <= res.iterations <= 10          # a nearby design: a handful of iterations
    assert res.history[0] == 1.0 and res.history[-1] <= 1e-12
    assert solver.n_factorizations == 1
    # a block of right-hand sides: every column its own CG, the same answers
    Y = np.random.default_rng(3).standard_normal((asm1.A.shape[0], 5))
    X = solver.solve(asm1.A, Y).x
    X_direct = factorize(asm1.A).solve(Y)
    assert np.linalg.norm(X - X_direct, axis=0).max() <= 1e-10 * np.linalg.norm(X_direct, axis=0).min()
    solver.close()


def test_reused_factorization_refactorizes_when_iterations_grow(small):
    _, asm0, asm1 = small
    solver = iterative.ReusedFactorSolver(asm0.A, rtol=1e-12, refactor_after=1)
    first = solver.solve(asm1.A, asm1.L)
    assert first.iterations > 1 and solver.n_factorizations == 2      # A(α1) is the new reference
    again = solver.solve(asm1.A, asm1.L)
    assert again.iterations == 1                                       # M = A⁻¹ exactly
    solver.close()


def test_pcg_not_converged_raises_with_history(small):
    _, _, asm1 = small
    with pytest.raises(iterative.KrylovNotConverged) as err:
        iterative.pcg(asm1.A, asm1.L, rtol=1e-12, max_iter=5)        # unpreconditioned: too few
    exc = err.value
    assert isinstance(exc, SolverError)
    assert len(exc.history) == 6 and exc.iterations == 5
    assert exc.history[0] == 1.0 and exc.history[-1] > 1e-12
    assert "after 5 iterations" in str(exc)


def test_pcg_refuses_an_indefinite_matrix(small):
    _, _, asm1 = small
    with pytest.raises(iterative.KrylovNotConverged, match="non-positive curvature"):
        iterative.pcg(-asm1.A, asm1.L, rtol=1e-12, max_iter=50)


def test_rigid_body_modes_are_the_kernel_of_a_free_element():
    from contactopt.verification.brick import _CORNERS, hex_stiffness
    h = np.array([0.3, 0.2, 0.5])
    K = hex_stiffness(h)
    B = iterative.rigid_body_modes(0.5 * h * (_CORNERS + 1.0), np.arange(24))
    assert np.linalg.matrix_rank(B) == 6
    assert np.abs(K @ B).max() <= 1e-12 * np.abs(K).max() * np.abs(B).max()


def test_amg_preconditioned_cg_agrees_with_direct(small):
    pytest.importorskip("pyamg")
    m, _, asm1 = small
    M, ml = iterative.amg_preconditioner(asm1.A, iterative.rigid_body_modes(asm1.coords, m.assembler.free))
    res = iterative.pcg(asm1.A, asm1.L, M, rtol=1e-12, max_iter=300)
    x_direct = factorize(asm1.A).solve(asm1.L)
    assert np.linalg.norm(res.x - x_direct) <= 1e-10 * np.linalg.norm(x_direct)
    assert res.iterations < 100


def test_cholesky_refactor_keeps_the_analysis(small):
    _, asm0, asm1 = small
    chol = iterative.Cholesky(asm0.A)
    x = chol.refactor(asm1.A).solve(asm1.L)
    x_direct = factorize(asm1.A).solve(asm1.L)
    assert np.linalg.norm(x - x_direct) <= 1e-12 * np.linalg.norm(x_direct)
    assert chol.timings["analyze"] == 0.0
    with pytest.raises(SolverError, match="same sparsity pattern"):
        chol.refactor(asm1.A[:-3, :-3])
    chol.close()


def test_delassus_products_agree_with_the_condensation(small):
    """W_D r = B_D A⁻¹ B_Dᵀ r by one solve against the principal block of W = S⁻¹ of today's
    condensation; the recovery u = A⁻¹L + A⁻¹B_Dᵀr and the A-harmonic extension from the same
    by-product against the condensation's recover/extend."""
    from contactopt.fem.linsolve import condense
    m, _, asm1 = small
    c = m.contact_dofs
    zone = np.arange(0, m.n_contact, 2)                       # every other contact node
    pos = (3 * zone[:, None] + np.arange(3)).ravel()          # their rows in the order of c
    D = c[pos]
    chol = iterative.Cholesky(asm1.A)
    W_op = iterative.DelassusOperator(chol.solve, asm1.A.shape[0], D)
    with condense(asm1.A, c) as cond:
        W_D = np.linalg.inv(cond.S)[np.ix_(pos, pos)]
        r = np.random.default_rng(5).standard_normal(D.size)
        Wr = W_op @ r
        assert np.linalg.norm(Wr - W_D @ r) <= 1e-10 * np.linalg.norm(W_D @ r)
        # u = A⁻¹(L + B_Dᵀ r) is the state with contact forces r on D: the recovery of its u_c
        u = chol.solve(asm1.L) + W_op.last_full
        f = asm1.L.copy()
        f[D] += r
        assert np.linalg.norm(u - factorize(asm1.A).solve(f)) <= 1e-10 * np.linalg.norm(u)
        u_rec = cond.recover(f, u[c])
        assert np.linalg.norm(u_rec - u) <= 1e-10 * np.linalg.norm(u)
    assert np.linalg.norm(W_op.dense() - W_D) <= 1e-10 * np.linalg.norm(W_D)
    assert W_op.n_products == 1 + D.size
    # the extension ṽ = A⁻¹B_Dᵀz of v_D = W_D z is condense(A, D).extend(v_D)
    z = np.random.default_rng(6).standard_normal(D.size)
    v_D = W_op @ z
    with condense(asm1.A, D) as cond_D:
        ext = cond_D.extend(v_D)
    assert np.linalg.norm(W_op.last_full - ext) <= 1e-10 * np.linalg.norm(ext)
    chol.close()


