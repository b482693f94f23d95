"""What one evaluation (state solve + subgradient) costs on the condensation path, part by part.

    python benchmarks/bench_evaluation.py [--example example1 example2 example3] [--designs 8] [--step 2e-3]
    python benchmarks/bench_evaluation.py --bt-iter 40 [--example ...] [--zone-schur]

An optimization's evaluations are at nearby designs: the benchmark evaluates the oracle
(``ShapeProblem.evaluate``, Θ and ξ) at α0 and then at ``--designs`` designs α0 + k·step·d along
a fixed volume-preserving direction d, so PARDISO's analysis, the contact zone, the kept Delassus
block and the Newton warm start carry over from design to design as they do in a run. With
``--bt-iter N`` the designs are instead those of the first N iterations of ``minimize_bundle``
on the example (the evaluations of ``contactopt run``, in their order). The parts
are the cumulative times of the functions that do them (cProfile over the evaluations after the
first), printed per evaluation and as ratios to one clean factorization of A(α0) (MKL PARDISO
Cholesky, mtype 2, analysis included), measured in the same process before and after the
evaluations (the median of both sets), because absolute times drift on a shared machine:

* assembly of A(α), L(α) and the gaps (the harmonic morph weight is computed once per model);
* the condensation: PARDISO's numerical factorization of A(α) in Schur-complement mode, which
  returns S (the analysis is reused), and its partial solves for ℓ and the interior recovery u_i;
* the contact zone's dense Cholesky factor of S, the semismooth Newton iterations (the dense
  LU of their 3z × 3z matrices included) and the Delassus block W_Z where it is formed;
* the adjoint (4.15) (the dense LU of its reduced matrix), the A-harmonic extension ṽ, and the
  design terms vᵀ(∂A/∂α u − ∂L/∂α) (element by element, chunked einsums);
* the rest (objective, classification of the nodes, bookkeeping).

``--zone-schur`` also times PARDISO's Schur-mode factorization of the same A(α0) onto the DOFs
of the largest contact zone of the evaluations only (the other contact nodes then count as
interior), against the one onto all contact DOFs that the condensation path does: what a
condensation onto the zone alone would save on this factorization.

The run keeps OpenBLAS sequential, as ShapeProblem does (contactopt._threads); set
MKL_NUM_THREADS=1 for the single-threaded figures of docs/measurements.md.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import time

import numpy as np

from contactopt._threads import sequential_openblas
from contactopt.config import load_config
from contactopt.fem.linsolve import factorize
from contactopt.problem import ShapeProblem

# (label, [(file suffix, function name)]): the functions whose cumulative time is the part
PARTS = [
    ("assembly of A(α), L(α), gaps", [("fem/model.py", "assemble")]),
    ("Schur factorization (PARDISO phase 22)", [("fem/linsolve.py", "refactor")]),
    ("ℓ and interior recovery (331/333)", [("fem/linsolve.py", "condense_load"), ("fem/linsolve.py", "recover")]),
    ("Cholesky of S (contact zone)", [("contact/zone.py", "__init__")]),
    ("Delassus block W_Z", [("contact/zone.py", "W"), ("paths/condensation.py", "own_block")]),
    ("contact Newton iterations", [("contact/newton.py", "solve_newton"), ("contact/local.py", "solve_local")]),
    ("adjoint (4.15)", [("sensitivity/adjoint.py", "solve_adjoint")]),
    ("extension ṽ", [("fem/linsolve.py", "extend")]),
    ("design terms ∂A/∂α u, ∂L/∂α", [("fem/model.py", "design_contraction")]),
]


def reference(A, repeat):
    """Times of clean factorizations of A (analysis included), after one warm-up."""
    factorize(A).close()
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        factorize(A).close()
        out.append(time.perf_counter() - t0)
    return out


def designs(model, a0, n, step, seed=0):
    d = np.random.default_rng(seed).standard_normal(model.n_design)
    d -= d.mean()
    d /= np.abs(d).max()
    return [a0 + (k + 1) * step * d for k in range(n)]


def part_times(stats: pstats.Stats) -> dict:
    """Cumulative seconds per part; a function counted once even if it calls itself, and its calls
    from another function of the same part not again (e.g. the Newton solve inside solve_local)."""
    out = {}
    for label, funcs in PARTS:
        mine = {key for key in stats.stats
                if any(key[0].endswith(suffix) and key[2] == fn for suffix, fn in funcs)}
        total = 0.0
        for key in mine:
            _cc, _nc, _tt, ct, callers = stats.stats[key]
            total += ct - sum(v[3] for caller, v in callers.items() if caller in mine and caller != key)
        out[label] = total
    return out


def zone_schur(A, model, zone, repeat):
    """Seconds of the Schur-mode numerical factorization of A onto the DOFs of the contact nodes
    ``zone`` (analysis done before), median of ``repeat``."""
    import scipy.sparse as sp

    from contactopt.fem import _pardiso
    mask = np.zeros(A.shape[0], dtype=bool)
    mask[np.asarray(model.contact_dofs).reshape(-1, 3)[zone].ravel()] = True
    ps = _pardiso.PardisoSPD(sp.triu(A, format="csr"), schur_mask=mask)
    try:
        ps.analyze()
        ps.factor()
        ts = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            ps.factor()
            ts.append(time.perf_counter() - t0)
        return statistics.median(ts)
    finally:
        ps.close()


def optimizer_designs(pr, a0, n_iter, evaluate):
    """Run ``minimize_bundle`` for ``n_iter`` iterations on the example, each evaluation through
    ``evaluate`` (as ``contactopt run`` scales Θ by Θ(α0))."""
    from contactopt.optimize import minimize_bundle
    opt = pr.config.optimizer
    scale = []

    def oracle(x):
        f, g = evaluate(x)
        if not scale:
            scale.append(f if f > 0 else 1.0)
        return f / scale[0], g / scale[0]

    minimize_bundle(oracle, a0, **pr.model.admissible.constraints(), eps=opt.eps, max_iter=n_iter)


def bench(example, args):
    cfg = load_config(example)
    if args.path:
        cfg = cfg.with_updates({"linear_solver": {"path": args.path}})
    pr = ShapeProblem(cfg)
    m = pr.model
    a0 = m.initial_design()
    A = pr.model.assemble(a0).A
    prof = cProfile.Profile()
    walls, states, clear = [], [], []

    def evaluate(a):
        t0 = time.perf_counter()
        prof.enable()
        out = pr.evaluate(a)
        prof.disable()
        walls.append(time.perf_counter() - t0)
        st = pr.solve_state(a)                   # the cached state of this design
        states.append((st.info.get("zone_nodes", 0), st.iterations, st.info.get("delassus"),
                       np.flatnonzero(st.lam > 0).size))
        clear.append((st.info.get("zone_nodes", 0), st.u_c[:, 2] + st.gap))
        return out

    if args.bt_iter:
        ref = reference(A, args.repeat)
        t0 = time.perf_counter()
        optimizer_designs(pr, a0, args.bt_iter, evaluate)
        t_run = time.perf_counter() - t0
        walls, states = walls[1:], states[1:]     # the first evaluation (analysis, cold start) apart
        first = "the first evaluation (analysis, cold start) excluded"
    else:
        pr.evaluate(a0)                                  # analysis, first zone, first Delassus block
        ref = reference(A, args.repeat)
        for a in designs(m, a0, args.designs, args.step):
            evaluate(a)
        t_run, first = None, "after the one at α0"
    ref += reference(A, args.repeat)
    t_ref = statistics.median(ref)
    n = len(walls)
    per_eval = sum(walls) / n
    stats = pstats.Stats(prof)
    parts = part_times(stats)
    how = (f"the evaluations of {args.bt_iter} bundle iterations" if args.bt_iter
           else f"{n} evaluations at α0 + k·{args.step:g}·d")
    print(f"\n== {example}, {type(pr.path).__name__}: {A.shape[0]} free DOFs, {m.n_contact} contact nodes "
          f"({3 * m.n_contact} contact DOFs), {m.n_design} design variables; {how} ({n}, {first})")
    print(f"reference: one clean PARDISO factorization of A(α0) (analysis included) {t_ref:.3f} s "
          f"(median of {len(ref)}, {min(ref):.3f}–{max(ref):.3f} s)")
    print(f"zone {min(s[0] for s in states)}–{max(s[0] for s in states)} nodes "
          f"(median {statistics.median(s[0] for s in states):g}) "
          f"({min(s[3] for s in states)}–{max(s[3] for s in states)} in contact), "
          f"{statistics.mean(s[1] for s in states):.1f} Newton steps on average, Delassus block "
          f"{sum(s[2] == 'reused' for s in states)} of {n} times reused")
    print(f"{'part':42s} {'s / eval':>9s} {'× ref':>7s} {'share':>6s}")
    for label, t in parts.items():
        print(f"{label:42s} {t / n:9.4f} {t / n / t_ref:7.2f} {t / n / per_eval:6.1%}")
    rest = per_eval - sum(parts.values()) / n
    print(f"{'rest (objective, classes, bookkeeping)':42s} {rest:9.4f} {rest / t_ref:7.2f} {rest / per_eval:6.1%}")
    print(f"{'one evaluation (wall, profiled)':42s} {per_eval:9.4f} {per_eval / t_ref:7.2f}")
    if t_run is not None:
        outside = (t_run - sum(walls) - 0.0) / (n + 1)
        print(f"{'outside the evaluations (bundle step, per it)':42s} {outside:9.4f} {outside / t_ref:7.2f}")
    if args.zone_schur:
        from contactopt.paths.condensation import CondensationPath
        if isinstance(pr.path, CondensationPath):
            t_all = zone_schur(A, m, np.arange(m.n_contact), args.repeat)
            sizes = sorted(z[0] for z in clear)
            out = []
            for size in (sizes[len(sizes) // 2], sizes[-1]):          # the median and the largest zone
                _, clearance = next(z for z in clear if z[0] == size)
                zone = np.sort(np.argsort(clearance, kind="stable")[:size])   # its nodes nearest the foundation
                out.append(f"onto {size} nodes {zone_schur(A, m, zone, args.repeat) / t_ref:.2f} ×")
            print(f"Schur-mode factorization of A(α0) (analysis reused) onto all {m.n_contact} contact nodes "
                  f"{t_all / t_ref:.2f} ×; " + ", ".join(out) + " (a zone's size: median, largest)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--example", nargs="+", default=["example1"])
    ap.add_argument("--designs", type=int, default=8)
    ap.add_argument("--step", type=float, default=2e-3, help="design step (of the largest coefficient)")
    ap.add_argument("--bt-iter", type=int, default=0, help="profile the evaluations of this many bundle iterations")
    ap.add_argument("--repeat", type=int, default=3, help="reference factorizations before and after")
    ap.add_argument("--path", default=None, help="[linear_solver] path instead of the example's (e.g. delassus)")
    ap.add_argument("--zone-schur", action="store_true", help="also time the Schur factorization onto the zone")
    args = ap.parse_args()
    with sequential_openblas():
        for example in args.example:
            bench(example, args)


if __name__ == "__main__":
    main()
