"""Atomic file writes: a reader never sees a half-written file.

Every writer here builds the whole file under a temporary name in the *same directory* as the
target (so the final rename never crosses a file system), flushes and fsyncs it, then moves it
over the target with :func:`os.replace`, which is atomic on POSIX and Windows. On any error the
temporary file is removed and the target is left as it was (absent, or its previous content).

Temporary names start with a dot and contain ``.tmp`` (``.state.json.k3j9x1.tmp.json``), so a
crash between creation and rename leaves only an obviously stale hidden file behind.

For writers that insist on a file name of their own (meshio, matplotlib), use
:func:`atomic_output`, a context manager yielding the temporary path to write to.

A write that fails in the operating system (no space, a read-only file system, permission
denied, a directory in the way) raises :class:`WriteError`, which names the target file and the
cause; the target keeps its previous content.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from ..errors import ContactOptError

log = logging.getLogger(__name__)

__all__ = ["WriteError", "write_error", "atomic_output", "atomic_write_bytes", "atomic_write_text", "atomic_write_json",
           "atomic_savez", "atomic_savez_compressed", "to_jsonable", "fsync_dir"]


class WriteError(ContactOptError):
    """A file could not be written: ``path`` is the file, ``cause`` the OSError (``errno``).

    Raised by the writers of this module (the file then keeps its previous content, or stays
    absent) and by the other writers of a run through :func:`~contactopt.io.atomic.write_error`."""

    def __init__(self, path, cause: OSError):
        self.path = Path(path)
        self.cause = cause
        self.errno = cause.errno if isinstance(cause, OSError) else None
        super().__init__(f"cannot write {self.path}: {describe_os_error(cause)}")

    def __reduce__(self):
        return type(self), (self.path, self.cause)


_CAUSES = {
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "the disk quota is exhausted",
    errno.EROFS: "the file system is read-only",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EISDIR: "a directory is in the way",
    errno.ENOTDIR: "a file is in the way of a directory on the path",
    errno.ENOENT: "the directory does not exist (any more)",
    errno.EIO: "input/output error of the device",
}


def describe_os_error(exc: OSError) -> str:
    """The cause of a failed write in words, with the system's own message."""
    code = exc.errno if isinstance(exc, OSError) else None
    system = exc.strerror or str(exc)
    words = _CAUSES.get(code)
    return f"{words} ({system})" if words else system


def write_error(path, exc: OSError) -> WriteError:
    """``exc`` as a :class:`WriteError` of ``path`` (itself if it is one already)."""
    return exc if isinstance(exc, WriteError) else WriteError(path, exc)


# mode of a newly created file (mkstemp makes 0o600, which is wrong for result files)
_NEW_FILE_MODE = 0o644


def fsync_dir(directory) -> None:
    """Flush a directory entry to disk (best effort: not every platform/file system supports it)."""
    try:
        fd = os.open(os.fspath(directory), os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _mkstemp(path: Path) -> tuple[int, Path]:
    """A fresh temporary file next to ``path`` that keeps its extension (format sniffing)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    return fd, Path(tmp)


def _finish(tmp: Path, path: Path) -> None:
    """fsync ``tmp``, give it the target's mode and move it over ``path``."""
    try:
        mode = path.stat().st_mode & 0o7777
    except FileNotFoundError:
        mode = _NEW_FILE_MODE
    os.chmod(tmp, mode)
    with open(tmp, "rb+") as fh:
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    fsync_dir(path.parent)


@contextlib.contextmanager
def atomic_output(path):
    """Context manager: yield a temporary path next to ``path``; on success move it onto ``path``.

    The temporary path keeps the suffix of ``path`` (``.vtu``, ``.png``) because some writers choose
    the format from it. If the body raises, the temporary file is deleted and ``path`` is untouched.
    The parent directory must exist.

    >>> with atomic_output("body.vtu") as tmp:          # doctest: +SKIP
    ...     meshio.write(tmp, mesh, file_format="vtu")
    """
    path = Path(path)
    try:
        fd, tmp = _mkstemp(path)
    except OSError as exc:
        raise WriteError(path, exc) from exc
    os.close(fd)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"the writer did not create the temporary file {tmp}")
        _finish(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise write_error(path, exc) from exc
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    log.debug("wrote %s", path)


def _write_atomically(path, write) -> Path:
    """Call ``write(fh)`` on a temporary file beside ``path``, then move it into place; on any
    failure the temporary file is removed and ``path`` keeps its old content."""
    path = Path(path)
    try:
        fd, tmp = _mkstemp(path)
    except OSError as exc:
        raise WriteError(path, exc) from exc
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        _finish(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise write_error(path, exc) from exc
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    return path


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    path = _write_atomically(path, lambda fh: fh.write(data))
    log.debug("wrote %s (%d bytes)", path, len(data))
    return path


def atomic_write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (newlines written as given, no translation)."""
    return atomic_write_bytes(path, text.encode(encoding))


def to_jsonable(obj):
    """Convert numpy arrays/scalars, tuples, sets and paths to plain JSON types (recursively).

    Non-finite floats are left as they are: the JSON writer decides whether they are an error.
    """
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return obj


def _first_nonfinite(obj, where="$"):
    """JSON path of the first NaN/inf in a jsonable object, or None."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return where
    if isinstance(obj, dict):
        for k, v in obj.items():
            hit = _first_nonfinite(v, f"{where}.{k}")
            if hit:
                return hit
    elif isinstance(obj, list):
        for n, v in enumerate(obj):
            hit = _first_nonfinite(v, f"{where}[{n}]")
            if hit:
                return hit
    return None


def atomic_write_json(path, obj, *, indent: int | None = 2, allow_nan: bool = False,
                      sort_keys: bool = False) -> Path:
    """Write ``obj`` as JSON atomically; numpy arrays and scalars are converted to lists/numbers.

    Strict JSON by default: a NaN or infinity raises ``ValueError`` naming where it is (JSON has no
    such numbers, and a silent NaN in a results file is a defect). ``allow_nan=True`` writes them as
    Python's ``NaN``/``Infinity`` tokens instead.
    """
    data = to_jsonable(obj)
    if not allow_nan:
        bad = _first_nonfinite(data)
        if bad:
            raise ValueError(f"{path}: non-finite number at {bad}; JSON cannot represent it")
    text = json.dumps(data, indent=indent, allow_nan=allow_nan, sort_keys=sort_keys, ensure_ascii=False)
    return atomic_write_text(path, text + "\n")


def _savez(path, arrays, compressed):
    # a file object, not a name: np.savez would append ".npz" to a name without it
    saver = np.savez_compressed if compressed else np.savez
    path = _write_atomically(path, lambda fh: saver(fh, **arrays))
    log.debug("wrote %s (%d arrays)", path, len(arrays))
    return path


def atomic_savez(path, **arrays) -> Path:
    """``numpy.savez`` to exactly ``path`` (no ``.npz`` appended), atomically."""
    return _savez(path, arrays, compressed=False)


def atomic_savez_compressed(path, **arrays) -> Path:
    """``numpy.savez_compressed`` to exactly ``path``, atomically."""
    return _savez(path, arrays, compressed=True)
