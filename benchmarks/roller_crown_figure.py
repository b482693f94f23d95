"""The crowned roller of examples/roller_crowning.toml against a logarithmic crown.

    contactopt run examples/roller_crowning.toml --out runs/roller_crowning
    python benchmarks/roller_crown_figure.py runs/roller_crowning docs/figures/roller_crown.png

Reads the run's alpha.json and summary.json, solves the straight roller (α = 0) and the optimum,
and along the contact line x2 = 0 (the roller's generatrix on the race) takes

* the contact pressure p = λ/a (lumped areas on the designed face), p_mid at the mid-plane
  x1 = 0, p_end at the free end x1 = ℓ = 2 and the peak of the line;
* the crown drop(x1) = ϑ_α(x1) − ϑ_α(0): how far the optimized generatrix stands off the race
  relative to the middle (the design lifts the face away from the race);
* the Johns–Gohar logarithmic crown fitted to the same end drop,

      drop_JG(x) = A ln(1 / (1 − k (x/ℓ)²)),   k = 1 − 0.3033 b/ℓ,

  ℓ the half-length, b = (4 w R / (π E*))^½ the Hertz half-width of the line contact under the
  load per unit length w (R = 1 the roller's radius, the race flat, 1/E* = 2(1 − ν²)/E for two
  bodies of one material), A such that drop_JG(ℓ) = drop(ℓ); the k → 1 limit is Lundberg's crown,
  whose drop grows without bound at the end.

Writes the figure (profile and both pressure lines) and prints a Markdown table.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from contactopt.io.pressure import contact_pressure  # noqa: E402
from contactopt.problem import ShapeProblem  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "examples" / "roller_crowning.toml"
HALF_LENGTH, RADIUS = 2.0, 1.0


def line_data(problem, alpha):
    """(x1, p, height, load) on the contact line x2 = 0, sorted by x1: the pressure, the designed
    face's height x3 at its nodes and the whole roller's load 4 Σλ (a quarter model)."""
    model = problem.model
    state = problem.solve_state(alpha, warm_start=False)
    p = contact_pressure(model, state.lam, state.coords)
    x = model.body.reference.points[model.contact_nodes]
    on = np.flatnonzero(np.abs(x[:, 1]) < 1e-9)
    on = on[np.argsort(x[on, 0])]
    height = model.mesh.coordinates(alpha)[model.contact_nodes[on], 2]
    return x[on, 0], p[on], height, 4.0 * float(state.lam.sum())


def johns_gohar(x, end_drop, w, E, nu):
    """The Johns–Gohar crown through drop(ℓ) = ``end_drop`` (module docstring) and its k, b."""
    e_star = E / (2.0 * (1.0 - nu ** 2))
    b = np.sqrt(4.0 * w * RADIUS / (np.pi * e_star))
    k = 1.0 - 0.3033 * b / HALF_LENGTH
    shape = lambda s: np.log(1.0 / (1.0 - k * (s / HALF_LENGTH) ** 2))  # noqa: E731
    return end_drop / shape(HALF_LENGTH) * shape(x), k, b


def main(run: str, out: str) -> int:
    run = Path(run)
    summary = json.loads((run / "summary.json").read_text())
    alpha = np.asarray(json.loads((run / "alpha.json").read_text())["alpha"], float).ravel()
    problem = ShapeProblem(str(CONFIG))
    cfg = problem.model.config
    rows = {}
    for name, a in (("straight", problem.model.initial_design()), ("optimized", alpha)):
        x1, p, h, load = line_data(problem, a)
        rows[name] = dict(x1=x1, p=p, h=h, load=load, p_mid=p[0], p_end=p[-1], p_max=p.max(),
                          x_max=x1[int(np.argmax(p))])
    x1 = rows["straight"]["x1"]
    drop = rows["optimized"]["h"] - rows["straight"]["h"]
    drop = drop - drop[0]
    w = rows["straight"]["load"] / (2.0 * HALF_LENGTH)
    fine = np.linspace(0.0, HALF_LENGTH, 400)
    jg, k, b = johns_gohar(fine, drop[-1], w, cfg.material.E, cfg.material.nu)
    jg_nodes, _, _ = johns_gohar(x1, drop[-1], w, cfg.material.E, cfg.material.nu)

    fig, ax = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    ax[0].plot(x1, 1e3 * drop, "o-", ms=3, label="optimized roller (degree [6, 0])")
    ax[0].plot(fine, 1e3 * jg, "--", label=f"Johns–Gohar crown, same end drop (k = {k:.4f})")
    ax[0].set_xlabel("x1 (0: mid-length, 2: free end)")
    ax[0].set_ylabel("crown drop ϑ(x1) − ϑ(0)  [10⁻³]")
    ax[0].legend(fontsize=8)
    ax[0].set_title("crown profile along the axis", fontsize=9)
    for name, style in (("straight", "s-"), ("optimized", "o-")):
        r = rows[name]
        ax[1].plot(r["x1"], r["p"], style, ms=3, label=f"{name}: p_end/p_mid = {r['p_end'] / r['p_mid']:.3f}")
    ax[1].set_xlabel("x1")
    ax[1].set_ylabel("contact pressure on x2 = 0")
    ax[1].legend(fontsize=8)
    ax[1].set_title(f"pressed by the force: load {rows['straight']['load']:.4g} on the roller", fontsize=9)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)

    print("| roller | p_mid | p_end | p_end / p_mid | peak (x1) | load (4 Σλ) |")
    print("|---|---|---|---|---|---|")
    for name, r in rows.items():
        print(f"| {name} | {r['p_mid']:.5g} | {r['p_end']:.5g} | {r['p_end'] / r['p_mid']:.3f} | "
              f"{r['p_max']:.5g} ({r['x_max']:.3f}) | {r['load']:.5g} |")
    print(f"\nrun: J0 = {summary['J0']:.6g}, J = {summary['J']:.6g}, {summary['iterations']} iterations, "
          f"{summary['evaluations']} evaluations, {summary['wall_time_s']:.1f} s")
    print(f"end drop {drop[-1]:.4g}; Johns–Gohar: w = {w:.4g}, b = {b:.4g}, k = {k:.5f}, "
          f"rms(drop − drop_JG) at the line's nodes {np.sqrt(np.mean((drop - jg_nodes) ** 2)):.3g}")
    print("\n| x1 | drop | drop_JG |\n|---|---|---|")
    for x, d, j in zip(x1, drop, jg_nodes):
        print(f"| {x:.3f} | {d:.4e} | {j:.4e} |")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
