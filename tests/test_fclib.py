"""FCLIB I/O and the three public FCLIB problems (rigid bodies: W singular)."""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.contact import LocalResult, solve_local
from contactopt.errors import ContactOptError, FclibError
from contactopt.io.fclib import FclibProblem, read_fclib, solve_fclib, write_fclib

DATA = Path(os.environ.get("CONTACTOPT_FCLIB_DIR", Path(__file__).parent / "data" / "fclib"))
FILES = {  # name: (contacts, distinct friction coefficients)
    "local_problem_test.hdf5": (48, [0.7]),
    "LMGC_100_PR_PerioBox-i00361-60-03000.hdf5": (60, [0.3, 0.5]),
    "Capsules-i125-1213.hdf5": (286, [0.7]),
}


def reference_error(W, q, mu, r):
    """Siconos error recomputed contact by contact (independent of contactopt.contact.cones)."""
    u = W @ r + q
    total = 0.0
    for i, m in enumerate(mu):
        ri, ui = r[3 * i:3 * i + 3], u[3 * i:3 * i + 3]
        z = ri - (ui + np.array([m * np.hypot(ui[1], ui[2]), 0.0, 0.0]))
        zn, zt = z[0], np.hypot(z[1], z[2])
        if zt <= m * zn:
            proj = z
        elif m * zt <= -zn:
            proj = np.zeros(3)
        else:
            a = (zn + m * zt) / (1 + m * m)
            proj = np.array([a, *(m * a * z[1:] / zt)])
        total += float(np.sum((ri - proj) ** 2))
    return np.sqrt(total) / max(np.linalg.norm(q), np.linalg.norm(r), np.linalg.norm(u))


@pytest.mark.parametrize("name", list(FILES))
def test_read_public_problems(name):
    prob = read_fclib(DATA / name)
    p, mus = FILES[name]
    assert prob.n_contacts == p and prob.W.shape == (3 * p, 3 * p) and prob.q.shape == (3 * p,)
    assert prob.spacedim == 3 and sorted(np.unique(prob.mu).tolist()) == mus
    with h5py.File(DATA / name, "r") as f:
        assert prob.W.nnz == int(f["fclib_local/W/nzmax"][0])
        assert prob.info.get("title") == f["fclib_local/info/title"][()].decode()
    # rigid-body Delassus operators: positive diagonal, singular
    assert np.all(prob.W.diagonal() > 0)
    assert np.linalg.matrix_rank(prob.W.toarray()) < 3 * p


@pytest.mark.parametrize("name", list(FILES))
def test_public_problems_reach_1e_8_with_newton(name):
    prob = read_fclib(DATA / name)
    res = solve_fclib(DATA / name, "newton", tol=1e-8)
    assert isinstance(res, LocalResult) and res.method == "newton"
    assert res.converged and res.error <= 1e-8, res.message
    assert reference_error(prob.W, prob.q, prob.mu, res.r) <= 1e-8
    assert len(res.history) == res.iterations and np.all(np.isfinite(res.r))


@pytest.mark.parametrize("name", list(FILES))
def test_public_problems_with_fixed_point(name):
    prob = read_fclib(DATA / name)
    res = solve_local(prob.W, prob.q, prob.mu, method="fixed-point", tol=1e-8)
    assert res.converged and reference_error(prob.W, prob.q, prob.mu, res.r) <= 1e-8


def _problem(fmt="csr"):
    rng = np.random.default_rng(0)
    A = sp.random(12, 12, density=0.4, random_state=1) + sp.eye(12)
    W = (A @ A.T).asformat(fmt)
    return FclibProblem(
        W=W, q=rng.standard_normal(12), mu=np.array([0.1, 0.2, 0.3, 0.4]),
        info={"title": "round trip", "description": "four contacts", "math_info": "SPD",
              "numberOfDegreeOfFreedom": 7},
        matrix_info={"conditioning": 12.5, "rank": 12, "comment": "random"},
        guesses=[{"r": rng.standard_normal(12), "u": rng.standard_normal(12)}],
        solution={"r": np.zeros(12), "u": np.ones(12)})


@pytest.mark.parametrize("fmt,nz", [("csr", -2), ("csc", -1), ("coo", None)])
def test_round_trip(tmp_path, fmt, nz):
    prob = _problem(fmt)
    path = tmp_path / f"p_{fmt}.hdf5"
    write_fclib(path, prob)
    with h5py.File(path, "r") as f:
        stored_nz = int(f["fclib_local/W/nz"][0])
        assert stored_nz == (nz if nz is not None else prob.W.nnz)
    back = read_fclib(path)
    np.testing.assert_array_equal(back.W.toarray(), prob.W.toarray())
    np.testing.assert_array_equal(back.q, prob.q)
    np.testing.assert_array_equal(back.mu, prob.mu)
    assert back.spacedim == 3 and back.info == prob.info
    assert back.matrix_info == prob.matrix_info
    np.testing.assert_array_equal(back.guesses[0]["r"], prob.guesses[0]["r"])
    np.testing.assert_array_equal(back.solution["u"], prob.solution["u"])
    # and write the re-read problem again: identical content
    write_fclib(tmp_path / "again.hdf5", back)
    again = read_fclib(tmp_path / "again.hdf5")
    np.testing.assert_array_equal(again.W.toarray(), prob.W.toarray())


def test_round_trip_public_file(tmp_path):
    prob = read_fclib(DATA / "local_problem_test.hdf5")
    write_fclib(tmp_path / "copy.hdf5", prob)
    back = read_fclib(tmp_path / "copy.hdf5")
    assert (back.W != prob.W).nnz == 0
    np.testing.assert_array_equal(back.q, prob.q)
    assert back.info["description"] == prob.info["description"]
    assert len(back.guesses) == len(prob.guesses) == 1


def test_clear_errors(tmp_path):
    with pytest.raises(FclibError, match="not found"):
        read_fclib(tmp_path / "missing.hdf5")
    text = tmp_path / "text.hdf5"
    text.write_text("not hdf5")
    with pytest.raises(FclibError, match="not an HDF5 file"):
        read_fclib(text)
    other = tmp_path / "other.hdf5"
    with h5py.File(other, "w") as f:
        f.create_group("something")
    with pytest.raises(FclibError, match="fclib_local"):
        read_fclib(other)
    # wrong shapes: q of the wrong length, W pointers of the wrong length
    good = tmp_path / "good.hdf5"
    write_fclib(good, _problem())
    with pytest.raises(FclibError, match="exists"):
        write_fclib(good, _problem())
    bad_q = tmp_path / "bad_q.hdf5"
    write_fclib(bad_q, _problem())
    with h5py.File(bad_q, "a") as f:
        del f["fclib_local/vectors/q"]
        f["fclib_local/vectors/q"] = np.zeros(7)
    with pytest.raises(FclibError, match="q has length 7"):
        read_fclib(bad_q)
    bad_p = tmp_path / "bad_p.hdf5"
    write_fclib(bad_p, _problem())
    with h5py.File(bad_p, "a") as f:
        del f["fclib_local/W/p"]
        f["fclib_local/W/p"] = np.arange(5, dtype=np.int32)
    with pytest.raises(FclibError, match="pointers"):
        read_fclib(bad_p)
    assert issubclass(FclibError, ContactOptError)
