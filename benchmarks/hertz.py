"""Hertz validation of the rigid obstacles ([obstacle], docs/obstacles.md): one command,

    PYTHONPATH=src python benchmarks/hertz.py [--levels 3] [--figure docs/figures/obstacles_hertz.png]

- **Sphere**: a rigid sphere of radius R pressed by the force P (control = "force") into a block
  clamped at its far face, frictionless; a quarter model (u1 = 0 on x1 = 0, u2 = 0 on x2 = 0), the mesh
  uniform (h) out to 1.6 a and graded geometrically to L = H = 20 a. P = 4 Σ λ_m n3_m (the quarter's
  nodal forces); the contact radius a and the peak pressure p0 from a least-squares fit of
  p² = p0² (1 − r²/a²) to the nodal pressures p_m = λ_m / A_m (A_m the tributary area) inside the
  contact, against a = (3PR/4E*)^(1/3), p0 = 3P/(2πa²) and δ = a²/R (E* = E/(1 − ν²)). The
  prescribed δ is the approach to the clamped face at depth H; Hertz's is to points far away, so the
  column δ + w(H) adds the half-space's displacement at depth H on the axis (Boussinesq,
  w = P(1 + ν)(3 − 2ν)/(2πEH)).
- **Cylinder**: a rigid cylinder along x2 pressed into a long block: a half model (u1 = 0 on
  x1 = 0) one element long with u2 = 0 on both ends (plane strain: every section is the section
  far from a long block's ends); P′ = 2 Σ λ_m n3_m / b against a = √(4P′R/(πE*)), p0 = 2P′/(πa).

Prints one table per shape over the refinements h = a/3, a/6, a/12 (``--levels``), errors relative;
then, at h = a/6, the sphere with F = 0.3 against F = 0 (Goodman's coupling) and a half model of
the sphere pressed and moved sideways (d1 along x1, Q < FP): its stick core against Mindlin's
radius (``--figure``: the pressure profiles, and the stick/slip map beside it, ``*_stick.png``).
"""

from __future__ import annotations

import argparse
import copy
import math
import time

import numpy as np

from contactopt.config import load_config, validate
from contactopt.problem import ShapeProblem

E, NU, R = 1.0, 0.3, 10.0
E_STAR = E / (1 - NU ** 2)
A_TARGET = 0.5                      # the contact radius the prescribed δ aims at (δ = a²/R)


def graded_axis(h: float, fine: float, length: float, growth: float = 1.25) -> list:
    """Nodes 0, h, 2h, … up to ``fine``, then steps growing by ``growth`` up to ``length``."""
    x = list(np.arange(0.0, fine + 0.5 * h, h))
    step = h
    while x[-1] < length:
        step *= growth
        x.append(min(x[-1] + step, length))
    if length - x[-2] < 0.5 * step:      # no sliver at the end
        x.pop(-2)
    return [float(v) for v in x]


def configure(updates: dict):
    """Example 1's configuration with ``updates`` (its [mesh] replaced, the other sections updated)."""
    data = copy.deepcopy(load_config("example1").data)
    for sec, vals in updates.items():
        data[sec] = dict(vals) if sec == "mesh" else {**data.get(sec, {}), **vals}
    return validate(data, "hertz")


def common(friction=0.0):
    return {"material": {"E": E, "nu": NU}, "friction": {"coefficient": friction},
            "state": {"method": "newton", "tol": 1e-12, "max_iter": 200},
            "linear_solver": {"path": "condensation"},
            "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
            "design": {"degree": [2, 2], "initial": 0.0, "C0": 0.1, "C1": 1.0, "C2": 0.0}}


P_SPHERE = 4 * E_STAR * A_TARGET ** 3 / (3 * R)     # the force of contact radius A_TARGET


def sphere_problem(h: float, friction=0.0, size=20.0, force=P_SPHERE) -> ShapeProblem:
    """The quarter model pressed by the force P (the quarter carries P/4; control = "force")."""
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    cfg = configure({
        **common(friction), "geometry": {"a": L, "b": L, "c": L}, "mesh": {"x1": x, "x2": x, "x3": x},
        "body": {"clamped": ["top", {"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "sphere", "center": [0.0, 0.0, -R], "radius": R, "control": "force",
                     "force": [0.0, 0.0, force / 4]}})
    return ShapeProblem(cfg)


def punch_stl(path: str, radius: float, sides: int = 96, depth: float = 5.0) -> str:
    """A closed STL of a flat cylindrical punch: the ``sides``-gon of circumradius ``radius`` about
    the x3 axis (a vertex on x1 and on x2), its top face on x3 = 0, extruded down to −depth."""
    import meshio
    t = 2 * np.pi * np.arange(sides) / sides
    ring = np.c_[radius * np.cos(t), radius * np.sin(t)]
    pts = np.r_[np.c_[ring, np.zeros(sides)], np.c_[ring, np.full(sides, -depth)], [[0, 0, 0], [0, 0, -depth]]]
    tri = []
    for i in range(sides):
        j = (i + 1) % sides
        tri += [(i, sides + i, sides + j), (i, sides + j, j), (2 * sides, i, j), (2 * sides + 1, sides + j, sides + i)]
    meshio.write(path, meshio.Mesh(pts, [("triangle", np.asarray(tri))]), file_format="stl", binary=True)
    return path


def punch_problem(h: float, stl: str, radius: float, force: float, size=20.0) -> ShapeProblem:
    """The quarter block pressed by the flat punch (a surface obstacle, control = "force")."""
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    cfg = configure({
        **common(), "geometry": {"a": L, "b": L, "c": L}, "mesh": {"x1": x, "x2": x, "x3": x},
        "body": {"clamped": ["top", {"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "surface", "mesh": stl, "control": "force", "force": [0.0, 0.0, force / 4]}})
    return ShapeProblem(cfg)


def measure_punch(h: float, stl: str, radius: float, force: float) -> dict:
    """The approach δ of the flat punch against δ = P/(2aE*) (+ the far face's w(H), as the sphere's)."""
    t0 = time.perf_counter()
    pr = punch_problem(h, stl, radius, force)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    H = pr.config["geometry"]["c"]
    delta = st.info["obstacle_translation"]
    w_H = force * (1 + NU) * (3 - 2 * NU) / (2 * math.pi * E * H)
    return {"h": h, "p": pr.model.n_contact, "P": force, "delta": delta, "delta_corr": delta + w_H,
            "delta_H": force / (2 * radius * E_STAR), "in_contact": int(np.sum(st.lam > 0)),
            "time": time.perf_counter() - t0}


def pushed_sphere(h: float, friction: float, d1: float, size=20.0, delta=A_TARGET ** 2 / R) -> ShapeProblem:
    """A half model (u2 = 0 on x2 = 0) of the sphere pressed δ and moved d1 along x1 (displacement
    control): the centre at x1 = L of a block 2L × L × L."""
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    x1 = [L - v for v in reversed(x)] + [L + v for v in x[1:]]
    cfg = configure({
        **common(friction), "geometry": {"a": 2 * L, "b": L, "c": L}, "mesh": {"x1": x1, "x2": x, "x3": x},
        "body": {"clamped": ["top", {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "sphere", "center": [L, 0.0, -R], "radius": R, "control": "displacement",
                     "displacement": [d1, 0.0, delta]}})
    return ShapeProblem(cfg)


def cylinder_problem(h: float, friction=0.0, size=20.0, delta=None) -> ShapeProblem:
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    b = h
    delta = delta if delta is not None else 2.0 * A_TARGET ** 2 / R
    cfg = configure({
        **common(friction), "geometry": {"a": L, "b": b, "c": L}, "mesh": {"x1": x, "ny": 1, "x3": x},
        "body": {"clamped": ["top", {"on": {"x1": 0.0}, "components": [1]},
                             {"on": {"x2": 0.0}, "components": [2]}, {"on": {"x2": b}, "components": [2]}]},
        "obstacle": {"shape": "cylinder", "point": [0.0, 0.0, -R], "axis": [0.0, 1.0, 0.0], "radius": R,
                     "control": "displacement", "displacement": [0.0, 0.0, delta]}})
    return ShapeProblem(cfg)


def pressure(problem: ShapeProblem, state):
    """(r, p, n3) of the contact nodes: distance to the axis of symmetry, nodal pressure λ/A, n·e3."""
    m = problem.model
    x = m.body.reference.points[m.contact_nodes]
    n3 = m.frames[:, 2, 2]
    r = np.hypot(x[:, 0], x[:, 1]) if m.obstacle.shape == "sphere" else np.abs(x[:, 0])
    return r, state.lam / m.contact_areas(), n3, x


def fit(r, p):
    """(a, p0) of p² = p0²(1 − r²/a²) fitted to the nodes in contact but the outermost ring."""
    inside = p > 0
    rim = r[inside].max()
    use = inside & (r < rim - 1e-12)
    c = np.polyfit(r[use] ** 2, p[use] ** 2, 1)
    p0 = math.sqrt(c[1])
    return math.sqrt(-c[1] / c[0]), p0


def measure_sphere(h: float, friction=0.0) -> dict:
    t0 = time.perf_counter()
    pr = sphere_problem(h, friction)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    r, p, n3, _ = pressure(pr, st)
    P = 4.0 * float(resultant(pr, st)[2])
    a_fit, p0_fit = fit(r, p)
    a = (3 * P * R / (4 * E_STAR)) ** (1 / 3)
    p0 = 3 * P / (2 * math.pi * a ** 2)
    delta = st.info["obstacle_translation"]
    # the approach is prescribed against the clamped far face at depth H, Hertz's against points far
    # away: add the half-space's displacement on the axis at depth H (Boussinesq, point load P)
    H = pr.config["geometry"]["c"]
    w_H = P * (1 + NU) * (3 - 2 * NU) / (2 * math.pi * E * H)
    return {"delta_corr": delta + w_H, "h": h, "p": pr.model.n_contact, "P": P, "a": a_fit, "a_H": a, "p0": p0_fit, "p0_H": p0,
            "p0_node": float(p[np.argmin(r)]), "delta": delta, "delta_H": a ** 2 / R,
            "time": time.perf_counter() - t0, "state": st, "problem": pr, "counts": st.counts}


def resultant(problem, state) -> np.ndarray:
    """Σ_m R_m r_m: the force the obstacle exerts on the (part) model, global components."""
    r = np.c_[-state.tau, state.lam]
    return np.einsum("mij,mj->i", problem.model.frames, r)


def measure_mindlin(h: float, friction=0.3, d1=0.0035) -> dict:
    """The sphere pressed δ and moved d1 sideways: Q, P, the stick radius against Mindlin's
    c = a (1 − Q/FP)^(1/3) (a the contact radius of the same model, fitted)."""
    t0 = time.perf_counter()
    pr = pushed_sphere(h, friction, d1)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    Q, _, P = 2.0 * resultant(pr, st)
    m = pr.model
    x = m.body.reference.points[m.contact_nodes]
    L = pr.config["geometry"]["a"] / 2
    r = np.hypot(x[:, 0] - L, x[:, 1])
    names = st.class_names
    stick = (names == "M3+") & (st.lam > 0)
    slip = (names == "M1") & (st.lam > 0)
    A = m.contact_areas()
    a = fit(r, st.lam / A)[0]
    # radii of the half discs of the areas in contact and sticking (tributary areas of their nodes)
    return {"h": h, "P": P, "Q": Q, "ratio": Q / (friction * P), "a": a, "stick": float(r[stick].max()),
            "slip": float(r[slip].min()), "c_mindlin": a * (1 - Q / (friction * P)) ** (1 / 3),
            "c_area": math.sqrt(2 * A[stick].sum() / math.pi), "a_area": math.sqrt(2 * A[st.lam > 0].sum() / math.pi),
            "state": st, "problem": pr, "x": x, "time": time.perf_counter() - t0}


def measure_cylinder(h: float, friction=0.0) -> dict:
    t0 = time.perf_counter()
    pr = cylinder_problem(h, friction)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    r, p, n3, x = pressure(pr, st)
    b = pr.config["geometry"]["b"]
    P1 = 2.0 * float(st.lam @ n3) / b
    a_fit, p0_fit = fit(r, p)
    a = math.sqrt(4 * P1 * R / (math.pi * E_STAR))
    p0 = 2 * P1 / (math.pi * a)
    return {"h": h, "p": pr.model.n_contact, "P": P1, "a": a_fit, "a_H": a, "p0": p0_fit, "p0_H": p0,
            "p0_node": float(p[np.argmin(r)]), "time": time.perf_counter() - t0, "state": st, "problem": pr}


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
    L = q["problem"].config["geometry"]["a"] / 2
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
