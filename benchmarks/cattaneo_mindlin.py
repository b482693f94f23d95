"""Cattaneo–Mindlin on a load path: a paraboloidal pad pressed, then sheared, on an elastic
foundation of the same material (docs/load_paths.md).

The body is the block [0, 2]² × [0, 1] whose contact face is the paraboloid gap r²/2R about the
face's centre (a degree-2 Bézier design with a negative centre control point, design.lower < 0),
clamped on its top face; the foundation is the same material, a matching block [0, 2]² × [−1, 0]
clamped at its bottom (node-to-node partners). The loads are body forces in the pad: f3 < 0
presses it (P), f1 > 0 shears it (Q); the clamp carries part of them, so P and Q are measured as
the sums of λ and τ1 at the contact. Two bodies of one material: no normal–tangential coupling,
so Mindlin's solutions hold with E* = E/(2(1 − ν²)):

    a = (3PR/4E*)^(1/3),   c/a = (1 − Q/μP)^(1/3)   (press, then shear at constant P),

and with P and Q raised together (Q/P < μ) nothing slips (Mindlin–Deresiewicz). Radii from the
node counts: a = √(n_contact h²/π), c = √(n_stick h²/π); a also from the second moment of λ,
Σλr²/Σλ = (2/5)a² for Hertz's pressure.

    PYTHONPATH=src python benchmarks/cattaneo_mindlin.py [n ...]      (n: elements per side, default 16 24)
"""

from __future__ import annotations

import sys
import time

import numpy as np

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.problem import ShapeProblem

E, NU, MU, R, F3 = 1.0, 0.3, 0.3, 2.0, -0.08
ESTAR = E / (2 * (1 - NU ** 2))


def config(n: int, steps: list) -> dict:
    b = np.array([0.25, -0.25, 0.25])            # (x − 1)²/2R on [0, 2] in the Bernstein basis, R = 2
    initial = (b[:, None] + b[None, :]).tolist()
    return {"name": f"cm{n}", "geometry": {"a": 2.0, "b": 2.0, "c": 1.0},
            "mesh": {"nx": n, "ny": n, "nz": max(4, n // 2)},
            "body": {"clamped": "top"}, "material": {"E": E, "nu": NU}, "friction": {"coefficient": MU},
            "loads": {"top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
            "design": {"degree": [2, 2], "C0": 0.6, "lower": -0.6, "initial": initial},
            "linear_solver": {"path": "condensation"},
            "foundation": {"block": {"size": [2.0, 2.0, 1.0], "cells": [n, n, max(4, n // 2)]},
                           "top": "top", "clamped": "bottom", "material": {"E": E, "nu": NU}},
            "load_steps": steps}


def measure(state, h):
    lam, tau = state.lam, state.tau
    touching = lam > 1e-9 * lam.max()
    stick = state.classes == CLASS_CODES["M3+"]
    P, Q = lam.sum(), tau[:, 0].sum()
    return P, Q, np.sqrt(touching.sum() * h * h / np.pi), np.sqrt(stick.sum() * h * h / np.pi), stick.sum()


def moment_radius(state, model) -> float:
    """a from the second moment of λ: Σλr²/Σλ = (2/5)a² for Hertz's p0√(1 − r²/a²)."""
    r2 = ((model.mesh.contact_points() - 1.0) ** 2).sum(axis=1)
    return float(np.sqrt(2.5 * (state.lam * r2).sum() / state.lam.sum()))


def main(sizes):
    print("| n | Q/μP | P | a (nodes) | a (moment) | a Hertz | c/a | (1 − Q/μP)^(1/3) | stick nodes |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows, gains = [], {}
    for n in sizes:
        h = 2.0 / n
        # the clamp takes different shares of f1 and f3: f1 calibrated on a small shear (all stick)
        f0 = 0.05 * MU * abs(F3)
        pr = ShapeProblem(load_config(config(n, [{"name": "press", "body_force": [0.0, 0.0, F3]},
                                                 {"name": "shear", "body_force": [f0, 0.0, F3]}])))
        P, Q = measure(pr.solve_state(pr.model.initial_design()), h)[:2]
        gains[n] = Q / (MU * P) / f0
        for shear in (0.3, 0.6, 0.9):
            f1 = shear / gains[n]
            steps = [{"name": "press", "body_force": [0.0, 0.0, F3]},
                     {"name": "shear", "body_force": [f1, 0.0, F3]}]
            pr = ShapeProblem(load_config(config(n, steps)))
            t0 = time.perf_counter()
            st = pr.solve_state(pr.model.initial_design())
            P, Q, a, c, ns = measure(st, h)
            hertz = (3 * P * R / (4 * ESTAR)) ** (1 / 3)
            ratio = Q / (MU * P)
            print(f"| {n} | {ratio:.3f} | {P:.4g} | {a:.4f} | {moment_radius(st, pr.model):.4f} | {hertz:.4f} | {c / a:.3f} | "
                  f"{max(1 - ratio, 0) ** (1 / 3):.3f} | {ns} |   ({time.perf_counter() - t0:.1f} s)")
            rows.append((n, ratio, a, hertz, c / a))
    # the load path matters: the same final loads in 1, 2, 4, 8 proportional substeps
    n = sizes[-1]
    h = 2.0 / n
    f1 = 0.6 / gains[n]
    print("\n| substeps (proportional) | stick nodes | contact nodes | max ‖τ‖/(Fλ) | spread of τ1/λ |")
    print("|---|---|---|---|---|")
    per_substep = {}
    for m in (1, 2, 4, 8, 16):
        pr = ShapeProblem(load_config(config(n, [{"name": "all", "body_force": [f1, 0.0, F3], "substeps": m}])))
        st = pr.solve_state(pr.model.initial_design())
        touching = st.lam > 1e-6 * st.lam.max()
        ratio = np.linalg.norm(st.tau[touching], axis=1) / (MU * st.lam[touching])
        r1 = st.tau[touching, 0] / st.lam[touching]
        print(f"| {m} | {np.sum(st.classes == CLASS_CODES['M3+'])} | {touching.sum()} | {ratio.max():.3f} | "
              f"{r1.std() / abs(r1.mean()):.3f} |")
        # per substep: the nodes sliding in it and the nodes in contact at its end
        per_substep[m] = [(int(np.sum(s.classes == CLASS_CODES["M1"])), int(np.sum(s.lam > 0)))
                          for _, _, s in pr.step_results()]
    for m in (8, 16):
        print(f"{m} substeps, (sliding, in contact) per substep: {per_substep[m]}")
    return rows


if __name__ == "__main__":
    main([int(v) for v in sys.argv[1:]] or [16, 24])
