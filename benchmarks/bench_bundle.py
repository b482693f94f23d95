"""Benchmark of the bundle-trust optimizer on the Lukšan–Vlček nonsmooth test problems.

Run:  python benchmarks/bench_bundle.py [--eps 1e-4] [--max-iter 3000]

Prints one row per problem (n, f*, f found, relative error — absolute where f* = 0 —,
iterations, serious/null steps, oracle evaluations, wall time), then the 32-variable problem
on the paper-like admissible set against an SOCP reference (Clarabel, when installed) and the
time of one direction-finding QP: DAQP (as used by the optimizer) against Clarabel on the same
QP, as a ratio measured in this run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from contactopt.optimize import minimize_bundle
from contactopt.optimize._bundle_qp import Polyhedron
from contactopt.optimize.testproblems import (max_quadratics_reference, PROBLEMS, max_quadratics_problem,
                                              paper_admissible_set)


def _run(prob, eps, max_iter):
    t0 = time.perf_counter()
    res = minimize_bundle(prob, prob.x0, eps=eps, max_iter=max_iter, **prob.constraints())
    return res, time.perf_counter() - t0


def _socp_value(prob):
    """Reference optimum from Clarabel, or None when it is not installed."""
    try:
        return max_quadratics_reference(prob)[1]
    except ImportError:
        return None


def _qp_timing(repeats=200):
    """Median time of one 33-variable direction QP: DAQP (ours) and Clarabel, same data."""
    rng = np.random.default_rng(1)
    cons = paper_admissible_set()
    poly = Polyhedron(32, **cons)
    x, t = np.full(32, 0.01), 0.5
    G = rng.normal(size=(35, 32))
    alpha = np.abs(rng.normal(size=35)) * 0.1
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        poly.direction(x, G, alpha, t)
        times.append(time.perf_counter() - t0)
    ours = float(np.median(times))
    try:
        import clarabel
        import scipy.sparse as sp
    except ImportError:
        return ours, None
    n = 32
    P = sp.csc_matrix(np.diag(np.r_[np.full(n, 1.0 / t), 0.0]))
    q = np.r_[np.zeros(n), 1.0]
    A_in = np.vstack([np.hstack([G, -np.ones((35, 1))]),
                      np.hstack([cons["A_ub"], np.zeros((cons["A_ub"].shape[0], 1))]),
                      np.hstack([np.eye(n), np.zeros((n, 1))]),
                      np.hstack([-np.eye(n), np.zeros((n, 1))])])
    b_in = np.r_[alpha, cons["b_ub"] - cons["A_ub"] @ x, cons["ub"] - x, x - cons["lb"]]
    A = sp.csc_matrix(np.vstack([np.hstack([cons["A_eq"], np.zeros((1, 1))]), A_in]))
    b = np.r_[cons["b_eq"] - cons["A_eq"] @ x, b_in]
    s = clarabel.DefaultSettings()
    s.verbose = False
    times = []
    for _ in range(max(repeats // 10, 5)):
        t0 = time.perf_counter()
        clarabel.DefaultSolver(P, q, A, b, [clarabel.ZeroConeT(1),
                                            clarabel.NonnegativeConeT(len(b_in))], s).solve()
        times.append(time.perf_counter() - t0)
    return ours, float(np.median(times))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--eps", type=float, default=1e-4)
    ap.add_argument("--max-iter", type=int, default=3000)
    args = ap.parse_args(argv)

    head = (f"{'problem':<14}{'n':>4}{'f*':>15}{'f found':>17}{'rel err':>10}{'iter':>7}"
            f"{'serious/null':>14}{'evals':>7}{'time s':>8}  status")
    print(f"bundle-trust method, eps = {args.eps:g}")
    print(head)
    print("-" * len(head))
    n_ok = 0
    total_t = 0.0
    rows = [(p, p.f_star) for p in PROBLEMS.values()]
    big = max_quadratics_problem()
    rows.append((big, _socp_value(big)))
    for prob, f_star in rows:
        res, dt = _run(prob, args.eps, args.max_iter)
        total_t += dt
        if f_star is None:
            err_s, ok = "n/a", res.success
            fs = "n/a"
        else:
            err = abs(res.fun - f_star) / (abs(f_star) if f_star != 0 else 1.0)
            ok = res.success and err <= args.eps
            err_s, fs = f"{err:.1e}", f"{f_star:.8g}"
        n_ok += ok
        status = "ok" if ok else "MISSED"
        print(f"{prob.name:<14}{prob.n:>4}{fs:>15}{res.fun:>17.10g}{err_s:>10}{res.nit:>7}"
              f"{res.n_serious:>8}/{res.n_null:<5}{res.nfev:>7}{dt:>8.3f}  {status}")
    print("-" * len(head))
    print(f"{n_ok}/{len(rows)} problems reached f* to {args.eps:g} (relative; absolute where "
          f"f* = 0); total time {total_t:.2f} s")
    ours, ref = _qp_timing()
    line = f"direction QP, n = 32 (+ epigraph), 35 cuts, 104 slope rows, box, 1 equality: " \
           f"DAQP {ours * 1e3:.3f} ms"
    if ref is not None:
        line += f", Clarabel {ref * 1e3:.3f} ms, ratio Clarabel/DAQP {ref / ours:.1f}"
    print(line)


if __name__ == "__main__":
    main()
