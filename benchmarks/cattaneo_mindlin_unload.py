"""Cattaneo–Mindlin on a load path, continued: the tangential traction along a diameter against
Mindlin's profile, and unloading from Q* towards −Q* at constant P against the counter-slip
annulus of Mindlin–Deresiewicz, c′/a = (1 − (Q* − Q)/(2μP))^(1/3) (docs/load_paths.md). The
set-up is that of benchmarks/cattaneo_mindlin.py.

    PYTHONPATH=src python benchmarks/cattaneo_mindlin_unload.py [n] [figure.png]
"""

from __future__ import annotations

import sys

import numpy as np

from cattaneo_mindlin import ESTAR, F3, MU, R, config, measure
from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.problem import ShapeProblem


def main(n: int, figure: str | None):
    h = 2.0 / n
    f0 = 0.05 * MU * abs(F3)
    pr = ShapeProblem(load_config(config(n, [{"name": "press", "body_force": [0.0, 0.0, F3]},
                                             {"name": "shear", "body_force": [f0, 0.0, F3]}])))
    P, Q = measure(pr.solve_state(pr.model.initial_design()), h)[:2]
    fstar = 0.6 / (Q / (MU * P) / f0)
    unload = [1 - j / 2 for j in range(1, 5)]                 # Q/Q* = 1/2, 0, −1/2, −1
    steps = [{"name": "press", "body_force": [0.0, 0.0, F3]}, {"name": "load", "body_force": [fstar, 0.0, F3]}]
    steps += [{"name": f"u{j}", "body_force": [s * fstar, 0.0, F3]} for j, s in enumerate(unload, 1)]
    pr = ShapeProblem(load_config(config(n, steps)))
    pr.solve_states(pr.model.initial_design())
    res = {name: st for name, _, st in pr.step_results()}
    loaded = res["load"]
    P, Qs, a_m, c_m, _ = measure(loaded, h)
    a = (3 * P * R / (4 * ESTAR)) ** (1 / 3)
    print(f"n = {n}: P = {P:.4g}, Q*/μP = {Qs / (MU * P):.3f}, a = {a_m:.4f} (Hertz {a:.4f}), "
          f"c/a = {c_m / a_m:.3f} (Mindlin {(1 - Qs / (MU * P)) ** (1 / 3):.3f})")
    print("\n| step | Q/Q* | (Q* − Q)/(2μP) | stick nodes | c′/a | (1 − (Q* − Q)/(2μP))^(1/3) | reverse-slip nodes |")
    print("|---|---|---|---|---|---|---|")
    for j in range(1, 5):
        st = res[f"u{j}"]
        Pj, Qj, a_j, c_j, ns = measure(st, h)
        d = (Qs - Qj) / (2 * MU * P)
        rev = np.sum((st.classes == CLASS_CODES["M1"]) & (st.slip_increment[:, 0] < 0))
        print(f"| u{j} | {Qj / Qs:.3f} | {d:.3f} | {ns} | {c_j / a_j:.3f} | {max(1 - d, 0) ** (1 / 3):.3f} | {rev} |")
    if figure:
        plot_profile(pr, loaded, P, Qs, a, h, figure)


def plot_profile(pr, st, P, Q, a, h, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    xy = pr.model.mesh.contact_points()
    row = np.isclose(xy[:, 1], 1.0)
    x = xy[row, 0] - 1.0
    order = np.argsort(x)
    x = x[order]
    p = st.lam[row][order] / h ** 2
    q = st.tau[row, 0][order] / h ** 2
    p0 = 3 * P / (2 * np.pi * a ** 2)
    c = a * (1 - Q / (MU * P)) ** (1 / 3)
    r = np.linspace(-a, a, 401)
    hertz = p0 * np.sqrt(np.clip(1 - r ** 2 / a ** 2, 0, None))
    mindlin = MU * hertz - np.where(np.abs(r) < c, MU * p0 * (c / a) * np.sqrt(np.clip(1 - r ** 2 / c ** 2, 0, None)), 0)
    fig, ax = plt.subplots(figsize=(6.4, 4))
    ax.plot(r, hertz, "k-", lw=1, label="Hertz p")
    ax.plot(r, MU * hertz, "k:", lw=1, label="μp")
    ax.plot(r, mindlin, "r-", lw=1.2, label="Mindlin q (press, then shear)")
    ax.plot(x, p, "ko", ms=4, label="λ/h² (contactopt)")
    ax.plot(x, q, "rs", ms=4, label="τ1/h² (contactopt)")
    ax.set_xlim(-1.6 * a, 1.6 * a)
    ax.set_xlabel("x1 − 1 (along the diameter x2 = 1)")
    ax.set_ylabel("traction")
    ax.set_title(f"Cattaneo–Mindlin, Q/μP = {Q / (MU * P):.2f}, h = {h:.3g}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 24, sys.argv[2] if len(sys.argv) > 2 else None)
