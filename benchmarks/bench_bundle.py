"""Benchmark of the bundle optimizer on the Lukšan–Vlček nonsmooth test problems.

Run:  python benchmarks/bench_bundle.py [--eps EPS] [--max-iter 3000] [--ftol 0] [--tolf 1e-8]
      [--scale none]
      [--only NAME,...]
      [--set OPTION=VALUE ...]

Prints one row per problem of Lukšan & Vlček's collection (n, f*, f found, relative error —
absolute where f* = 0 —, iterations, serious/null steps, oracle evaluations, the evaluation at
which f first came within the tolerance of f* (the rest is the cost of the stop), wall time, the
stopping test that fired, and the evaluations of the published verification runs of PBUN and
PVAR, ACM TOMS Algorithm 811, where its drivers ran the problem, with options the drivers chose
per problem), with the defaults of ``minimize_bundle`` (``--eps``, ``--ftol`` and ``--tolf`` override
them, ``--set`` any other option of the method, e.g. ``--set extrapolation=1``; the stop
column names the test that fired: f_change, stationarity, roundoff, ...),
the total over the unconstrained problems 1–20 beside the published totals, then:
the 32-variable problem on the paper-like admissible set against an SOCP reference (Clarabel,
when installed); the polyhedral problems with n ≥ 50 — GOFFIN (Lukšan–Vlček, f* = 0, a
maximum of 50 linear pieces) and MAXLIN-60 (our construction, 120 pieces, f* = 1 at a known
x*), the latter with γ = 0 (convex: the locality term is not needed) to 1e-6 and with the
defaults; and the time of one direction-finding QP: DAQP (as used by the optimizer) against
Clarabel on the same QP, as a ratio measured in this run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from contactopt.optimize import minimize_bundle
from contactopt.optimize._bundle_qp import Polyhedron
from contactopt.optimize.gallery import (
    PROBLEMS,
    goffin_problem,
    max_linear_problem,
    max_quadratics_problem,
    max_quadratics_reference,
    paper_admissible_set,
)

# evaluations (NFV) of the published verification runs of ACM TOMS Algorithm 811 (the
# documentation of PBUN and PVAR): unconstrained problems 1–20 and linearly constrained 1–10
PUBLISHED = {
    ("unconstrained", "PBUN"): [45, 20, 33, 16, 19, 15, 12, 68, 15, 46, 45, 29, 62, 118, 93, 75,
                                159, 94, 151, 40],
    ("unconstrained", "PVAR"): [33, 16, 17, 17, 20, 19, 10, 59, 35, 14, 36, 31, 47, 32, 76, 89,
                                176, 78, 123, 23],
    ("linearly constrained", "PBUN"): [11, 5, 10, 80, 17, 17, 44, 76, 143, 68],
    ("linearly constrained", "PVAR"): [10, 4, 14, 89, 24, 25, 93, 138, 120, 139],
}


def published(prob, code):
    """Evaluations of ``code``'s published run on ``prob``, None where its driver skipped it."""
    counts = PUBLISHED.get((prob.group, code), [])
    return counts[prob.number - 1] if 1 <= prob.number <= len(counts) else None


def _run(prob, eps, max_iter, f_star=None, goal=1e-6, **options):
    """The run and its time, and the evaluation at which f first came within ``goal`` of
    ``f_star`` (relative, absolute where f* = 0; None if never)."""
    t0 = time.perf_counter()
    if eps is not None:
        options = {**options, "eps": eps}
    calls, first = 0, None

    def oracle(x):
        nonlocal calls, first
        f, g = prob(x)
        calls += 1
        if (first is None and f_star is not None
                and abs(f - f_star) <= goal * (abs(f_star) if f_star != 0 else 1.0)):
            first = calls
        return f, g

    res = minimize_bundle(oracle, prob.x0, max_iter=max_iter, **prob.constraints(), **options)
    return res, time.perf_counter() - t0, first


def _option(text):
    """``NAME=VALUE`` of ``--set``: VALUE as a number, true/false/none, or a string."""
    name, _, value = text.partition("=")
    low = value.strip().lower()
    if low in ("true", "false"):
        return name.strip(), low == "true"
    if low == "none":
        return name.strip(), None
    try:
        return name.strip(), int(value)
    except ValueError:
        pass
    try:
        return name.strip(), float(value)
    except ValueError:
        return name.strip(), value.strip()


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
    ap.add_argument("--eps", type=float, default=None, help="default: the method's")
    ap.add_argument("--max-iter", type=int, default=3000)
    ap.add_argument("--ftol", type=float, default=0.0,
                    help="practical stop (predicted relative decrease); 0: off")
    ap.add_argument("--tolf", type=float, default=None,
                    help="f-change stop (relative change of f in consecutive serious steps); "
                         "default: the method's, 0: off")
    ap.add_argument("--scale", default=None,
                    help="the variables the method works in (option scale): bounds, none; "
                         "default: the method's")
    ap.add_argument("--only", default=None,
                    help="comma-separated problem names (e.g. 'HS114,Dembo7'): run only these "
                         "problems of the collection, without the extra problems and the QP timing")
    ap.add_argument("--set", action="append", default=[], metavar="OPTION=VALUE",
                    help="any other option of minimize_bundle (repeatable)")
    args = ap.parse_args(argv)

    head = (f"{'problem':<18}{'n':>4}{'f*':>15}{'f found':>17}{'rel err':>10}{'iter':>7}"
            f"{'serious/null':>14}{'evals':>7}{'to f*':>7}{'PBUN':>6}{'PVAR':>6}{'time s':>8}  status")
    extra = dict(_option(s) for s in args.set)
    print(f"bundle method, eps = {args.eps or 'default'}, ftol = {args.ftol:g}, "
          f"tolf = {'default' if args.tolf is None else args.tolf}, "
          f"scale = {args.scale or 'default'}"
          + "".join(f", {k} = {v}" for k, v in extra.items()))
    print(head)
    print("-" * len(head))
    n_ok = 0
    total_t = 0.0
    opts = {"ftol": args.ftol} | ({} if args.tolf is None else {"tolf": args.tolf}) | extra
    opts |= {} if args.scale is None else {"scale": args.scale}
    if args.only:
        names = [s.strip() for s in args.only.split(",") if s.strip()]
        unknown = [s for s in names if s not in PROBLEMS]
        if unknown:
            ap.error(f"unknown problem(s) {', '.join(unknown)}; known: {', '.join(PROBLEMS)}")
        rows = [(PROBLEMS[s], PROBLEMS[s].f_star, args.eps, 1e-6, opts) for s in names]
    else:
        rows = [(p, p.f_star, args.eps, 1e-6, opts) for p in PROBLEMS.values()]
    ours_1_20 = first_1_20 = 0
    if not args.only:
        big = max_quadratics_problem()
        rows.append((big, _socp_value(big), args.eps, 1e-4, opts))
        rows.append((goffin_problem(), 0.0, args.eps, 1e-6, opts))
        lin = max_linear_problem(60)
        rows.append((lin, lin.f_star, 1e-8, 1e-6, {**opts, "gamma": 0.0}))
        rows.append((lin, lin.f_star, args.eps, 1e-6, opts))
    for prob, f_star, eps, goal, options in rows:
        res, dt, first = _run(prob, eps, args.max_iter, f_star, goal, **options)
        total_t += dt
        name = prob.name + (" γ=0" if options.get("gamma") == 0.0 else "")
        if f_star is None:
            err_s, ok = "n/a", res.success
            fs = "n/a"
        else:
            err = abs(res.fun - f_star) / (abs(f_star) if f_star != 0 else 1.0)
            ok = res.success and err <= goal
            err_s, fs = f"{err:.1e}", f"{f_star:.8g}"
        n_ok += ok
        status = ("ok" if ok else "MISSED") + f" ({res.criterion})"
        pb, pv = (published(prob, c) for c in ("PBUN", "PVAR"))
        if prob.group == "unconstrained" and prob.number <= 20:
            ours_1_20 += res.nfev
            first_1_20 += first if first is not None else res.nfev
        print(f"{name:<18}{prob.n:>4}{fs:>15}{res.fun:>17.10g}{err_s:>10}{res.nit:>7}"
              f"{res.n_serious:>8}/{res.n_null:<5}{res.nfev:>7}{first or '–':>7}{pb or '–':>6}{pv or '–':>6}"
              f"{dt:>8.3f}  {status}")
    print("-" * len(head))
    print(f"{n_ok}/{len(rows)} problems reached f* (to 1e-6 where the report tabulates it, relative "
          f"or absolute where f* = 0); total time {total_t:.2f} s")
    pub = {c: sum(PUBLISHED[("unconstrained", c)]) for c in ("PBUN", "PVAR")}
    print(f"evaluations over the unconstrained problems 1–20: {ours_1_20}, of which "
          f"{first_1_20} until f first came within the tolerance of f* (published: PBUN "
          f"{pub['PBUN']}, PVAR {pub['PVAR']})")
    if args.only:
        return
    ours, ref = _qp_timing()
    line = f"direction QP, n = 32 (+ epigraph), 35 cuts, 104 slope rows, box, 1 equality: " \
           f"DAQP {ours * 1e3:.3f} ms"
    if ref is not None:
        line += f", Clarabel {ref * 1e3:.3f} ms, ratio Clarabel/DAQP {ref / ours:.1f}"
    print(line)


if __name__ == "__main__":
    main()
