"""The optimal contact surface on the elastic foundation beside the rigid-foundation optimum.

    contactopt run example1 --out runs/example1
    contactopt run examples/example1_elastic.toml --out runs/example1_elastic
    python benchmarks/foundation_figure.py runs/example1 runs/example1_elastic docs/figures/foundation_surfaces.png

Reads each run's surface.csv (ϑ_α on the contact face's grid) and summary.json; draws both
surfaces as contour maps on one colour scale, their difference, and a cut along x2 at mid-width.
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def surface(run: Path):
    data = np.loadtxt(run / "surface.csv", delimiter=",", skiprows=1)
    x1, x2 = np.unique(data[:, 0]), np.unique(data[:, 1])
    theta = np.full((x2.size, x1.size), np.nan)
    theta[np.searchsorted(x2, data[:, 1]), np.searchsorted(x1, data[:, 0])] = data[:, 2]
    return x1, x2, theta, json.loads((run / "summary.json").read_text())


def main(rigid: str, elastic: str, out: str) -> None:
    x1, x2, t_r, s_r = surface(Path(rigid))
    y1, y2, t_e, s_e = surface(Path(elastic))
    if not (np.array_equal(x1, y1) and np.array_equal(x2, y2)):
        raise SystemExit("the two runs' surfaces are on different grids")
    lo, hi = min(np.nanmin(t_r), np.nanmin(t_e)), max(np.nanmax(t_r), np.nanmax(t_e))
    fig, ax = plt.subplots(1, 4, figsize=(19, 4.2), layout="constrained")
    for a, t, title, s in ((ax[0], t_r, "rigid foundation", s_r), (ax[1], t_e, "elastic foundation", s_e)):
        c = a.contourf(x1, x2, t, levels=np.linspace(lo, hi, 21), cmap="viridis")
        a.set_title(f"{title}: J/J0 = {s['J'] / s['J0']:.3g}", fontsize=9)
        a.set_aspect("equal")
        a.set_xlabel("$x_1$")
    ax[0].set_ylabel("$x_2$")
    fig.colorbar(c, ax=ax[:2], label=r"$\vartheta_\alpha$", shrink=0.8)
    d = t_e - t_r
    m = np.nanmax(np.abs(d))
    c = ax[2].contourf(x1, x2, d, levels=np.linspace(-m, m, 21), cmap="RdBu_r")
    ax[2].set_title("elastic − rigid", fontsize=9)
    ax[2].set_aspect("equal")
    ax[2].set_xlabel("$x_1$")
    fig.colorbar(c, ax=ax[2], shrink=0.8)
    j = x2.size // 2
    ax[3].plot(x1, t_r[j], label="rigid")
    ax[3].plot(x1, t_e[j], label="elastic")
    ax[3].set_title(f"cut at $x_2$ = {x2[j]:.3g}", fontsize=9)
    ax[3].set_xlabel("$x_1$")
    ax[3].legend(fontsize=8)
    fig.savefig(out, dpi=130, bbox_inches="tight")
    print(f"wrote {out}: max |ϑ_elastic − ϑ_rigid| = {m:.4g} (ϑ up to {hi:.4g})")


if __name__ == "__main__":
    main(*sys.argv[1:4])
