"""Evaluation cost on bodies from mesh files, against one factorization of their own A.

    python benchmarks/bench_bodies.py [--configs examples/bracket.toml examples/round_pad.toml example1]
                                      [--steps 8]

For each configuration: the mesh (nodes, cells, contact nodes), then the evaluations (state
solve + subgradient) at ``--steps`` designs along a path of small steps as in an optimization
(the first, cold one is reported apart), each as a ratio to one factorization of the same A(α)
by pypardiso's defaults timed in a clean process (benchmarks/_reference.py).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from _reference import clean_factorization
from bench_state import design_path
from contactopt.config import load_config
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient

DEFAULT = ["examples/bracket.toml", "examples/round_pad.toml", "example1"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--configs", nargs="+", default=DEFAULT)
    ap.add_argument("--steps", type=int, default=8)
    args = ap.parse_args()
    print(f"{'body':<12} {'cells':>14} {'nodes':>7} {'contact':>7} {'ref s':>7} {'first':>7} "
          f"{'median':>7} {'worst':>7}  (evaluation / one clean factorization of A)")
    for name in args.configs:
        cfg = load_config(name)
        problem = ShapeProblem(cfg)
        m = problem.model
        a0 = m.initial_design()
        times = []
        for alpha in [a0] + design_path(m, a0, args.steps):
            t0 = time.perf_counter()
            subgradient(problem, alpha)
            times.append(time.perf_counter() - t0)
        ref = clean_factorization(m.assemble(a0).A)
        r = np.array(times) / ref["seconds"]
        print(f"{cfg.name:<12} {m.mesh.n_elements:>7} {m.mesh.cell_type:>6} {m.mesh.n_nodes:>7} {m.n_contact:>7} "
              f"{ref['seconds']:>7.3f} {r[0]:>7.2f} {statistics.median(r[1:]):>7.2f} {r[1:].max():>7.2f}")
    print(f"reference: {ref['what']}")


if __name__ == "__main__":
    main()
