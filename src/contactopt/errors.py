"""Exceptions of contactopt: one base class, specific subclasses; and :class:`Interrupted`, the
KeyboardInterrupt of a process asked to stop."""

from __future__ import annotations

import signal


class ContactOptError(Exception):
    """Base class of every error raised by contactopt."""


class ConfigError(ContactOptError):
    """An invalid configuration; ``problems`` lists every problem found at once."""

    def __init__(self, problems):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = list(problems)
        text = "invalid configuration:\n" + "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(text)


class InfeasibleDesignError(ContactOptError):
    """A design vector violates a constraint of the admissible set U."""


class MeshError(ContactOptError):
    """The mapped mesh is invalid (for instance inverted elements where the surface reaches c)."""


class SolverError(ContactOptError):
    """A linear or nonlinear solver failed."""


class ContactNotConverged(SolverError):
    """The contact solver did not reach its tolerance.

    ``history`` holds the residual after each iteration, ``iterations`` their count.
    """

    def __init__(self, message, history=(), iterations=None):
        self.history = list(history)
        self.iterations = len(self.history) if iterations is None else iterations
        super().__init__(message)


class CheckpointError(ContactOptError):
    """A checkpoint file is missing, corrupt or belongs to another run."""


class OptimizerError(ContactOptError):
    """The optimizer cannot proceed: empty feasible set, failed QP subproblem, bad oracle value."""


class ProblemDataError(ContactOptError, ValueError):
    """Invalid data of a contact problem: wrong shapes, non-finite entries, negative friction."""


class FclibError(ContactOptError):
    """A file that cannot be read as, or written to, an FCLIB local problem."""


class Interrupted(KeyboardInterrupt):
    """The process was asked to stop (SIGINT, SIGTERM): the evaluation in progress is abandoned.

    ``signum`` is the signal; a run's summary.json then says ``"status": "interrupted"``, and
    ``message``/``resume`` say where the run stands and the command that continues it."""

    def __init__(self, signum=signal.SIGINT, message: str = "", resume: str | None = None):
        self.signum = int(signum)
        self.message = message
        self.resume = resume
        super().__init__(message)
