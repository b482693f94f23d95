"""Each rank's owned rows of the PETSc path's system of two bodies and more (fem/distributed.py
DistributedBodies), formed without PETSc: D[R] + Δ[R] with D = diag(A(α), K_f) and Δ the part of
Tᵀ D T − D near the contact DOFs, against the pyamg backend's Tᵀ D T (paths/coupled.py
FullSpaceCouple.system), on 1, 2 and 3 ranks (one object per rank, in this process): the values to
round-off, the pattern the structural product of T's and D's patterns (every design fills the same
one, a value that is an exact zero keeps its entry) with the contact nodes' blocks and the clamped
DOFs' diagonals; and the memory a design's rows take to form (tracemalloc), a small multiple of
the rows' own bytes.
"""

import tomllib
import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.config import load_config
from contactopt.fem.distributed import DistributedBodies
from contactopt.problem import ShapeProblem
from test_foundation_fullspace import FOUNDATIONS, _config


def _two_slabs():
    from test_assembly_pairs import DESIGN, TWO_SLABS
    return load_config(tomllib.loads(TWO_SLABS + DESIGN)).with_updates({"linear_solver": {"path": "fullspace"}})


MODELS = {"foundation, mortar partners": lambda: _config(FOUNDATIONS["mortar partners"], "fullspace"),
          "two slabs (two pairs)": _two_slabs}
_problems = {}


def problem(name):
    if name not in _problems:
        _problems[name] = ShapeProblem(MODELS[name]())
    return _problems[name]


def designs(pb):
    a0 = pb.model.initial_design()
    return a0, a0 + 0.003 * np.random.default_rng(1).standard_normal(a0.size)


def ranks(pb, size):
    couple = pb.path.couple
    return [DistributedBodies(pb.model, couple.T, list(couple.parts), size, r) for r in range(size)]


def coordinates(pb, alpha):
    m = pb.model
    return m.mesh.coordinates(m.surface.as_vector(alpha))


def gathered(dists, coords):
    """The owned rows of every rank as one matrix (PETSc numbering), and each rank's (indptr, cols)."""
    n = dists[0].n
    rows, cols, vals, patterns = [], [], [], []
    for d in dists:
        indptr, c, v = d.owned_stiffness(coords)
        rows.append(d.rstart + np.repeat(np.arange(indptr.size - 1), np.diff(indptr)))
        cols.append(c)
        vals.append(v)
        patterns.append((np.array(indptr), np.array(c)))
    M = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return M, patterns


def ones(M):
    M = sp.csr_matrix(M, copy=True)
    M.data[:] = 1.0
    return M


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("size", [1, 2, 3])
def test_the_owned_rows_are_the_rows_of_the_pyamg_backends_system(name, size):
    pb = problem(name)
    path, couple = pb.path, pb.path.couple
    assert not len(pb.model.pinned_dofs)
    dists = ranks(pb, size)
    d0 = dists[0]
    free = d0.dof_of_free
    patterns = []
    for alpha in designs(pb):
        law_A = path.prepare(path.assemble(alpha)).law_A
        M, pattern = gathered(dists, coordinates(pb, alpha))
        patterns.append(pattern)
        got = M[free][:, free]
        err = abs(got - law_A).max() / abs(law_A).max()
        assert err <= 1e-14, f"{name} on {size} ranks: {err:.2e}"
        clamped = np.flatnonzero(d0.fixed)            # a clamped DOF keeps its diagonal alone
        assert np.array_equal(np.diff(M.indptr)[clamped], np.ones(clamped.size))
        assert np.all(M.diagonal()[clamped] > 0)
    # every design fills the pattern of the first: the structure of Tᵀ D T (no value can cancel an
    # entry), each contact node's 3×3 block and the clamped diagonals
    assert all(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) for a, b in zip(*patterns))
    D = sp.block_diag([ones(path.prepare(path.assemble(designs(pb)[0])).assembled.A)]
                      + [ones(part.K) for part in couple.parts], format="csr")
    S = (ones(couple.T).T @ D @ ones(couple.T)).tocoo()
    cd = d0.contact
    want = np.unique(np.concatenate([free[S.row] * np.int64(d0.n) + free[S.col],
                                     np.repeat(cd, 3, axis=1).ravel() * np.int64(d0.n) + np.tile(cd, (1, 3)).ravel(),
                                     clamped * np.int64(d0.n) + clamped]))
    have = np.concatenate([(d.rstart + np.repeat(np.arange(ip.size - 1), np.diff(ip))) * np.int64(d.n) + c
                           for d, (ip, c) in zip(dists, patterns[0])])
    assert np.array_equal(np.sort(have), want)


@pytest.mark.parametrize("size", [1, 2])
def test_a_designs_owned_rows_take_little_more_memory_than_themselves(size):
    """Formed as D[R] + Δ[R] (the body's local stiffness, the counterparts' rows and the few rows
    near the contact): at a new design, at most 3 times the bytes of the owned rows (values and
    column indices) allocated at once, the body's local stiffness included — the products of the
    whole change of unknowns T[need, R]ᵀ D[need] T took 4.6 and 4.9 times (measured: 2.2 and 2.5)."""
    pb = problem("two slabs (two pairs)")
    a0, a1 = designs(pb)
    d = ranks(pb, size)[0]
    d.owned_stiffness(coordinates(pb, a0))           # the pattern, formed once
    coords = coordinates(pb, a1)
    tracemalloc.start()
    try:
        _, cols, _ = d.owned_stiffness(coords)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= 3 * 12 * cols.size, f"{peak / (12 * cols.size):.2f} times the owned rows' bytes"
