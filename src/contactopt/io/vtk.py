"""ParaView output: the body Ω(α) with its displacement and contact fields (VTU), and collections (PVD).

Fields written by :func:`write_body_vtu` as point data on *every* node of the mesh; on nodes off the
contact surface the contact fields are 0 (``node_class`` −1), never NaN:

* ``displacement`` (n_nodes, 3): u = (u1, u2, u3), zero on Γ_u (x1 = 0). The points are the
  reference coordinates of Ω(α) (the undeformed body of the design); in ParaView apply
  "Warp By Vector" with ``displacement`` to see the deformed body (or pass ``deformed=True``).
* ``normal_force`` λ: λ_m = (S u_c − ℓ)_ν ≥ 0, the normal contact force on the body (paper (3.17)).
* ``contact_pressure`` p: p_m = λ_m / a_m with a_m the node's lumped contact area on Ω(α)
  (force per unit area in the model's units, :mod:`contactopt.io.pressure`); smooth where the
  nodal forces follow the uneven nodal spacing of an unstructured face. On six-node faces the
  transformed reading of that module (no negative pressure, zero outside the contact).
* ``tangential_force`` (τ1, τ2, 0): τ_m = −(S u_c − ℓ)_t, the paper's tangential contact force,
  so that ‖τ_m‖ ≤ F λ_m and u_t ≠ 0 ⇒ τ_m = F λ_m u_t/‖u_t‖. The friction force acting on the
  body is −τ_m, opposite to the slip.
* ``node_class``: index into ("L", "M1", "M2", "M3+", "M3-", "M4") of Table 4.1, −1 off contact
  (on six-node faces the classes of :func:`contactopt.io.pressure.face_classes`, which class the
  corner nodes by the forces around them).
* ``gap`` g_m = ϑ_α(x'_m): initial distance to the foundation x3 ≤ 0; non-penetration u_ν + g ≥ 0
  with u_ν = u3.
* ``contact_node``: 1 on contact nodes, 0 elsewhere (to threshold the contact surface).
* ``part:<name>``: 1 on the nodes of each named part of the body (the groups of the mesh file, or
  the block's clamped, top, right, front, back, contact), 0 elsewhere.

On a rigid obstacle other than the plane ([obstacle], docs/obstacles.md) ``tangential_force`` is in
each node's tangents (t1, t2) and the file also has ``obstacle_normal`` n_m and ``contact_force``
R_m (−τ, λ), the force the obstacle exerts on the body in global components.

On an elastic foundation ([foundation], docs/foundation.md) the body's file also has, per contact
node, ``foundation_displacement`` Π u_f (the displacement of the partner point on the foundation's
top face) and ``relative_displacement`` w = u_c − Π u_f, on which the contact law acts (the gap
and the node classes are those of w), and :func:`write_foundation_vtu` writes the foundation:
its reference mesh with ``displacement`` u_f (zero on its clamped parts), ``contact_force`` (the
force −Πᵀr the body exerts on it, per node) and its parts.

Cells are the body's volume cells (hexahedra, tetrahedra or ten-node tetrahedra, in VTK order),
with cell data ``stress`` (the Cauchy stress averaged over the cell, Voigt order xx, yy, zz, yz,
xz, xy, tension positive), ``von_mises`` (of that average) and ``von_mises_max`` (the largest von
Mises stress at the cell's quadrature points: what the peak_stress objective takes the max of);
the foundation's file has the same.

The foundation is the half-space x3 ≤ 0 with normal e3, so tangential = (x1, x2), normal = x3.
"""

from __future__ import annotations

import logging
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path, PurePosixPath

import meshio
import numpy as np

from ..contact.state import FoundationState
from ..fem.stress import von_mises_points
from .atomic import atomic_output, atomic_write_text
from .pressure import contact_pressure, face_classes

log = logging.getLogger(__name__)

__all__ = ["body_point_data", "write_body_vtu", "write_foundation_vtu", "write_pvd"]


def _finite(name: str, arr: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f"field {name!r} has {bad} non-finite value(s); refusing to write it")
    return arr


def _on_nodes(name: str, values, n_nodes: int, contact_nodes: np.ndarray, fill=0.0) -> np.ndarray:
    """A point-data array on all nodes: given per node, or per contact node (``fill`` elsewhere)."""
    v = np.asarray(values)
    p = contact_nodes.size
    if v.shape[:1] == (n_nodes,):
        out = v
    elif v.shape[:1] == (p,):
        out = np.full((n_nodes,) + v.shape[1:], fill, dtype=np.result_type(v.dtype, type(fill)))
        out[contact_nodes] = v
    else:
        raise ValueError(f"field {name!r} has shape {v.shape}: expected ({n_nodes}, ...) per node "
                         f"or ({p}, ...) per contact node")
    if out.ndim > 2:
        raise ValueError(f"field {name!r}: at most one component axis is supported, got shape {out.shape}")
    if out.dtype.kind not in "biuf":
        raise ValueError(f"field {name!r}: numeric data expected, got dtype {out.dtype}")
    return _finite(name, out)


def face_body_rows(model, state):
    """``state`` on the face body's contact nodes alone: the rows of faces on other bodies
    (:mod:`contactopt.fem.faces`) are written with their bodies (:func:`write_foundation_vtu`)."""
    p = np.asarray(model.contact_nodes).size
    if np.shape(state.lam)[0] == p:
        return state
    cut = {name: (None if getattr(state, name) is None else np.asarray(getattr(state, name))[:p])
           for name in ("u_c", "lam", "tau", "gap", "classes", "slip_ref", "slip")}
    if np.ndim(state.friction):
        cut["friction"] = np.asarray(state.friction)[:p]
    f = state.foundation
    if f is not None:
        cut["foundation"] = FoundationState(f.u_body_c[:p], f.u_partner[:p], lambda: f.displacement)
    return replace(state, **cut)


def body_point_data(model, state, extra_point_data=None) -> dict:
    """The point-data dict written by :func:`write_body_vtu` (see the module docstring).

    ``extra_point_data`` maps names to arrays given per node (n_nodes, ...) or per contact node
    (p, ...); the latter are scattered onto the contact nodes with 0 elsewhere.
    """
    n = model.mesh.n_nodes
    cn = np.asarray(model.contact_nodes)
    p = cn.size
    state = face_body_rows(model, state)
    u = np.asarray(state.u, float)
    if u.size != 3 * n:
        raise ValueError(f"state.u has {u.size} entries, the mesh needs 3·{n} = {3 * n}")
    for name, arr, shape in (("lam", state.lam, (p,)), ("tau", state.tau, (p, 2)),
                             ("gap", state.gap, (p,)), ("classes", state.classes, (p,))):
        if np.shape(arr) != shape:
            raise ValueError(f"state.{name} has shape {np.shape(arr)}, expected {shape} (p = {p} contact nodes)")
    tau3 = np.zeros((p, 3))
    tau3[:, :2] = state.tau
    data = {
        "displacement": _finite("displacement", u.reshape(n, 3)),
        "normal_force": _on_nodes("normal_force", np.asarray(state.lam, float), n, cn),
        "contact_pressure": _on_nodes("contact_pressure", contact_pressure(model, state.lam, state.coords), n, cn),
        "tangential_force": _on_nodes("tangential_force", tau3, n, cn),
        "node_class": _on_nodes("node_class", np.asarray(face_classes(model, state), np.int32), n, cn,
                               fill=np.int32(-1)),
        "gap": _on_nodes("gap", np.asarray(state.gap, float), n, cn),
        "contact_node": _on_nodes("contact_node", np.ones(p, np.int8), n, cn, fill=np.int8(0)),
    }
    if state.foundation is not None:            # an elastic foundation (module docstring)
        data["foundation_displacement"] = _on_nodes("foundation_displacement", state.foundation.u_partner, n, cn)
        data["relative_displacement"] = _on_nodes("relative_displacement", np.asarray(state.u_c, float), n, cn)
    frames = model.frames
    if frames is not None:                      # a rigid obstacle: tangential_force is in (t1, t2) of each node
        r = np.c_[-np.asarray(state.tau, float), np.asarray(state.lam, float)]
        data["obstacle_normal"] = _on_nodes("obstacle_normal", frames[:, :, 2], n, cn)
        data["contact_force"] = _on_nodes("contact_force", np.einsum("mij,mj->mi", frames, r), n, cn)
    for name, part in getattr(model.mesh, "parts", {}).items():
        tag = np.zeros(n, np.int8)
        tag[part.nodes] = 1
        data[f"part:{name}"] = tag
    for name, values in (extra_point_data or {}).items():
        if name in data:
            raise ValueError(f"extra point data {name!r} would overwrite a standard field")
        data[name] = _on_nodes(name, values, n, cn)
    return data


def write_body_vtu(path, model, state, extra_point_data=None, *, deformed: bool = False) -> Path:
    """Write the body of ``state`` as an unstructured-grid VTU (the body's cells), atomically.

    Points are the reference coordinates of Ω(α) (``state.coords``), or the deformed ones
    x + u when ``deformed`` is true. Point data: see the module docstring for every field and its
    sign convention. Returns the path.
    """

    path = Path(path)
    coords = np.asarray(state.coords, float)
    n = model.mesh.n_nodes
    if coords.shape != (n, 3):
        raise ValueError(f"state.coords has shape {coords.shape}, expected ({n}, 3)")
    _finite("coords", coords)
    point_data = body_point_data(model, state, extra_point_data)
    points = coords + point_data["displacement"] if deformed else coords
    # the body's cells are in meshio's (= VTK's) node order for every supported type
    mesh = meshio.Mesh(points, [(model.mesh.cell_type, np.asarray(model.mesh.elements, np.int64))],
                       point_data=point_data,
                       cell_data=cell_stress_data(model.assembler, coords, point_data["displacement"].ravel()))
    with atomic_output(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    log.info("wrote %s (%d nodes, %d %s cells, %s)", path, n, model.mesh.n_elements, model.mesh.cell_type,
             "deformed" if deformed else "reference configuration")
    return path


def cell_stress_data(assembler, coords, u_full) -> dict:
    """Cell data of a body: the Cauchy stress (cell average, Voigt order xx, yy, zz, yz, xz, xy;
    tension positive), its von Mises equivalent, and the largest von Mises stress at the cell's
    quadrature points."""
    s = _finite("stress", assembler.cell_stresses(np.asarray(coords, float), np.asarray(u_full, float)))
    vm = np.sqrt(0.5 * ((s[:, 0] - s[:, 1]) ** 2 + (s[:, 1] - s[:, 2]) ** 2 + (s[:, 2] - s[:, 0]) ** 2)
                 + 3.0 * (s[:, 3] ** 2 + s[:, 4] ** 2 + s[:, 5] ** 2))
    peak = _finite("von_mises_max", von_mises_points(assembler, np.asarray(coords, float),
                                                     np.asarray(u_full, float)).max(axis=1))
    return {"stress": [s], "von_mises": [vm], "von_mises_max": [peak]}


def write_foundation_vtu(path, foundation, state, pair: int | None = None) -> Path:
    """Write the elastic foundation of ``state`` (its reference mesh, module docstring) as a VTU;
    the counterpart bodies of several pairs (:class:`~contactopt.fem.counterparts.Counterparts`) one
    after the other in one file, each node tagged with its body's index ``pair`` (the pair's where
    each body is the counterpart of one pair), or the counterpart body ``pair`` alone."""
    path = Path(path)
    r = np.zeros(3 * state.lam.size)
    r[0::3], r[1::3], r[2::3] = -state.tau[:, 0], -state.tau[:, 1], state.lam
    parts, rows = foundation.parts, foundation.rows
    u_all = np.asarray(state.foundation.displacement, float)
    points, blocks, data, cells_data, offset, start = [], [], {}, {}, 0, 0
    for k, (fnd, nodes) in enumerate(zip(parts, rows)):
        if fnd.n_nodes == 0:            # a rigid counterpart of several pairs: no mesh, no displacement
            continue
        ref = fnd.mesh.reference
        n = ref.n_nodes
        u = _finite("foundation displacement", u_all[3 * start:3 * (start + n)].reshape(n, 3))
        start += n
        if pair is not None and k != pair:
            continue
        dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
        f = np.zeros((n, 3))
        f[fnd.support] = -(fnd.Pi.T @ r[dofs]).reshape(-1, 3)
        for j, view in fnd.face_views.items():   # a pair's face on this body (fem.faces)
            mine = foundation.pair_rows[j]
            f[view.contact_nodes] += np.einsum("mij,mj->mi", foundation.frames[mine], r.reshape(-1, 3)[mine])
        own = {"displacement": u, "contact_force": _finite("contact_force", f)}
        if len(parts) > 1 and pair is None:
            own["pair"] = np.full(n, k, np.int8)
        for name, part in ref.parts.items():
            tag = np.zeros(n, np.int8)
            tag[part.nodes] = 1
            own[f"part:{name}"] = tag
        for key, v in own.items():
            data.setdefault(key, []).append(v)
        for key, v in cell_stress_data(fnd.assembler, ref.points, u.ravel()).items():
            cells_data.setdefault(key, []).extend(v)
        points.append(ref.points)
        blocks.append((ref.cell_type, ref.cells + offset))
        offset += n
    names = {k for k in data if len(data[k]) == len(blocks)}
    point_data = {k: np.concatenate(v) for k, v in data.items() if k in names}
    mesh = meshio.Mesh(np.vstack(points), blocks, point_data=point_data, cell_data=cells_data)
    with atomic_output(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    log.info("wrote %s (the foundation: %d nodes in %d bodies)", path, offset, len(parts))
    return path


def write_pvd(path, entries) -> Path:
    """Write a ParaView collection (.pvd) listing VTU files, atomically.

    ``entries``: iterable of ``(time_or_index, filename)`` or ``(time_or_index, filename, part)``
    (several parts of one time step: the body and its foundation); the filename is relative to the
    directory of the .pvd file (absolute names are refused: the collection must stay valid when the
    run directory is moved). ParaView shows the entries as time steps ``time_or_index``.
    """
    path = Path(path)
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for n, entry in enumerate(entries):
        try:
            time, fname, *part = entry
            part = int(part[0]) if part else 0
            if len(entry) > 3:
                raise ValueError
        except (TypeError, ValueError):
            raise ValueError(f"pvd entry {n}: expected (time_or_index, filename[, part]), got {entry!r}") from None
        try:
            t = float(time)
        except (TypeError, ValueError):
            raise ValueError(f"pvd entry {n}: time {time!r} is not a number") from None
        if not math.isfinite(t):
            raise ValueError(f"pvd entry {n}: time {time!r} is not finite")
        fname = os.fspath(fname)
        if os.path.isabs(fname) or PurePosixPath(fname.replace("\\", "/")).is_absolute():
            raise ValueError(f"pvd entry {n}: {fname!r} must be relative to the .pvd file's directory")
        ET.SubElement(coll, "DataSet", timestep=repr(t) if not t.is_integer() else str(int(t)),
                      group="", part=str(part), file=fname.replace(os.sep, "/"))
    ET.indent(root, space="  ")
    text = '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    atomic_write_text(path, text)
    log.info("wrote %s (%d data sets)", path, len(coll))
    return path
