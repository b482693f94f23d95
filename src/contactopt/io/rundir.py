"""Output directories: one run (or one state solve) = one directory, one writer at a time."""

from __future__ import annotations

import csv
import logging
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import ContactOptError
from .atomic import atomic_write_json, atomic_write_text, write_error
from .checkpoint import CHECKPOINT_NAME
from .lock import LOCK_NAME, DirLock, LockedError, acquire, describe, held_by, live_holders

log = logging.getLogger(__name__)


class OutputDirError(ContactOptError):
    """The output directory cannot be used (not empty, not writable, a file, ...)."""


def _contents(out: Path) -> list[Path]:
    """What a directory holds, its lock file aside."""
    return [p for p in out.iterdir() if p.name != LOCK_NAME] if out.is_dir() else []


def prepare_output_dir(path, *, overwrite: bool = False, resume: bool = False) -> Path:
    """Create (or reuse) an output directory and check that it is writable.

    A non-empty directory is refused unless ``overwrite`` (its contents are removed) or ``resume``
    (kept as it is).
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise OutputDirError(f"output path {out} exists and is not a directory")
    if out.exists() and any(out.iterdir()):
        if resume:
            pass
        elif overwrite:
            _clear(out)
        else:
            raise OutputDirError(f"output directory {out} is not empty; pass --overwrite to replace it "
                                 "or --resume to continue the run in it")
    elif resume:
        raise OutputDirError(f"--resume: {out} holds no run to resume")
    _make_writable(out)
    return out


def _clear(out: Path) -> None:
    for child in _contents(out):
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child)
        else:
            child.unlink()


def _make_writable(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=out, prefix=".write-test-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputDirError(f"output directory {out} is not writable: {exc.strerror or exc}") from None


def _remove_temporaries(out: Path) -> None:
    """Remove what a killed writer left half-made: the hidden temporary files of atomic writes
    (``.name.XXXX.tmp.ext``), export's temporary directories, a write probe. Safe once the lock
    is held: no other process writes here."""
    for child in out.iterdir():
        name = child.name
        if name != LOCK_NAME and name.startswith(".") and (".tmp" in name or name.startswith(".write-test-")):
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child, ignore_errors=True)
            else:
                child.unlink(missing_ok=True)
            log.info("%s: removed %s, left half-made by a writer that was stopped", out, name)


def claim_output_dir(path, *, overwrite: bool = False, resume: bool = False, what: str = "run") -> DirLock:
    """:func:`prepare_output_dir` for a writer that must be alone: the directory's lock is taken
    before anything in it is written or removed, and returned (release it when done).

    A directory another live process holds is refused (:class:`~contactopt.io.lock.LockedError`,
    naming the holder), ``overwrite`` included; so is ``overwrite`` of a directory below which a
    live process holds a lock (a sweep's run). A stale lock is taken over (``DirLock.previous``)."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise OutputDirError(f"output path {out} exists and is not a directory")
    if resume and not _contents(out):
        raise OutputDirError(f"--resume: {out} holds no run to resume")
    try:
        out.mkdir(parents=True, exist_ok=True)
        lock = acquire(out, what=f"{what} directory")
    except OSError as exc:
        raise OutputDirError(f"output directory {out} is not writable: {exc.strerror or exc}") from None
    try:
        if _contents(out) and not resume:
            if not overwrite:
                raise OutputDirError(f"output directory {out} is not empty; pass --overwrite to replace it "
                                     f"or --resume to continue the {what} in it")
            busy = live_holders(out)
            if busy:
                raise OutputDirError(f"--overwrite: {busy[0][0]} inside {out} is in use by another contactopt "
                                     f"process ({describe(busy[0][1])}); nothing was removed")
            _clear(out)
        _remove_temporaries(out)
        _make_writable(out)
    except BaseException:
        lock.release()
        raise
    return lock


class _RunLog(logging.FileHandler):
    """run.log; a write that fails (a full disk) silences it instead of printing a traceback:
    the write of a file that matters fails soon after and says why."""

    def handleError(self, record):
        self.setLevel(logging.CRITICAL + 1)


class RunDirectory:
    """The directory of one optimization run and the files it owns: its lock, run.log,
    config.toml, history.csv, checkpoint.npz (:mod:`contactopt.io.checkpoint`), summary.json and
    the result files (``contactopt.io.outputs``).

    :meth:`claim` takes the lock (one writer per directory), :meth:`start_log` starts run.log,
    :meth:`close` undoes both. A stale lock left by a killed writer is taken over and noted in run.log at
    INFO level (nothing is printed: the takeover is what a resume after ``kill -9`` expects)."""

    LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"

    def __init__(self, path):
        self.path = Path(path)
        self.lock = None
        self._handler = None
        self._level = None

    @property
    def checkpoint(self) -> Path:
        return self.path / CHECKPOINT_NAME

    @property
    def history(self) -> Path:
        return self.path / "history.csv"

    @property
    def summary(self) -> Path:
        return self.path / "summary.json"

    def refuse_if_held(self) -> None:
        """:class:`~contactopt.io.lock.LockedError` when a live process holds the directory
        (checked before a run's set-up, not only once it is done)."""
        holder = held_by(self.path) if self.path.is_dir() else None
        if holder is not None:
            raise LockedError(self.path, holder, "run directory")

    def claim(self, *, overwrite: bool = False, resume: bool = False) -> None:
        """Take the lock (``claim_output_dir``: nothing is written or removed before)."""
        self.lock = claim_output_dir(self.path, overwrite=overwrite, resume=resume)

    def start_log(self) -> None:
        """Start run.log (INFO and above of the ``contactopt`` loggers) and note a taken-over lock."""
        root = logging.getLogger("contactopt")
        try:
            self._handler = _RunLog(self.path / "run.log")
        except OSError as exc:
            raise write_error(self.path / "run.log", exc) from exc
        self._level = root.level
        self._handler.setFormatter(logging.Formatter(self.LOG_FORMAT))
        self._handler.setLevel(logging.INFO)
        root.addHandler(self._handler)
        if root.getEffectiveLevel() > logging.INFO:
            root.setLevel(logging.INFO)
        if self.lock is not None and self.lock.previous:
            log.info("took over the lock of %s from a writer that no longer runs (%s)", self.path,
                     describe(self.lock.previous))

    def close(self) -> None:
        """Stop run.log and release the lock (whichever of them was started)."""
        root = logging.getLogger("contactopt")
        if self._handler is not None:
            root.removeHandler(self._handler)
            self._handler.close()
            self._handler = None
        if self._level is not None:
            root.setLevel(self._level)
            self._level = None
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    # ------------------------------------------------------------------ files
    def write_config(self, text: str, versions: dict) -> None:
        """config.toml: the resolved configuration ``text`` under a line of package versions."""
        atomic_write_text(self.path / "config.toml", "# resolved configuration of this run\n# versions: "
                          + ", ".join(f"{k} {v}" for k, v in versions.items()) + "\n" + text)

    def start_history(self, fields: list, keep_rows: int | None = None) -> None:
        """history.csv with its header; ``keep_rows``: keep that many rows of the file there is
        (a resume: the rows after its checkpoint, perhaps cut short by a full disk, are dropped)."""
        rows = []
        if keep_rows and self.history.exists():
            text = self.history.read_bytes().decode("utf-8", errors="replace").replace("\0", "")
            rows = list(csv.reader(text.splitlines()))[1:1 + keep_rows]
        atomic_write_text(self.history, ",".join(fields) + "\n" + "".join(",".join(r) + "\n" for r in rows))

    def append_history(self, row: list) -> None:
        """One row of history.csv (appended: rows after the checkpoint are dropped on resume)."""
        try:
            with open(self.history, "a", newline="") as fh:
                csv.writer(fh).writerow(row)
        except OSError as exc:
            raise write_error(self.history, exc) from exc

    def sync_history(self) -> None:
        """history.csv on disk before a checkpoint that counts its rows."""
        try:
            with open(self.history, "rb+") as fh:
                os.fsync(fh.fileno())
        except FileNotFoundError:
            pass
        except OSError as exc:
            raise write_error(self.history, exc) from exc

    def write_summary(self, summary: dict) -> None:
        atomic_write_json(self.summary, summary)
