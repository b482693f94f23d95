"""A wedge in a rigid V-groove (docs/charts.md, contactopt.verification.vgroove):

    PYTHONPATH=src python benchmarks/vgroove.py [--levels 2] [--run DIR] [--figure docs/figures/vgroove.png]

1. Statics: the whole wedge (both flanks its contact face, hexahedra n1 × n3 × n2 per half) pressed
   by q on its top and held by the groove alone; the normal force on each flank against
   N = F / (2 (sin β + F_c cos β)), frictionless and sliding in with F_c = 0.3, and the fraction of
   each flank's nodes that slide; then the half model (the symmetry plane x1 = 0) on the same mesh.
2. examples/vgroove.toml (the half model, its flank designed along the normal, objective
   max_pressure): run in DIR (or a temporary directory), then the design's normal displacement
   ϑ along the flank and the pressure along the slope at α0 and at the optimum; the figure shows
   the cross-section (ϑ exaggerated) mirrored to the other flank and the two pressure profiles.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from contactopt.config import validate
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization
from contactopt.verification import vgroove as vg

ROOT = Path(__file__).resolve().parents[1]


def statics(levels: int):
    print("| model | mesh (per half) | F_c | flank | N | statics | error | sliding |\n|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        groove = vg.groove_stl(f"{d}/groove.stl")
        for k in range(1, levels + 1):
            n1, n3, n2 = 3 * k, 6 * k, k
            for half in (False, True):
                mesh = vg.wedge_mesh(f"{d}/wedge.msh", n1, n3, n2, half=half)
                for friction in (0.0, 0.3):
                    pr = ShapeProblem(validate(vg.config(mesh, groove, half=half, friction=friction), "vgroove"))
                    st = pr.solve_state(pr.model.initial_design())
                    n = vg.flank_force(friction)
                    for side, f in vg.flank_forces(pr, st).items():
                        print(f"| {'half' if half else 'whole'} | {n1} × {n3} × {n2} | {friction} | {side} | "
                              f"{f['normal']:.8g} | {n:.8g} | {f['normal'] / n - 1:+.1e} | {f['slide']:.0%} |")


def profile(problem, alpha):
    """(coordinates, nodal pressure, state) of the contact nodes on x2 = 0, sorted up the flank, and
    their indices among the contact nodes."""
    model = problem.model
    x = model.body.reference.points[model.contact_nodes]
    st = problem.solve_state(alpha)
    p = st.lam / model.contact_areas()
    sel = np.flatnonzero(np.abs(x[:, 1]) < 1e-12)
    o = sel[np.argsort(x[sel, 2])]
    return x[o], p[o], st, o


def design(run_dir, figure):
    cfg = ROOT / "examples" / "vgroove.toml"
    if run_dir is None:
        run_dir = Path(tempfile.mkdtemp(prefix="vgroove"))
    run_dir = Path(run_dir)
    if not (run_dir / "summary.json").exists():
        run_optimization(cfg, run_dir, plots=False)
    s = json.loads((run_dir / "summary.json").read_text())
    alpha = np.ravel(s["alpha"])
    pr = ShapeProblem(str(cfg))
    model = pr.model
    a0 = model.initial_design()
    x, p0, st0, o = profile(pr, a0)
    _, p1, st1, _ = profile(pr, alpha)
    # ϑ along the inward normal: the face's displacement from the design 0 (α0 is the mean offset)
    inward = np.array([-np.cos(vg.BETA), 0.0, np.sin(vg.BETA)])
    xs = model.mesh.coordinates(np.zeros_like(alpha)).reshape(-1, 3)[model.contact_nodes][o]
    theta0 = (model.mesh.coordinates(a0).reshape(-1, 3)[model.contact_nodes][o] - xs) @ inward
    theta = (model.mesh.coordinates(alpha).reshape(-1, 3)[model.contact_nodes][o] - xs) @ inward
    n = vg.flank_force(0.3)
    area = model.contact_areas().sum()
    ref = model.body.reference.points
    top = np.flatnonzero(np.abs(ref[:, 2] - vg.H) < 1e-12)

    def statics_of(a):
        """N of the designed wedge: the design moves the top's corner with the flank (the morph), so
        the load q·(top's area) is the designed top's."""
        width = model.mesh.coordinates(a).reshape(-1, 3)[top, 0].max() - model.mesh.coordinates(a).reshape(-1, 3)[top, 0].min()
        return vg.Q * width * vg.W / (np.sin(vg.BETA) + 0.3 * np.cos(vg.BETA))

    f0, f1 = vg.flank_forces(pr, st0)["right"], vg.flank_forces(pr, st1)["right"]
    print(f"run {run_dir}: {s['iterations']} iterations, {s['evaluations']} evaluations, {s['wall_time_s']:.1f} s, "
          f"J/J0 = {s['ratio']:.4f}")
    print(f"alpha* = {np.array2string(alpha, precision=5)}")
    print("| design | max pressure | mean pressure N/A | max/mean | N (flank) | statics (the design's top) | sliding | "
          "ϑ tip | ϑ top | "
          "ϑ min | ϑ max |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, p, f, th, a in (("α0", p0, f0, theta0, a0), ("optimal", p1, f1, theta, alpha)):
        print(f"| {name} | {p.max():.5g} | {n / area:.5g} | {p.max() / (n / area):.3f} | {f['normal']:.6g} | "
              f"{statics_of(a):.6g} | "
              f"{f['slide']:.0%} | "
              f"{th[0]:.2e} | {th[-1]:.2e} | {th.min():.2e} | {th.max():.2e} |")
    if figure:
        draw(figure, x, theta, p0, p1, n / area)


def draw(path, x, theta, p0, p1, mean):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    scale = 20.0
    inward = np.array([-np.cos(vg.BETA), np.sin(vg.BETA)])
    xz = x[:, [0, 2]]
    moved = xz + scale * (theta - theta.mean())[:, None] * inward
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4.2))
    t = np.tan(vg.BETA)
    ax.fill([-1.2 * t, 0, 1.2 * t, 1.2, 1.2, -1.2, -1.2], [1.2, 0, 1.2, 1.2, -0.3, -0.3, 1.2],
            color="0.85", label="groove (rigid)")
    ax.plot(xz[:, 0], xz[:, 1], "k-", lw=1.0, label="flank at α0")
    ax.plot(-xz[:, 0], xz[:, 1], "k-", lw=1.0)
    ax.plot(moved[:, 0], moved[:, 1], "r-", lw=1.6, label=f"optimal flank, ϑ − mean × {scale:.0f}")
    ax.plot(-moved[:, 0], moved[:, 1], "r--", lw=1.2, label="mirrored by the symmetry plane")
    ax.plot([-vg.H * t, vg.H * t], [vg.H, vg.H], "k-", lw=1.0)
    ax.plot([-vg.Z0 * t, vg.Z0 * t], [vg.Z0, vg.Z0], "k-", lw=1.0)
    ax.axvline(0.0, color="0.5", lw=0.6, ls=":")
    ax.set_aspect("equal")
    ax.set_xlim(-0.8, 0.8)
    ax.set_ylim(-0.1, 1.1)
    ax.set_xlabel("x1")
    ax.set_ylabel("x3")
    ax.set_title("wedge in the V-groove (cross-section)")
    ax.legend(fontsize=7, loc="lower right")
    bx.plot(x[:, 2], p0, "ks-", ms=3, label="α0 (straight flanks)")
    bx.plot(x[:, 2], p1, "ro-", ms=3, label="optimal design")
    bx.axhline(mean, color="b", lw=0.8, ls="--", label="N / flank area (statics)")
    bx.set_xlabel("x3 along the flank (tip at 0.25)")
    bx.set_ylabel("contact pressure λ/a")
    bx.set_title("pressure along the flank (x2 = 0)")
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, default=2, help="refinements of the statics table (0: none)")
    ap.add_argument("--run", default=None, help="the example's run directory (run there if it has no summary.json)")
    ap.add_argument("--figure", default=None, help="write the figure there")
    ap.add_argument("--no-design", action="store_true", help="the statics table only")
    args = ap.parse_args()
    if args.levels:
        statics(args.levels)
    if not args.no_design:
        print()
        design(args.run, args.figure)


if __name__ == "__main__":
    main()
