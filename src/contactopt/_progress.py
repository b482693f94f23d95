"""Progress of long solves: on large meshes the AMG set-up and the first Newton steps of one
design take minutes, so they report as they go, at INFO on the ``contactopt.progress`` logger
(which the CLI shows) from PROGRESS_DOFS unknowns on or once PROGRESS_SECONDS have passed, else
at DEBUG."""

from __future__ import annotations

import logging
import time

progress = logging.getLogger("contactopt.progress")
PROGRESS_DOFS = 100_000
PROGRESS_SECONDS = 10.0


def progress_level(n: int, t_start: float) -> int:
    """The level of a progress line of a solve of ``n`` unknowns started at ``t_start``."""
    return logging.INFO if n >= PROGRESS_DOFS or time.perf_counter() - t_start > PROGRESS_SECONDS else logging.DEBUG
