"""A counterpart held only by its contacts on the full-space path (docs/foundation.md, "A counterpart
held only by its contacts"): the cost of its anchor against the same model with the body clamped.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/floating_fullspace.py [--refine 1 2 3]

examples/block_two_slabs.toml (its first design only) with the right slab clamped at its bottom
(``held``) or along x3 only (``floating``: friction holds its translations along x1, x2 and its
rotation about x3), every mesh refined ``--refine`` times (the pairs' faces over each slab alone), state tolerance
1e-12. Each model is
evaluated (state and subgradient) at α0 (cold), α1 = α0 + h d and α2 = α0 + 2h d (warm, as in a
run); per evaluation: the Newton steps, the Krylov iterations of the state and the adjoint, the
anchored solves and the seconds, with the floating model's time over the held one's of the same
refinement. ``floating, anchor only`` runs the anchor's iteration β ← Nᵀu to its end
(contactopt.paths.floating) without the unanchored Newton steps that follow the first anchored
solve by default.
"""

from __future__ import annotations

import argparse
import time
import tomllib
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.paths import fullspace
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]
HELD = 'clamped = "bottom"\nmaterial = { E = 6.0'
FLOATING = 'clamped = { on = "bottom", components = [3] }\nmaterial = { E = 6.0'


def model(k: int, floating: bool) -> ShapeProblem:
    text = (ROOT / "examples" / "block_two_slabs.toml").read_text()
    text = text[:text.rindex("[[designs]]")]                  # the design over the left slab
    if floating:
        text = text.replace(HELD, FLOATING)
    # the faces over each slab alone (refined, the block has nodes above the gap 1 < x1 < 1.25)
    text = text.replace("[[0.0, 1.1]", "[[0.0, 1.01]").replace("[[1.1, 2.0]", "[[1.24, 2.0]")
    data = tomllib.loads(text)
    data["mesh"] = {"nx": 8 * k, "ny": 4 * k, "nz": 4 * k}
    data["bodies"]["left"]["block"]["cells"] = [6 * k, 8 * k, 2 * k]
    data["bodies"]["right"]["block"]["cells"] = [5 * k, 8 * k, 3 * k]
    data["linear_solver"] = {"path": "fullspace"}
    data["state"] = {"tol": 1e-12}
    return ShapeProblem(load_config(data))


def evaluations(pb: ShapeProblem, h: float = 2e-3) -> list:
    a0 = pb.model.initial_design()
    d = np.cos(np.arange(a0.size))
    out = []
    for alpha in (a0, a0 + h * d, a0 + 2 * h * d):
        t0 = time.perf_counter()
        pb.evaluate(alpha)
        seconds = time.perf_counter() - t0
        st = pb.solve_state(alpha)
        out.append({"newton": st.iterations, "krylov": st.stats.krylov_iterations,
                    "adjoint": st.stats.adjoint_krylov, "anchored": st.rigid.iterations if st.rigid else 0,
                    "seconds": seconds, "dofs": pb.path.n_unknowns})
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--refine", nargs="+", type=int, default=[1, 2, 3])
    args = ap.parse_args(argv)
    print(f"{'model':<24} {'DOFs':>7} {'at':>3} {'Newton':>6} {'Krylov':>6} {'adjoint':>7} {'anchored':>8} "
          f"{'s':>7} {'/held':>6}")
    saved = fullspace.FREE_NEWTON_STEPS
    for k in args.refine:
        held = None
        for name, floating, free_steps in (("held", False, saved), ("floating", True, saved),
                                           ("floating, anchor only", True, 0)):
            fullspace.FREE_NEWTON_STEPS = free_steps
            try:
                rows = evaluations(model(k, floating))
            finally:
                fullspace.FREE_NEWTON_STEPS = saved
            held = rows if held is None else held
            for j, (r, ref) in enumerate(zip(rows, held)):
                print(f"{name:<24} {r['dofs']:>7} {'α' + str(j):>3} {r['newton']:>6} {r['krylov']:>6} {r['adjoint']:>7} "
                      f"{r['anchored']:>8} {r['seconds']:>7.2f} {r['seconds'] / ref['seconds']:>6.2f}")


if __name__ == "__main__":
    main()
