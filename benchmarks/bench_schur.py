"""Cost of the condensation onto the contact DOFs versus one factorization of A.

    python benchmarks/bench_schur.py               # Example 1, Example 2, fine (~113k DOFs)
    python benchmarks/bench_schur.py --repeat 5 --meshes ex1
    python benchmarks/bench_schur.py --scipy-fine  # also SciPy on the fine mesh (~10 min, 12 GB)

For every mesh and backend, in the same run and interleaved (absolute times drift on a shared
machine, ratios much less), the script measures the minimum over ``--repeat`` runs of

* factor:   ``factorize(A)`` (ordering + symbolic + numeric factorization of the whole A),
* Schur:    ``condense(A, c)`` (everything needed for S, ℓ and the interior solves),
* refactor: ``fac.refactor(A)`` (PARDISO only: new values, same pattern, analysis reused),
* solve_i:  one ``solve_interior`` and one ``recover`` (single right-hand side),

and prints Schur / factor, together with the ratios of factor sizes (nnz) and of PARDISO's
factorization flop counts, which do not depend on the machine load. The goal on the Example 1
mesh is Schur <= 1.5 x factor (PARDISO).
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from contactopt.fem._pardiso import factorization_mflop  # noqa: E402
from contactopt.fem.linsolve import condense, factorize, pardiso_available  # noqa: E402
from contactopt.verification.brick import EXAMPLE1, EXAMPLE2, FINE, brick  # noqa: E402

MESHES = {"ex1": ("Example 1", EXAMPLE1), "ex2": ("Example 2", EXAMPLE2), "fine": ("fine", FINE)}
GOAL = 1.5


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def bench_backend(A, c, backend, repeat, rng):
    t_fact, t_schur, t_refac = [], [], []
    fac = None
    for _ in range(repeat):
        t, f = _timed(lambda: factorize(A, backend))
        t_fact.append(t)
        fact_stats = f.stats
        f.close()
        del f
        if fac is not None:
            fac.close()
            fac = None
        gc.collect()
        t, fac = _timed(lambda: condense(A, c, backend))
        t_schur.append(t)
        if backend == "pardiso":
            t_refac.append(_timed(lambda: fac.refactor(A))[0])
    flop_ratio = None
    if backend == "pardiso":     # PARDISO's own flop counts: independent of the machine load
        upper = sp.triu(A, format="csr")
        mask = np.zeros(A.shape[0], dtype=bool)
        mask[c] = True
        flop_ratio = factorization_mflop(upper, mask) / factorization_mflop(upper)
    b_i = rng.standard_normal(len(fac.interior))
    L = rng.standard_normal(A.shape[0])
    u_c = rng.standard_normal(len(c))
    t_si = min(_timed(lambda: fac.solve_interior(b_i))[0] for _ in range(5))
    t_rec = min(_timed(lambda: fac.recover(L, u_c))[0] for _ in range(5))
    u = fac.recover(L, u_c)
    res = np.linalg.norm((A @ u - L)[fac.interior]) / np.linalg.norm(L)
    row = dict(factor=min(t_fact), schur=min(t_schur), refactor=min(t_refac) if t_refac else None,
               solve_i=t_si, recover=t_rec, residual=res, S=fac.S,
               flop_ratio=flop_ratio,
               nnz_ratio=fac.stats["nnz_factor"] / fact_stats["nnz_factor"])
    fac.close()
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs per measurement (minimum kept)")
    ap.add_argument("--meshes", nargs="+", choices=list(MESHES), default=list(MESHES))
    ap.add_argument("--scipy-fine", action="store_true",
                    help="also run the SciPy backend on the fine mesh (slow, ~12 GB)")
    args = ap.parse_args(argv)
    backends = (["pardiso"] if pardiso_available() else []) + ["scipy"]
    if "pardiso" not in backends:
        print("MKL PARDISO not available: SciPy only")
    rng = np.random.default_rng(0)

    header = (f"{'mesh':<10} {'n':>7} {'n_c':>5} {'backend':<8} {'factor[s]':>9} {'Schur[s]':>9} "
              f"{'Schur/fac':>9} {'refac[s]':>8} {'solve_i[ms]':>11} {'recover[ms]':>11} "
              f"{'resid':>8} {'nnzL S/fac':>10} {'flop S/fac':>10}")
    print(header)
    print("-" * len(header))
    summary = []
    for key in args.meshes:
        name, shape = MESHES[key]
        b = brick(*shape)
        A, c = b.A, b.c
        rows = {}
        for backend in backends:
            if key == "fine" and backend == "scipy" and not args.scipy_fine:
                print(f"{name:<10} {A.shape[0]:>7} {len(c):>5} {backend:<8} "
                      "(skipped: minutes and ~12 GB; use --scipy-fine)")
                continue
            repeat = args.repeat if A.shape[0] < 50_000 else max(1, (args.repeat + 1) // 2)
            r = bench_backend(A, c, backend, repeat, rng)
            rows[backend] = r
            refac = f"{r['refactor']:8.3f}" if r["refactor"] is not None else f"{'-':>8}"
            flops = f"{r['flop_ratio']:10.2f}" if r["flop_ratio"] is not None else f"{'-':>10}"
            print(f"{name:<10} {A.shape[0]:>7} {len(c):>5} {backend:<8} {r['factor']:9.3f} "
                  f"{r['schur']:9.3f} {r['schur'] / r['factor']:9.2f} {refac} "
                  f"{1e3 * r['solve_i']:11.2f} {1e3 * r['recover']:11.2f} {r['residual']:8.1e} "
                  f"{r['nnz_ratio']:10.2f} {flops}",
                  flush=True)
        if len(rows) == 2:
            Sp, Ss = rows["pardiso"]["S"], rows["scipy"]["S"]
            diff = np.linalg.norm(Sp - Ss) / np.linalg.norm(Ss)
            print(f"{'':<10} S(pardiso) vs S(scipy): relative difference {diff:.1e}; "
                  f"PARDISO Schur is {rows['scipy']['schur'] / rows['pardiso']['schur']:.1f}x "
                  "faster than SciPy")
        if key == "ex1" and "pardiso" in rows:
            summary.append(rows["pardiso"]["schur"] / rows["pardiso"]["factor"])
        del b, A, rows
        gc.collect()
    if summary:
        ratio = summary[0]
        verdict = "met" if ratio <= GOAL else "NOT met"
        print(f"\nGoal PARDISO Schur <= {GOAL} x factorization on Example 1: ratio {ratio:.2f} "
              f"-> {verdict}")


if __name__ == "__main__":
    from contactopt._threads import sequential_openblas
    with sequential_openblas():    # the thread policy of ShapeProblem (contactopt._threads)
        main()
