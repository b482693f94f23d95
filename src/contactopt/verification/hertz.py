"""Hertz, Mindlin and the flat punch with contactopt's rigid obstacles ([obstacle]): the set-ups and
what is measured on them, against the analytic solutions.

- **Sphere**: a rigid sphere of radius R pressed by the force P (control = "force") into a block
  clamped at its far face, frictionless; a quarter model (u1 = 0 on x1 = 0, u2 = 0 on x2 = 0), the mesh
  uniform (h) out to 1.6 a and graded geometrically to L = H = 20 a. P = 4 Σ λ_m n3_m (the quarter's
  nodal forces); the contact radius a and the peak pressure p0 from a least-squares fit of
  p² = p0² (1 − r²/a²) to the nodal pressures p_m = λ_m / A_m (A_m the tributary area) inside the
  contact, against a = (3PR/4E*)^(1/3), p0 = 3P/(2πa²) and δ = a²/R (E* = E/(1 − ν²)). The
  prescribed δ is the approach to the clamped face at depth H; Hertz's is to points far away, so
  δ + w(H) adds the half-space's displacement at depth H on the axis (Boussinesq,
  w = P(1 + ν)(3 − 2ν)/(2πEH)).
- **Cylinder**: a rigid cylinder along x2 pressed into a long block: a half model (u1 = 0 on
  x1 = 0) one element long with u2 = 0 on both ends (plane strain); P′ = 2 Σ λ_m n3_m / b against
  a = √(4P′R/(πE*)), p0 = 2P′/(πa).
- **Flat punch** (a closed STL cylinder): the approach against δ = P/(2aE*).
- **Mindlin**: the sphere pressed, then moved sideways (Q < FP): the stick core against
  c = a(1 − Q/FP)^(1/3).

Used by tests/test_obstacles.py (coarse meshes) and benchmarks/hertz.py (the refinement tables and
figures of docs/obstacles.md).
"""

from __future__ import annotations

import math
import time

import meshio
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
    """Example 1's configuration with ``updates`` (its [mesh] and arrays of tables replaced, the other
    sections updated)."""
    data = load_config("example1").to_dict()
    for sec, vals in updates.items():
        data[sec] = (list(vals) if isinstance(vals, list) else dict(vals) if sec == "mesh"
                     else {**data.get(sec, {}), **vals})
    return validate(data, "hertz")


def common(friction=0.0):
    return {"material": {"E": E, "nu": NU}, "friction": {"coefficient": friction},
            "state": {"method": "newton", "tol": 1e-12, "max_iter": 200},
            "linear_solver": {"path": "condensation"},
            "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
            "design": {"degree": [2, 2], "initial": 0.0, "C0": 0.1, "C1": 1.0, "C2": 0.0}}


P_SPHERE = 4 * E_STAR * A_TARGET ** 3 / (3 * R)     # the force of contact radius A_TARGET


def sphere_problem(h: float, friction=0.0, size=20.0, force=P_SPHERE, steps=0) -> ShapeProblem:
    """The quarter model pressed by the force P (the quarter carries P/4; control = "force");
    ``steps`` N > 0: P reached in N equal increments (one load step of N substeps)."""
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    updates = {
        **common(friction), "geometry": {"a": L, "b": L, "c": L}, "mesh": {"x1": x, "x2": x, "x3": x},
        "body": {"clamped": ["top", {"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "sphere", "center": [0.0, 0.0, -R], "radius": R, "control": "force",
                     "force": [0.0, 0.0, force / 4]}}
    if steps:
        updates["load_steps"] = [{"name": "press", "substeps": steps}]
    return ShapeProblem(configure(updates))


def punch_stl(path: str, radius: float, sides: int = 96, depth: float = 5.0) -> str:
    """A closed STL of a flat cylindrical punch: the ``sides``-gon of circumradius ``radius`` about
    the x3 axis (a vertex on x1 and on x2), its top face on x3 = 0, extruded down to −depth."""
    t = 2 * np.pi * np.arange(sides) / sides
    ring = np.c_[radius * np.cos(t), radius * np.sin(t)]
    pts = np.r_[np.c_[ring, np.zeros(sides)], np.c_[ring, np.full(sides, -depth)], [[0, 0, 0], [0, 0, -depth]]]
    tri = []
    for i in range(sides):
        j = (i + 1) % sides
        tri += [(i, sides + i, sides + j), (i, sides + j, j), (2 * sides, i, j), (2 * sides + 1, sides + j, sides + i)]
    meshio.write(path, meshio.Mesh(pts, [("triangle", np.asarray(tri))]), file_format="stl", binary=True)
    return path


def punch_problem(h: float, stl: str, radius: float, force: float, size=20.0, friction=0.0) -> ShapeProblem:
    """The quarter block pressed by the flat punch (a surface obstacle, control = "force")."""
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    cfg = configure({
        **common(friction), "geometry": {"a": L, "b": L, "c": L}, "mesh": {"x1": x, "x2": x, "x3": x},
        "body": {"clamped": ["top", {"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "surface", "mesh": stl, "control": "force", "force": [0.0, 0.0, force / 4]}})
    return ShapeProblem(cfg)


def measure_punch(h: float, stl: str, radius: float, force: float) -> dict:
    """The approach δ of the flat punch against δ = P/(2aE*) (+ the far face's w(H), as the sphere's)."""
    t0 = time.perf_counter()
    pr = punch_problem(h, stl, radius, force)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    H = pr.config.geometry.c
    delta = st.obstacle.translation
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
    delta = st.obstacle.translation
    # the approach is prescribed against the clamped far face at depth H, Hertz's against points far
    # away: add the half-space's displacement on the axis at depth H (Boussinesq, point load P)
    H = pr.config.geometry.c
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
    L = pr.config.geometry.a / 2
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
    b = pr.config.geometry.b
    P1 = 2.0 * float(st.lam @ n3) / b
    a_fit, p0_fit = fit(r, p)
    a = math.sqrt(4 * P1 * R / (math.pi * E_STAR))
    p0 = 2 * P1 / (math.pi * a)
    return {"h": h, "p": pr.model.n_contact, "P": P1, "a": a_fit, "a_H": a, "p0": p0_fit, "p0_H": p0,
            "p0_node": float(p[np.argmin(r)]), "time": time.perf_counter() - t0, "state": st, "problem": pr}
