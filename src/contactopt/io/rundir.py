"""Output directories: one run (or one state solve) = one directory, one writer at a time."""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import ContactOptError
from .lock import LOCK_NAME, DirLock, acquire, describe, live_holders

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
