"""The cost of an assembly's evaluation against its designed body alone (docs/assemblies.md).

Example 1's block (32 × 15 × 9 cells) designed, once on the rigid plane and once on two elastic
slabs of about as many cells each (a pair per slab, non-matching meshes, mortar partners; the model
is examples/block_on_slab.toml with its slab split in two): the slabs are
condensed once per run, so an evaluation (state and subgradient) adds only their coupling with the
block's condensed stiffness. Evaluations of the two problems interleaved at the same designs, one
BLAS thread; prints each problem's set-up, the median evaluation time and their ratio. ``--parts``:
also the median time of each part of an evaluation (designs after the first), by timing the
condensation path's methods, and the zone's nodes and sticking nodes (docs/guide/assemblies.md).

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/assembly_cost.py [repeats] [--parts]
"""

import functools
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
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


PARTS = {"prepare": "assembly, factorization, Schur complement (and before: the coupling)",
         "zone_problem": "the zone's factor", "solve_local": "the zone's Newton solve",
         "adjoint": "the adjoint", "foundation_state": "the counterparts' displacements"}


def timed(acc: dict):
    """Wrap the condensation path's methods of PARTS so that each call adds its time to acc."""
    from contactopt.paths.condensation import CondensationPath
    for name in PARTS:
        f = getattr(CondensationPath, name)

        def g(*a, _f=f, _name=name, **k):
            t = time.perf_counter()
            try:
                return _f(*a, **k)
            finally:
                acc[_name] = acc.get(_name, 0.0) + time.perf_counter() - t
        setattr(CondensationPath, name, functools.wraps(f)(g))


def main(repeats: int = 5, parts: bool = False) -> None:
    acc = {}
    if parts:
        timed(acc)
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
    split = {"three": {}, "alone": {}}
    for i in range(repeats):
        d = rng.standard_normal(a0.size)
        alpha = a0 + 0.003 * (d - d.mean())
        for name, pb in (("alone", alone), ("three", three)):
            pb.clear_cache()
            acc.clear()
            t0 = time.perf_counter()
            pb.evaluate(alpha)
            times[name].append(time.perf_counter() - t0)
            if parts and i:
                for key, v in acc.items():
                    split[name].setdefault(key, []).append(v)
                st = pb.solution(alpha).states[0]
                split[name].setdefault("zone nodes", []).append(st.stats.zone_nodes)
                split[name].setdefault("sticking nodes", []).append(int(np.sum(st.classes == CLASS_CODES["M3+"])))
    ratio = np.array(times["three"]) / np.array(times["alone"])
    print(f"evaluation (state and subgradient), median of {repeats}: three bodies {np.median(times['three']):.3f} s, "
          f"the block alone {np.median(times['alone']):.3f} s; ratio median {np.median(ratio):.3f} "
          f"(min {ratio.min():.3f}, max {ratio.max():.3f})")
    for name, d in split.items() if parts else ():
        print(f"{name}: " + ", ".join(f"{PARTS.get(k, k)} {np.median(v):.3g}" + (" s" if k in PARTS else "")
                                    for k, v in d.items()))


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--parts"]
    main(int(args[0]) if args else 5, parts="--parts" in sys.argv[1:])
