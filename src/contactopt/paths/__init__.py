"""Solver paths: how a design's contact states and adjoints are solved (docs/architecture.md).

Every path implements :class:`~contactopt.paths.base.SolverPath`; :func:`select_path` decides
once, from ``[linear_solver]`` and the size of the body, which one a configuration runs on.

======================  ===============================================  =====================
``path``                a design costs                                   for
======================  ===============================================  =====================
``"condensation"``      a sparse factorization of A(α) onto the contact  small and medium meshes
                        DOFs, dense S and the zone's W_Z
``"delassus"``          a sparse Cholesky of A(α), products W r by        large meshes with MKL
                        solves, W_Z on the zone only
``"fullspace"``         semismooth Newton on all DOFs, AMG-preconditioned meshes no factorization
                        GMRES, nothing factorized                        fits
``"petsc"``             the full-space method on PETSc (GAMG, GMRES),    one optimization on
                        the mesh split over MPI ranks                    many cores / machines
======================  ===============================================  =====================

The PETSc path imports petsc4py and mpi4py only when it runs: ``pip install .`` does not need them.
"""

from __future__ import annotations

import logging

from ..errors import ConfigError
from .base import Context, Settings, SolverPath
from .condensation import CondensationPath
from .delassus import DelassusPath
from .fullspace import FullSpacePath
from .petsc import PetscPath

log = logging.getLogger(__name__)


PATHS = {cls.name: cls for cls in (CondensationPath, DelassusPath, FullSpacePath, PetscPath)}
NAMES = tuple(PATHS)

__all__ = ["PATHS", "NAMES", "SolverPath", "Settings", "Context", "select_path", "make_path", "library_for"]


def library_for(name: str, library: str) -> str:
    """The sparse direct solver of a path: ``library`` unless "auto" (then MKL PARDISO where the
    mkl wheel is installed, else SciPy); "pyamg" on the full-space path."""
    if name == "fullspace":
        return "pyamg"
    if name == "petsc":
        return "petsc"
    if library != "auto":
        return library
    from ..fem.linsolve import pardiso_available
    return "pardiso" if pardiso_available() else "scipy"


def select_path(config, n_free: int, pinned: int = 0) -> tuple[str, str]:
    """(path, library) of a configuration for a body of ``n_free`` free DOFs.

    ``path = "auto"``: the full-space path from ``crossover`` free DOFs on (the measured crossover,
    docs/large_meshes.md), the condensation below — the Delassus path instead of the full-space one
    where pyamg is missing. The compliance objective needs the condensed load ℓ on every contact
    DOF, so it stays on the condensation under "auto" and is refused on the other paths; so does
    an elastic ``[foundation]`` (:mod:`.condensation`).

    Under ``mpiexec`` with more than one rank only the PETSc path shares one optimization among
    the ranks: "auto" takes it, and another path is refused (every rank would run the whole
    optimization); so is "petsc" without petsc4py.

    ``pinned``: the number of clamped tangential components of contact nodes (a symmetry plane
    through the contact face, :mod:`contactopt.mesh.body`). Every path takes them; an elastic
    ``[foundation]`` refuses them. A rigid ``[obstacle]`` other than the plane runs on the
    condensation path, which "auto" takes; the other paths refuse it."""
    from .._mpi import petsc_missing, world_size
    from ..sensitivity.objectives import FULL_SPACE, objective_types
    ls, foundation = config.linear_solver, config.foundation is not None
    types = objective_types(config)
    name, objective = ls.path, "compliance" if "compliance" in types else config.objective.type
    full = sorted(types & FULL_SPACE)
    if full and (foundation or name == "petsc" or ranks_of() > 1):
        where = "an elastic [foundation]" if foundation else "the 'petsc' path"
        raise ConfigError([f"objective: {', '.join(full)} needs ∂J/∂u on every DOF, which the adjoint on "
                           f"{where} does not take; use path 'condensation', 'delassus' or 'fullspace' "
                           "without a foundation"])
    ranks = world_size()
    if pinned and foundation:
        raise ConfigError([f"body.clamped: {pinned} tangential component(s) of contact nodes are clamped (a "
                           "symmetry plane through the contact face), which an elastic [foundation] does not "
                           "take (its compliance would add to the clamped direction); the rigid foundation does"])
    obst = config.obstacle
    obstacle = "plane" if obst is None else obst.shape
    if obst is not None and obst.control == "force":
        obstacle = f"force-controlled {obstacle}"
    elif obst is not None and obst.moves_tangentially:
        obstacle = f"{obstacle} moved tangentially"
    if obstacle != "plane":
        # the contact frames rotate the condensed system (paths/condensation.py)
        if name not in ("auto", "condensation") or ranks > 1:
            raise ConfigError([f"linear_solver.path = '{name}'" + (f" on {ranks} MPI ranks" if ranks > 1 else "")
                               + f": a {obstacle} [obstacle] is solved on the 'condensation' path only (one "
                               "process); use path 'condensation' or 'auto'"])
        log.info("linear solver: condensation path (%s obstacle)", obstacle)
        return "condensation", library_for("condensation", ls.library)
    if ranks > 1 and name not in ("auto", "petsc"):
        raise ConfigError([f"linear_solver.path = '{name}' runs on one process, and this run has {ranks} MPI "
                           "ranks: use path 'petsc' (or 'auto'), or run without mpiexec"])
    if name == "petsc" or (name == "auto" and ranks > 1):
        problems = []
        if foundation:
            problems.append("linear_solver.path = 'petsc': an elastic [foundation] is solved on the "
                            "'condensation' path only (one process)")
        if objective == "compliance":
            problems.append("linear_solver.path = 'petsc': the compliance objective needs the condensed "
                            "load on every contact DOF; use path 'condensation' on one process")
        missing = petsc_missing()
        if missing:
            problems.append(f"linear_solver.path = '{name}'"
                            + (f" under mpiexec with {ranks} ranks" if name == "auto" else "")
                            + f" needs petsc4py and mpi4py: {missing}")
        if problems:
            raise ConfigError(problems)
        log.info("linear solver: petsc path on %d rank(s)", ranks)
        return "petsc", "petsc"
    if foundation:
        # the foundation's compliance C enters the condensed Delassus operator W = S⁻¹ + C
        if name not in ("auto", "condensation"):
            raise ConfigError([f"linear_solver.path = '{name}': an elastic [foundation] is solved on the "
                               "'condensation' path only; use path 'condensation' or 'auto'"])
        log.info("linear solver: condensation path (elastic foundation)")
        return "condensation", library_for("condensation", ls.library)
    if name == "auto":
        name = "condensation"
        if n_free >= ls.crossover and objective != "compliance":
            from ..fem.linsolve import pardiso_available
            if _have_pyamg():
                name = "fullspace"
            elif pardiso_available():
                name = "delassus"
        log.info("linear solver: %s path for %d DOFs (crossover %d)", name, n_free, ls.crossover)
    elif name != "condensation" and objective == "compliance":
        raise ConfigError([f"linear_solver.path = '{name}': the compliance objective needs the condensed "
                           "load on every contact DOF; use path 'condensation' or 'auto'"])
    return name, library_for(name, ls.library)


def make_path(config, model, name: str, library: str) -> SolverPath:
    """The path ``name`` for a model, with the configuration's [state] settings."""
    return PATHS[name](model, Settings.from_config(config.state, config.friction, library))


def ranks_of() -> int:
    from .._mpi import world_size
    return world_size()


def _have_pyamg() -> bool:
    try:
        import pyamg  # noqa: F401
    except ImportError:
        return False
    return True
