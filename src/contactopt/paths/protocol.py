"""How rank 0's PETSc path has the other MPI ranks make its calls: a small explicit protocol.

Rank 0 sends three kinds of message: :class:`Problem` (build the problem of a configuration: its
PETSc path is the one later calls name), :class:`Call` (make one of the :class:`Command` calls
with the path of a problem) and :class:`Stop`. A :class:`Follower` (held by
:func:`contactopt.ranks.serve`) keeps the paths it built and dispatches the calls; the paths
themselves say which method answers which command (``PetscPath.handlers``). Messages travel as a
flag by a non-blocking broadcast, which the waiting ranks poll without spinning a core, then the
pickled message.
"""

from __future__ import annotations

import enum
import time
import uuid
from dataclasses import dataclass, field

import numpy as np


class Command(enum.Enum):
    """The calls of a PETSc path that every rank makes together."""

    PREPARE = "prepare"            # a design's A(α) and its first load case
    FOR_LOAD = "for_load"          # another load case of the design
    SOLVE = "solve"                # a state (semismooth Newton; a load step's slip reference with it)
    ADJOINT = "adjoint"            # the adjoint (4.15)
    CONTRACTION = "contraction"    # the design terms vᵀ(∂A/∂α)u, reduced to rank 0
    PRODUCT = "product"            # A(α) x for an objective of the whole displacement, on every rank
    IMPORT = "import"              # a checkpoint's context


@dataclass(frozen=True)
class Problem:
    """Build the problem of ``config``; its path answers to ``path_id``."""

    path_id: str
    config: object


@dataclass(frozen=True)
class Call:
    """Make ``command`` with ``args`` on the path ``path_id``."""

    path_id: str
    command: Command
    args: tuple


@dataclass(frozen=True)
class Stop:
    """The serving ranks return."""


def new_path_id() -> str:
    """A fresh id for a path of rank 0 (unique without a counter kept between calls)."""
    return uuid.uuid4().hex


def _world():
    from mpi4py import MPI
    return MPI.COMM_WORLD


def send(msg) -> None:
    """Rank 0: a message to every serving rank."""
    comm = _world()
    flag = np.ones(1, dtype=np.int64)
    comm.Ibcast(flag, root=0).Wait()
    comm.bcast(msg, root=0)


def receive():
    """A rank > 0: the next message of rank 0 (waiting without spinning a core)."""
    comm = _world()
    flag = np.zeros(1, dtype=np.int64)
    req = comm.Ibcast(flag, root=0)
    while not req.Test():
        time.sleep(0.002)
    return comm.bcast(None, root=0)


def stop_serving() -> None:
    """Rank 0: the serving ranks return from :func:`contactopt.ranks.serve`."""
    comm = _world()
    if comm.Get_size() > 1 and comm.Get_rank() == 0:
        send(Stop())


@dataclass
class Follower:
    """A rank > 0: the paths of the problems rank 0 built, by id, and the dispatch of its calls."""

    paths: dict = field(default_factory=dict)

    def add(self, path_id: str, path) -> None:
        self.paths[path_id] = path

    def make(self, call: Call):
        """Make rank 0's call with the path it names."""
        path = self.paths[call.path_id]
        return path.handlers[call.command](path, *call.args)
