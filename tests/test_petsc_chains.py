"""Pairs whose faces lie on several bodies (a chain, contactopt.fem.faces) on the PETSc path: the
rows of a face on a counterpart body are that body's DOFs in the Newton system of all bodies
(contactopt.paths.coupled), spread over the ranks with the body (fem/distributed.py
DistributedBodies: Δ's rows of such a face come from its body's stiffness, a clamped component of
its node is that node's clamped PETSc DOF with a unit diagonal). Against the pyamg full-space path
on one rank and under ``mpiexec -n 2`` (Θ, ξ, λ, τ, u and v_λ at two designs, within 1e-9
relative), and ξ against central differences on two ranks.

Conventions: per contact node (t1, t2, ν) in the node's frame, ν from the counterpart to the face,
r the contact force on the face's body, λ = r_ν ≥ 0, τ = −r_t. Skipped without petsc4py/mpi4py;
``.ci/run`` runs this file with them installed.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from contactopt._mpi import petsc_missing
from contactopt.config import load_config

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "mpi"))
from compare_paths import evaluations  # noqa: E402

from test_assembly_topology import DESIGN, _chain_text, _write  # noqa: E402
from test_petsc import compare_on_two_ranks  # noqa: E402
from test_petsc_bodies import TOL  # noqa: E402

MISSING = petsc_missing()
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"PETSc path: {MISSING}")

SLIDING = DESIGN + '[[loads.traction]]\non = "top.right"\nvalue = [0.001, 0.0, 0.0]\n'
CHAINS = {
    # held in x1 by friction alone, the face body too; rows of the face on upper slide
    "sliding chain": dict(friction=(0.3, 0.3, 0.15), sides=False, extra=SLIDING),
    # rollers on every side: the face on upper has clamped components at its edges (pinned rows)
    "chain on rollers": dict(friction=(0.3, 0.3, 0.3), extra=DESIGN),
}


def assert_agree(ref, got, what):
    """Every array within 1e-9 relative to its largest entry; τ relative to the largest λ of its
    design (on the rollers τ is zero at the flat face: the contact patch test)."""
    assert set(ref) == set(got)
    for key in sorted(ref):
        x, y = np.atleast_1d(ref[key]), np.atleast_1d(got[key])
        assert x.shape == y.shape, f"{what}: {key} has shape {y.shape}, expected {x.shape}"
        scale = np.abs(ref[key.replace("tau", "lam")] if key.startswith("tau") else x).max()
        err = float(np.abs(x - y).max()) / max(float(scale), 1e-300)
        assert err <= TOL, f"{what}: {key} differs from the full-space path by {err:.2e} (relative) > {TOL:g}"


def _config(tmp_path, name):
    text = _chain_text(tmp_path, **CHAINS[name]).replace("tol = 1.0e-14", "tol = 1.0e-12")
    return _write(tmp_path, text, "chain.toml")


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_a_chain_on_one_and_two_ranks_equals_the_full_space(name, tmp_path):
    file = _config(tmp_path, name)
    ref = evaluations(load_config(file), "fullspace")
    assert_agree(ref, evaluations(load_config(file), "petsc"), f"{name}, PETSc path on 1 rank")
    got = compare_on_two_ranks(tmp_path, file)
    assert int(got.pop("ranks")) == 2
    assert_agree(ref, got, f"{name}, PETSc path on 2 ranks")


def test_the_subgradient_of_a_sliding_chain_matches_central_differences_on_two_ranks(tmp_path):
    """Rows of the face on upper sliding, the face body held only by contact: ξ·d against central
    differences of Θ (step 1e-6 of α) on two ranks, to 1e-6."""
    got = compare_on_two_ranks(tmp_path, _config(tmp_path, "sliding chain"), "--differences")
    fd, xi, sliding = got["fd"], got["fd_xi"], int(got["fd_M1"])
    assert sliding > 0
    err = np.abs(fd - xi) / np.abs(fd).max()
    assert err.max() <= 1e-6, (fd, xi)
