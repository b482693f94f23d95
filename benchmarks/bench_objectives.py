"""What the objectives of the whole displacement add to an evaluation of Θ and its subgradient.

    PYTHONPATH=src python benchmarks/bench_objectives.py [--config example1] [--repeat 5] [--path condensation]

One evaluation = the state solve, the objective, the adjoint (4.15) and the design terms
(:meth:`contactopt.problem.ShapeProblem.subgradient`), the state solved anew each time (the
cache cleared; the warm start of the previous solve of the same design kept, alike for every
objective). The same design is evaluated with the configuration's objective (the baseline) and
with a sum of it and each objective under test (the peak stress over the whole body: its von
Mises stress at every quadrature point, and one more interior solve A_ii⁻¹g_i for the adjoint),
alternating, so that a slow spell of the machine hits both; the ratio of medians is printed.
Results in docs/objectives.md.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from contactopt.config import load_config
from contactopt.problem import ShapeProblem

TERMS = {
    "peak_stress (max)": {"type": "peak_stress"},
    "peak_stress (ks)": {"type": "peak_stress", "aggregate": "ks", "rho": 20.0},
    "frictional_dissipation": {"type": "frictional_dissipation"},
    "max_pressure": {"type": "max_pressure"},
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="example1")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--path", default="condensation")
    args = ap.parse_args(argv)
    base_cfg = load_config(args.config).with_updates({"linear_solver": {"path": args.path}})
    base_obj = {k: v for k, v in base_cfg["objective"].items() if k in ("type", "target", "scale")}
    problems = {"baseline": ShapeProblem(base_cfg)}
    for name, term in TERMS.items():
        terms = [{**base_obj, "weight": 1.0}, {**term, "weight": 1.0}]
        terms[0].pop("scale", None)
        problems[name] = ShapeProblem(base_cfg.with_updates({"objective": {"type": "sum", "terms": terms}}))
    model = problems["baseline"].model
    alpha = model.initial_design() + 0.002 * np.sin(np.arange(model.n_design))
    alpha += 0.01 - alpha.mean()
    times = {k: [] for k in problems}
    parts = {k: [] for k in problems}
    for pr in problems.values():                   # the first solve (analysis, cold start) is not timed
        pr.subgradient(alpha)
    for _ in range(args.repeat):
        for name, pr in problems.items():
            pr.clear_cache()
            t0 = time.perf_counter()
            res = pr.subgradient(alpha)
            times[name].append(time.perf_counter() - t0)
            parts[name].append(res.timings)
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"{args.config} on the {problems['baseline'].path.name} path: {model.assembler.n_free} free DOFs, "
          f"{len(model.body.reference.cells)} elements, {model.n_contact} contact nodes; median of {args.repeat}")
    print("| objective | evaluation s | ratio to the baseline | state s | adjoint s | design terms s |")
    print("|---|---|---|---|---|---|")
    for name in problems:
        p = {k: statistics.median(t[k] for t in parts[name]) for k in ("state", "adjoint", "design_terms")}
        label = name if name == "baseline" else f"baseline + {name}"
        print(f"| {label} | {med[name]:.3f} | {med[name] / med['baseline']:.3f} | {p['state']:.3f} | "
              f"{p['adjoint']:.3f} | {p['design_terms']:.3f} |")


if __name__ == "__main__":
    main()
