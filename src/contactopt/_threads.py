"""One thread pool at a time: OpenBLAS is kept sequential around the state solve and the adjoint.

A state solve alternates MKL PARDISO (OpenMP threads) with NumPy/SciPy dense algebra (OpenBLAS
threads) on the same cores. After each call OpenBLAS's threads keep spinning and PARDISO's
next parallel region then competes with them; on the 2-core reference machine that made the
Schur complement 1.3–1.8× slower and the Newton phase 2–5× slower, with large run-to-run
scatter (``benchmarks/bench_state.py``; Example 1: state solve 0.5–0.8 s against 0.40 s with
sequential OpenBLAS). The Newton steps work on matrices of a few hundred rows, where OpenBLAS's
threading gains nothing, and the one large dense factorization of a state solve (the Delassus
factorization, the zone's Delassus block) runs in MKL's pool (:mod:`contactopt.fem.dense`) when
MKL is present. The Newton LU (a few hundred to a few thousand rows) runs on one MKL thread
(:func:`contactopt.fem.dense.mkl_sequential`): with the second core held by other work, two MKL
threads made it 2–4 times slower than one.

:func:`sequential_openblas` is the context manager used by :class:`contactopt.ShapeProblem`
around the state solve and the whole subgradient (the adjoint's dense LU and the design terms
too: with OpenBLAS's threads there, the adjoint of a ``contactopt run`` with the libraries'
default threads cost ten times that of a single-threaded run, docs/measurements.md). On the
condensation path MKL itself runs on ``[linear_solver] threads`` (default 1) inside the model's
construction and every evaluation (``SolverPath.library_threads``): an evaluation is then that of
a single-threaded run bit for bit, whatever MKL_NUM_THREADS or OMP_NUM_THREADS say.
Set ``CONTACTOPT_OPENBLAS_THREADS=keep`` to leave OpenBLAS's threading alone.
"""

from __future__ import annotations

import logging
import os
from contextlib import nullcontext

log = logging.getLogger(__name__)

_selection = None     # threadpoolctl selection of the OpenBLAS libraries, found once


def _openblas():
    global _selection
    if _selection is None:
        try:
            from threadpoolctl import ThreadpoolController
            _selection = ThreadpoolController().select(internal_api="openblas")
        except Exception as exc:  # pragma: no cover - threadpoolctl is a dependency
            log.debug("threadpoolctl unavailable (%s): OpenBLAS threads left alone", exc)
            _selection = ()
    return _selection


def sequential_openblas():
    """Context manager: OpenBLAS runs on one thread inside it (MKL's threads are untouched)."""
    if os.environ.get("CONTACTOPT_OPENBLAS_THREADS", "").lower() == "keep":
        return nullcontext()
    sel = _openblas()
    return sel.limit(limits=1) if sel else nullcontext()
