"""The constrained bundle method on the nonlinearly constrained test problems.

Run:  OPENBLAS_CORETYPE=<kernel> OPENBLAS_NUM_THREADS=1 python benchmarks/bench_constrained.py [--sigma0 S]

Prints one row per problem of ``contactopt.optimize.gallery.CONSTRAINED`` (n, number of
constraints m, f*, f found, relative error of f — of max(1, |f*|) —, the largest c(x), oracle
evaluations, iterations, the final σ and how often it was raised, the stop) with
``minimize_constrained``'s defaults but ctol = 1e-8 and eps = 1e-7 (as the tests), and the
BLAS kernel that ran (threadpoolctl). ``--sigma0`` starts every problem from that weight
instead of the multiplier estimate (to see the outer loop raise it).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from contactopt.optimize.constrained import minimize_constrained
from contactopt.optimize.gallery import CONSTRAINED


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sigma0", type=float, default=None)
    args = ap.parse_args()
    print("| problem | n | m | f* | f | rel. error | max c | evaluations | iterations | σ | raised | stop | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, p in CONSTRAINED.items():
        t0 = time.perf_counter()
        r = minimize_constrained(p, p.x0, ctol=1e-8, eps=1e-7, max_iter=3000, sigma0=args.sigma0,
                                 **p.constraints())
        wall = time.perf_counter() - t0
        err = abs(r.objective - p.f_star) / max(1.0, abs(p.f_star))
        m = p(p.x0)[2].size
        print(f"| {name} | {p.n} | {m} | {p.f_star:.8g} | {r.objective:.10g} | {err:.1e} | "
              f"{float(np.max(r.constraints)):.1e} | {r.nfev} | {r.nit} | {r.sigma:.3g} | {r.outer} | "
              f"{r.criterion} | {wall:.1f} |")
    from threadpoolctl import threadpool_info
    print("OpenBLAS kernels:", sorted({str(i.get("architecture")) for i in threadpool_info()
                                       if i.get("internal_api") == "openblas"}))


if __name__ == "__main__":
    main()
