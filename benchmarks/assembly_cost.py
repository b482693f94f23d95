"""The cost of an assembly's evaluation against its designed body alone (docs/assemblies.md).

Example 1's block (32 × 15 × 9 cells) designed, once on the rigid plane and once on two elastic
slabs of as many cells each (a pair per slab, non-matching meshes, mortar partners): the slabs are
condensed once per run, so an evaluation (state and subgradient) adds only their coupling with the
block's condensed stiffness. Evaluations of the two problems interleaved at the same designs, one
BLAS thread; prints each problem's set-up, the median evaluation time and their ratio.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/assembly_cost.py [repeats]
"""

import sys
import time

import numpy as np

from contactopt.config import load_config
from contactopt.problem import ShapeProblem

SLABS = """
name = "three_bodies"
[geometry]
a = 2.0
b = 1.0
c = 1.0
[mesh]
nx = 32
ny = 15
nz = 9
[material]
E = 21.19
nu = 0.277
[loads]
top_traction = [0.0, 0.0, -8.0e-2]
right_traction = [5.0e-2, 0.0, 0.0]
[bodies.block]
clamped = "clamped"
[bodies.left]
block = { size = [1.0625, 1.0625, 1.0], cells = [17, 17, 15], origin = [-0.03125, -0.03125] }
clamped = "bottom"
material = { E = 2.119 }
[bodies.right]
block = { size = [1.0, 1.0625, 1.0], cells = [16, 17, 16], origin = [1.03125, -0.03125] }
clamped = "bottom"
material = { E = 2.119 }
[[contacts]]
face = { body = "block", x3 = 0.0, box = [[0.0, 1.01], [0.0, 1.0], [-1.0, 1.0]] }
counterpart = "left.top"
friction = 0.3
[[contacts]]
face = { body = "block", x3 = 0.0, box = [[1.05, 2.0], [0.0, 1.0], [-1.0, 1.0]] }
counterpart = "right.top"
friction = 0.3
[[designs]]
face = "block.contact"
degree = [7, 3]
C0 = 0.75
C1 = 0.5
C2 = 0.01
slope_divisor = "degree"
initial = 0.01
[state]
method = "newton"
tol = 1.0e-12
max_iter = 200
"""


def main(repeats: int = 5) -> None:
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "three_bodies.toml"
        path.write_text(SLABS)
        t0 = time.perf_counter()
        three = ShapeProblem(load_config(path))
        t_three = time.perf_counter() - t0
    t0 = time.perf_counter()
    alone = ShapeProblem(load_config("example1").with_updates({"friction": {"coefficient": 0.3},
                                                                "design": {"C2": 0.01}}))
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
