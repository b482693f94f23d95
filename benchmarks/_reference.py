"""The timing reference of the benchmarks: one factorization of the same matrix by pypardiso's
defaults (MKL PARDISO), timed in a clean process.

A factorization timed in a process that has already run contactopt's own solves is 1.5–2× slower
(MKL's state); a fresh ``python`` process loads the matrix from a file and times
``pypardiso.PyPardisoSolver().factorize(A)`` alone. Without pypardiso (``pip install
".[bench]"``) the clean process times ``contactopt.fem.linsolve.factorize`` instead, and says so.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import scipy.sparse as sp

_SCRIPT = r"""
import json, sys, time
import numpy as np, scipy.sparse as sp
A = sp.load_npz(sys.argv[1]).tocsr()
repeat = int(sys.argv[2])
times = []
try:
    import pypardiso
    what = "pypardiso defaults"
    for _ in range(repeat):
        s = pypardiso.PyPardisoSolver()
        t0 = time.perf_counter(); s.factorize(A); times.append(time.perf_counter() - t0)
        s.free_memory(everything=True)
except ImportError:
    from contactopt.fem.linsolve import factorize
    what = "contactopt.fem.linsolve.factorize (pypardiso not installed)"
    for _ in range(repeat):
        t0 = time.perf_counter(); f = factorize(A); times.append(time.perf_counter() - t0); f.close()
print(json.dumps({"seconds": sorted(times)[len(times) // 2], "all": times, "what": what}))
"""


def clean_factorization(A, repeat: int = 3) -> dict:
    """Median seconds of one factorization of ``A`` in a clean process: {"seconds", "all", "what"}."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "A.npz"
        sp.save_npz(path, sp.csr_matrix(A))
        out = subprocess.run([sys.executable, "-c", _SCRIPT, str(path), str(repeat)], capture_output=True,
                             text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])
