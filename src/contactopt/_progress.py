"""Progress of long solves and set-ups.

On large meshes the AMG set-up and the first Newton steps of one design take minutes, so they
report as they go, at INFO on the ``contactopt.progress`` logger (which the CLI shows) from
PROGRESS_DOFS unknowns on or once PROGRESS_SECONDS have passed, else at DEBUG.

A set-up that is one long call (a sparse factorization, the compliance of an elastic
foundation) is wrapped in :func:`task`: it logs its start and end at DEBUG with the record
attributes ``progress_task`` ("start"/"end") and ``progress_what``. The library prints nothing;
the command line, on an interactive terminal, turns those records into one line that counts the
seconds (:class:`LiveLine`), and on a pipe or a file leaves them out."""

from __future__ import annotations

import contextlib
import logging
import threading
import time

progress = logging.getLogger("contactopt.progress")
PROGRESS_DOFS = 100_000
PROGRESS_SECONDS = 10.0


def progress_level(n: int, t_start: float) -> int:
    """The level of a progress line of a solve of ``n`` unknowns started at ``t_start``."""
    return logging.INFO if n >= PROGRESS_DOFS or time.perf_counter() - t_start > PROGRESS_SECONDS else logging.DEBUG


@contextlib.contextmanager
def task(what: str):
    """A long set-up step named ``what`` ("factorizing 113 088 unknowns"): its start and end as
    DEBUG records of the ``contactopt.progress`` logger, for a live line on a terminal."""
    t0 = time.perf_counter()
    progress.debug("%s", what, extra={"progress_task": "start", "progress_what": what})
    try:
        yield
    finally:
        progress.debug("%s: %.1f s", what, time.perf_counter() - t0,
                       extra={"progress_task": "end", "progress_what": what})


class LiveLine(logging.Handler):
    """Shows the innermost running :func:`task` on one line of ``stream`` (a terminal), rewritten
    every ``interval`` seconds once it has run for ``delay`` seconds, and erased when it ends:
    "factorizing 113 088 unknowns … 12 s". Other records pass by untouched."""

    def __init__(self, stream, delay: float = 1.0, interval: float = 0.5):
        super().__init__(logging.DEBUG)
        self.stream, self.delay, self.interval = stream, delay, interval
        self._tasks: list[tuple[str, float]] = []
        self._shown = False
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None

    def emit(self, record):
        kind = getattr(record, "progress_task", None)
        if kind is None:
            return
        with self._lock:
            if kind == "start":
                self._tasks.append((record.progress_what, time.perf_counter()))
                if self._thread is None:
                    self._thread = threading.Thread(target=self._tick, name="contactopt-progress", daemon=True)
                    self._thread.start()
            else:
                self._tasks = [t for t in self._tasks if t[0] != record.progress_what]
                self._clear()
            self._wake.set()

    def _clear(self):
        if self._shown:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self._shown = False

    def _tick(self):
        while True:
            self._wake.wait(self.interval)
            self._wake.clear()
            with self._lock:
                if self._tasks:
                    what, t0 = self._tasks[-1]
                    elapsed = time.perf_counter() - t0
                    if elapsed >= self.delay:
                        self.stream.write(f"\r\033[K{what} … {elapsed:.0f} s")
                        self.stream.flush()
                        self._shown = True

    def close(self):
        with self._lock:
            self._tasks.clear()
            self._clear()
        super().close()
