"""Contact faces on charts, interference fits and curved elastic counterparts (docs/charts.md):

    PYTHONPATH=src python benchmarks/charts.py [--levels 3] [--hertz 2] [--push-out 3] [--partner point|mortar]

(a count of 0 leaves its tables out: ``--levels 0 --hertz 0`` gives the push-out alone).

1. Lamé's shrink fit, a quarter hub (b = 1, c = 2, length 0.25) on a rigid shaft of radius b + δ
   (δ = 0.001, plane strain, frictionless, symmetry planes through the bore): the nodal contact
   pressure against Lamé's, rms and max relative error, over refinements (the hub nr × nθ × 1).
2. The same hub on an elastic quarter shaft of the same material (an O-grid, ``[foundation]``),
   matching meshes (the shaft's nθ the hub's) and non-matching ones (the shaft's 3/4 of it): the
   nodal pressure's rms and max error, and that of the mean pressure Σλ/Σa. ``--partner mortar``:
   the same with mortar partners segmented on the bore's chart, and a shaft of 3/2 of the hub's nθ.
3. A spherical pad (R1 = 10) on a convex (R2 = 20) or concave (R2 = 20) elastic seat: the contact
   radius and the peak pressure of the fit p² = p0²(1 − r²/a²) against Hertz, h = a/4, a/8, ….
4. Push-out with friction F = 0.3: the hub on the elastic shaft (hub nr × nθ × nz, matching meshes,
   u3 clamped on both end faces of both bodies but on the contact face's end rings), the hub's end
   faces pushed along x3 by s = 1e-4, 2e-4, … 1.6e-3 (load steps after the fit): the force at
   which the whole interface slides against 2πbLμp/4 (a quarter), and against μΣλ of the FE.

The set-ups: :mod:`contactopt.verification.lame`, :mod:`contactopt.verification.two_spheres`.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

from contactopt.config import validate
from contactopt.problem import ShapeProblem
from contactopt.verification import lame, two_spheres


def rigid_shaft(levels: int):
    print("| hub nr × nθ | contact nodes | p (mean) | Lamé | rms error | max error | time |\n|---|---|---|---|---|---|---|")
    p = lame.pressure_rigid_shaft()
    with tempfile.TemporaryDirectory() as d:
        for k in range(levels):
            nr, nt = 4 * 2 ** k, 8 * 2 ** k
            t0 = time.perf_counter()
            pr = ShapeProblem(validate(lame.shrink_fit_config(lame.quarter_hub_mesh(f"{d}/hub.msh", nr, nt, 1)), "lame"))
            _, pm, _ = lame.contact_pressure(pr)
            e = pm / p - 1
            print(f"| {nr} × {nt} | {pm.size} | {pm.mean():.6g} | {p:.6g} | {np.sqrt(np.mean(e ** 2)):.2e} | "
                  f"{np.abs(e).max():.2e} | {time.perf_counter() - t0:.1f} s |")


def elastic_shaft(levels: int, partner: str = "point"):
    print("| hub nr × nθ | shaft nθ | meshes | rms error | max error | mean pressure error | time |\n"
          "|---|---|---|---|---|---|---|")
    p = lame.pressure_equal_materials()
    with tempfile.TemporaryDirectory() as d:
        for k in range(levels):
            for ns in (8 * 2 ** k, 6 * 2 ** k) + ((12 * 2 ** k,) if partner == "mortar" else ()):
                nr, nt = 4 * 2 ** k, 8 * 2 ** k
                match = ns == nt
                t0 = time.perf_counter()
                hub = lame.quarter_hub_mesh(f"{d}/hub.msh", nr, nt, 1)
                shaft = lame.quarter_shaft_mesh(f"{d}/shaft.msh", 3 * 2 ** k, ns, 1, radius=lame.B + lame.DELTA)
                cfg = lame.shaft_config(hub, shaft)
                cfg["foundation"]["partner"] = partner
                pr = ShapeProblem(validate(cfg, "lame"))
                _, pm, st = lame.contact_pressure(pr)
                e = pm / p - 1
                mean = st.lam.sum() / pr.model.contact_areas().sum() / p - 1
                print(f"| {nr} × {nt} | {ns} | {'matching' if match else 'non-matching'} | "
                      f"{np.sqrt(np.mean(e ** 2)):.2e} | {np.abs(e).max():.2e} | {mean:+.2e} | "
                      f"{time.perf_counter() - t0:.1f} s |")


PUSHES = [1e-4 * k for k in range(1, 17)]     # the hub's axial displacements, one load step each


def push_out(levels: int):
    print("| hub nr × nθ × nz | contact nodes | s at full slide | F (plateau) | 2πbLμp/4 | error | "
          "Σλ / (πbLp/2) − 1 | F / (μΣλ) − 1 | time |\n|---|---|---|---|---|---|---|---|---|")
    mu = 0.3
    ref = 2 * np.pi * lame.B * 0.25 * mu * lame.pressure_equal_materials() / 4
    with tempfile.TemporaryDirectory() as d:
        for k in range(1, levels + 1):
            nr, nt, nz = 4 * k, 8 * k, 2 * k
            t0 = time.perf_counter()
            hub = lame.quarter_hub_mesh(f"{d}/hub.msh", nr, nt, nz, ends=True)
            shaft = lame.quarter_shaft_mesh(f"{d}/shaft.msh", 3 * k, nt, nz, radius=lame.B + lame.DELTA, ends=True)
            pr = ShapeProblem(validate(lame.push_out_config(hub, shaft, len(PUSHES), friction=mu), "push-out"))
            rows = lame.push_out(pr, PUSHES)
            full = next((r["s"] for r in rows if r["slide"] == 1.0), float("nan"))
            last = rows[-1]
            print(f"| {nr} × {nt} × {nz} | {pr.model.n_contact} | {full:.1e} | {last['force']:.6g} | {ref:.6g} | "
                  f"{last['force'] / ref - 1:+.2%} | {last['normal'] / (ref / mu) - 1:+.2%} | "
                  f"{last['force'] / (mu * last['normal']) - 1:+.1e} | {time.perf_counter() - t0:.1f} s |")


def two_curved(levels: int):
    print("| seat | h | contact nodes | P | a (fit) | a Hertz | error | p0 (fit) | p0 Hertz | error | time |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        for concave in (False, True):
            for k in range(levels):
                h = two_spheres.A_TARGET / (4 * 2 ** k)
                t0 = time.perf_counter()
                pr = ShapeProblem(validate(two_spheres.two_spheres_config(d, h, concave=concave), "hertz"))
                q = two_spheres.measure(pr, concave)
                print(f"| {'concave' if concave else 'convex'} | a/{two_spheres.A_TARGET / h:.0f} | {q['p']} | "
                      f"{q['P']:.5g} | {q['a']:.5g} | {q['a_H']:.5g} | {q['a'] / q['a_H'] - 1:+.2%} | {q['p0']:.5g} | "
                      f"{q['p0_H']:.5g} | {q['p0'] / q['p0_H'] - 1:+.2%} | {time.perf_counter() - t0:.1f} s |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, default=3, help="refinements of the shrink fits")
    ap.add_argument("--hertz", type=int, default=2, help="refinements of the two spheres")
    ap.add_argument("--push-out", type=int, default=3, help="refinements of the push-out with friction (0: none)")
    ap.add_argument("--partner", choices=("point", "mortar"), default="point",
                    help="the partners of the hub on the elastic shaft")
    args = ap.parse_args()
    tables = [(args.levels, rigid_shaft), (args.levels, lambda n: elastic_shaft(n, args.partner)),
              (args.hertz, two_curved), (args.push_out, push_out)]
    for j, (levels, table) in enumerate((n, f) for n, f in tables if n):       # 0 refinements: no table
        if j:
            print()
        table(levels)


if __name__ == "__main__":
    main()
