"""A wedge in a rigid V-groove: both flanks carry the load, against statics.

The wedge is a prism along x2 (0 ≤ x2 ≤ W, u2 = 0 on both end faces: plane strain) whose cross
section in (x1, x3) is the trapezoid between its flat bottom x3 = z0 and its top x3 = H, its flanks
x1 = ±x3 tan β on the flanks of a rigid V-groove of half-angle β (the angle between a flank and the
vertical) with its apex at the origin: the flanks touch the groove with zero gap, the bottom stays
clear of it. A pressure q on the top presses it in; nothing else holds it along x1 and x3 (a body
held by its contact, :mod:`contactopt.paths.rigid`). The groove is a closed STL surface (an obstacle
``shape = "surface"``).

Statics of the whole wedge, F = q · 2H tan β · W the load and N the normal force on each flank
(outward normal n = (±cos β, 0, −sin β) of the wedge):

- frictionless: 2N sin β = F, N = F / (2 sin β);
- with friction F_c sliding in (every contact node slides down its flank, the friction on the wedge
  up the flank): 2N (sin β + F_c cos β) = F.

The full model has both flanks as its contact face (a graph over (x1, x2): the paper's vertical
chart); the half model x1 ≥ 0 has one flank and the symmetry plane x1 = 0 (u1 = 0), whose contact
face is a plane that is not horizontal, designed along its normal (``motion = "normal"`` on its
best-fit plane): its design is mirrored to the other flank by the symmetry plane.
Used by tests/test_vgroove.py and examples/vgroove.toml (examples/vgroove/make_mesh.py).
"""

from __future__ import annotations

import meshio
import numpy as np

E, NU = 1.0, 0.3
BETA = np.radians(30.0)          # the groove's half-angle
Z0, H, W = 0.25, 1.0, 0.5        # the wedge's bottom, top and width along x2
Q = 0.01                         # the pressure on the top


def load(q=Q, beta=BETA, h=H, w=W) -> float:
    """F: the whole wedge's load, q times its top's area."""
    return q * 2 * h * np.tan(beta) * w


def flank_force(friction=0.0, q=Q, beta=BETA, h=H, w=W) -> float:
    """N, the normal force on each flank from statics (module docstring): F / (2 (sin β + F_c cos β))."""
    return load(q, beta, h, w) / (2 * (np.sin(beta) + friction * np.cos(beta)))


def wedge_mesh(path, n1: int, n3: int, n2: int, *, half: bool = False, beta=BETA, z0=Z0, h=H, w=W,
               grading: float = 1.0):
    """Write the wedge (module docstring) as hexahedra to a Gmsh 2.2 file: n1 cells across each half
    (x1 from the middle to a flank), n3 up, n2 along x2; ``half``: the half x1 ≥ 0 only. Groups:
    ``flank`` (the face(s) on the groove), ``top`` and ``wedge`` (the volume). ``grading`` > 1
    makes the cells across grow from the flank towards the middle. Returns ``path``."""
    g = grading ** np.arange(n1)[::-1]
    s = np.r_[0.0, np.cumsum(g)] / g.sum()                     # 0 at the middle, 1 at the flank
    s = s if half else np.r_[-s[:0:-1], s]
    eta = np.arange(n3 + 1) / n3
    y = w * np.arange(n2 + 1) / n2
    S, Et, Y = np.meshgrid(s, eta, y, indexing="ij")
    z = z0 + Et * (h - z0)
    pts = np.c_[(S * z * np.tan(beta)).ravel(), Y.ravel(), z.ravel()]
    pts[np.abs(pts) < 1e-15] = 0.0
    m1 = s.size

    def node(i, j, k):
        return (i * (n3 + 1) + j) * (n2 + 1) + k
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(m1 - 1), np.arange(n3), np.arange(n2), indexing="ij"))
    # (x1, x3, x2) is left-handed: order the base (i, k), (i+1, k), (i+1, k+1), (i, k+1) in x1, x2, then up in x3
    hexes = np.stack([node(i, j, k), node(i + 1, j, k), node(i + 1, j, k + 1), node(i, j, k + 1),
                      node(i, j + 1, k), node(i + 1, j + 1, k), node(i + 1, j + 1, k + 1), node(i, j + 1, k + 1)],
                     axis=1)
    j, k = (a.ravel() for a in np.meshgrid(np.arange(n3), np.arange(n2), indexing="ij"))
    flanks = [np.stack([node(m1 - 1, j, k), node(m1 - 1, j + 1, k), node(m1 - 1, j + 1, k + 1),
                        node(m1 - 1, j, k + 1)], axis=1)]
    if not half:
        flanks.append(np.stack([node(0, j, k), node(0, j, k + 1), node(0, j + 1, k + 1), node(0, j + 1, k)], axis=1))
    flank = np.vstack(flanks)
    i, k = (a.ravel() for a in np.meshgrid(np.arange(m1 - 1), np.arange(n2), indexing="ij"))
    top = np.stack([node(i, n3, k), node(i + 1, n3, k), node(i + 1, n3, k + 1), node(i, n3, k + 1)], axis=1)
    blocks = [("quad", flank), ("quad", top), ("hexahedron", hexes)]
    tags = [np.full(len(flank), 1), np.full(len(top), 2), np.full(len(hexes), 3)]
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data={"flank": np.array([1, 2]), "top": np.array([2, 2]),
                                               "wedge": np.array([3, 3])}),
                 file_format="gmsh22", binary=False)
    return str(path)


def groove_stl(path, *, beta=BETA, h=H, w=W):
    """Write the rigid V-groove (module docstring) as a closed STL: the block |x1| ≤ 2h, −h ≤ x3 ≤
    1.5 h tan… with the V notch of half-angle β from the apex (0, 0) up to x3 = 1.5 h, extruded along
    x2 beyond the wedge (−w to 2w), its caps fanned from the centroid. Returns ``path``."""
    top = 1.5 * h
    half = 2.0 * h
    poly = np.array([(-half, -h), (half, -h), (half, top), (top * np.tan(beta), top), (0.0, 0.0),
                     (-top * np.tan(beta), top), (-half, top)])
    k = len(poly)
    c = np.array([0.0, -0.5 * h])                 # the notch and every edge are seen from here
    y0, y1 = -w, 2 * w
    pts = [(u, y0, v) for u, v in poly] + [(u, y1, v) for u, v in poly] + [(c[0], y0, c[1]), (c[0], y1, c[1])]
    tri = []
    for i in range(k):
        j = (i + 1) % k
        tri += [(i, j, k + j), (i, k + j, k + i), (2 * k, j, i), (2 * k + 1, k + i, k + j)]
    meshio.write(path, meshio.Mesh(np.asarray(pts, float), [("triangle", np.asarray(tri))]), file_format="stl",
                 binary=True)
    return str(path)


def config(mesh_path, groove_path, *, half: bool = False, friction=0.0, q=Q, w=W, path="condensation",
           **updates) -> dict:
    """The configuration (a dict) of the wedge of ``mesh_path`` (:func:`wedge_mesh`) in the groove
    of ``groove_path`` (:func:`groove_stl`): u2 = 0 on both end faces, u1 = 0 on x1 = 0 (``half``),
    the pressure q on the top; the full wedge on the paper's chart (vertical motion), the half on
    its flank's plane, moved along the normal."""
    clamped = [{"on": {"x2": 0.0}, "components": [2]}, {"on": {"x2": w}, "components": [2]}]
    design = {"degree": [3, 0], "initial": 0.0, "C0": 0.02, "C2": 0.0}
    if half:
        clamped.append({"on": {"x1": 0.0}, "components": [1]})
        design.update({"motion": "normal", "chart": "plane"})
    cfg = {
        "name": "vgroove",
        "body": {"mesh": str(mesh_path), "contact": "flank", "clamped": clamped, "initial_gap": "mesh"},
        "material": {"E": E, "nu": NU},
        "friction": {"coefficient": friction},
        "loads": {"pressure": [{"on": "top", "value": q}]},
        "obstacle": {"shape": "surface", "mesh": str(groove_path)},
        "design": design,
        "state": {"method": "newton", "tol": 1e-12},
        "linear_solver": {"path": path},
    }
    for key, val in updates.items():
        cfg.setdefault(key, {}).update(val)
    return cfg


def flank_forces(problem, state, beta=BETA) -> dict:
    """The contact forces of ``state`` per flank (x1 > 0: "right", x1 < 0: "left"; a half model has
    the right one only): {"normal": Σλ, "up": the friction's resultant along the flank's up-slope
    direction, "vertical": the x3 component of the forces' resultant, "slide": the fraction of the
    flank's contact nodes that slide (M1, M2)}. Convention: per node the frame R_m = (t1, t2, n),
    n the groove's outward normal; the force on the wedge R_m (−τ1, −τ2, λ), λ ≥ 0."""
    model = problem.model
    x = model.body.reference.points[model.contact_nodes]
    R = model.frames
    force = np.einsum("pij,pj->pi", R, np.c_[-state.tau, state.lam])
    names = state.class_names
    out = {}
    for side, sel, sign in (("right", x[:, 0] > 0, 1.0), ("left", x[:, 0] < 0, -1.0)):
        if sel.any():
            up = np.array([sign * np.sin(beta), 0.0, np.cos(beta)])
            out[side] = {"normal": float(state.lam[sel].sum()), "up": float((force[sel] @ up).sum()),
                         "vertical": float(force[sel, 2].sum()),
                         "slide": float(np.isin(names[sel], ("M1", "M2")).mean())}
    return out
