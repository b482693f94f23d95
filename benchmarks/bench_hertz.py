"""Hertz contact: the peak von Mises stress of a paraboloid pressed onto the rigid foundation, over
refinements (the set-up and the analytic field: :mod:`contactopt.verification.hertz_stress`).

Run: ``PYTHONPATH=src python benchmarks/bench_hertz.py [n ...] [--figure PNG]`` (default n = 3 4
6 8): one row per refinement, FE peak against the analytic value and the depth of the peak. Results in
docs/objectives.md.
"""

from __future__ import annotations

import sys

import numpy as np

from contactopt.verification.hertz_stress import NU, hertz_axis, hertz_peak


def axis_figure(path, rows):
    """σ_vM/p0 against depth/a near the axis for each refinement, and Hertz's curve on it."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    z = np.linspace(1e-3, 2.5, 400)
    sz = -1.0 / (1.0 + z * z)
    sr = -(1.0 + NU) * (1.0 - z * np.arctan(1.0 / z)) + 0.5 / (1.0 + z * z)
    ax.plot(z, np.abs(sz - sr), "k-", lw=1.5, label="Hertz, on the axis")
    for r, marker in zip(rows, "os^dv"):
        d, v = r["axis"]
        ax.plot(d, v, marker, ms=3.5, alpha=0.7, label=f"n = {r['n']} (quadrature points, r < a/4)")
    ratio, zeta = hertz_axis()
    ax.axvline(zeta, color="0.6", lw=0.8, ls="--")
    ax.set_xlabel("depth $z/a$")
    ax.set_ylabel("$\\sigma_{vM} / p_0$")
    ax.set_title(f"Hertz contact, $\\nu$ = {NU}: peak {ratio:.3f} $p_0$ at $z$ = {zeta:.3f} $a$", fontsize=10)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=120)


def main(argv=None):
    argv = list(argv or [])
    figure = None
    if "--figure" in argv:
        k = argv.index("--figure")
        figure = argv[k + 1]
        del argv[k:k + 2]
    ns = [int(v) for v in argv] or [3, 4, 6, 8]
    rows = []
    ratio, zeta = hertz_axis()
    print(f"Hertz on the axis, nu = {NU}: max von Mises {ratio:.4f} p0 at depth {zeta:.4f} a")
    print("| n = a/h | free DOFs | P | a (Hertz) | p0 | peak σ_vM/p0 | error | depth/a | r/a | time s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n in ns:
        r = hertz_peak(n)
        rows.append(r)
        print(f"| {n} | {r['dofs']} | {r['P']:.5g} | {r['a']:.4f} | {r['p0']:.4f} | {r['peak_over_p0']:.4f} | "
              f"{100 * r['error']:+.2f} % | {r['depth_over_a']:.3f} | {r['r_over_a']:.3f} | {r['seconds']:.1f} |",
              flush=True)
    if figure:
        axis_figure(figure, rows)


if __name__ == "__main__":
    main(sys.argv[1:])
