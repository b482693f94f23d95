"""Lamé's shrink fit at scale on the full-space path: the quarter hub on an elastic quarter shaft
of its material (contactopt.verification.lame, plane strain, frictionless, symmetry planes through
both), the shaft's mesh coarser around than the hub's (meshes that do not match), mortar partners.

    python benchmarks/press_fit_scale.py [--hub NR NT] [--path fullspace]

Prints the DOFs of both bodies, the contact pressure's rms and largest deviation from Lamé's
p = E δ (c² − b²) / (2 (1 − ν²) b c²), the set-up and state times, Newton steps and Krylov
iterations, and the peak RSS (one BLAS thread)."""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time

import numpy as np

from contactopt.config import validate
from contactopt.problem import ShapeProblem
from contactopt.verification import lame


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hub", nargs=2, type=int, default=[96, 384], metavar=("NR", "NT"))
    ap.add_argument("--path", default="fullspace", choices=("fullspace", "condensation"))
    ap.add_argument("--partner", default="mortar", choices=("mortar", "point"))
    args = ap.parse_args(argv)
    nr, nt = args.hub
    ns = 3 * nt // 4                                    # the shaft coarser around: meshes that do not match
    with tempfile.TemporaryDirectory() as d:
        hub = lame.quarter_hub_mesh(f"{d}/hub.msh", nr, nt, 1)
        shaft = lame.quarter_shaft_mesh(f"{d}/shaft.msh", 3 * nr // 4, ns, 1, radius=lame.B + lame.DELTA)
        cfg = lame.shaft_config(hub, shaft)
        cfg["foundation"]["partner"] = args.partner
        cfg["linear_solver"] = {"path": args.path, "memory_check": False}
        t0 = time.perf_counter()
        pb = ShapeProblem(validate(cfg, "lame"))
        t1 = time.perf_counter()
        _, pm, st = lame.contact_pressure(pb)
        t2 = time.perf_counter()
    e = pm / lame.pressure_equal_materials() - 1
    n_hub, n_shaft = pb.model.assembler.n_free, pb.model.foundation.assembler.n_free
    print(f"| {nr} × {nt} | {ns} | {n_hub:,} + {n_shaft:,} | {pm.size} | {np.sqrt(np.mean(e ** 2)):.2e} | "
          f"{np.abs(e).max():.2e} | {t1 - t0:.1f} | {t2 - t1:.1f} | {st.iterations} | "
          f"{st.info.get('krylov_iterations')} | {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20:.2f} |")


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
