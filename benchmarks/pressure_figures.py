"""Nodal contact forces λ against the contact pressure p = λ/a at the optimal designs of the round
pad and the bracket (issue #24): docs/figures/pressure_<name>.png and a roughness ratio.

    PYTHONPATH=src python benchmarks/pressure_figures.py [--runs DIR] [--out docs/figures]

Optimizes both examples (or reuses DIR/<name> when it holds a finished run) and prints, for each,
the roughness of λ and of p: the mean over the contact face's edges between two loaded nodes of
|f_i − f_j| / mean(f) — how much a field jumps from a node to its neighbour.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.io.plots import plot_force_and_pressure
from contactopt.io.pressure import contact_pressure
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization

ROOT = Path(__file__).resolve().parent.parent


def roughness(model, values) -> float:
    faces = np.asarray(model.body.contact_face.faces)
    nc = 4 if faces.shape[1] == 4 else 3
    index = np.full(model.mesh.n_nodes, -1)
    index[model.contact_nodes] = np.arange(model.n_contact)
    e = np.unique(np.sort(np.concatenate([faces[:, [k, (k + 1) % nc]] for k in range(nc)]), axis=1), axis=0)
    e = index[e]
    e = e[np.all(e >= 0, axis=1)]
    v = np.asarray(values, float)
    loaded = (v[e[:, 0]] > 0) & (v[e[:, 1]] > 0)
    e = e[loaded]
    return float(np.mean(np.abs(v[e[:, 0]] - v[e[:, 1]])) / np.mean(v[v > 0]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="runs", help="directory of the runs (reused when finished)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    args = ap.parse_args()
    for name in ("round_pad", "bracket"):
        run = Path(args.runs) / name
        if not (run / "summary.json").is_file():
            run_optimization(ROOT / "examples" / f"{name}.toml", run, overwrite=True)
        alpha = np.asarray(json.loads((run / "alpha.json").read_text())["alpha"], float).ravel()
        problem = ShapeProblem(load_config(ROOT / "examples" / f"{name}.toml"))
        st = problem.solve_state(alpha)
        p = contact_pressure(problem.model, st.lam, st.coords)
        path = plot_force_and_pressure(Path(args.out) / f"pressure_{name}.png", problem.model, st.lam, p,
                                       title=f"{name}: optimal design ({problem.model.mesh.cell_type} mesh)")
        print(f"{name}: roughness of lambda {roughness(problem.model, st.lam):.3f}, of p "
              f"{roughness(problem.model, p):.3f}; p in [{p[p > 0].min():.4g}, {p.max():.4g}]; {path}")


if __name__ == "__main__":
    main()
