"""The contact pressure along the roller's axis (the contact line x2 = 0 of
examples/roller_rigid.toml) at the initial design and at a run's optimum.

    contactopt run examples/roller_rigid.toml --out runs/roller
    python benchmarks/roller_pressure.py runs/roller

Prints x1 and p = λ/a (the lumped contact area a of each node on the design's surface) at every
node of the line, from the mid-plane x1 = 0 to the roller's end x1 = 10, and the peak of each.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from contactopt.io.pressure import contact_pressure
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    run = Path(argv[0]) if argv else None
    problem = ShapeProblem(str(ROOT / "examples" / "roller_rigid.toml"))
    model = problem.model
    designs = {"initial": model.initial_design()}
    if run is not None:
        designs["optimal"] = np.asarray(json.loads((run / "alpha.json").read_text())["alpha"], float).ravel()
    cols = {}
    for name, alpha in designs.items():
        state = problem.solve_state(alpha, warm_start=False)
        p = contact_pressure(model, state.lam, state.coords)
        xc = state.coords[model.contact_nodes]
        cols[name] = (p, xc)
    p0, xc = cols["initial"]
    on_line = np.flatnonzero(np.abs(xc[:, 1]) < 1e-9)
    order = on_line[np.argsort(xc[on_line, 0])]
    print("x1       " + "  ".join(f"p_{n:8s}" for n in cols))
    for m in order:
        print(f"{xc[m, 0]:7.3f}  " + "  ".join(f"{cols[n][0][m]:.4e}" for n in cols))
    for n, (p, _) in cols.items():
        print(f"peak {n}: {p.max():.4e} at x1 = {xc[int(np.argmax(p)), 0]:.3f}, x2 = {xc[int(np.argmax(p)), 1]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
