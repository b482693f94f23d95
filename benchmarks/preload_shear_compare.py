"""examples/preload_shear.toml optimized on its load path and on the same final loads applied in
one step; each optimum evaluated on both loadings (docs/load_paths.md).

    PYTHONPATH=src python benchmarks/preload_shear_compare.py [outdir]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization


def main(outdir: Path):
    path_cfg = load_config("examples/preload_shear.toml")
    once = path_cfg.data | {"name": "preload_shear_once", "load_steps": path_cfg.data["load_steps"][1:]}
    once_cfg = load_config(once)
    runs = {}
    for label, cfg in (("path", path_cfg), ("one step", once_cfg)):
        rr = run_optimization(cfg, outdir / cfg.name, overwrite=True)
        runs[label] = (np.asarray(rr.summary["alpha"]).ravel(), rr.summary)
    problems = {"path": ShapeProblem(path_cfg), "one step": ShapeProblem(once_cfg)}
    print("| optimum of | Θ on the path (press, then shear) | Θ in one step | stick nodes (path) | stick nodes (one step) |")
    print("|---|---|---|---|---|")
    rows = {}
    for label, (alpha, _) in runs.items():
        vals, sticks = [], []
        for pr in problems.values():
            vals.append(pr.evaluate_value(alpha))
            st = pr.solve_state(alpha)
            sticks.append(int(st.counts["M3+"] + st.counts["M3-"]))
        rows[label] = vals
        print(f"| {label} | {vals[0]:.4e} | {vals[1]:.4e} | {sticks[0]} | {sticks[1]} |")
    (outdir / "compare.json").write_text(json.dumps({k: v for k, v in rows.items()}, indent=1))


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "runs/preload_shear_compare"))
