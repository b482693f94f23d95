"""Large meshes (issue #16): the up-front memory estimate and the refusal of a mesh that would
not fit. Fast: only the design-independent model of Example 1 is built."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from contactopt import cli
from contactopt.config import load_config
from contactopt.errors import ContactOptError
from contactopt.fem import memory
from contactopt.fem.model import ElasticModel
from contactopt.problem import ShapeProblem

GB = memory.GB


@pytest.fixture(scope="module")
def model():
    return ElasticModel(load_config("example1"))


def test_matrix_entries_counted_from_the_mesh(model):
    """nnz(A) from the cells alone, against the assembled A(α0) (clamped DOFs scaled out)."""
    est = memory.estimate_evaluation(model)
    nnz = model.assemble(model.initial_design()).A.nnz
    assert est.nnz_A == nnz
    assert est.n_dofs == model.assembler.n_free == 15360
    assert est.n_contact_dofs == 3 * 512


def test_estimate_grows_like_the_factor_and_the_dense_block():
    small = memory.estimate_counts(15360, 1536, 4320, 1_064_000)
    big = memory.estimate_counts(113088, 5952, 34560, 8_558_550)
    # fill ∝ n^0.372: the factor grows faster than A, the dense part like (3p)²
    assert big.parts["factor"] / small.parts["factor"] == pytest.approx(
        8_558_550 / 1_064_000 * (113088 / 15360) ** memory.FILL_EXPONENT, rel=1e-3)
    assert big.parts["dense"] / small.parts["dense"] == pytest.approx((5952 / 1536) ** 2)
    # calibrated against the measured peak RSS of an evaluation (benchmarks/bench_scale.py)
    assert 0.3 < small.total_gb < 0.7      # measured 0.42 GB
    assert 2.6 < big.total_gb < 4.2        # measured 3.29 GB


def test_mesh_too_large_is_refused_up_front(monkeypatch):
    monkeypatch.setattr(memory, "available_memory", lambda: 0.2 * GB)
    with pytest.raises(memory.InsufficientMemoryError) as err:
        ShapeProblem("example1")
    exc = err.value
    assert isinstance(exc, ContactOptError)
    assert exc.available_gb == pytest.approx(0.2)
    assert exc.estimate.total > 0.2 * GB
    text = str(exc)
    assert "15360 DOFs" in text and "0.2 GB are available" in text and "memory_check = false" in text


def test_memory_check_can_be_switched_off(monkeypatch):
    monkeypatch.setattr(memory, "available_memory", lambda: 0.2 * GB)
    cfg = load_config("example1").with_updates({"linear_solver": {"memory_check": False}})
    pr = ShapeProblem(cfg)
    assert pr.model.n_contact == 512


def test_enough_memory_passes(monkeypatch):
    monkeypatch.setattr(memory, "available_memory", lambda: 64 * GB)
    est = memory.check_memory(ElasticModel(load_config("example1")))
    assert np.isfinite(est.total)


def test_cli_exit_2_and_nothing_written(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(memory, "available_memory", lambda: 0.2 * GB)
    out = tmp_path / "st"
    code = cli.main(["state", "example1", "--out", str(out)])
    assert code == 2
    assert "too large for the memory available" in capsys.readouterr().err
    assert not (out / "state.json").exists()


# ------------------------------------------------------------------ Krylov core (fem.iterative)

from contactopt.errors import SolverError  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import _iterative as iterative  # noqa: E402  (Krylov candidates kept with the benchmarks)
from contactopt.fem.linsolve import factorize  # noqa: E402


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
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from _brick import _CORNERS, hex_stiffness
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


def test_refused_before_the_model_is_built(monkeypatch):
    """The check runs on the body (mesh, clamps, contact nodes) before the assembler and the
    harmonic weight, the first costly steps on a large mesh."""
    import contactopt.fem.model as fem_model

    def boom(*a, **k):
        raise AssertionError("the model was built before the memory check")
    monkeypatch.setattr(fem_model, "harmonic_weight", boom)
    monkeypatch.setattr(memory, "available_memory", lambda: 0.2 * GB)
    with pytest.raises(memory.InsufficientMemoryError):
        ElasticModel(load_config("example1"))
