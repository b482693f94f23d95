"""Benchmark of the local contact solvers (Newton and the paper's fixed point).

Run:  python benchmarks/bench_local.py [--fclib-dir DIR] [--repeat N] [--no-fixed-point]
                                      [--blas-threads N]

Two parts, all figures measured in this one run:

1. The public FCLIB problems (rigid bodies, singular W): error, iterations and time of both
   methods at tolerance 1e-8.
2. A paper-size elastic brick: Q1 elasticity on 32 x 15 x 9 hexahedra of [0,2]x[0,1]x[0,1]
   (E = 21.19, nu = 0.277), face x = 0 clamped, 16 x 32 = 512 contact nodes on the bottom,
   W = S^{-1} the dense Delassus operator (S condensed onto the contact DOFs, ordered
   (normal z, tangent x, tangent y) per node), q = W l + gap (gap 0.01, top pressure -0.08,
   right-face traction (0, 0, -0.05)), mu = 0.3. Reported: cold-start time and iterations of
   both methods, warm starts after small changes of q (a smooth change of the gap, as a
   design step makes, and a uniform scaling of q), and the time of one dense Cholesky
   factorization of W measured in the same run, as the reference of the ratios.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path


def _preset_blas_threads(argv):
    """Apply ``--blas-threads N`` before numpy loads its BLAS (it reads the variables once)."""
    for k, arg in enumerate(argv):
        if arg == "--blas-threads" and k + 1 < len(argv):
            value = argv[k + 1]
        elif arg.startswith("--blas-threads="):
            value = arg.split("=", 1)[1]
        else:
            continue
        for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
            os.environ[var] = value


if __name__ == "__main__":
    _preset_blas_threads(sys.argv)

import numpy as np  # noqa: E402
from scipy.linalg import lapack  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from contactopt.contact import node_class, solve_local  # noqa: E402
from contactopt.io.fclib import read_fclib  # noqa: E402
from contactopt.verification import brick as _brick  # noqa: E402

FCLIB_FILES = ["local_problem_test.hdf5", "LMGC_100_PR_PerioBox-i00361-60-03000.hdf5",
               "Capsules-i125-1213.hdf5"]


def brick_problem(nx=32, ny=15, nz=9, *, a=2.0, b=1.0, c=1.0, pressure=-0.08,
                  side=(0.0, 0.0, -0.05), gap=0.01, mu=0.3):
    """Dense Delassus problem (W, q, mu) of the clamped Q1 brick; contacts (N, T1, T2)."""
    from contactopt.fem.linsolve import condense

    B = _brick.brick(nx, ny, nz, a, b, c)
    cdofs = B.c.reshape(-1, 3)[:, [2, 0, 1]].ravel()       # (x, y, z) -> (z, x, y)
    cond = condense(B.A, cdofs)
    # consistent nodal loads of uniform tractions on the top face and the right face
    ii, jj, kk = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1),
                             indexing="ij")
    node = ii + (nx + 1) * (jj + (ny + 1) * kk)
    wx, wy, wz = (np.where((v == 0) | (v == m), 0.5, 1.0)
                  for v, m in ((ii, nx), (jj, ny), (kk, nz)))
    L = np.zeros(3 * B.n_nodes)
    top, right = kk == nz, ii == nx
    L[3 * node[top] + 2] += pressure * (a / nx) * (b / ny) * (wx * wy)[top]
    for d in range(3):
        L[3 * node[right] + d] += side[d] * (b / ny) * (c / nz) * (wy * wz)[right]
    ell = cond.condense_load(L[B.free])
    W = np.linalg.inv(cond.S)
    W = np.ascontiguousarray(0.5 * (W + W.T))
    q = W @ ell
    q[0::3] += gap
    return W, q, np.full(cdofs.size // 3, mu)


def timed(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return out, statistics.median(times)


def run_fclib(directory: Path, methods, repeat):
    print(f"\n== FCLIB problems ({directory}), tol 1e-8, times: median of {repeat}")
    print(f"{'problem':44s} {'method':12s} {'conv':>5s} {'error':>9s} {'iter':>5s} "
          f"{'outer/inner':>12s} {'time s':>8s}")
    for name in FCLIB_FILES:
        path = directory / name
        if not path.exists():
            print(f"{name:44s} missing")
            continue
        prob = read_fclib(path)
        for method in methods:
            res, t_m = timed(lambda: solve_local(prob.W, prob.q, prob.mu, method=method,
                                                 tol=1e-8, raise_on_failure=False), repeat)
            print(f"{name[:44]:44s} {method:12s} {str(res.converged):>5s} {res.error:9.2e} "
                  f"{res.iterations:5d} {res.outer_iterations:5d}/{res.inner_iterations:<6d} "
                  f"{t_m:8.3f}")


def run_brick(repeat, methods):
    print("\n== Elastic brick, 512 contacts (Example 1 mesh), dense W, mu = 0.3, tol 1e-8")
    t = time.perf_counter()
    W, q, mu = brick_problem()
    print(f"problem built in {time.perf_counter() - t:.1f} s: W {W.shape[0]} x {W.shape[1]}, "
          f"times: median of {repeat}")
    _, t_chol = timed(lambda: lapack.dpotrf(W, lower=1, overwrite_a=0), repeat + 2)
    _, t_lu = timed(lambda: lapack.dgetrf(W, overwrite_a=0), repeat + 2)
    print(f"reference: dense Cholesky of W {t_chol * 1e3:7.1f} ms, dense LU {t_lu * 1e3:7.1f} ms")
    base = {}
    for method in methods:
        res, t_m = timed(lambda: solve_local(W, q, mu, method=method, tol=1e-8), repeat)
        base[method] = res
        cls = node_class(res.r, res.u, mu, rtol=1e-6)
        counts = {k: int(np.sum(cls == k)) for k in ("L", "M1", "M2", "M3+", "M3-", "M4")}
        print(f"{method:12s} cold: {t_m * 1e3:8.1f} ms = {t_m / t_chol:5.1f} Cholesky; "
              f"{res.iterations} iterations (inner {res.inner_iterations}), error {res.error:.1e}")
        print(f"{'':12s} node classes (Table 4.1): {counts}")
    if "newton" in base and "fixed-point" in base:
        diff = np.linalg.norm(base["newton"].r - base["fixed-point"].r)
        print(f"{'':12s} ||r_newton - r_fixed_point|| / ||r|| = "
              f"{diff / np.linalg.norm(base['newton'].r):.1e}")
    # Warm starts from the previous solution after small changes of q: a smooth change of the
    # gap (what a design step does) and a uniform scaling of q (load and gap).
    p = mu.size
    xs = np.tile(np.linspace(0.0, 2.0, 33)[1:], p // 32)
    ys = np.repeat(np.linspace(0.0, 1.0, p // 32), 32)
    rng = np.random.default_rng(0)
    field = sum(rng.standard_normal() * np.cos(i * np.pi * xs / 2) * np.cos(j * np.pi * ys)
                for i in range(4) for j in range(3))
    field /= np.abs(field).max()
    print("warm starts (r0 = cold solution):")
    for eps in (1e-4, 1e-3, 1e-2):
        q_gap = q.copy()
        q_gap[0::3] += eps * 0.01 * field          # gap 0.01 changed by eps (relative)
        for label, q2 in (("gap", q_gap), ("scale", q * (1 + eps))):
            for method in methods:
                res, t_m = timed(lambda: solve_local(W, q2, mu, method=method, tol=1e-8,
                                                     r0=base[method].r), repeat)
                print(f"{method:12s} {label:5s} change {eps:.0e}: {t_m * 1e3:8.1f} ms = "
                      f"{t_m / t_chol:5.2f} Cholesky; {res.iterations} iterations "
                      f"(inner {res.inner_iterations})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fclib-dir", default=os.environ.get("CONTACTOPT_FCLIB_DIR",
                                                          str(Path(__file__).resolve().parent.parent / "tests" / "data" / "fclib")))
    ap.add_argument("--repeat", type=int, default=3, help="timings are medians of REPEAT runs")
    ap.add_argument("--no-fixed-point", action="store_true", help="Newton only")
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="BLAS threads (set before numpy loads; 1 is steadier on a busy machine)")
    args = ap.parse_args(argv)
    methods = ["newton"] if args.no_fixed_point else ["newton", "fixed-point"]
    threads = os.environ.get("OPENBLAS_NUM_THREADS")
    print(f"cores: {os.cpu_count()}, OPENBLAS_NUM_THREADS={threads}, "
          f"load average: {os.getloadavg()[0]:.2f}")
    run_fclib(Path(args.fclib_dir), methods, args.repeat)
    run_brick(args.repeat, methods)


if __name__ == "__main__":
    main()
