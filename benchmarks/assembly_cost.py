"""The cost of an assembly's evaluation against its designed body alone (docs/assemblies.md).

Example 1's block (32 × 15 × 9 cells) designed, once on the rigid plane and once on two elastic
slabs of about as many cells each (a pair per slab, non-matching meshes, mortar partners; the model
is examples/block_on_slab.toml with its slab split in two): the slabs are
condensed once per run, so an evaluation (state and subgradient) adds only their coupling with the
block's condensed stiffness. Evaluations of the two problems interleaved at the same designs, one
BLAS thread; prints each problem's set-up, the median evaluation time and their ratio.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/assembly_cost.py [repeats]
"""

import sys
import time
import tomllib
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]


def three_bodies() -> dict:
    """examples/block_on_slab.toml with its slab split in two, a pair each (friction 0.3, the
    partners chosen by 'auto'), the block's face designed as there."""
    data = tomllib.loads((ROOT / "examples" / "block_on_slab.toml").read_text())
    slab = data["bodies"].pop("slab")
    data["bodies"]["left"] = {**slab, "block": {"size": [1.0625, 1.0625, 1.0], "cells": [17, 17, 15],
                                                "origin": [-0.03125, -0.03125]}}
    data["bodies"]["right"] = {**slab, "block": {"size": [1.0, 1.0625, 1.0], "cells": [16, 17, 16],
                                                 "origin": [1.03125, -0.03125]}}
    face = {"body": "block", "x3": 0.0}
    data["contacts"] = [
        {"face": {**face, "box": [[0.0, 1.01], [0.0, 1.0], [-1.0, 1.0]]}, "counterpart": "left.top", "friction": 0.3},
        {"face": {**face, "box": [[1.05, 2.0], [0.0, 1.0], [-1.0, 1.0]]}, "counterpart": "right.top", "friction": 0.3}]
    return data


def main(repeats: int = 5) -> None:
    t0 = time.perf_counter()
    three = ShapeProblem(load_config(three_bodies()))
    t_three = time.perf_counter() - t0
    t0 = time.perf_counter()
    alone = ShapeProblem(load_config("example1").with_updates({"friction": {"coefficient": 0.3}}))
    t_alone = time.perf_counter() - t0
    m = three.model
    print(f"block {m.assembler.n_free} free DOFs, {m.n_contact} contact nodes; slabs "
          + ", ".join(f"{f.assembler.n_free} free DOFs ({f.partner})" for f in m.foundation.parts))
    print(f"set-up: three bodies {t_three:.2f} s, the block alone {t_alone:.2f} s")
    rng = np.random.default_rng(0)
    a0 = m.initial_design()
    times = {"three": [], "alone": []}
    for _ in range(repeats):
        d = rng.standard_normal(a0.size)
        alpha = a0 + 0.003 * (d - d.mean())
        for name, pb in (("alone", alone), ("three", three)):
            pb.clear_cache()
            t0 = time.perf_counter()
            pb.evaluate(alpha)
            times[name].append(time.perf_counter() - t0)
    ratio = np.array(times["three"]) / np.array(times["alone"])
    print(f"evaluation (state and subgradient), median of {repeats}: three bodies {np.median(times['three']):.3f} s, "
          f"the block alone {np.median(times['alone']):.3f} s; ratio median {np.median(ratio):.3f} "
          f"(min {ratio.min():.3f}, max {ratio.max():.3f})")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
