"""One writer per directory: a lock file naming the writer (host, PID, start time, command).

The lock is the file ``.contactopt.lock`` in the directory, held with ``flock`` for as long as the
writer runs. The kernel drops a flock when its process ends, however it ends (``kill -9``
included), so a lock file that nobody holds is stale whatever it says: the next writer takes it
over and is told whose it was (:attr:`DirLock.previous`). The file's content only names the
holder in the refusal. Where the file system has no flock (some NFS mounts), a lock left on this
host by a PID that no longer exists is stale, and one of another host is honoured: its owner, or
the user who knows that process is gone, removes the file.

A writer that ends normally removes the file, so a finished directory holds no lock.
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
import socket
import sys
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from ..errors import ContactOptError

log = logging.getLogger(__name__)

__all__ = ["LOCK_NAME", "DirLock", "LockedError", "acquire", "held_by", "live_holders", "describe"]

LOCK_NAME = ".contactopt.lock"
_NO_FLOCK = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL}


class LockedError(ContactOptError):
    """Another live process writes to the directory; ``holder`` is what its lock file says."""

    def __init__(self, directory, holder: dict, what: str = "directory"):
        self.directory = Path(directory)
        self.holder = holder
        super().__init__(f"{what} {directory} is in use by another contactopt process ({describe(holder)}); "
                         f"one writer per directory: wait for it to end or choose another directory"
                         + ("" if holder.get("flock", True) else
                            f" (if that process is gone, remove {self.directory / LOCK_NAME})"))


def describe(holder: dict) -> str:
    """'PID 123 on host, started 2026-01-01T10:00:00Z: contactopt run ...' (what is known)."""
    if not holder or "pid" not in holder:
        return "holder unknown"
    text = f"PID {holder['pid']} on {holder.get('host', '?')}, started {holder.get('started', '?')}"
    return text + (f": {holder['command']}" if holder.get("command") else "")


def _me() -> dict:
    return {"host": socket.gethostname(), "pid": os.getpid(),
            "started": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "command": " ".join(["contactopt"] + sys.argv[1:]) if sys.argv and "contactopt" in sys.argv[0]
            else None}


def _flock(fd: int):
    """True: locked; False: held by another open file; None: the file system has no flock."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in _NO_FLOCK:
            return None
        raise


def _read(fd: int) -> dict:
    try:
        data = os.pread(fd, 65536, 0)
        return json.loads(data.decode()) if data.strip() else {}
    except (OSError, ValueError):
        return {"raw": "unreadable"}


def _alive(holder: dict) -> bool:
    """Whether the holder may still run (no flock: by PID on this host; another host's: yes)."""
    if "pid" not in holder:
        return False
    if holder.get("host") != socket.gethostname():
        return True
    try:
        os.kill(int(holder["pid"]), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, ValueError, OverflowError):
        return True
    return True


@dataclass
class DirLock:
    """A held lock; ``previous`` is the stale lock's content it replaced (None: there was none)."""

    directory: Path
    fd: int | None
    previous: dict | None = None

    @property
    def path(self) -> Path:
        return self.directory / LOCK_NAME

    def release(self) -> None:
        """Remove the lock file (if it is still this lock's) and drop the flock."""
        if self.fd is None:
            return
        try:
            if _same_file(self.fd, self.path):
                self.path.unlink()
        except OSError:
            pass
        finally:
            os.close(self.fd)
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def _same_file(fd: int, path: Path) -> bool:
    try:
        a, b = os.fstat(fd), os.stat(path)
    except FileNotFoundError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def acquire(directory, *, what: str = "directory") -> DirLock:
    """Take the lock of an existing ``directory``; :class:`LockedError` when a live process holds it.

    A stale lock is taken over (its content in ``previous``, and logged). OSError when the lock
    file cannot be created (a read-only or foreign directory)."""
    directory = Path(directory)
    path = directory / LOCK_NAME
    for _ in range(100):        # retries only when a releasing writer removed the file meanwhile
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            got = _flock(fd)
            if got is False:
                holder = {}
                for _ in range(20):          # the holder may be writing its name just now
                    holder = _read(fd)
                    if "pid" in holder:
                        break
                    time.sleep(0.01)
                raise LockedError(directory, holder, what)
            if got is None:
                holder = _read(fd)
                if _alive(holder):
                    raise LockedError(directory, dict(holder, flock=False), what)
            if not _same_file(fd, path):
                os.close(fd)
                continue
            previous = _read(fd) or None
            data = (json.dumps(_me()) + "\n").encode()
            os.ftruncate(fd, 0)
            os.pwrite(fd, data, 0)
        except BaseException:
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
            raise
        if previous:
            log.info("%s: took over the lock of a writer that no longer runs (%s)", directory,
                        describe(previous))
        return DirLock(directory, fd, previous)
    raise OSError(errno.EAGAIN, f"cannot take the lock {path}: it keeps being replaced")


def held_by(directory) -> dict | None:
    """What the lock of ``directory`` says if a live process holds it, else None (no side effect
    on a held lock; a stale one is left where it is)."""
    path = Path(directory) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        got = _flock(fd)
        holder = _read(fd)
        if got is False:
            return holder or {}
        if got is None and _alive(holder):
            return dict(holder, flock=False)
        return None
    finally:
        os.close(fd)       # drops the flock taken for the test


def live_holders(root) -> list[tuple[Path, dict]]:
    """(directory, holder) of every live lock strictly below ``root`` (e.g. a sweep's runs)."""
    root = Path(root)
    found = []
    for path in root.rglob(LOCK_NAME):
        if path.parent != root:
            holder = held_by(path.parent)
            if holder is not None:
                found.append((path.parent, holder))
    return found
