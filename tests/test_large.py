"""Large meshes (issue #16): the up-front memory estimate and the refusal of a mesh that would
not fit. Fast: only the design-independent model of Example 1 is built."""

from __future__ import annotations

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
