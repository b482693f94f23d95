"""Work of a run's outputs done in a forked child process beside the parent's own.

A run's figures take most of the time after its last evaluation, and they only read arrays the
parent already holds. :class:`Forked` runs a list of such jobs (callables without arguments
that write their own files, atomically) in a child made by ``fork``, so that the child has every
array without copying, while the parent writes its other files; :meth:`Forked.join` waits for the
child and raises the child's exception in the parent (the exception itself where it can be
pickled, else a :class:`~contactopt.errors.ContactOptError` with its text). :meth:`Forked.cancel`
stops the child (an exception or a signal in the parent), and so does the parent's end, however
it ends: the child ends by an exception of its own, so that a file it was writing leaves no
temporary behind, and holds no inherited lock beyond its parent.

A child that stops making progress (no job finished for ``stall`` seconds: a lock inherited in
a held state would do it) is killed, its temporary files in ``directory`` are removed, and the
jobs it had not finished run in the parent, with a warning: the run's files are complete either way.

Forking is used only where it is safe and pays: on Linux, with more than one CPU available to
the process, no thread in it but the main one and the idle workers of the assembly's pool, and
no MPI loaded (a forked MPI process may hang). Elsewhere the jobs run in the parent, at
:meth:`Forked.join`: the files are the same either way.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import pickle
import select
import signal
import sys
import threading
import time
from pathlib import Path

from ..errors import ContactOptError

log = logging.getLogger(__name__)

__all__ = ["Forked", "can_fork"]


def can_fork() -> bool:
    """Whether :class:`Forked` runs its jobs in a child process here (module docstring)."""
    if not sys.platform.startswith("linux") or not hasattr(os, "fork"):
        return False
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cpus = os.cpu_count() or 1
    others = [t for t in threading.enumerate() if t is not threading.main_thread()]
    return cpus > 1 and all(t.name.startswith(IDLE_THREADS) for t in others) and "mpi4py.MPI" not in sys.modules


STALL_S = 600.0
"""Seconds without a finished job after which the parent takes the child's jobs over."""

IDLE_THREADS = ("contactopt-assembly",)
"""Threads that may live in a process that forks: the assembly's pool, whose workers wait
between the solves (the outputs solve nothing) and which a forked child makes anew."""


class _Stop(BaseException):
    """Raised in the child by SIGTERM or SIGINT: unwinds it through the writers' clean-up."""


def _stop(signum, frame):
    raise _Stop(signum)


class Forked:
    """``jobs`` run in a forked child (or, where :func:`can_fork` says no, in the parent at
    :meth:`join`); use as a context manager, which cancels the child on an exception."""

    def __init__(self, jobs, *, fork: bool | None = None, directory=None, stall: float = STALL_S):
        self.jobs = list(jobs)
        self.pid = None
        self._read = None
        self.directory = None if directory is None else Path(directory)
        self.stall = float(stall)
        if self.jobs and (can_fork() if fork is None else fork):
            self._start()

    def _start(self) -> None:
        read, write = os.pipe()
        for stream in (sys.stdout, sys.stderr):          # nothing buffered is written twice
            with contextlib.suppress(Exception):
                stream.flush()
        parent = os.getpid()
        # SIGINT and SIGTERM held across the fork: one arriving then would run the parent's handler
        # in the child's fork hooks (the random module's reseed), where its exception is printed
        # and lost; the child takes its own handlers first, the parent gets a held signal after
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            pid = os.fork()
        finally:
            if os.getpid() == parent:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        if pid == 0:                                       # the child: the jobs, then _exit
            code = 1
            try:
                os.close(read)
                signal.signal(signal.SIGTERM, _stop)
                signal.signal(signal.SIGINT, _stop)
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
                _end_with(parent)
                try:
                    for job in self.jobs:
                        job()
                        os.write(write, _DONE)            # one byte a finished job: the progress
                    code = 0
                except BaseException as exc:              # noqa: BLE001 - carried to the parent
                    with os.fdopen(write, "wb") as pipe:
                        pipe.write(_FAILED + _payload(exc))
            finally:
                os._exit(code)
        os.close(write)
        self.pid, self._read, self._started = pid, read, time.time()

    def join(self) -> None:
        """Wait for the jobs (run them here where no child was made, or where the child stalled);
        raise a child's exception."""
        if self.pid is None:
            self._run_here(0)
            return
        done, data = self._progress()
        if data is None:                                  # stalled: the rest is done here
            self._take_over(done)
            return
        _, status = os.waitpid(self.pid, 0)
        self.pid = None
        if data:
            raise _exception(data)
        if status != 0:
            raise ContactOptError(f"the process writing the figures ended with status {status}")

    def _run_here(self, start: int) -> None:
        jobs, self.jobs = self.jobs[start:], []
        for job in jobs:
            job()

    def _progress(self) -> tuple[int, bytes | None]:
        """Read the child's pipe to its end: the number of jobs it finished and its exception's
        payload (b"" for none); None for the payload where ``stall`` seconds passed without a byte."""
        done, payload = 0, None
        with os.fdopen(self._read, "rb", buffering=0) as pipe:
            self._read = None
            while True:
                ready, _, _ = select.select([pipe], [], [], self.stall)
                if not ready:
                    return done, None
                chunk = pipe.read(65536)
                if not chunk:
                    return done, b"" if payload is None else bytes(payload)
                if payload is None:                   # progress bytes, then perhaps "!" and the payload
                    head, failed, rest = chunk.partition(_FAILED)
                    done += len(head)
                    if failed:
                        payload = bytearray(rest)
                else:
                    payload += chunk

    def _take_over(self, done: int) -> None:
        """The child finished ``done`` jobs and then nothing for ``stall`` seconds: kill it, remove
        its temporary files and run the other jobs here."""
        log.warning("the process drawing the figures finished no job for %.0f s (%d of %d done); it is "
                    "stopped and the other %d are drawn by the run itself", self.stall, done, len(self.jobs),
                    len(self.jobs) - done)
        with contextlib.suppress(OSError):
            os.kill(self.pid, signal.SIGKILL)             # a deadlocked child runs no signal handler
        with contextlib.suppress(OSError):
            os.waitpid(self.pid, 0)
        self.pid = None
        if self.directory is not None:
            for leftover in self.directory.glob(".*.tmp*"):
                with contextlib.suppress(OSError):
                    if leftover.stat().st_mtime >= self._started - 1.0:
                        leftover.unlink()
        self._run_here(done)

    def cancel(self) -> None:
        """Stop the child (if any) and wait for it; its exception, if any, is dropped."""
        if self.pid is None:
            return
        with contextlib.suppress(OSError):
            os.kill(self.pid, signal.SIGTERM)
        if self._read is not None:
            with contextlib.suppress(OSError):
                os.close(self._read)
        with contextlib.suppress(OSError):
            os.waitpid(self.pid, 0)
        self.pid = None

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        if kind is not None:
            self.cancel()
        return False


def _end_with(parent: int) -> None:
    """SIGTERM to this child when its parent ends (a parent killed by SIGKILL leaves no child
    that holds the run directory's lock through an inherited descriptor)."""
    with contextlib.suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:                             # it ended before the request
        raise _Stop(signal.SIGTERM)


_PR_SET_PDEATHSIG = 1
_DONE, _FAILED = b".", b"!"          # the child's pipe: a byte a finished job; "!" and the exception


def _payload(exc: BaseException) -> bytes:
    """The child's exception as bytes: pickled where it unpickles again, else its text."""
    with contextlib.suppress(Exception):
        data = pickle.dumps(exc)
        pickle.loads(data)
        return data
    return pickle.dumps(f"{type(exc).__name__}: {exc}")


def _exception(data: bytes) -> BaseException:
    exc = pickle.loads(data)
    if isinstance(exc, _Stop):
        return ContactOptError(f"the process writing the figures was stopped by signal {exc.args[0]}")
    if isinstance(exc, str):
        return ContactOptError(f"writing the figures failed: {exc}")
    return exc
