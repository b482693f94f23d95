"""One optimization on many MPI ranks: rank 0 runs the program, the others serve its PETSc path.

``mpiexec -n N contactopt run CONFIG`` (or any program wrapped in :func:`run_on_ranks`): rank 0
does everything a single process does — the bundle method, the objective, the run directory, the
log and the progress lines — and every other rank waits in :func:`serve` for the calls of rank 0's
PETSc path (:mod:`contactopt.paths.petsc`) and makes them with it, on its own part of the mesh.
Without mpiexec, :func:`run_on_ranks` is a plain call.
"""

from __future__ import annotations

import logging

from ._mpi import petsc_missing, world_size
from .errors import ContactOptError
from .paths import protocol
from .problem import ShapeProblem

log = logging.getLogger(__name__)


def run_on_ranks(main, *args, **kw):
    """``main(*args, **kw)`` on rank 0 while the other ranks :func:`serve`; their result is 0."""
    if world_size() <= 1:
        return main(*args, **kw)
    # PETSc's initialization is collective: every rank makes it here, before rank 0 goes its own way
    if petsc_missing():
        return main(*args, **kw)      # every rank meets the configuration error of the missing PETSc
    from mpi4py import MPI

    if MPI.COMM_WORLD.Get_rank() == 0:
        try:
            out = main(*args, **kw)
        except (SystemExit, ContactOptError):
            protocol.stop_serving()
            raise
        except BaseException:
            # an error of rank 0 alone: the others may be inside a collective call and never
            # read "stop" — end them all, after the traceback
            import traceback
            traceback.print_exc()
            MPI.COMM_WORLD.Abort(1)
        protocol.stop_serving()
        return out
    quiet = logging.getLogger("contactopt")      # the log and the progress are rank 0's
    quiet.handlers[:] = [logging.NullHandler()]
    quiet.propagate = False
    serve()
    return 0


def serve() -> None:
    """A rank > 0: build the problems rank 0 builds and make its PETSc paths' calls with it, until
    rank 0 sends "stop". An error that rank 0 meets as well (a solver error, a bad input) is
    logged and the rank waits for the next call; any other error aborts all ranks (rank 0 would
    wait for this one forever)."""
    from mpi4py import MPI

    follower = protocol.Follower()
    while True:
        msg = protocol.receive()
        try:
            if isinstance(msg, protocol.Stop):
                return
            if isinstance(msg, protocol.Problem):
                # rank 0 checks the memory; a check here could fail where rank 0's passed, and rank 0
                # would wait for this rank in PETSc's collective calls
                config = msg.config.with_updates({"linear_solver": {"memory_check": False}})
                follower.add(msg.path_id, ShapeProblem(config).path)
            else:
                follower.make(msg)
        except ContactOptError as exc:
            log.debug("rank %d: %s", MPI.COMM_WORLD.Get_rank(), exc)
        except BaseException:
            log.exception("rank %d failed; aborting all ranks", MPI.COMM_WORLD.Get_rank())
            MPI.COMM_WORLD.Abort(1)
