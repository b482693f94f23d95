"""Cost of a load path: one evaluation (Θ, ξ) of Example 1 (mesh 32×15×9, condensation path) as
the static problem, as a 2-step path (press, then the side traction) and as 8 solves (the same
two steps in 4 substeps each). The configurations evaluate the same designs, interleaved (the
first one a warm-up), forwards and backwards; the ratios are of the mean time per evaluation.

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


def timed(problems, designs, rounds=2):
    """Mean seconds per evaluation of each problem, the problems interleaved design by design (and
    the sequence run ``rounds`` times) so that the machine's load drifts alike over all of them."""
    for pr in problems.values():
        pr.evaluate(designs[0])
    spent = dict.fromkeys(problems, 0.0)
    for _ in range(rounds):
        for a in designs[1:]:
            for k, pr in problems.items():
                t0 = time.perf_counter()
                pr.evaluate(a)
                spent[k] += time.perf_counter() - t0
        designs = designs[::-1]
    return {k: t / (rounds * (len(designs) - 1)) for k, t in spent.items()}


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
    times = timed(problems, designs)
    print("| evaluation | s per evaluation | ratio to static |")
    print("|---|---|---|")
    for k, t in times.items():
        print(f"| {k} | {t:.3f} | {t / times['static']:.2f} |")


if __name__ == "__main__":
    main()
