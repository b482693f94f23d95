"""Hertz contact of two elastic curved bodies: a spherical pad on a spherical seat.

The pad (radius R1, convex, above) and the seat (radius R2, below; convex, or concave with
R2 > R1) are graded blocks L × L × L whose facing faces are the paraboloids x3 = r²/(2R1) and
x3 = δ ∓ r²/(2R2) (small-deformation Hertz: the spheres' paraboloids, flat from r = 4a on), the seat raised by the
interference δ (``[body] interference``); both clamped at their far faces, a quarter model with
the symmetry planes x1 = 0 and x2 = 0 through both bodies, frictionless, the same material. The
pad's face is designed on the plane chart normal to x3 (``design.chart = "plane"``, ``axis``),
its contact normals e3, its partners on the seat's top face along them (matching meshes).

Measured: the resultant P = 4 Σ λ_m, the contact radius a and peak pressure p0 of the fit
p² = p0²(1 − r²/a²) (:func:`contactopt.verification.hertz.fit`), against Hertz for P:
a = (3PR/(4E*))^(1/3), p0 = 3P/(2πa²), 1/R = 1/R1 ± 1/R2 (concave seat: −), 1/E* = 2(1 − ν²)/E.
Used by tests/test_charts.py (coarse) and benchmarks/lame.py (the refinements of docs/charts.md).
"""

from __future__ import annotations

import math

import numpy as np

from .hertz import fit, graded_axis
from .lame import NU, E

R1, R2 = 10.0, 20.0
A_TARGET = 0.5


def effective_radius(R1=R1, R2=R2, concave=False) -> float:
    return 1.0 / (1.0 / R1 - 1.0 / R2) if concave else 1.0 / (1.0 / R1 + 1.0 / R2)


def _block(path, x, z, lift, groups):
    """A graded block on the grid x × x × z (hexahedra), each node raised by lift(r, z); ``groups``:
    name → (axis, value) of its boundary faces. Written as Gmsh 2.2 with those physical groups."""
    import meshio

    from ..mesh.block import graded_block_mesh
    ref = graded_block_mesh(x, x, np.asarray(z) - z[0])
    pts = ref.points + [0.0, 0.0, z[0]]
    r = np.hypot(pts[:, 0], pts[:, 1])
    pts[:, 2] += lift(r, pts[:, 2])
    bnd = ref.boundary_faces()
    blocks, tags, fd = [], [], {}
    for t, (name, (axis, value)) in enumerate(groups.items(), start=1):
        on = np.all(np.abs(ref.points[bnd, axis] + (z[0] if axis == 2 else 0.0) - value) < 1e-12, axis=1)
        blocks.append(("quad", bnd[on]))
        tags.append(np.full(int(on.sum()), t))
        fd[name] = np.array([t, 2])
    blocks.append(("hexahedron", ref.cells))
    tags.append(np.full(ref.n_cells, len(groups) + 1))
    fd["volume"] = np.array([len(groups) + 1, 3])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data=fd), file_format="gmsh22", binary=False)
    return str(path)


def two_spheres_config(directory, h: float, *, concave=False, size=20.0, R1=R1, R2=R2) -> dict:
    """The configuration (a dict) of the pad on the seat, mesh size h in the contact region."""
    L = size * A_TARGET
    x = graded_axis(h, 1.6 * A_TARGET, L)
    R = effective_radius(R1, R2, concave)
    delta = A_TARGET ** 2 / R
    s2 = -1.0 if not concave else 1.0
    rc = np.minimum(x[-1], 4 * A_TARGET)        # the paraboloids end flat 4a out: far from the contact
    pad = _block(f"{directory}/pad.msh", x, x, lambda r, z: np.minimum(r, rc) ** 2 / (2 * R1) * (1 - z / L),
                 {"contact": (2, 0.0), "top": (2, L)})
    zs = [-v for v in reversed(x)]
    seat = _block(f"{directory}/seat.msh", x, zs, lambda r, z: (delta + s2 * np.minimum(r, rc) ** 2 / (2 * R2)) * (1 + z / L),
                  {"top": (2, 0.0), "bottom": (2, -L)})
    sym = [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]
    return {
        "name": "two-spheres",
        "body": {"mesh": pad, "contact": "contact", "interference": True, "clamped": ["top"] + sym},
        "material": {"E": E, "nu": NU}, "friction": {"coefficient": 0.0},
        "loads": {"body_force": [0.0, 0.0, 0.0]},
        "design": {"degree": [2, 2], "initial": 0.0, "C0": 0.1, "C1": 1.0, "C2": 0.0, "chart": "plane",
                   "axis": [0.0, 0.0, -1.0]},
        "state": {"method": "newton", "tol": 1e-12, "max_iter": 200},
        "linear_solver": {"path": "condensation"},
        "foundation": {"mesh": seat, "top": "top", "partner": "point", "clamped": ["bottom"] + sym},
    }


def measure(problem, concave=False, R1=R1, R2=R2) -> dict:
    """P, the fitted (a, p0) and Hertz's for P (module docstring)."""
    m = problem.model
    st = problem.solve_state(np.zeros(m.n_design))
    x = m.body.reference.points[m.contact_nodes]
    r, p = np.hypot(x[:, 0], x[:, 1]), st.lam / m.contact_areas()
    P = 4.0 * float(st.lam.sum())
    a_fit, p0_fit = fit(r, p)
    e_star = E / (2 * (1 - NU ** 2))
    R = effective_radius(R1, R2, concave)
    a = (3 * P * R / (4 * e_star)) ** (1 / 3)
    return {"P": P, "a": a_fit, "a_H": a, "p0": p0_fit, "p0_H": 3 * P / (2 * math.pi * a ** 2),
            "p": m.n_contact, "counts": st.counts}
