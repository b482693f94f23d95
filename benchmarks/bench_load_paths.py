"""Cost of a load path: one evaluation (Θ, ξ) of Example 1 (mesh 32×15×9, condensation path) as
the static problem, as a 2-step path (press, then the side traction) and as 8 solves (the same
two steps in 4 substeps each). Each configuration evaluates the same sequence of designs (the
first one a warm-up); the ratios are of the mean time per evaluation, measured in one run.

    PYTHONPATH=src python benchmarks/bench_load_paths.py
"""

from __future__ import annotations

import time

import numpy as np

from contactopt.config import load_config
from contactopt.problem import ShapeProblem

TOP, SIDE = [0.0, 0.0, -8e-2], [5e-2, 0.0, 0.0]


def problem(steps):
    base = load_config("example1").data
    if steps is None:
        return ShapeProblem(load_config(base))
    data = {**base, "loads": {**base["loads"], "top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
            "load_steps": steps}
    return ShapeProblem(load_config(data))


def timed(pr, designs):
    pr.evaluate(designs[0])
    t0 = time.perf_counter()
    for a in designs[1:]:
        pr.evaluate(a)
    return (time.perf_counter() - t0) / (len(designs) - 1)


def main():
    variants = {"static": None,
                "2 steps": [{"name": "press", "top_traction": TOP},
                            {"name": "shear", "top_traction": TOP, "right_traction": SIDE}],
                "8 solves": [{"name": "press", "top_traction": TOP, "substeps": 4},
                             {"name": "shear", "top_traction": TOP, "right_traction": SIDE, "substeps": 4}]}
    problems = {k: problem(v) for k, v in variants.items()}
    a0 = problems["static"].model.initial_design()
    rng = np.random.default_rng(0)
    designs = [a0 + 0.002 * k * rng.random(a0.size) for k in range(6)]
    times = {k: timed(pr, designs) for k, pr in problems.items()}
    print("| evaluation | s per evaluation | ratio to static |")
    print("|---|---|---|")
    for k, t in times.items():
        print(f"| {k} | {t:.3f} | {t / times['static']:.2f} |")


if __name__ == "__main__":
    main()
