"""Friction in the Hertz contact of a rigid sphere (docs/obstacles.md, "Friction"): how much does
F change the pressure, and is it the normal–tangential coupling? One command,

    PYTHONPATH=src python benchmarks/goodman.py [--levels 2] [--nus 0.3 0.4 0.49]

The quarter model of benchmarks/hertz.py (a rigid sphere R = 10 pressed by the force P of the
frictionless contact radius 0.5, the block clamped at its far face, E = 1), solved with F = 0, 0.3
and 1.0 at the same P. Printed per ν and mesh: the peak pressure at the centre node and fitted, the
fitted contact radius and the approach δ, each relative to F = 0, the node classes, and Dundurs'
β = (1 − 2ν)/(2(1 − ν)), the coupling of normal and tangential tractions of a rigid body on an
elastic one (β = 0: no coupling, friction cannot change the pressure; ν = 0.49 on B-bar hexahedra).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from contactopt.problem import ShapeProblem
from contactopt.verification.hertz import A_TARGET, R, configure, fit, graded_axis, pressure


def sphere(h: float, nu: float, friction: float, size=20.0) -> dict:
    e_star = 1.0 / (1 - nu ** 2)
    force = 4 * e_star * A_TARGET ** 3 / (3 * R)
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    cfg = configure({
        "material": {"E": 1.0, "nu": nu}, "friction": {"coefficient": friction},
        "state": {"method": "newton", "tol": 1e-12, "max_iter": 200}, "linear_solver": {"path": "condensation"},
        "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
        "design": {"degree": [2, 2], "initial": 0.0, "C0": 0.1, "C1": 1.0, "C2": 0.0},
        "geometry": {"a": L, "b": L, "c": L}, "mesh": {"x1": x, "x2": x, "x3": x},
        "body": {"clamped": ["top", {"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "sphere", "center": [0.0, 0.0, -R], "radius": R, "control": "force",
                     "force": [0.0, 0.0, force / 4]}})
    t0 = time.perf_counter()
    pr = ShapeProblem(cfg)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    r, p, _, _ = pressure(pr, st)
    a, p0 = fit(r, p)
    shear = np.linalg.norm(st.tau, axis=1) / pr.model.contact_areas()
    return {"p0_node": float(p[np.argmin(r)]), "p0": p0, "a": a, "delta": st.obstacle.translation,
            "counts": st.counts, "shear_max": float(shear.max()), "time": time.perf_counter() - t0}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, default=2)
    ap.add_argument("--nus", type=float, nargs="+", default=[0.3, 0.4, 0.49])
    args = ap.parse_args()
    print("| ν | β | h | F | p0 (centre node) | p0 (fit) | a (fit) | δ | max shear / p0(F=0) | stick / slip nodes | time |")
    print("|---" * 11 + "|")
    for nu in args.nus:
        beta = (1 - 2 * nu) / (2 * (1 - nu))
        for level in range(args.levels):
            h = A_TARGET / (3 * 2 ** level)
            ref = sphere(h, nu, 0.0)
            for F in (0.0, 0.3, 1.0):
                q = ref if F == 0 else sphere(h, nu, F)
                rel = {k: q[k] / ref[k] - 1 for k in ("p0_node", "p0", "a", "delta")}
                print(f"| {nu:g} | {beta:.3f} | a/{3 * 2 ** level} | {F:g} | {rel['p0_node']:+.2%} | {rel['p0']:+.2%} | "
                      f"{rel['a']:+.2%} | {rel['delta']:+.2%} | {q['shear_max'] / ref['p0_node']:.3f} | "
                      f"{q['counts']['M3+']} / {q['counts']['M1']} | {q['time']:.1f} s |", flush=True)


if __name__ == "__main__":
    main()
