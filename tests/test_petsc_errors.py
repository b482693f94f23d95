"""Bad input for the PETSc path, checked without PETSc (these run in the default test suite): a
clear error, exit 2, nothing written — for path "petsc" without petsc4py, for another path under
mpiexec with more than one rank, and for more ranks than the mesh can be split over."""

import contextlib
import io

import numpy as np
import pytest
import tomli_w

import contactopt._mpi as mpi
from contactopt.cli import main
from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.fem.distributed import DistributedBody, rcb_partition
from contactopt.fem.model import ElasticModel

SMALL = {"mesh": {"nx": 4, "ny": 2, "nz": 2}}


def write_config(directory, path):
    cfg = load_config("example1").with_updates({"name": "p", **SMALL, "linear_solver": {"path": path}})
    file = directory / "p.toml"
    file.write_text(tomli_w.dumps(cfg.data))
    return file


def run(*args):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = main([str(a) for a in args])
    return code, out.getvalue()


def test_petsc_asked_for_without_petsc4py(tmp_path, monkeypatch):
    monkeypatch.setattr(mpi, "petsc_missing", lambda: "No module named 'petsc4py'")
    code, out = run("run", write_config(tmp_path, "petsc"), "--out", tmp_path / "out")
    assert code == 2, out
    assert "needs petsc4py and mpi4py" in out and "Traceback" not in out
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("path", ["auto", "fullspace"])
def test_under_mpiexec_only_the_petsc_path_runs(tmp_path, monkeypatch, path):
    """Two ranks (as mpiexec tells them) without petsc4py: "auto" cannot share the run, and a
    one-process path would run the whole optimization on every rank."""
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    monkeypatch.setattr(mpi, "petsc_missing", lambda: "No module named 'petsc4py'")
    code, out = run("run", write_config(tmp_path, path), "--out", tmp_path / "out")
    assert code == 2, out
    assert ("under mpiexec with 2 ranks" if path == "auto" else "runs on one process") in out
    assert not (tmp_path / "out").exists()


def test_more_ranks_than_elements():
    model = ElasticModel(load_config("example1").with_updates(SMALL))
    n = len(model.body.reference.cells)
    with pytest.raises(ConfigError, match="fewer than the ranks"):
        DistributedBody(model, n + 1, 0)
    parts = [DistributedBody(model, 3, r) for r in range(3)]
    # the ranks own every node once, in contiguous ranges, and every element once
    assert [p.node_range for p in parts] == [(0, parts[0].node_range[1]), (parts[0].node_range[1],
                                             parts[1].node_range[1]), (parts[1].node_range[1], model.assembler.n_nodes)]
    assert sum(p.n_elements for p in parts) == n


def test_coordinate_bisection_balances_the_parts():
    rng = np.random.default_rng(3)
    pts = rng.uniform(size=(1000, 3)) * [4.0, 1.0, 0.5]
    for n in (2, 3, 5, 8):
        counts = np.bincount(rcb_partition(pts, n), minlength=n)
        assert counts.max() - counts.min() <= 3, (n, counts)
        assert counts.sum() == 1000
