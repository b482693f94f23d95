"""Output directories: one run (or one state solve) = one directory."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from ..errors import ContactOptError


class OutputDirError(ContactOptError):
    """The output directory cannot be used (not empty, not writable, a file, ...)."""


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
            for child in out.iterdir():
                if child.is_dir() and not child.is_symlink():
                    shutil.rmtree(child)
                else:
                    child.unlink()
        else:
            raise OutputDirError(f"output directory {out} is not empty; pass --overwrite to replace it "
                                 "or --resume to continue the run in it")
    elif resume:
        raise OutputDirError(f"--resume: {out} holds no run to resume")
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=out, prefix=".write-test-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputDirError(f"output directory {out} is not writable: {exc.strerror or exc}") from None
    return out
