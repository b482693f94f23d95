"""State-solve and subgradient benchmark on the paper's meshes.

    python benchmarks/bench_state.py [--meshes example1 example2] [--repeat 5] [--bt-iter 40]

Every time is also printed as a ratio to one factorization of A (ordering, analysis and
numerical factorization, MKL PARDISO) measured in the same run, because absolute times drift on
a shared machine. The next-design and in-optimization ratios are per solve: each state solve is
followed by one factorization of its own A, timed as its reference (``paired_factorization``),
so that a slow spell of the machine affects both. For each mesh:

* the parts: assembly of A(α), the Schur complement S onto all contact nodes (fresh, and with
  the analysis reused), the whole Delassus inverse S⁻¹ (for comparison: a state solve forms only
  the zone's block, :mod:`contactopt.contact.zone`);
* **first solve**: a new ShapeProblem solving α0 (PARDISO analysis included, zone = all contact
  nodes, cold contact start);
* **next design**: the whole state solve at a new design, the analysis and the zone planned at
  the previous design kept, both methods, cold contact start and (Newton) warm start;
* **in an optimization**: the state solves of ``--bt-iter`` bundle-trust iterations on the
  example (the real oracle), zone misses included: median, mean and worst state solve, and the
  subgradient cost;
* agreement of the two methods, and of a zone solve (started from a deliberately small zone, so
  that it misses) with a solve on all contact nodes.

Times are medians over --repeat runs. The run keeps OpenBLAS sequential, as ShapeProblem does
(contactopt._threads).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from contactopt._threads import sequential_openblas
from contactopt.config import load_config
from contactopt.fem.dense import spd_inverse
from contactopt.fem.linsolve import condense, factorize
from contactopt.optimize import minimize_bundle
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient

MESHES = {"example1": ("example1", None), "example2": ("example2", None),
          "fine": ("example1", {"nx": 64, "ny": 30, "nz": 18})}


def timed(fn, repeat):
    out, ts = None, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return out, statistics.median(ts)


def design_path(model, a0, n, step=2e-4, seed=0):
    """n designs a0 + k·step·d along a volume-preserving direction (small BT-like steps)."""
    d = np.random.default_rng(seed).standard_normal(model.n_design)
    d -= d.mean()
    d /= np.abs(d).max()
    return [a0 + (k + 1) * step * d for k in range(n)]


def parts(name, pr, a0, repeat):
    m = pr.model
    asm, t_asm = timed(lambda: m.assemble(a0), repeat)
    factorize(asm.A).close()                      # warm-up: library load, first analysis
    ref, t_fact = timed(lambda: factorize(asm.A), repeat)
    ref.close()
    fac, t_schur = timed(lambda: condense(asm.A, m.contact_dofs), repeat)
    _, t_refac = timed(lambda: fac.refactor(asm.A), repeat)
    _, t_inv = timed(lambda: spd_inverse(fac.S), repeat)
    fac.close()
    print(f"\n== {name}: {asm.A.shape[0]} DOFs, {m.n_contact} contact nodes, backend {fac.backend}")
    print(f"  factorization of A     {t_fact:7.3f} s   (reference, analysis included)")
    print(f"  assembly               {t_asm:7.3f} s = {t_asm / t_fact:5.2f} ×")
    print(f"  Schur, all contacts    {t_schur:7.3f} s = {t_schur / t_fact:5.2f} ×   "
          f"(analysis reused: {t_refac:.3f} s = {t_refac / t_fact:.2f} ×)")
    print(f"  Delassus inverse, all  {t_inv:7.3f} s = {t_inv / t_fact:5.2f} ×")
    return t_fact


def paired_factorization(pr, alpha):
    """Time of one factorization of A(α) (analysis included), taken right after a state solve at
    α: on a shared machine whose speed drifts, each solve gets a reference measured under the
    same conditions, and the ratios are per solve."""
    A = pr.cached_condensed(alpha).assembled.A
    t0 = time.perf_counter()
    factorize(A).close()
    return time.perf_counter() - t0


def first_solve(cfg, a0, t_fact, repeat):
    def run():
        pr = ShapeProblem(cfg)
        return pr.solve_state(a0)
    st, t = timed(run, repeat)
    tm = st.timings
    print(f"  first solve (new problem, all {st.info['zone_nodes']} nodes, analysis included) "
          f"{t:7.3f} s = {t / t_fact:5.2f} × | Schur {tm['schur']:.3f}, Delassus {tm['delassus']:.3f}, "
          f"contact {tm['contact']:.3f} ({st.iterations} it)")


def next_design(cfg, a0, repeat):
    rows = {}
    for method in ("newton", "fixed-point"):
        for warm in ((True, False) if method == "newton" else (False,)):
            pr = ShapeProblem(cfg, method=method)
            pr.solve_state(a0)                       # plans the zone
            pr.solve_state(design_path(pr.model, a0, 1, seed=7)[0])   # settles it
            path = design_path(pr.model, a0, repeat, seed=1)
            ts, ratios, st = [], [], None
            for a in path:
                t0 = time.perf_counter()
                st = pr.solve_state(a, warm_start=warm)
                ts.append(time.perf_counter() - t0)
                ratios.append(ts[-1] / paired_factorization(pr, a))
            t = statistics.median(ts)
            tm = st.timings
            label = f"{method}{' warm' if warm else ' cold'}"
            print(f"  next design, {label:16s} {t:7.3f} s = {statistics.median(ratios):5.2f} × "
                  f"(max {max(ratios):.2f} ×) | zone {st.info['zone_nodes']} "
                  f"nodes, {pr.path.n_zone_misses} misses | assembly {tm['assembly']:.3f}, "
                  f"Schur {tm['schur']:.3f}, Delassus {tm['delassus']:.3f}, contact {tm['contact']:.3f} "
                  f"({st.iterations} it, residual {st.residual:.1e}), recovery {tm['recovery']:.3f}")
            rows[label] = (pr, st, t)
    return rows


def small_change(cfg, a0):
    """The issue's warm-start figure: Newton steps after a design change of 1e-4 (and 1e-5, 5e-4)."""
    out = []
    for h in (1e-5, 1e-4, 5e-4):
        pr = ShapeProblem(cfg)
        pr.solve_state(a0)
        d = np.sin(np.arange(pr.model.n_design))
        d -= d.mean()
        st = pr.solve_state(a0 + h * d)
        out.append(f"{h:g}: {st.iterations}")
    print("  warm-started Newton steps after a design change of " + ", ".join(out))


def agreement(cfg, a0):
    designs = [a0] + design_path(ShapeProblem(cfg).model, a0, 2, step=2e-3, seed=3)
    worst_m, worst_z = 0.0, 0.0
    for a in designs:
        sn = ShapeProblem(cfg, method="newton").solve_state(a)
        sf = ShapeProblem(cfg, method="fixed-point").solve_state(a)
        full = ShapeProblem(cfg.with_updates({"state": {"zone": False}}))
        zone = ShapeProblem(cfg)
        zone.next_zone = np.flatnonzero(sn.lam > 0)          # force a small zone, so misses occur
        s_full, s_zone = full.solve_state(a), zone.solve_state(a)
        worst_m = max(worst_m, np.abs(sn.lam - sf.lam).max() / sf.lam.max())
        worst_z = max(worst_z, np.abs(s_full.lam - s_zone.lam).max() / s_full.lam.max(),
                      np.abs(s_full.u - s_zone.u).max() / np.abs(s_full.u).max())
    print(f"  newton vs fixed-point: max |Δλ|/max λ = {worst_m:.2e}; zone vs all contact nodes: "
          f"max relative difference of λ, u = {worst_z:.2e} ({len(designs)} designs)")


def in_optimization(cfg, n_iter):
    pr = ShapeProblem(cfg)
    model = pr.model
    a0 = model.initial_design()
    states, subs = [], []
    scale = [None]

    def oracle(x):
        t0 = time.perf_counter()
        st = pr.solve_state(x)
        t1 = time.perf_counter()
        res = subgradient(pr, x)
        t2 = time.perf_counter()
        states.append((t1 - t0, st.info["zone_nodes"], st.info["zone_misses"],
                       (t1 - t0) / paired_factorization(pr, x), st.info["delassus"] == "reused",
                       st.iterations))
        subs.append(t2 - t1)
        if scale[0] is None:
            scale[0] = res.value
        return res.value / scale[0], res.gradient / scale[0]

    t0 = time.perf_counter()
    res = minimize_bundle(oracle, a0, **model.admissible.constraints(), eps=1e-12, max_iter=n_iter)
    wall = time.perf_counter() - t0
    t = np.array([s[0] for s in states[1:]])        # the first solve is reported above
    ratio = np.array([s[3] for s in states[1:]])
    zones = [s[1] for s in states]
    print(f"  in an optimization ({res.nit} BT iterations, {len(states)} evaluations, J/J0 = {res.fun:.3g}): "
          f"state solve median {np.median(t):.3f} s, ratio to the paired factorization: median "
          f"{np.median(ratio):.2f} ×, mean {ratio.mean():.2f} ×, 90th percentile "
          f"{np.percentile(ratio, 90):.2f} ×, worst {ratio.max():.2f} × | "
          f"Delassus block reused in {sum(s[4] for s in states)} of {len(states)} solves, "
          f"{np.mean([s[5] for s in states]):.1f} Newton steps on average | "
          f"{pr.path.n_zone_misses} zone misses, zone {min(zones)}–{max(zones)} of "
          f"{model.n_contact} nodes | subgradient median {np.median(subs):.3f} s = "
          f"{np.median(subs) / np.median(t):.2f} × state solve | {wall:.1f} s in all")
    return t


def bench(name, repeat, bt_iter):
    base, mesh = MESHES[name]
    cfg = load_config(base)
    if mesh:
        cfg = cfg.with_updates({"mesh": mesh})
    pr = ShapeProblem(cfg)
    a0 = pr.model.initial_design()
    t_fact = parts(name, pr, a0, repeat)
    if name == "fine":
        return
    first_solve(cfg, a0, t_fact, repeat)
    next_design(cfg, a0, repeat)
    small_change(cfg, a0)
    agreement(cfg, a0)
    if bt_iter:
        in_optimization(cfg, bt_iter)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["example1", "example2"], choices=list(MESHES))
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--bt-iter", type=int, default=40, help="BT iterations of the in-situ measurement (0: skip)")
    args = ap.parse_args()
    # the whole benchmark, reference included, runs under the thread policy of ShapeProblem
    with sequential_openblas():
        for name in args.meshes:
            bench(name, args.repeat, args.bt_iter)


if __name__ == "__main__":
    main()
