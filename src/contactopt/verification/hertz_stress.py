"""Hertz contact: the peak von Mises stress of a paraboloid pressed onto the rigid foundation.

A block [−L, L]² × [0, H] of hexahedra whose bottom is lifted by r²/2R (written with meshio, read
with ``[body] initial_gap = "mesh"``), its top clamped, frictionless. Displacement control: the
foundation is raised by δ (the gaps g_m = z_m − δ, set through the Python API), so the centre
penetrates and the contact force P = Σλ follows. With P measured, Hertz gives (rigid foundation,
E* = E/(1 − ν²))

    a = (3PR/(4E*))^(1/3),   p0 = 3P/(2πa²),

and on the axis (ζ = z/a) σ_z = −p0/(1 + ζ²), σ_r = σ_θ = p0[−(1 + ν)(1 − ζ atan(1/ζ)) + 1/(2(1 + ζ²))],
so σ_vM = |σ_z − σ_r|, whose maximum at ν = 0.3 is 0.620 p0 at ζ = 0.481. The mesh is uniform
(h = a/n) in a cube of side 3a around the contact centre and graded outside; L = H = 8a.

The table: ``python benchmarks/bench_hertz.py [n ...] [--figure PNG]`` (default n = 3 4
6 8): one row per refinement, FE peak against the analytic value and the depth of the peak. Results in
docs/objectives.md.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import meshio
import numpy as np
from scipy.optimize import minimize_scalar

from contactopt.config import load_config
from contactopt.fem.stress import quadrature_points
from contactopt.mesh.block import block_mesh
from contactopt.problem import ShapeProblem

E, NU, R, A_TARGET = 21.19, 0.3, 10.0, 0.1


def hertz_axis(nu: float = NU):
    """(max σ_vM/p0, its depth ζ = z/a) on the axis of the Hertz contact (module docstring)."""

    def vm(z):
        sz = -1.0 / (1.0 + z * z)
        sr = -(1.0 + nu) * (1.0 - z * np.arctan(1.0 / z)) + 0.5 / (1.0 + z * z)
        return abs(sz - sr)
    res = minimize_scalar(lambda z: -vm(z), bounds=(0.05, 2.0), method="bounded", options={"xatol": 1e-10})
    return vm(res.x), float(res.x)


def graded(h: float, fine: float, end: float, ratio: float = 1.3) -> np.ndarray:
    """Nodes 0 = x_0 < … ≤ end: spacing h up to ``fine``, then growing by ``ratio`` (the last
    interval ends exactly at ``end``)."""
    x = list(np.arange(0.0, fine + 0.5 * h, h))
    step = h
    while x[-1] < end - 1e-12:
        step *= ratio
        x.append(min(x[-1] + step, end))
        if end - x[-1] < 0.5 * step * ratio:
            x[-1] = end
    return np.array(x)


def hertz_mesh(path: Path, n: int, a: float = A_TARGET, ratio: float = 1.3) -> Path:
    """The lifted block of the module docstring as a Gmsh 2.2 file with groups body, top, contact
    (the bottom quadrilaterals within 1.5a of the axis)."""

    h = a / n
    half = graded(h, 1.5 * a, 8 * a, ratio)
    xs = np.concatenate([-half[:0:-1], half])
    zs = graded(h, 1.5 * a, 8 * a, ratio)
    ref = block_mesh(len(xs) - 1, len(xs) - 1, len(zs) - 1, len(xs) - 1, len(xs) - 1, len(zs) - 1)
    idx = np.rint(ref.points).astype(int)
    pts = np.column_stack((xs[idx[:, 0]], xs[idx[:, 1]], zs[idx[:, 2]]))
    H = zs[-1]
    r2 = pts[:, 0] ** 2 + pts[:, 1] ** 2
    pts[:, 2] += r2 / (2 * R) * (1.0 - pts[:, 2] / H)
    bottom = ref.parts["contact"].faces
    centre = pts[bottom].mean(axis=1)
    contact = bottom[np.max(np.abs(centre[:, :2]), axis=1) <= 1.5 * a + 1e-9]
    cells = [("hexahedron", ref.cells), ("quad", contact), ("quad", ref.parts["top"].faces)]
    tags = [np.full(len(c[1]), k + 1) for k, c in enumerate(cells)]
    m = meshio.Mesh(pts, cells, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                    field_data={"body": np.array([1, 3]), "contact": np.array([2, 2]), "top": np.array([3, 2])})
    meshio.write(path, m, file_format="gmsh22", binary=False)
    return path


def hertz_problem(mesh: Path, path: str = "condensation"):
    cfg = load_config({
        "name": "hertz",
        "body": {"mesh": str(mesh), "contact": "contact", "clamped": "top", "initial_gap": "mesh"},
        "material": {"E": E, "nu": NU}, "friction": {"coefficient": 0.0},
        "design": {"degree": [2, 2], "C0": 0.01, "C1": 0.5, "C2": 0.0, "initial": 0.0},
        "objective": {"type": "peak_stress"},
        "state": {"tol": 1e-12},
        "linear_solver": {"path": path, "memory_check": False},
    })
    return ShapeProblem(cfg)


def hertz_peak(n: int, *, a: float = A_TARGET, path: str = "condensation", workdir=None) -> dict:
    """The FE peak von Mises stress of the refinement n against Hertz (module docstring)."""
    with tempfile.TemporaryDirectory() as tmp:
        mesh = hertz_mesh(Path(workdir or tmp) / f"hertz_{n}.msh", n, a)
        t0 = time.perf_counter()
        problem = hertz_problem(mesh, path)
        model = problem.model
        model.gap0 = model.gap0 - a * a / R          # the foundation raised by δ = a²/R
        alpha = np.zeros(model.n_design)
        state = problem.solve_state(alpha)
        obj = problem.objective
        vm = obj.values(state)
        e, q = np.unravel_index(int(np.argmax(vm)), vm.shape)
        xq = quadrature_points(model.assembler, state.coords, obj.cells)
        x = xq[e, q]
        seconds = time.perf_counter() - t0
    P = float(state.lam.sum())
    Es = E / (1 - NU ** 2)
    a_h = (3 * P * R / (4 * Es)) ** (1 / 3)
    p0 = 3 * P / (2 * np.pi * a_h ** 2)
    ratio, zeta = hertz_axis()
    return {"n": n, "dofs": model.assembler.n_free, "contact_nodes": model.n_contact, "P": P, "a": a_h,
            "p0": p0, "peak": float(vm[e, q]), "peak_over_p0": float(vm[e, q]) / p0,
            "analytic_over_p0": ratio, "error": float(vm[e, q]) / (ratio * p0) - 1.0,
            "depth_over_a": float(x[2]) / a_h, "analytic_depth": zeta, "r_over_a": float(np.hypot(x[0], x[1])) / a_h,
            "contact_radius_nodes": int(np.sum(state.lam > 0)), "seconds": seconds,
            "axis": _near_axis(xq.reshape(-1, 3), vm.ravel(), a_h, p0)}


def _near_axis(x, vm, a, p0, radius=0.25):
    """(depth/a, σ_vM/p0) at the quadrature points within ``radius``·a of the axis, by depth."""
    near = (np.hypot(x[:, 0], x[:, 1]) < radius * a) & (x[:, 2] < 2.5 * a)
    order = np.argsort(x[near, 2])
    return x[near, 2][order] / a, vm[near][order] / p0
