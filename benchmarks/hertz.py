"""Hertz validation of the rigid obstacles ([obstacle], docs/obstacles.md): one command,

    PYTHONPATH=src python benchmarks/hertz.py [--levels 3] [--figure docs/figures/obstacles_hertz.png]

The set-ups (sphere, cylinder, flat punch, the sphere moved sideways) and what is measured on them
against Hertz, Mindlin and Boussinesq: :mod:`contactopt.verification.hertz`.

Prints one table per shape over the refinements h = a/3, a/6, a/12 (``--levels``), errors relative;
then, at h = a/6, the sphere with F = 0.3 against F = 0 (Goodman's coupling) and a half model of
the sphere pressed and moved sideways (d1 along x1, Q < FP): its stick core against Mindlin's
radius (``--figure``: the pressure profiles, and the stick/slip map beside it, ``*_stick.png``).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from contactopt.verification.hertz import (
    A_TARGET,
    P_SPHERE,
    measure_cylinder,
    measure_mindlin,
    measure_punch,
    measure_sphere,
    pressure,
    punch_stl,
)


def table(rows, kind: str) -> str:
    out = [f"| h | contact nodes | {'P' if kind == 'sphere' else 'P′'} | a (fit) | a Hertz | error | p0 (fit) | "
           f"p0 Hertz | error | p0 (centre node) | error |" + (" δ | a²/R (Hertz) | error | δ + w(H) | error |" if kind == "sphere" else ""),
           "|---" * (11 + (5 if kind == "sphere" else 0)) + "|"]
    for q in rows:
        line = (f"| a/{A_TARGET / q['h']:.0f} | {q['p']} | {q['P']:.5g} | {q['a']:.5g} | {q['a_H']:.5g} | "
                f"{q['a'] / q['a_H'] - 1:+.2%} | {q['p0']:.5g} | {q['p0_H']:.5g} | {q['p0'] / q['p0_H'] - 1:+.2%} | "
                f"{q['p0_node']:.5g} | {q['p0_node'] / q['p0_H'] - 1:+.2%} |")
        if kind == "sphere":
            line += (f" {q['delta']:.5g} | {q['delta_H']:.5g} | {q['delta'] / q['delta_H'] - 1:+.2%} | "
                     f"{q['delta_corr']:.5g} | {q['delta_corr'] / q['delta_H'] - 1:+.2%} |")
        out.append(line)
    return "\n".join(out)


def figure(path: str, sphere: dict, cylinder: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    for ax, q, name in ((axes[0], sphere, "sphere (point contact)"), (axes[1], cylinder, "cylinder (line contact)")):
        r, p, _, _ = pressure(q["problem"], q["state"])
        s = np.linspace(0, 1, 200)
        ax.plot(s * q["a_H"], q["p0_H"] * np.sqrt(1 - s ** 2), "k-", label="Hertz p0 √(1 − r²/a²)")
        ax.plot(r, p, "o", ms=3, label=f"nodal λ/A, h = a/{A_TARGET / q['h']:.0f}")
        ax.set_xlim(0, 2 * q["a_H"])
        ax.set_xlabel("r" if "sphere" in name else "|x1|")
        ax.set_ylabel("contact pressure")
        ax.set_title(f"frictionless rigid {name}")
        ax.legend(fontsize=8)
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, default=3)
    ap.add_argument("--figure", default="")
    args = ap.parse_args()
    hs = [A_TARGET / 3 * 0.5 ** k for k in range(args.levels)]
    cyl = [measure_cylinder(h) for h in hs]
    print("cylinder (line contact, plane strain)\n" + table(cyl, "cylinder"))
    sph = []
    for h in hs:
        sph.append(measure_sphere(h))
        print(f"  sphere h = a/{A_TARGET / h:.0f}: {sph[-1]['p']} contact nodes, {sph[-1]['time']:.1f} s", flush=True)
    print("sphere (point contact)\n" + table(sph, "sphere"))
    if args.figure:
        figure(args.figure, sph[-1], cyl[-1])
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        radius = A_TARGET * (1 + 1 / 24)        # the rim between nodes on every mesh (h = a/3 · 2⁻ᵏ)
        stl = punch_stl(f"{tmp}/punch.stl", radius / math.cos(math.pi / 96) ** 0.5)
        punch = [measure_punch(h, stl, radius, P_SPHERE) for h in hs]
    print("flat punch (force control), radius a = %.5g\n" % radius
          + "| h | contact nodes | nodes in contact | P | δ | P/(2aE*) | error | δ + w(H) | error | time |\n"
          + "|---" * 10 + "|\n" + "\n".join(
              f"| a/{A_TARGET / q['h']:.0f} | {q['p']} | {q['in_contact']} | {q['P']:.5g} | {q['delta']:.5g} | "
              f"{q['delta_H']:.5g} | {q['delta'] / q['delta_H'] - 1:+.2%} | {q['delta_corr']:.5g} | "
              f"{q['delta_corr'] / q['delta_H'] - 1:+.2%} | {q['time']:.1f} s |" for q in punch))
    h = hs[min(1, len(hs) - 1)]
    goodman = measure_sphere(h, friction=0.3)
    base = sph[min(1, len(hs) - 1)]
    print(f"Goodman, F = 0.3 against F = 0 at h = a/{A_TARGET / h:.0f}, the same P: "
          f"p0 {goodman['p0_node'] / base['p0_node'] - 1:+.3%} (centre node), "
          f"a {goodman['a'] / base['a'] - 1:+.3%}, δ {goodman['delta'] / base['delta'] - 1:+.3%}; classes "
          f"{goodman['counts']}, {goodman['time']:.1f} s")
    mind = measure_mindlin(h)
    print(f"Mindlin, F = 0.3, h = a/{A_TARGET / h:.0f}: P = {mind['P']:.5g}, Q = {mind['Q']:.5g} "
          f"(Q/FP = {mind['ratio']:.3f}), a = {mind['a']:.4g} (fit; {mind['a_area']:.4g} from the area in "
          f"contact); stick out to r = {mind['stick']:.4g}, slip from r = {mind['slip']:.4g}, stick radius "
          f"from its area {mind['c_area']:.4g}; Mindlin c = a(1 − Q/FP)^(1/3) = {mind['c_mindlin']:.4g}; "
          f"{mind['time']:.1f} s")
    if args.figure:
        stick_figure(args.figure.replace(".png", "_stick.png"), mind)


def stick_figure(path: str, q: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    st, x = q["state"], q["x"]
    L = q["problem"].config.geometry.a / 2
    names = st.class_names
    fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
    for cls, mk, lab in (("M3+", "s", "stick (M3+)"), ("M1", "o", "slip (M1)"), ("L", ".", "open (L)")):
        on = names == cls
        ax.plot(x[on, 0] - L, x[on, 1], mk, ms=4, label=lab)
    t = np.linspace(0, np.pi, 100)
    ax.plot(q["a"] * np.cos(t), q["a"] * np.sin(t), "k-", lw=1, label="contact radius a (fit)")
    ax.plot(q["c_mindlin"] * np.cos(t), q["c_mindlin"] * np.sin(t), "k--", lw=1,
            label="Mindlin stick radius a(1 − Q/FP)^(1/3)")
    ax.set_xlim(-1.5 * q["a"], 1.5 * q["a"])
    ax.set_ylim(0, 1.2 * q["a"])
    ax.set_aspect("equal")
    ax.set_xlabel("x1 − centre")
    ax.set_ylabel("x2")
    ax.set_title(f"sphere pushed sideways, F = 0.3, Q/FP = {q['ratio']:.2f}", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
