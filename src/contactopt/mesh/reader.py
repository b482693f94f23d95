"""Mesh files as reference meshes: any format meshio reads (Gmsh 2.2/4.1, VTU/VTK, Abaqus, MED, …).

Volume cells: one of ``hexahedron`` (Q1), ``tetra`` (P1), ``tetra10`` (P2); any other volume cell
type is refused, naming it. Named groups become parts (:class:`~contactopt.mesh.reference.Part`):

- Gmsh 4.1 (and meshio's other readers): ``cell_sets`` — name → per-block cell indices; meshio's
  own ``gmsh:*`` sets are ignored;
- Gmsh 2.2: only the ``gmsh:physical`` tag of each cell, with the names in ``field_data``
  (name → [tag, dimension]);
- ``point_sets`` (Abaqus NSET, …): node parts.

A group's nodes are the nodes of its cells (a face may belong to two groups). Its boundary faces
are the mesh's boundary faces with the corners of the group's surface cells, oriented outward by
their volume cell (face node order in files is arbitrary); a volume group has no faces of its own.
Points that belong to no volume cell (geometry points of a CAD export) are kept but ignored.
"""

from __future__ import annotations

import contextlib
import io
import logging
from pathlib import Path

import meshio
import numpy as np

from ..errors import MeshError
from .reference import CELL_FACES, FACE_CORNERS, SUPPORTED_CELLS, Part, ReferenceMesh

log = logging.getLogger(__name__)

VOLUME_TYPES = {"tetra", "tetra10", "hexahedron", "hexahedron20", "hexahedron27", "wedge", "wedge15",
                "pyramid", "pyramid13", "tetra20", "hexahedron24", "VTK_LAGRANGE_HEXAHEDRON",
                "VTK_LAGRANGE_TETRAHEDRON", "polyhedron"}
SURFACE_TYPES = {"triangle", "triangle6", "triangle7", "quad", "quad8", "quad9", "polygon"}


def read_mesh(path) -> ReferenceMesh:
    """Read a mesh file into a :class:`ReferenceMesh` (see the module docstring)."""
    path = Path(path)
    if not path.exists():
        raise MeshError(f"mesh file {path}: no such file")
    if path.is_dir():
        raise MeshError(f"mesh file {path}: is a directory")
    chatter = io.StringIO()
    try:
        # meshio prints its readers' complaints and may even sys.exit() on a file it cannot read
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            m = meshio.read(path)
    except (Exception, SystemExit) as exc:
        said = " ".join(chatter.getvalue().split())
        raise MeshError(f"mesh file {path}: cannot be read by meshio ({type(exc).__name__}: {exc}"
                        + (f"; {said}" if said else "") + ")") from None
    return from_meshio(m, str(path))


def from_meshio(m, source: str = "<meshio>") -> ReferenceMesh:
    """A :class:`ReferenceMesh` from a ``meshio.Mesh``."""
    blocks = [(i, cb.type, np.asarray(cb.data)) for i, cb in enumerate(m.cells)]
    volume = [(i, t) for i, t, _ in blocks if t in VOLUME_TYPES]
    types = sorted({t for _, t in volume})
    if not types:
        found = ", ".join(sorted({t for _, t, _ in blocks})) or "no cells"
        raise MeshError(f"{source}: no volume cells (found {found}); supported volume cells: "
                        f"{', '.join(SUPPORTED_CELLS)}")
    bad = [t for t in types if t not in SUPPORTED_CELLS]
    if bad:
        raise MeshError(f"{source}: volume cells of type {', '.join(bad)} are not supported "
                        f"(supported: {', '.join(SUPPORTED_CELLS)})")
    if len(types) > 1:
        raise MeshError(f"{source}: mixed volume cell types {', '.join(types)}; use one type "
                        f"({', '.join(SUPPORTED_CELLS)})")
    ctype = types[0]
    vol_ids = [i for i, _ in volume]
    cells = np.concatenate([blocks[i][2] for i in vol_ids]).astype(np.int64)
    points = np.asarray(m.points, float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise MeshError(f"{source}: points must be three-dimensional, got an array of shape {points.shape}")
    # points in no volume cell (CAD geometry points) are dropped: they would carry no stiffness
    used = np.unique(cells)
    renum = np.full(points.shape[0], -1, np.int64)
    renum[used] = np.arange(used.size)
    mesh = ReferenceMesh(points[used], renum[cells], ctype, source=source)
    blocks = [(i, t, renum[np.asarray(d, np.int64)]) for i, t, d in blocks]
    for name, per_block in _groups(m, blocks).items():
        nodes, faces = [], []
        for i, idx in per_block.items():
            t, data = blocks[i][1], blocks[i][2]
            sel = data[np.asarray(idx, np.int64)]
            sel = sel[np.all(sel >= 0, axis=1)]
            if sel.size == 0:
                continue
            nodes.append(sel.ravel())
            if t in SURFACE_TYPES:
                if t not in FACE_CORNERS:
                    raise MeshError(f"{source}: group {name!r} has surface cells of type {t}, not supported "
                                    f"(supported: {', '.join(FACE_CORNERS)})")
                faces.append(sel[:, :FACE_CORNERS[t]])
        if not nodes:
            continue
        face_nodes = np.concatenate(faces) if faces else np.zeros((0, FACE_CORNERS[mesh.face_type]), np.int64)
        fk = mesh.match_faces(face_nodes, f"group {name!r}")
        mesh.parts[name] = Part(name, np.unique(np.concatenate(nodes + [fk.ravel()])), fk, "file")
    for name, idx in (getattr(m, "point_sets", None) or {}).items():
        if name.startswith("gmsh:") or name in mesh.parts:
            continue
        nodes = renum[np.unique(np.asarray(idx, np.int64))]
        nodes = nodes[nodes >= 0]
        mesh.parts[name] = Part(name, nodes, mesh.faces_within(nodes), "file")
    log.info("read %s: %d nodes, %d %s cells, parts: %s", source, mesh.n_nodes, mesh.n_cells, ctype,
             ", ".join(sorted(mesh.parts)) or "none")
    return mesh


def _groups(m, blocks) -> dict:
    """name → {block index: cell indices} from cell_sets, else from gmsh:physical + field_data."""
    out = {}
    for name, per_block in (m.cell_sets or {}).items():
        if name.startswith("gmsh:"):
            continue
        d = {i: np.asarray(idx) for i, idx in enumerate(per_block) if idx is not None and len(idx)}
        if d:
            out[name] = d
    if out:
        return out
    phys = (m.cell_data or {}).get("gmsh:physical")
    if phys is None:
        return out
    names = {}
    for name, val in (m.field_data or {}).items():
        tag, dim = int(val[0]), int(val[1]) if len(val) > 1 else None
        names[(tag, dim)] = name
    dims = {"vertex": 0, "line": 1, "line3": 1}
    for i, tags in enumerate(phys):
        t = blocks[i][1]
        dim = 3 if t in VOLUME_TYPES else 2 if t in SURFACE_TYPES else dims.get(t, None)
        tags = np.asarray(tags)
        for tag in np.unique(tags):
            name = names.get((int(tag), dim)) or next((n for (tg, _), n in names.items() if tg == int(tag)), None)
            if name is None:
                continue
            out.setdefault(name, {})[i] = np.flatnonzero(tags == tag)
    return out


__all__ = ["read_mesh", "from_meshio", "CELL_FACES"]
