"""State-solve and subgradient benchmark on the paper's meshes (DESIGN.md §3–§5).

    python benchmarks/bench_state.py [--meshes example1 example2 fine] [--repeat 3]

For each mesh: assembly of A(α), one full factorization of A (the reference measured in the same
run), the Schur complement S (PARDISO) and its ratio to the factorization, the Delassus inverse,
the contact phase of both methods (newton, fixed-point), interior recovery, the whole state solve
as a ratio to one factorization, a warm-started Newton solve after a small design change, and one
subgradient as a ratio to the state solve. Times are medians over --repeat runs. The run keeps
OpenBLAS sequential, as ShapeProblem does (contactopt._threads).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from contactopt._threads import sequential_openblas
from contactopt.config import load_config
from contactopt.fem.linsolve import condense, factorize
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


def bench(name, repeat, full):
    base, mesh = MESHES[name]
    cfg = load_config(base)
    if mesh:
        cfg = cfg.with_updates({"mesh": mesh})
    pr = ShapeProblem(cfg)
    m = pr.model
    a0 = m.initial_design()
    asm, t_asm = timed(lambda: m.assemble(a0), repeat)
    factorize(asm.A)                                   # warm-up: library load, first analysis
    fac_ref, t_fact = timed(lambda: factorize(asm.A), repeat)
    fac, t_schur = timed(lambda: condense(asm.A, m.contact_dofs), repeat)
    print(f"\n== {name}: {asm.A.shape[0]} DOFs, {m.contact_dofs.size} contact DOFs, backend {fac.backend}")
    print(f"  assembly            {t_asm:8.3f} s")
    print(f"  factorization of A  {t_fact:8.3f} s   (reference)")
    print(f"  Schur complement S  {t_schur:8.3f} s   = {t_schur / t_fact:5.2f} × factorization")
    if not full:
        return
    rows = {}
    for method in ("newton", "fixed-point"):
        def solve():
            pr._cache = None
            pr._warm = None
            return pr.solve_state(a0, method=method)
        try:
            st, t_state = timed(solve, repeat)
        except Exception as exc:  # report and go on with the other method
            print(f"  {method:12s} FAILED: {exc}")
            continue
        rows[method] = (st, t_state)
        tm = st.timings
        print(f"  {method:12s} state {t_state:7.3f} s = {t_state / t_fact:5.2f} × factorization | contact "
              f"{tm['contact']:.3f} s ({st.iterations} it, residual {st.residual:.1e}), Delassus "
              f"{tm['delassus']:.3f} s, recovery {tm['recovery']:.3f} s")
    if "newton" in rows and "fixed-point" in rows:
        ln, lf = rows["newton"][0].lam, rows["fixed-point"][0].lam
        print(f"  newton vs fixed-point: max |Δλ|/max λ = {np.abs(ln - lf).max() / lf.max():.2e}")
    if "newton" in rows:
        pr._cache = None
        pr.solve_state(a0, method="newton")
        d = np.sin(np.arange(m.n_design))
        d -= d.mean()
        st = pr.solve_state(a0 + 1e-4 * d, method="newton")
        print(f"  warm-started newton after a design change of 1e-4: {st.iterations} Newton steps, "
              f"contact {st.timings['contact']:.3f} s")
        pr._cache = None
        st, t_state = timed(lambda: (setattr(pr, "_cache", None), pr.solve_state(a0))[1], 1)
        res, t_sub = timed(lambda: subgradient(pr, a0), repeat)
        print(f"  subgradient          {t_sub:7.3f} s = {t_sub / rows['newton'][1]:5.2f} × state solve "
              f"(adjoint {res.timings['adjoint']:.3f} s, design terms {res.timings['design_terms']:.3f} s)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["example1", "example2", "fine"], choices=list(MESHES))
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    # the whole benchmark, reference included, runs under the thread policy of ShapeProblem
    with sequential_openblas():
        for name in args.meshes:
            bench(name, args.repeat, full=(name != "fine"))


if __name__ == "__main__":
    main()
