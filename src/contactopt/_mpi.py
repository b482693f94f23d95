"""MPI without importing it: the number of ranks this process was started with, and whether
petsc4py is importable (the PETSc path is optional; ``pip install .`` does not need it)."""

from __future__ import annotations

import os

# what mpiexec of OpenMPI, MPICH/Hydra, Intel MPI and Slurm put into each rank's environment
_SIZE_VARS = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS", "SLURM_NTASKS")
_RANK_VARS = ("OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK", "SLURM_PROCID")


def world_size() -> int:
    """The number of MPI ranks of this run (1 when not started by mpiexec)."""
    for var in _SIZE_VARS[:3]:
        if os.environ.get(var, "").isdigit():
            return int(os.environ[var])
    return 1


def world_rank() -> int:
    """This process's MPI rank (0 when not started by mpiexec)."""
    for var in _RANK_VARS[:3]:
        if os.environ.get(var, "").isdigit():
            return int(os.environ[var])
    return 0


def petsc_missing() -> str | None:
    """None when petsc4py and mpi4py import, else why not (for an error message)."""
    try:
        import mpi4py  # noqa: F401
        import petsc4py  # noqa: F401
        from petsc4py import PETSc  # noqa: F401
    except ImportError as exc:
        return (f"{exc}; install Debian's python3-petsc4py-real and python3-mpi4py, or PETSc and "
                "petsc4py from source (docs/install.md, 'PETSc and MPI')")
    return None
