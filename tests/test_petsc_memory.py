"""What a rank of the PETSc path holds: the Newton systems of an evaluation leave nothing behind.

PetscHierarchy.coarse forms each Newton system's coarse operators from Galerkin products of a few
rows (P_0ᵀ Y P_0, then level by level); a PETSc product keeps references to its factors, so those
products are freed only when destroyed. Left to Python they stayed, one set per Newton system (0.07 GB
each on every one of 2 ranks at 200k DOFs, docs/scaling.md): each product held a reference to its
prolongation, whose reference count is what the test reads. Skipped without petsc4py/mpi4py."""

import pytest

from contactopt._mpi import petsc_missing
from contactopt.config import load_config
from test_petsc import random_newton_piece

MISSING = petsc_missing()
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"PETSc path: {MISSING}")


def test_the_coarse_operators_of_a_newton_system_keep_no_products():
    from petsc4py import PETSc

    from contactopt.problem import ShapeProblem

    cfg = load_config("example1").with_updates({"mesh": {"nx": 24, "ny": 12, "nz": 8},
                                                "linear_solver": {"path": "petsc"}})
    options = PETSc.Options()
    options.setValue("pc_gamg_coarse_eq_limit", "200")        # three coarse levels on this mesh
    try:
        problem = ShapeProblem(cfg)
        problem.subgradient(problem.model.initial_design())
    finally:
        options.delValue("pc_gamg_coarse_eq_limit")
    nw, hier = problem.path.newton, problem.path._hier
    assert len(hier._P) >= 2, [M.getSize() for M in hier._levels]
    held = [P.getRefCount() for P in hier._P]
    cd = nw.cd
    D, slide, blk = random_newton_piece(nw, 5)
    for _ in range(3):
        hier.coarse(D, (cd[slide, :2], blk))
    assert [P.getRefCount() for P in hier._P] == held
    # and a second evaluation's Newton systems add none either
    problem.subgradient(problem.model.initial_design() + 1e-4)
    assert [P.getRefCount() for P in hier._P] == held
