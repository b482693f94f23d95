"""Where the hysteresis loop's excess over Mindlin–Deresiewicz comes from (docs/load_paths.md):
the pad of benchmarks/mindlin_deresiewicz_loop.py on its virgin loading curve, its top moved in
m equal steps of Q/μP up to 0.95 at constant P, against Cattaneo–Mindlin's curve.

With g(Q) = δ(Q) − Q/k0 (the FE: the slip part of the remote displacement, its own full-stick
compliance 1/k0 removed) and g_MD(Q) = (3μPK/16a)[1 − (1 − x)^(2/3)] − QK/8a (x = Q/μP), the
Masing construction of Mindlin–Deresiewicz (unloading δ* − 2δ_L((Q* − Q)/2), reloading likewise)
gives the loop's area from the loading curve alone,

    ΔW = ∮δ dQ = 4Q* g(Q*) − 8 ∫_0^Q* g(s) ds,

in which a part of g linear in Q (an error of the stick compliance) cancels. Printed: g/g_MD along
the curve (Hertz's a and the FE's own a from the second moment of λ), the stick (M3+) nodes, and
the Masing area of the FE's g for Q*/μP = 0.3, 0.5, 0.7, 0.9 (``--at``) against ΔW, next to c·ΔW with c the
least-squares factor of g ≈ c·g_MD + e·Q for x ≥ 0.4 (the part that scales like a compliance;
the rest is the curve's shape at small x, where the slip annulus is thinner than an element).
``--figure``: g/g_MD of each n's loading curve and of its elastic test (below).

``--rings``: after the press, the nodal normal forces summed over rings of r/a against the nodal
forces of Hertz's pressure (consistent: ∫pφ_i over the four faces around node i; lumped: ∫p over
the node's h × h square), with Hertz's a and with the FE's; and the tangential forces the press
leaves (‖τ‖/μλ, the nodes at the friction limit). ``--elastic``: :func:`elastic`. ``--unloading``:
:func:`unloading` (``--steps``: steps per quarter).

    cd benchmarks && PYTHONPATH=../src python mindlin_deresiewicz_virgin.py [n ...] [--steps m] [--at x*,…] [--figure out.png]
        [--rings | --elastic | --unloading]
        [--depth d] [--f3 f] [--fine w] [--nu ν]
        (graded meshes of benchmarks/mindlin_deresiewicz_loop.py, fine spacing 2/n; default 48, 16 steps)
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import mindlin_deresiewicz_loop as loop
from cattaneo_mindlin import MU, R, moment_radius
from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.problem import ShapeProblem


def g_md(Q, P, a):
    """Cattaneo–Mindlin's loading curve less its initial slope K/8a (module docstring)."""
    return analytic_loading(P, a)(Q) - loop.KCOMP / (8 * a) * np.asarray(Q)


def analytic_loading(P, a):
    return loop.analytic(P, a)[0]


def masing_area(Q, g, Qs: float, samples: int = 4001) -> float:
    """4Q* g(Q*) − 8∫_0^Q* g: the area of the Masing loop of the loading curve (Q, g), piecewise linear
    through (0, 0)."""
    Qv, gv = np.concatenate([[0.0], Q]), np.concatenate([[0.0], g])
    s = np.linspace(0.0, Qs, samples)
    gs = np.interp(s, Qv, gv)
    return float(4 * Qs * gs[-1] - 8 * np.trapezoid(gs, s))


def virgin(n: int, m: int, xmax: float = 0.95) -> dict:
    """The loading curve on the graded mesh n in m steps of Q/μP up to ``xmax``."""
    cal = loop.calibrate(n, graded=True)
    xs = np.linspace(0.0, xmax, m + 1)[1:]
    pr, sts = loop.solve_path(n, [cal["d0"]] + [loop.remote(cal, x) for x in xs], graded=True)
    Q = np.array([st.tau[:, 0].sum() for st in sts[2:]])
    d = np.array([loop.remote(cal, x) for x in xs])
    stick = [int(np.sum(st.classes == CLASS_CODES["M3+"])) for st in sts[2:]]
    return dict(cal, n=n, Q=Q, g=d - Q / cal["k0"], stick=stick, contact=int(np.sum(sts[0].lam > 0)))


def figure(curves: dict, path: str) -> None:
    """g/g_MD against Q/μP: the loading curve of each n and the elastic test's (``curves``:
    label → (x, ratio))."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for (label, (x, ratio)), style in zip(curves.items(), ("rs-", "bo-", "r--", "b--")):
        ax.plot(x, ratio, style, ms=3, lw=1, label=label)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylim(0.0, 1.3)
    ax.set_xlabel("Q/μP")
    ax.set_ylabel("g / g_MD (slip part of δ against Cattaneo–Mindlin)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def report(v: dict, at=(0.3, 0.5, 0.7, 0.9)) -> None:
    P, a, a_fe, Q, g = v["P"], v["a"], v["a_fe"], v["Q"], v["g"]
    x = Q / (MU * P)
    h = 2.0 / v["n"]
    print(f"\nn = {v['n']} (graded), a/h = {a / h:.2f}, P = {P:.6g}, a Hertz {a:.4f}, a FE {a_fe:.4f}, "
          f"k0 = {v['k0']:.5g} (8a/K = {8 * a / loop.KCOMP:.5g}), contact nodes {v['contact']}")
    print("\n| Q/μP | g/g_MD (Hertz a) | g/g_MD (FE a) | stick nodes |")
    print("|---|---|---|---|")
    for k in range(len(Q)):
        print(f"| {x[k]:.3f} | {g[k] / g_md(Q[k], P, a):.4f} | {g[k] / g_md(Q[k], P, a_fe):.4f} | {v['stick'][k]} |")
    fit = x >= 0.4
    basis = np.column_stack([g_md(Q[fit], P, a), Q[fit]])
    c, e = np.linalg.lstsq(basis, g[fit], rcond=None)[0]
    c_fe = np.linalg.lstsq(np.column_stack([g_md(Q[fit], P, a_fe), Q[fit]]), g[fit], rcond=None)[0][0]
    print(f"\ng ≈ c·g_MD + e·Q on x ≥ 0.4: c = {c:.4f} (FE a: {c_fe:.4f}), e·8a/K = {e * 8 * a / loop.KCOMP:+.4f}")
    print("\n| Q*/μP | Masing area (FE g) / ΔW | c | Masing area (FE g) / ΔW (FE a) | c (FE a) |")
    print("|---|---|---|---|---|")
    for xs in at:
        Qs = xs * MU * P
        dW, dW_fe = loop.analytic(P, a)[1](Qs), loop.analytic(P, a_fe)[1](Qs)
        area = masing_area(Q, g, Qs)
        print(f"| {xs} | {area / dW:.4f} | {c:.4f} | {area / dW_fe:.4f} | {c_fe:.4f} |")


def rings(n: int) -> None:
    """The nodal normal forces after the press, ring by ring, against Hertz's (module docstring)."""
    h = 2.0 / n
    cfg = loop.graded_config(n, [{"name": "press", "body_force": [0.0, 0.0, loop.F3]}], Path(tempfile.mkdtemp()))
    pr = ShapeProblem(load_config(cfg))
    st = pr.solve_state(pr.model.initial_design())
    lam, P = st.lam, st.lam.sum()
    xy = pr.model.mesh.contact_points()[:, :2] - 1.0
    r = np.hypot(xy[:, 0], xy[:, 1])
    a_h, a_fe = (3 * P * R / (4 * loop.ESTAR)) ** (1 / 3), moment_radius(st, pr.model)
    s = (np.arange(40) + 0.5) / 40 * 2 - 1                       # midpoints on [−1, 1]²
    S1, S2 = np.meshgrid(s, s, indexing="ij")
    tent = (1 - np.abs(S1)) * (1 - np.abs(S2))

    def nodal(a, consistent):
        p0 = 3 * P / (2 * np.pi * a * a)
        out = np.zeros(len(lam))
        for i in np.flatnonzero(r < a + 1.5 * h):
            half, w = (h, tent * 4 * h * h / S1.size) if consistent else (h / 2, h * h / S1.size)
            rho2 = ((xy[i, 0] + half * S1) ** 2 + (xy[i, 1] + half * S2) ** 2) / (a * a)
            out[i] = np.sum(w * p0 * np.sqrt(np.clip(1 - rho2, 0, None)))
        return out
    ref = {"consistent": nodal(a_h, True), "lumped": nodal(a_h, False), "FE a": nodal(a_fe, True)}
    touching = lam > 0
    ratio = np.linalg.norm(st.tau[touching], axis=1) / (MU * lam[touching])
    print(f"\nn = {n} (graded), ν = {loop.NU}, a/h = {a_h / h:.2f}, P = {P:.6g}, a Hertz {a_h:.4f}, a FE {a_fe:.4f}; "
          f"after the press ‖τ‖/μλ ≤ {ratio.max():.3f}, {np.sum(ratio > 1 - 1e-6)} of {touching.sum()} contact nodes "
          "at the friction limit")
    print("\n| r/a (Hertz a) | nodes | Σλ/P (FE) | consistent Hertz | lumped Hertz | consistent, FE's a |")
    print("|---|---|---|---|---|---|")
    edges = np.array([0, .5, .7, .8, .85, .9, .95, 1.0, 1.05, 1.1, 1.5])
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (r >= lo * a_h) & (r < hi * a_h)
        print(f"| {lo:.2f}–{hi:.2f} | {sel.sum()} | {lam[sel].sum() / P:.4f} | "
              + " | ".join(f"{v[sel].sum() / P:.4f}" for v in ref.values()) + " |")


XS = tuple(np.round(np.arange(0.025, 0.951, 0.025), 3))      # Q/μP of the elastic test


def profile_forces(xy, h: float, rad: float, samples: int = 60) -> np.ndarray:
    """∫√(1 − r²/rad²)₊ φ_i over the four h × h faces around each node (xy relative to the centre):
    the consistent nodal forces of a Hertz-shaped traction of unit peak on radius ``rad``."""
    s = (np.arange(samples) + 0.5) / samples * 2 - 1
    S1, S2 = np.meshgrid(s, s, indexing="ij")
    tent = (1 - np.abs(S1)) * (1 - np.abs(S2)) * 4 * h * h / S1.size
    out = np.zeros(len(xy))
    for i in np.flatnonzero(np.hypot(xy[:, 0], xy[:, 1]) < rad + 1.5 * h):
        rho2 = ((xy[i, 0] + h * S1) ** 2 + (xy[i, 1] + h * S2) ** 2) / rad ** 2
        out[i] = np.sum(tent * np.sqrt(np.clip(1 - rho2, 0, None)))
    return out


def unloading(n: int, m: int = 4, target: float = 0.7) -> None:
    """The loop's unloading branch (m steps per quarter up to Q*/μP ≈ ``target``, then 2m down to
    −δ*) radius by radius: τ1 summed over rings of r/a against Mindlin–Deresiewicz's traction
    q_L(Q*) − 2q_L((Q* − Q)/2), q_L(Q') = μp0[√(1 − r²/a²) − (c'/a)√(1 − r²/c'²)],
    c' = a(1 − Q'/μP)^(1/3) (consistent nodal forces; Hertz's a and p0 from P, Q and Q* measured),
    and the stick radius from the stick (M3+) nodes' area against c′ of (Q* − Q)/2."""
    cal = loop.calibrate(n, graded=True)
    dstar = loop.remote(cal, target)
    deltas = [cal["d0"]] + [dstar * j / m for j in range(1, m + 1)] + [dstar * (1 - j / m) for j in range(1, 2 * m + 1)]
    pr, sts = loop.solve_path(n, deltas, graded=True)
    h = 2.0 / n
    P, a = cal["P"], cal["a"]
    p0 = 3 * P / (2 * np.pi * a * a)
    xy = pr.model.mesh.contact_points()[:, :2] - 1.0
    r = np.hypot(xy[:, 0], xy[:, 1])
    H = {}

    def q_loading(Q):
        c = a * (1 - Q / (MU * P)) ** (1 / 3)
        H.setdefault(c, profile_forces(xy, h, c))
        H.setdefault(a, profile_forces(xy, h, a))
        return MU * p0 * (H[a] - c / a * H[c])
    Qs = sts[m + 1].tau[:, 0].sum()
    edges = np.array([0, .5, .8, .9, 1.0, 1.2])
    print(f"\nn = {n} (graded), a/h = {a / h:.2f}, Q*/μP = {Qs / (MU * P):.3f}; τ1 summed over rings of r/a, "
          "/μP: contactopt / Mindlin–Deresiewicz")
    print("\n| Q/Q* | c′/a (stick nodes) | c′/a (M–D) | " + " | ".join(f"{lo:.1f}–{hi:.1f}" for lo, hi in zip(edges[:-1], edges[1:]))
          + " |")
    print("|---|---|---|" + "---|" * (len(edges) - 1))
    for st in sts[m + 2:]:                   # the unloading steps
        Q = st.tau[:, 0].sum()
        md = q_loading(Qs) - 2 * q_loading((Qs - Q) / 2)
        stick = np.sum(st.classes == CLASS_CODES["M3+"])
        contact = np.sum(st.lam > 0)
        cells = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            sel = (r >= lo * a) & (r < hi * a)
            cells.append(f"{st.tau[sel, 0].sum() / (MU * P):+.3f} / {md[sel].sum() / (MU * P):+.3f}")
        print(f"| {Q / Qs:+.3f} | {np.sqrt(stick / contact) if contact else 0:.3f} | "
              f"{(1 - (Qs - Q) / (2 * MU * P)) ** (1 / 3):.3f} | " + " | ".join(cells) + " |")


def elastic(n: int, xs=XS):
    """No friction solve: Mindlin's tangential traction at Q/μP = x, μp0[√(1 − r²/a²) − (c/a)√(1 − r²/c²)]
    (Hertz's a and p0 from the pressed state's P, c = a(1 − x)^(1/3)), applied as consistent nodal
    forces to the pad and, opposite, to the foundation; w1 = (W r)_1 at the centre (W = S_eff⁻¹ the
    interface's compliance, both bodies clamped), uniform inside c in Mindlin's solution (the spread
    over the nodes inside c − h is printed).
    Its nonlinear part g_el(x) = w1(x) − Q w1(x0)/Q(x0) (x0 the first x) against g_MD, and the
    Masing area of g_el against ΔW: the elastic discretization alone, Mindlin's tractions given.
    Returns (x, g_el/g_MD)."""
    from scipy.linalg import cho_factor, cho_solve
    h = 2.0 / n
    cfg = loop.graded_config(n, [{"name": "press", "body_force": [0.0, 0.0, loop.F3]}], Path(tempfile.mkdtemp()))
    pr = ShapeProblem(load_config(cfg))
    alpha = pr.model.initial_design()
    P = pr.solve_state(alpha).lam.sum()
    W = cho_factor(pr.cached_system(alpha).contact_S)
    a = (3 * P * R / (4 * loop.ESTAR)) ** (1 / 3)
    p0 = 3 * P / (2 * np.pi * a * a)
    xy = pr.model.mesh.contact_points()[:, :2] - 1.0
    r = np.hypot(xy[:, 0], xy[:, 1])
    s = (np.arange(60) + 0.5) / 60 * 2 - 1
    S1, S2 = np.meshgrid(s, s, indexing="ij")
    tent = (1 - np.abs(S1)) * (1 - np.abs(S2)) * 4 * h * h / S1.size
    near = np.flatnonzero(r < a + 1.5 * h)
    centre = np.argmin(r)
    rho2 = [((xy[i, 0] + h * S1) ** 2 + (xy[i, 1] + h * S2) ** 2) for i in near]

    def hertz_forces(rad):
        out = np.zeros(len(r))
        out[near] = [np.sum(tent * np.sqrt(np.clip(1 - q / rad ** 2, 0, None))) for q in rho2]
        return out
    unit_a = MU * p0 * hertz_forces(a)
    Q, w, spread = [], [], []
    for x in xs:
        c = a * (1 - x) ** (1 / 3)
        f = unit_a - MU * p0 * (c / a) * hertz_forces(c)
        force = np.zeros(3 * len(r))
        force[0::3] = f
        w1 = cho_solve(W, force)[0::3]
        Q.append(f.sum())
        w.append(w1[centre])
        spread.append(np.ptp(w1[r < c - h]))
    Q, w = np.array(Q), np.array(w)
    g = w - Q * w[0] / Q[0]
    gm = g_md(Q, P, a)
    print(f"\nn = {n} (graded), a/h = {a / h:.2f}, P = {P:.6g}; Σf/μP − x at most {np.abs(Q / (MU * P) - xs).max():.1e}")
    print("\n| Q/μP | g_el/g_MD | spread of w1 inside c − h / g_MD |")
    print("|---|---|---|")
    for k in range(1, len(xs), 4):
        print(f"| {xs[k]} | {g[k] / gm[k]:.4f} | {spread[k] / gm[k]:.4f} |")
    fit = np.asarray(xs) >= 0.4
    c, e = np.linalg.lstsq(np.column_stack([gm[fit], Q[fit]]), g[fit], rcond=None)[0]
    print(f"g_el ≈ c·g_MD + e·Q on x ≥ 0.4: c = {c:.4f}, e·8a/K = {e * 8 * a / loop.KCOMP:+.4f}")
    print("| Q*/μP | Masing area of g_el / ΔW |")
    print("|---|---|")
    for xstar in (0.3, 0.5, 0.7, 0.9):
        print(f"| {xstar} | {masing_area(Q, g, xstar * MU * P) / loop.analytic(P, a)[1](xstar * MU * P):.4f} |")
    return np.asarray(xs)[1:], (g / gm)[1:]            # g_el = 0 at x0 by construction


def main(argv):
    m, sizes, mode, at, path = 16, [], "virgin", (0.3, 0.5, 0.7, 0.9), None
    it = iter(argv)
    for arg in it:
        if arg == "--steps":
            m = int(next(it))
        elif arg == "--figure":
            path = next(it)
        elif arg == "--at":
            at = tuple(float(v) for v in next(it).split(","))
        elif arg in ("--depth", "--f3", "--fine"):
            loop.set_geometry(**{arg[2:]: float(next(it))})
        elif arg == "--nu":
            loop.set_poisson(float(next(it)))
        elif arg in ("--rings", "--elastic", "--unloading"):
            mode = arg[2:]
        else:
            sizes.append(int(arg))
    curves = {}
    for n in sizes or [48]:
        if mode == "rings":
            rings(n)
        elif mode == "elastic":
            elastic(n)
        elif mode == "unloading":
            unloading(n, m)
        else:
            v = virgin(n, m)
            report(v, at)
            curves[f"n = {n}, contactopt"] = (v["Q"] / (MU * v["P"]), v["g"] / g_md(v["Q"], v["P"], v["a"]))
    if path and curves:
        for n in sizes or [48]:
            curves[f"n = {n}, Mindlin's tractions on the FE bodies"] = elastic(n)
        figure(curves, path)


if __name__ == "__main__":
    main(sys.argv[1:])
