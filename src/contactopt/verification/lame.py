"""Lamé's shrink fit with contactopt's curved contact faces: a hub's bore on a shaft.

A hub (inner radius b, outer radius c, length L) sits on a shaft whose radius exceeds b by the
radial interference δ. Plane strain (u3 = 0 on both end faces: generalized plane strain without
axial load), frictionless, a quarter model with the symmetry planes x1 = 0 (u1 = 0) and x2 = 0
(u2 = 0) through the contact face. The contact face is the bore, a cylinder around x3: its chart
is the cylinder's (arc length, axial position), the design moves it along its normal.

Analytic contact pressure (thick-walled cylinders in plane strain):

- rigid shaft: p = E δ (c² − b²) / ((1 + ν) b ((1 − 2ν) b² + c²)), the hub's bore pushed out by δ;
- shaft of the hub's material: p = E δ (c² − b²) / (2 (1 − ν²) b c²).

The hub's mesh is structured in (r, θ, x3) with its bore as the named part ``bore``; the contact
pressure p_m = λ_m / A_m (A_m the tributary area of node m on the faceted bore) is compared with p.
Used by tests/test_charts.py (coarse) and benchmarks/lame.py (the refinements of docs/charts.md).
"""

from __future__ import annotations

import meshio
import numpy as np

from ..fem.loadset import LoadSet

E, NU = 1.0, 0.3
B, C, DELTA = 1.0, 2.0, 1e-3


def pressure_rigid_shaft(E=E, nu=NU, b=B, c=C, delta=DELTA) -> float:
    """Lamé's contact pressure of a hub (b, c) pushed out by δ at its bore (rigid shaft), plane strain."""
    return E * delta * (c * c - b * b) / ((1 + nu) * b * ((1 - 2 * nu) * b * b + c * c))


def pressure_equal_materials(E=E, nu=NU, b=B, c=C, delta=DELTA) -> float:
    """Lamé's shrink-fit pressure of a hub (b, c) on a solid shaft of the same material, plane strain."""
    return E * delta * (c * c - b * b) / (2 * (1 - nu * nu) * b * c * c)


def quarter_hub_mesh(path, nr: int, nt: int, nz: int, b=B, c=C, length=0.25, grading=1.0, angle=0.5 * np.pi,
                     ends: bool = False):
    """Write the quarter hub b ≤ r ≤ c, 0 ≤ θ ≤ ``angle`` (π/2), 0 ≤ x3 ≤ length as hexahedra (nr × nt × nz) to a
    Gmsh 2.2 file with the physical groups ``bore`` (its faces at r = b) and ``hub`` (the volume).
    ``grading`` > 1 makes the radial elements grow geometrically from the bore. ``ends``: also the
    node group ``ends``, the nodes of both end faces off the bore (r > b). Returns ``path``."""
    w = grading ** np.arange(nr)
    r = b + (c - b) * np.r_[0.0, np.cumsum(w)] / w.sum()
    t = angle * np.arange(nt + 1) / nt
    z = length * np.arange(nz + 1) / nz
    R, T, Z = np.meshgrid(r, t, z, indexing="ij")
    pts = np.c_[(R * np.cos(T)).ravel(), (R * np.sin(T)).ravel(), Z.ravel()]
    pts[np.abs(pts) < 1e-15] = 0.0

    def node(i, j, k):
        return (i * (nt + 1) + j) * (nz + 1) + k
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(nr), np.arange(nt), np.arange(nz), indexing="ij"))
    hexes = np.stack([node(i, j, k), node(i + 1, j, k), node(i + 1, j + 1, k), node(i, j + 1, k),
                      node(i, j, k + 1), node(i + 1, j, k + 1), node(i + 1, j + 1, k + 1), node(i, j + 1, k + 1)],
                     axis=1)
    j, k = (a.ravel() for a in np.meshgrid(np.arange(nt), np.arange(nz), indexing="ij"))
    bore = np.stack([node(0, j, k), node(0, j + 1, k), node(0, j + 1, k + 1), node(0, j, k + 1)], axis=1)
    blocks = [("quad", bore), ("hexahedron", hexes)]
    tags = [np.full(len(bore), 1), np.full(len(hexes), 2)]
    field = {"bore": np.array([1, 2]), "hub": np.array([2, 3])}
    if ends:
        i, j, k = (a.ravel() for a in np.meshgrid(np.arange(1, nr + 1), np.arange(nt + 1), [0, nz], indexing="ij"))
        blocks.append(("vertex", node(i, j, k)[:, None]))
        tags.append(np.full(i.size, 3))
        field["ends"] = np.array([3, 0])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data=field),
                 file_format="gmsh22", binary=False)
    return str(path)


def _write_groups(path, pts, surface, hexes, names, ends=None):
    pts = np.asarray(pts, float)
    pts[np.abs(pts) < 1e-15] = 0.0
    blocks = [("quad", surface), ("hexahedron", hexes)]
    tags = [np.full(len(surface), 1), np.full(len(hexes), 2)]
    field = {names[0]: np.array([1, 2]), names[1]: np.array([2, 3])}
    if ends is not None:
        blocks.append(("vertex", np.asarray(ends)[:, None]))
        tags.append(np.full(len(ends), 3))
        field["ends"] = np.array([3, 0])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data=field),
                 file_format="gmsh22", binary=False)
    return str(path)


def quarter_shaft_mesh(path, n: int, nt: int, nz: int, radius=B, length=0.25, core=0.5, ends: bool = False):
    """Write the quarter of a solid shaft r ≤ ``radius``, 0 ≤ θ ≤ π/2, 0 ≤ x3 ≤ length as hexahedra
    (an O-grid: an n × n square core [0, core·radius]² and a ring of nt/2 + nt/2 cells around it,
    n radial layers, nt cells along the arc at equal angles, nz along x3; nt even) to a Gmsh 2.2
    file with the physical groups ``surface`` (its faces at r = radius) and ``shaft``; ``ends``: also
    the node group ``ends``, the nodes of both end faces off the surface (r < radius)."""
    if nt % 2:
        raise ValueError("nt must be even")
    s = core * radius
    h = nt // 2
    # the core's nodes, then the ring's (layers 1..n, layer 0 is the core's boundary)
    ii, jj = np.meshgrid(np.arange(h + 1), np.arange(h + 1), indexing="ij")
    core_xy = np.c_[(s * ii / h).ravel(), (s * jj / h).ravel()]
    core_id = (ii * (h + 1) + jj)
    # the core's outer boundary from θ = 0 to π/2: along x1 = s upwards, then along x2 = s leftwards
    bnd = [core_id[h, j] for j in range(h + 1)] + [core_id[i, h] for i in range(h - 1, -1, -1)]
    theta = 0.5 * np.pi * np.arange(nt + 1) / nt
    arc = radius * np.c_[np.cos(theta), np.sin(theta)]
    inner = core_xy[bnd]
    ring_xy = [inner + (k / n) * (arc - inner) for k in range(1, n + 1)]
    xy = np.vstack([core_xy] + ring_xy)
    n0 = core_xy.shape[0]
    ring_id = np.vstack([np.asarray(bnd)] + [n0 + (k - 1) * (nt + 1) + np.arange(nt + 1) for k in range(1, n + 1)])
    quads = [[core_id[i, j], core_id[i + 1, j], core_id[i + 1, j + 1], core_id[i, j + 1]]
             for i in range(h) for j in range(h)]
    quads += [[ring_id[k, j], ring_id[k + 1, j], ring_id[k + 1, j + 1], ring_id[k, j + 1]]
              for k in range(n) for j in range(nt)]
    quads = np.asarray(quads)
    a, b, c = xy[quads[:, 0]], xy[quads[:, 1]], xy[quads[:, 2]]
    u, v = b - a, c - a
    neg = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0] < 0
    quads[neg] = quads[neg][:, ::-1]
    z = length * np.arange(nz + 1) / nz
    m = xy.shape[0]
    pts = np.vstack([np.c_[xy, np.full(m, zk)] for zk in z])
    hexes = np.vstack([np.c_[quads + k * m, quads + (k + 1) * m] for k in range(nz)])
    outer = ring_id[n]
    surface = np.vstack([np.c_[outer[j] + k * m, outer[j + 1] + k * m, outer[j + 1] + (k + 1) * m, outer[j] + (k + 1) * m]
                         for k in range(nz) for j in range(nt)])
    off = np.setdiff1d(np.arange(m), outer)
    end_nodes = np.r_[off, off + nz * m] if ends else None
    return _write_groups(path, pts, surface, hexes, ("surface", "shaft"), end_nodes)


def shrink_fit_config(mesh_path, *, delta=DELTA, b=B, length=0.25, degree=(2, 1), friction=0.0,
                      path="condensation", motion="normal", **updates) -> dict:
    """The configuration (a dict) of the quarter hub on a rigid shaft of radius b + δ."""
    cfg = {
        "name": "lame-shrink-fit",
        "body": {"mesh": str(mesh_path), "contact": "bore", "interference": True,
                 "clamped": [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]},
                             {"on": {"x3": 0.0}, "components": [3]}, {"on": {"x3": length}, "components": [3]}]},
        "material": {"E": E, "nu": NU},
        "friction": {"coefficient": friction},
        "loads": {"body_force": [0.0, 0.0, 0.0]},
        "obstacle": {"shape": "cylinder", "point": [0.0, 0.0, 0.0], "axis": [0.0, 0.0, 1.0], "radius": b + delta},
        "design": {"degree": list(degree), "initial": 0.0, "C0": 0.01, "C2": 0.0, "motion": motion},
        "state": {"method": "newton", "tol": 1e-12},
        "linear_solver": {"path": path},
    }
    for key, val in updates.items():
        cfg.setdefault(key, {}).update(val)
    return cfg


def shaft_config(hub_path, shaft_path, *, delta=DELTA, b=B, length=0.25, foundation_clamped=None,
                 partner: str = "point", **kw) -> dict:
    """The quarter hub (bore radius b) on an elastic quarter shaft of radius b + δ of the same
    material (``[foundation]``), both in plane strain with the symmetry planes through both
    (``foundation_clamped``: the shaft's clamps in place of those)."""
    hub = shrink_fit_config(hub_path, delta=delta, b=b, length=length, **kw)
    clamps = foundation_clamped or [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]},
                                    {"on": {"x3": 0.0}, "components": [3]}, {"on": {"x3": length}, "components": [3]}]
    return {**{k: v for k, v in hub.items() if k != "obstacle"},
            "foundation": {"mesh": str(shaft_path), "top": "surface", "partner": partner, "clamped": clamps}}


def edge_relief_config(hub_path, shaft_path, *, delta=DELTA, b=B, degree: int = 4, path="fullspace") -> dict:
    """A hub shorter than its shaft: the quarter hub of half-length 0.25 (mesh of
    :func:`quarter_hub_mesh` with ``length=0.25``) on a quarter shaft of half-length 0.5
    (:func:`quarter_shaft_mesh` with ``length=0.5``), both cut at their common mid-plane x3 = 0
    (u3 = 0 there, the symmetry planes x1 = 0 and x2 = 0 through both), frictionless, mortar
    partners. The shaft goes on past the hub's free end, where the fit's pressure peaks (the
    edge effect the hub's bore is relieved against). The design is an axial profile of the bore
    (degree 0 around it, ``degree`` along it), moved along the bore's normal within ±δ; the
    objective the peak contact pressure (a KS aggregate)."""
    sym = [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]},
           {"on": {"x3": 0.0}, "components": [3]}]
    return shaft_config(hub_path, shaft_path, delta=delta, b=b, foundation_clamped=sym, partner="mortar",
                        body={"clamped": sym},
                        design={"degree": [0, degree], "initial": 0.0, "lower": -delta, "C0": delta, "C1": 1.0,
                                "C2": 0.0, "motion": "normal", "nonnegative_gap": False},
                        objective={"type": "max_pressure", "aggregate": "ks", "rho": 2.0e4},
                        state={"method": "newton", "tol": 1e-10}, linear_solver={"path": path})


def contact_pressure(problem, alpha=None):
    """(chart coordinates (p, 2), nodal contact pressures λ_m/A_m (p,)) of a state of ``problem``."""
    model = problem.model
    alpha = model.initial_design() if alpha is None else alpha
    st = problem.solve_state(alpha)
    return model.mesh.contact_points(), st.lam / model.contact_areas(), st


def pressure_errors(problem, p_exact: float) -> tuple[float, float]:
    """(rms, max) relative error of the nodal contact pressures against ``p_exact``."""
    _, p, _ = contact_pressure(problem)
    e = (p - p_exact) / p_exact
    return float(np.sqrt(np.mean(e ** 2))), float(np.abs(e).max())


# ------------------------------------------------------------------ push-out with friction
def push_out_config(hub_path, shaft_path, pushes: int, *, friction=0.3, delta=DELTA, b=B, length=0.25,
                    path="condensation") -> dict:
    """The shrink fit of :func:`shaft_config` with friction as a load path, on meshes with the node
    groups ``ends`` (:func:`quarter_hub_mesh`, :func:`quarter_shaft_mesh` with ``ends=True``): the
    step ``fit`` (the interference alone), then ``pushes`` steps ``push1``, … in which
    :func:`push_out` moves the hub's end faces along x3. u3 is clamped on both end faces of both
    bodies but on the contact face's two end rings, whose nodes slide along x3 with the rest of
    the interface (a clamped u3 there would carry part of the push by the clamps, not by friction)."""
    clamps = [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]},
              {"on": "ends", "components": [3]}]
    cfg = shaft_config(hub_path, shaft_path, delta=delta, b=b, length=length, friction=friction, path=path,
                       body={"clamped": clamps}, foundation_clamped=clamps)
    return {**cfg, "load_steps": [{"name": "fit"}] + [{"name": f"push{k}"} for k in range(1, pushes + 1)]}


class _WithNodal(LoadSet):
    """A load set plus a fixed nodal force vector (a prescribed displacement's −K_fd u_d)."""

    def __init__(self, base: LoadSet, extra: np.ndarray):
        super().__init__(base.tractions, base.pressures, base.body_force)
        self.extra = extra

    def vector(self, coords, assembler):
        return super().vector(coords, assembler) + self.extra


def push_out(problem, pushes) -> list[dict]:
    """Push the hub of ``problem`` (:func:`push_out_config`) along its shaft: in step ``push<k>``
    the hub's end faces (the group ``ends``, u3 clamped) are displaced by s_k = ``pushes[k-1]``
    along x3 through their equivalent nodal load −K_fd u_d (K the hub's stiffness on every DOF),
    the shaft's held at u3 = 0. Displacement control: past the push-out force the interface slides
    as a whole at a constant force, where a force beyond it would have no static solution.

    Returns per step (the fit first) {"step", "s", "force": the axial force on the hub's end faces
    (the reaction Σ (K u)_d over their u3, u with s on them; = the interface's friction force on
    the hub, −e3·Σ contact forces), "normal": Σλ, "slide": the fraction of contact nodes that slide
    (classes M1, M2), "stick": those that stick (M3+)}, per quarter model. Contact conventions:
    λ ≥ 0 on the hub, the friction force opposes the hub's slip (+x3 here), so the force is > 0."""
    model = problem.model
    asm = model.assembler
    alpha = model.initial_design()
    K = asm.full_stiffness(model.mesh.coordinates(alpha))
    ends = model.body.part("ends").nodes
    ud = np.zeros(asm.n_full)
    ud[3 * ends + 2] = 1.0
    unit = -(K @ ud)
    fixed = np.ones(asm.n_full, bool)
    fixed[asm.free] = False
    unit[fixed] = 0.0
    pushes = [0.0] + [float(x) for x in pushes]
    steps = problem.steps[0]
    if len(steps) != len(pushes):
        raise ValueError(f"{len(pushes) - 1} pushes for a load path of {len(steps) - 1} push steps")
    for step in steps[1:]:
        step.loads = _WithNodal(step.loads, pushes[step.index] * unit)
    problem.solve_states(alpha, warm_start=False)
    rows = []
    for (name, _, st), s in zip(problem.step_results(), pushes):
        u = st.u + s * ud
        names = st.class_names
        rows.append({"step": name, "s": s, "force": float((K @ u)[3 * ends + 2].sum()), "normal": float(st.lam.sum()),
                     "slide": float(np.isin(names, ("M1", "M2")).mean()), "stick": float((names == "M3+").mean())})
    return rows
