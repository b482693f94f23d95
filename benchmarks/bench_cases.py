"""Cost of load cases: an evaluation with K cases against one with a single case, same designs.

    python benchmarks/bench_cases.py [--config example1] [--steps 10] [--step 5e-4]

Example 1's mesh with its own loads (one case), and with four cases (the paper's loads, the side
traction reversed, halved, and with a shear component) combined by the max and by the sum.
Each problem evaluates Θ and a subgradient at the same designs along a path of small steps, as
in an optimization (each warm-started from its own previous design; the first, cold evaluation
is reported apart), the problems taking turns at every design so that a change of the machine's
load hits all alike. Printed: per problem the median time per evaluation over the warm steps and
its ratio to the single case, with the split into state (assembly, factorization, per-case
condensed loads and contact solves), adjoint and design terms.
"""

from __future__ import annotations

import argparse
import statistics
import time

from bench_state import design_path
from contactopt.config import load_config
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient

CASES = [{"name": "pull", "right_traction": [5e-2, 0.0, 0.0]},
         {"name": "push", "right_traction": [-5e-2, 0.0, 0.0]},
         {"name": "half", "right_traction": [2.5e-2, 0.0, 0.0]},
         {"name": "shear", "right_traction": [5e-2, 2e-2, 0.0]}]


def problems(name: str) -> dict:
    cfg = load_config(name)
    raw = cfg.data.copy()
    top = {"top_traction": raw["loads"]["top_traction"]}
    out = {"1 case": ShapeProblem(cfg)}
    for combine in ("max", "sum"):
        multi = {**raw, "loads": top, "load_cases": CASES, "objective": {**raw["objective"], "combine": combine}}
        out[f"4 cases, {combine}"] = ShapeProblem(load_config(multi))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default="example1")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--step", type=float, default=5e-4)
    args = ap.parse_args()
    probs = problems(args.config)
    m = probs["1 case"].model
    times = {k: [] for k in probs}
    split = {k: [] for k in probs}
    for alpha in [m.initial_design()] + design_path(m, m.initial_design(), args.steps, args.step):
        for name, pr in probs.items():
            t0 = time.perf_counter()
            res = subgradient(pr, alpha)
            times[name].append(time.perf_counter() - t0)
            split[name].append(res.timings)
    print(f"{args.config}: {m.mesh.n_nodes} nodes, {m.n_contact} contact nodes, {args.steps} warm steps of "
          f"{args.step:g} (+ 1 cold)")
    print(f"{'problem':<14} {'cold s':>7} {'median s':>8} {'ratio':>6}   {'state':>6} {'adjoint':>7} {'design':>6}")
    base = statistics.median(times["1 case"][1:])
    for name in probs:
        t = times[name]
        med = statistics.median(t[1:])
        parts = {k: statistics.median(s[k] for s in split[name][1:]) for k in ("state", "adjoint", "design_terms")}
        print(f"{name:<14} {t[0]:>7.3f} {med:>8.3f} {med / base:>6.2f}   {parts['state']:>6.3f} "
              f"{parts['adjoint']:>7.3f} {parts['design_terms']:>6.3f}")


if __name__ == "__main__":
    main()
