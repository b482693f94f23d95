"""The optimal design back to CAD and to other FE tools: body mesh, STL boundary, STEP/IGES surface.

Everything is written in the coordinate frame and the length unit of the input: the foundation is
the plane x3 = 0, the body lies above it, and the contact surface of the design α is the graph of
ϑ_α over the design rectangle R (:mod:`contactopt.design.bezier`). Files (``export_design``):

* ``optimal_body.<ext>`` — Ω(α) as a volume mesh: a body read from a file keeps that file's blocks,
  groups and entity tags with only the node coordinates moved, in the input's format where meshio
  writes it (Gmsh 2.2 stays 2.2, 4.1 stays 4.1; else Gmsh 4.1); the paper's block becomes a Gmsh 2.2
  file (it keeps the node numbering, which 4.1 groups by entity) with its parts (clamped, top, right, front, back, contact) as physical surfaces and the
  volume as ``body``. ``optimal_body.toml`` next to it is a configuration of that body: at α = 0
  (``initial_gap = "mesh"``: the face's height above the foundation is its gap) contactopt solves the
  state of the optimal design again.
* ``optimal_body.stl`` — the boundary of Ω(α), binary, watertight (every edge in exactly two
  triangles), normals outward; quadrilateral faces as four triangles around their bilinear centre
  (then the enclosed volume is the volume of the trilinear hexahedra, see :func:`stl_triangles`),
  six-node triangles as four.
* ``contact_surface.step`` / ``.iges`` — ϑ_α as an exact B-spline surface (a Bézier surface is a
  B-spline without interior knots: degrees (d1, d2), knots {0, 1} of multiplicity d+1, unit
  weights, control points at the Greville abscissae x1lo + a·i/d1, x2lo + b·j/d2 with height α_ij),
  through Gmsh's OpenCASCADE kernel (``pip install contactopt[cad]``). Where the contact face's
  outline is not R (a disc) the face is trimmed by it: the outline in the surface's parameter
  space, split at its corners into straight lines and interpolating splines.

Units: no file here scales coordinates unless told. STEP and IGES always declare a length unit
(OpenCASCADE writes millimetres); ``unit`` names the unit of the model's coordinates, and the
CAD surface is scaled to millimetres (``unit = "m"``: ×1000) so that CAD shows the true size.
Meshes and STL (which has no unit) keep the model's numbers.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import struct
import sys
import tempfile
import threading
from pathlib import Path

import meshio
import numpy as np
from meshio._helpers import _writer_map
from meshio.gmsh.common import _meshio_to_gmsh_type

from ..errors import ContactOptError
from ..fem.elasticity import element_geometry
from ..mesh.reader import VOLUME_TYPES
from ..mesh.reference import CELL_FACES, FACE_CORNERS
from .atomic import WriteError, atomic_output, atomic_write_text, fsync_dir, write_error

log = logging.getLogger(__name__)

__all__ = ["ExportError", "FORMATS", "UNITS", "export_design", "write_body_mesh", "write_stl", "stl_triangles",
           "read_stl", "triangle_mesh_check", "write_contact_surface", "fe_volume", "roundtrip_config"]

FORMATS = ("mesh", "stl", "step", "iges")
ALIASES = {"msh": "mesh", "igs": "iges", "stp": "step"}
UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "um": 1e-3}
CAD_HINT = "pip install contactopt[cad]  (Gmsh with OpenCASCADE)"


class ExportError(ContactOptError):
    """A result cannot be exported (unknown format, no CAD kernel, unreadable source mesh)."""


def normalize_formats(formats) -> list[str]:
    """Format names in FORMATS order, aliases (msh, igs, stp) resolved; ExportError for others."""
    if formats is None:
        return list(FORMATS)
    out, bad = set(), []
    for f in formats:
        f = ALIASES.get(str(f).lower(), str(f).lower())
        (out.add(f) if f in FORMATS else bad.append(f))
    if bad:
        raise ExportError(f"unknown export format(s) {', '.join(bad)}; choose from {', '.join(FORMATS)} "
                          f"(aliases: {', '.join(ALIASES)})")
    return [f for f in FORMATS if f in out]


def has_cad_kernel() -> bool:
    try:
        import gmsh  # noqa: F401
    except ImportError:
        return False
    return True


# ---------------------------------------------------------------------- volume mesh
def _source_format(path: Path) -> tuple[str, bool, bool]:
    """(meshio writer, binary, in the input's format) of the input mesh file: Gmsh keeps its
    version, else the writer of the extension, else Gmsh 4.1."""
    if path.suffix.lower() == ".msh":
        with open(path, "rb") as fh:
            head = fh.read(64).split()
        try:
            i = head.index(b"$MeshFormat")
            version, binary = head[i + 1].decode(), head[i + 2] == b"1"
        except (ValueError, IndexError):
            return "gmsh", False, True
        return ("gmsh22" if version.startswith("2") else "gmsh"), binary, True
    types = meshio.extension_to_filetypes.get(path.suffix.lower(), [])
    writable = [t for t in types if t in _writer_map]
    return (writable[0], False, True) if writable else ("gmsh", False, False)


def _block_meshio(model, coords):
    """The paper's block as a meshio mesh with its parts as Gmsh physical surfaces."""
    ref = model.body.reference
    ftype = CELL_FACES[ref.cell_type][0]
    cells = [(ref.cell_type, ref.cells)]
    phys, geom = [np.ones(ref.n_cells, np.int32)], [np.ones(ref.n_cells, np.int32)]
    field = {"body": np.array([1, 3])}
    for k, (name, part) in enumerate(sorted(ref.parts.items()), start=1):
        if part.faces.shape[0] == 0:
            continue
        cells.append((ftype, part.faces))
        phys.append(np.full(part.faces.shape[0], k + 1, np.int32))
        geom.append(np.full(part.faces.shape[0], k, np.int32))
        field[name] = np.array([k + 1, 2])
    return meshio.Mesh(coords, cells, cell_data={"gmsh:physical": phys, "gmsh:geometrical": geom}, field_data=field)


def body_meshio(model, coords):
    """(meshio.Mesh of Ω at ``coords``, meshio format, binary, file suffix).

    A body from a file is that file re-read with the nodes of its volume cells moved (the reader
    drops the other points and numbers the rest in order: :func:`contactopt.mesh.reader.from_meshio`),
    so every block, group, tag and extra point stays as the input had it."""
    src = model.config.body.mesh
    if not src:
        # Gmsh 2.2 keeps the node numbering (4.1 lists nodes by geometric entity): the exported
        # block's node n is the model's node n
        return _block_meshio(model, coords), "gmsh22", False, ".msh"
    path = Path(src)
    if not path.is_file():
        raise ExportError(f"body.mesh = {src}: the input mesh is needed to export the body in its format "
                          "and with its groups, and it is not there any more")
    with _quiet():                          # meshio's readers print
        m = meshio.read(path)
    vol = [np.asarray(cb.data) for cb in m.cells if cb.type in VOLUME_TYPES]
    used = np.unique(np.concatenate(vol).astype(np.int64))
    if used.size != coords.shape[0]:
        raise ExportError(f"body.mesh = {src}: has {used.size} nodes in volume cells, the model {coords.shape[0]}: "
                          "the file changed since the run")
    m.points = np.array(m.points, float, copy=True)
    m.points[used] = coords
    fmt, binary, native = _source_format(path)
    return m, fmt, binary, path.suffix if native else ".msh"


def write_body_mesh(path, model, coords) -> Path:
    """Write Ω at ``coords`` as a volume mesh (see :func:`body_meshio`) to ``path``, atomically."""
    m, fmt, binary, _ = body_meshio(model, coords)
    kw = {"binary": binary} if fmt in ("gmsh", "gmsh22") else {}
    path = Path(path)
    with atomic_output(path) as tmp, _quiet():
        if fmt == "gmsh22" and not binary and _plain_gmsh(m):
            _write_gmsh22_ascii(tmp, m)
        else:
            meshio.write(tmp, m, file_format=fmt, **kw)
    log.info("wrote %s (%s, %d nodes)", path, fmt, coords.shape[0])
    return path


def _plain_gmsh(m) -> bool:
    """Whether :func:`_write_gmsh22_ascii` writes ``m``: 3D points, cells of a type whose Gmsh node
    order is VTK's, no data but the physical and geometrical tags, no periodic section."""
    return (m.points.ndim == 2 and m.points.shape[1] == 3 and not m.point_data and m.gmsh_periodic is None
            and set(m.cell_data) == {"gmsh:physical", "gmsh:geometrical"}
            and all(c.type in _meshio_to_gmsh_type and c.type not in _GMSH_REORDERED for c in m.cells))


_GMSH_REORDERED = ("tetra10", "hexahedron20", "hexahedron27", "wedge15", "pyramid13")


def _write_gmsh22_ascii(path, m) -> None:
    """The bytes of meshio's Gmsh 2.2 ASCII writer (nodes as ``%.16e``, one line per element with
    its physical and geometrical tag), formatted from lists at once instead of line by line."""
    out = ["$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"]
    names = sorted((int(dim), int(num), name) for name, (num, dim) in m.field_data.items())
    if names:
        out.append(f"$PhysicalNames\n{len(names)}\n" + "".join(f'{d} {n} "{name}"\n' for d, n, name in names)
                   + "$EndPhysicalNames\n")
    pts = m.points.tolist()
    out.append(f"$Nodes\n{len(pts)}\n" + "".join(f"{k} {x:.16e} {y:.16e} {z:.16e}\n"
                                                  for k, (x, y, z) in enumerate(pts, start=1)) + "$EndNodes\n")
    out.append(f"$Elements\n{sum(len(c.data) for c in m.cells)}\n")
    first = 1
    for k, block in enumerate(m.cells):
        head = f" {_meshio_to_gmsh_type[block.type]} 2 "
        tags = np.stack([np.asarray(m.cell_data["gmsh:physical"][k]), np.asarray(m.cell_data["gmsh:geometrical"][k])],
                        axis=1).astype(np.int32).tolist()
        nodes = (np.asarray(block.data, dtype=np.int64) + 1).tolist()
        out.append("".join(f"{first + i}{head}{t[0]} {t[1]} {' '.join(map(str, c))}\n"
                           for i, (t, c) in enumerate(zip(tags, nodes))))
        first += len(nodes)
    out.append("$EndElements\n")
    with open(path, "wb") as fh:
        fh.write("".join(out).encode())


def roundtrip_config(model, mesh_name: str, alpha) -> dict:
    """A configuration of the exported body ``mesh_name`` (relative to the config file) whose
    state at α = 0 is the state of the exported design ``alpha``: the same material, friction,
    loads, objective and design rectangle, with ``body.initial_gap = "mesh"`` (the face's height
    is the gap), C2 = 0 (α = 0 admissible) and C0 = the room the bound C0 leaves above the design,
    C0 − max α (the lifted mesh may allow less: contactopt then names the largest safe C0)."""
    out = model.config.to_dict()
    block = not model.config.body.mesh
    out["name"] = f"{model.config.name}_optimal"
    out["description"] = (f"The optimal body of {model.config.name} exported by contactopt: its state at "
                          "alpha = 0 is the state of the optimal design")
    out["body"]["mesh"] = mesh_name
    out["body"]["initial_gap"] = "mesh"
    (x1lo, x1hi), (x2lo, x2hi) = model.body.domain
    # on a chart the moved face is fitted anew (its cylinder's radius moves with the design): its
    # own bounding rectangle, not the reference face's
    out["design"]["domain"] = [[x1lo, x1hi], [x2lo, x2hi]] if model.body.chart is None else []
    chart = model.body.chart
    if chart is not None:            # the same chart: the moved face is no plane or cylinder any more
        out["design"]["chart"] = chart.kind
        out["design"]["axis"] = [float(v) for v in (chart.axis if chart.kind == "cylinder" else chart.normal)]
        out["design"]["origin"] = [float(v) for v in chart.origin]
    out["design"]["initial"] = 0.0
    out["design"]["C2"] = 0.0
    C0 = float(model.config.design.C0)
    out["design"]["C0"] = max(C0 - float(np.max(alpha)), 1e-3 * C0)
    if block:
        out.pop("geometry", None)
        out.pop("mesh", None)

        def moved(loads):
            for name in ("top", "right"):
                t = loads.pop(f"{name}_traction", None)
                if t is not None and any(t):
                    loads.setdefault("traction", []).append({"on": name, "value": list(t)})
        moved(out["loads"])
        for case in out.get("load_cases", []):
            moved(case)
            for step in case.get("steps", []):
                moved(step)
        for step in out.get("load_steps", []):
            moved(step)
    return out


# ---------------------------------------------------------------------- STL
def stl_triangles(model, coords) -> tuple[np.ndarray, np.ndarray]:
    """(points, triangles) of the boundary of Ω at ``coords``, triangles oriented outward.

    Triangles (three nodes) as they are; six-node triangles as four; quadrilaterals as four around
    a new point at the bilinear centre (the mean of the corners). That fan encloses, with the
    divergence theorem, exactly the volume of the trilinear hexahedra: the flux of x through a
    bilinear patch is (1/3)∫ x·(x_s × x_t), a polynomial the four triangles reproduce — two would
    cut each warped face along a diagonal and miss the volume between it and the patch."""
    ref = model.body.reference
    faces = ref.boundary_faces()
    coords = np.asarray(coords, float)
    if faces.shape[1] == 4:
        nf = faces.shape[0]
        centre = coords[faces].mean(axis=1)
        c = coords.shape[0] + np.arange(nf)
        pts = np.vstack([coords, centre])
        tris = np.concatenate([np.column_stack([faces[:, k], faces[:, (k + 1) % 4], c]) for k in range(4)])
    elif faces.shape[1] == 6:
        pts = coords
        tris = np.concatenate([faces[:, [0, 3, 5]], faces[:, [3, 1, 4]], faces[:, [5, 4, 2]], faces[:, [3, 4, 5]]])
    else:
        pts, tris = coords, faces[:, :FACE_CORNERS[ref.face_type]]
    used = np.unique(tris)
    renum = np.full(pts.shape[0], -1, np.int64)
    renum[used] = np.arange(used.size)
    return pts[used], renum[tris]


def write_stl(path, model, coords, header: str = "") -> Path:
    """Binary STL of the boundary of Ω at ``coords`` (:func:`stl_triangles`), atomically.

    Coordinates are the model's (STL has no unit), as 32-bit floats (the format's), rounded so
    that the file encloses the mesh's volume (:func:`float32_keeping_volume`)."""
    pts, tris = stl_triangles(model, coords)
    X = pts[tris]
    n = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    rec = np.zeros(tris.shape[0], dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"], rec["v"] = n, float32_keeping_volume(pts, tris)[tris]
    head = (header or "contactopt optimal body").encode("ascii", "replace")[:80].ljust(80, b" ")
    path = Path(path)
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(head)
            fh.write(struct.pack("<I", tris.shape[0]))
            fh.write(rec.tobytes())
    log.info("wrote %s (%d triangles)", path, tris.shape[0])
    return path


def float32_keeping_volume(points, tris) -> np.ndarray:
    """The vertices as 32-bit floats, each coordinate one of the two floats around its value,
    chosen so that the closed surface ``tris`` encloses the volume it encloses in double precision.

    Rounding every coordinate to the nearest float (relative error 6e-8) changes the enclosed
    volume by a sum of random terms, 5e-9 of it on the meshes of the tests. The volume is linear in
    each vertex, with gradient g_i = (1/6) Σ x_j × x_k over the triangles (i, j, k) at vertex i, so
    moving a coordinate to its other neighbouring float changes it by g_ic·δ_ic. Those moves are
    taken greedily, largest first, while each brings the volume closer: the volume error ends below
    the smallest moves (about ulp × the area per vertex), every coordinate still within one ulp."""
    pts = np.asarray(points, float)
    tris = np.asarray(tris, np.int64)
    near = pts.astype(np.float32)
    up = near.astype(float) < pts
    other = np.where(up, np.nextafter(near, np.float32(np.inf)), np.nextafter(near, np.float32(-np.inf)))
    other = np.where(near.astype(float) == pts, near, other)
    X = near.astype(float)[tris]
    g = np.zeros_like(pts)
    for a in range(3):                        # ∂V/∂x_a of (1/6) x_a·(x_b × x_c), (a, b, c) cyclic
        np.add.at(g, tris[:, a], np.cross(X[:, (a + 1) % 3], X[:, (a + 2) % 3]) / 6.0)
    err = _volume(X) - _volume(pts[tris])
    d = (g * (other.astype(float) - near.astype(float))).ravel()
    out = near.ravel().copy()
    flat_other = other.ravel()
    for k in np.argsort(-np.abs(d)):
        if d[k] == 0.0 or abs(err) <= 1e-300:
            break
        if abs(err + d[k]) < abs(err):
            out[k] = flat_other[k]
            err += d[k]
    return out.reshape(pts.shape)


def _volume(X: np.ndarray) -> float:
    return float(np.einsum("ij,ij->i", X[:, 0], np.cross(X[:, 1], X[:, 2])).sum() / 6.0)


def read_stl(path) -> tuple[np.ndarray, np.ndarray]:
    """(points, triangles) of a binary STL, vertices merged where their coordinates are equal."""
    data = Path(path).read_bytes()
    count = struct.unpack("<I", data[80:84])[0]
    rec = np.frombuffer(data, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")], count=count,
                        offset=84)
    if len(data) != 84 + 50 * count:
        raise ExportError(f"{path}: not a binary STL of {count} triangles ({len(data)} bytes)")
    v = rec["v"].astype(float).reshape(-1, 3)
    pts, inv = np.unique(v, axis=0, return_inverse=True)
    return pts, inv.reshape(-1, 3)


def triangle_mesh_check(points, tris) -> dict:
    """Watertightness, orientation and enclosed volume of a triangle surface.

    ``edges_ok``: every undirected edge lies in exactly two triangles; ``oriented``: those two run
    through it in opposite directions (consistent normals); ``volume`` = (1/6) Σ x0·(x1 × x2), > 0
    for outward normals (divergence theorem)."""
    tris = np.asarray(tris, np.int64)
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    und = np.sort(e, axis=1)
    count = np.unique(und, axis=0, return_counts=True)[1]
    dcount = np.unique(e, axis=0, return_counts=True)[1]
    vol = _volume(np.asarray(points, float)[tris])
    return {"triangles": int(tris.shape[0]), "edges": int(count.size),
            "edges_ok": bool(np.all(count == 2)), "oriented": bool(np.all(dcount == 1)) and bool(np.all(count == 2)),
            "volume": vol}


def fe_volume(model, coords) -> float:
    """Volume of the FE mesh at ``coords``: Σ ∫ det J over the cells (the body-load rule, exact for
    the elements' polynomial Jacobians)."""
    el = model.assembler.element
    _, dN, w = el.reference(load=True)
    _, det = element_geometry(np.asarray(coords, float)[model.assembler.elements], dN, check=False)
    return float(np.sum(det * w))


# ---------------------------------------------------------------------- STEP / IGES
@contextlib.contextmanager
def _quiet():
    """Silence C/C++ writes to stdout/stderr (OpenCASCADE prints transfer statistics): the library
    does not print."""
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = [os.dup(1), os.dup(2)]
    except (OSError, ValueError):          # no real file descriptors (embedded interpreters)
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            yield
    finally:
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()          # Python-level writes made meanwhile go to the null device too
            sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in saved:
            os.close(fd)


def _gmsh():
    try:
        import gmsh
    except ImportError:
        raise ExportError("STEP and IGES export needs a CAD kernel: " + CAD_HINT) from None
    return gmsh


_GMSH_LOCK = threading.RLock()       # Gmsh is one global state per process


@contextlib.contextmanager
def gmsh_session():
    """An initialised Gmsh without terminal output; finalised afterwards if it was started here.

    Not interruptible: Gmsh would install a SIGINT handler, which only the main thread may (the
    tasks of a sweep run in worker threads)."""
    gmsh = _gmsh()
    with _GMSH_LOCK:
        started = not gmsh.isInitialized()
        if started:
            with _quiet():
                gmsh.initialize(readConfigFiles=False, interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            yield gmsh
        finally:
            if started:
                with _quiet():
                    gmsh.finalize()


def control_net(surface, alpha) -> np.ndarray:
    """(d1+1, d2+1, 3) control points of ϑ_α as a B-spline: Greville abscissae and heights α_ij."""
    A = surface.as_matrix(alpha)
    t1 = np.linspace(0.0, 1.0, surface.d1 + 1) if surface.d1 else np.array([0.5])
    t2 = np.linspace(0.0, 1.0, surface.d2 + 1) if surface.d2 else np.array([0.5])
    P = np.empty(A.shape + (3,))
    P[..., 0] = surface.x1lo + surface.a * t1[:, None]
    P[..., 1] = surface.x2lo + surface.b * t2[None, :]
    P[..., 2] = A
    return P


def outline_loops(model) -> list[np.ndarray]:
    """Closed loops (x1, x2) of the contact face's boundary edges, outer first (corner nodes only)."""
    ref = model.body.reference
    nc = FACE_CORNERS[ref.face_type]
    faces = np.asarray(model.body.contact_face.faces)[:, :nc]
    e = np.concatenate([faces[:, [k, (k + 1) % nc]] for k in range(nc)])
    und = np.sort(e, axis=1)
    _, inv, count = np.unique(und, axis=0, return_inverse=True, return_counts=True)
    bnd = e[count[inv] == 1]                      # directed as in their (outward) face
    nxt = dict(zip(bnd[:, 0].tolist(), bnd[:, 1].tolist()))
    loops = []
    while nxt:
        start = next(iter(nxt))
        loop = [start]
        n = nxt.pop(start)
        while n != start:
            loop.append(n)
            n = nxt.pop(n)
        xy = ref.points[loop, :2]
        loops.append(xy)
    area = [0.5 * np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1]) for xy in loops]
    order = np.argsort(-np.abs(area))
    return [loops[i] for i in order]


def _is_rectangle(loops, surface, tol) -> bool:
    if len(loops) != 1:
        return False
    xy = loops[0]
    area = abs(0.5 * np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1]))
    return abs(area - surface.a * surface.b) <= tol * max(surface.a, surface.b)


CORNER_ANGLE = np.deg2rad(25.0)


def _loop_curves(occ, uv: np.ndarray, tol: float) -> list[int]:
    """Curves of a closed loop in parameter space: split at corners (turning angle > 25°); a piece
    whose points lie on a line is a line, else an interpolating spline through them."""
    n = uv.shape[0]
    d_in = uv - np.roll(uv, 1, axis=0)
    d_out = np.roll(uv, -1, axis=0) - uv
    ang = np.abs(np.arctan2(d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0], np.einsum("ij,ij->i", d_in, d_out)))
    corners = np.flatnonzero(ang > CORNER_ANGLE)
    pts = [occ.addPoint(u, v, 0.0) for u, v in uv]
    if corners.size == 0:                     # smooth closed loop: one periodic spline
        return [occ.addSpline(pts + [pts[0]])]
    curves = []
    for a, b in zip(corners, np.roll(corners, -1)):
        idx = list(range(a, b + 1)) if b > a else list(range(a, n)) + list(range(0, b + 1))
        seg = uv[idx]
        dirn = seg[-1] - seg[0]
        dist = np.abs(dirn[0] * (seg[:, 1] - seg[0, 1]) - dirn[1] * (seg[:, 0] - seg[0, 0])) / max(np.linalg.norm(dirn), 1e-300)
        if len(idx) == 2 or dist.max() <= tol:
            curves.append(occ.addLine(pts[idx[0]], pts[idx[-1]]))
        else:
            curves.append(occ.addSpline([pts[i] for i in idx]))
    return curves


def write_contact_surface(path, model, alpha, *, unit: str = "mm", trim: bool = True) -> dict:
    """Write ϑ_α as an exact B-spline surface to ``path`` (.step/.stp or .iges/.igs), atomically.

    Trimmed to the contact face's outline where that is not the design rectangle (``trim``).
    ``unit``: the unit of the model's coordinates (mm, cm, m, in, um); the file is in millimetres.
    Returns ``{"trimmed": bool, "scale": factor to mm, "degrees": (d1, d2)}``. A face on a chart
    other than (x1, x2) (design.chart) is refused: its surface is the chart's, not a graph ϑ_α."""
    if model.body.chart is not None:
        raise ExportError(f"STEP/IGES: the contact face lies on a {model.body.chart.kind} chart, whose designed "
                          "surface is not the graph of ϑ_α over (x1, x2); export the mesh or STL of the body")
    path = Path(path)
    if unit not in UNITS:
        raise ExportError(f"unit {unit!r}: choose from {', '.join(UNITS)}")
    if path.suffix.lower() not in (".step", ".stp", ".iges", ".igs"):
        raise ExportError(f"{path}: a CAD surface is written as .step/.stp or .iges/.igs")
    s = model.surface
    P = control_net(s, alpha)
    d1, d2 = max(s.d1, 1), max(s.d2, 1)
    if s.d1 == 0:                             # degree 0 as degree 1 with equal end points (exact)
        P = np.concatenate([P, P], axis=0)
        P[0, :, 0], P[1, :, 0] = s.x1lo, s.x1lo + s.a
    if s.d2 == 0:
        P = np.concatenate([P, P], axis=1)
        P[:, 0, 1], P[:, 1, 1] = s.x2lo, s.x2lo + s.b
    loops = outline_loops(model)
    trimmed = trim and not _is_rectangle(loops, s, model.body.tol)
    scale = UNITS[unit]
    with gmsh_session() as gmsh:
        name = "contactopt_contact_surface"
        gmsh.model.add(name)
        try:
            occ = gmsh.model.occ
            tags = [occ.addPoint(*P[i, j]) for j in range(d2 + 1) for i in range(d1 + 1)]   # U = x1 fastest
            wires = []
            if trimmed:
                lo = np.array([s.x1lo, s.x2lo])
                span = np.array([s.a, s.b])
                for xy in loops:
                    wires.append(occ.addWire(_loop_curves(occ, (xy - lo) / span, 1e-9)))
            surf = occ.addBSplineSurface(tags, d1 + 1, degreeU=d1, degreeV=d2, weights=[1.0] * len(tags),
                                         knotsU=[0.0, 1.0], knotsV=[0.0, 1.0], multiplicitiesU=[d1 + 1, d1 + 1],
                                         multiplicitiesV=[d2 + 1, d2 + 1], wireTags=wires, wire3D=False)
            occ.remove([(0, t) for t in tags])
            if scale != 1.0:
                occ.dilate([(2, surf)], 0.0, 0.0, 0.0, scale, scale, scale)
            occ.synchronize()
            with atomic_output(path) as tmp, _quiet():
                gmsh.write(str(tmp))
        finally:
            gmsh.model.remove()
    log.info("wrote %s (B-spline surface of degree (%d, %d)%s, unit %s)", path, d1, d2,
             ", trimmed to the contact face" if trimmed else "", unit)
    return {"trimmed": bool(trimmed), "scale": scale, "degrees": (d1, d2)}


# ---------------------------------------------------------------------- all of it
def export_design(model, alpha, outdir, formats=None, *, unit: str = "mm", strict: bool = True) -> dict:
    """Write the export files of design ``alpha`` into ``outdir`` (created), all or nothing.

    ``formats``: a subset of FORMATS (None: all). Without a CAD kernel, STEP/IGES raise
    ExportError when ``strict`` (asked for), else are left out with a warning; for a contact face
    on a chart (design.chart) they raise when ``strict``, else are left out. Returns
    ``{"files": {format: [file names]}, "skipped": {format: reason}, "unit": unit, ...}``."""
    formats = normalize_formats(formats)
    if unit not in UNITS:
        raise ExportError(f"unit {unit!r}: choose from {', '.join(UNITS)}")
    skipped = {}
    if any(f in ("step", "iges") for f in formats) and not has_cad_kernel():
        if strict:
            raise ExportError("STEP and IGES export needs a CAD kernel: " + CAD_HINT)
        for f in ("step", "iges"):
            if f in formats:
                formats.remove(f)
                skipped[f] = "no CAD kernel: " + CAD_HINT
                log.warning("export: %s skipped (no CAD kernel; %s)", f.upper(), CAD_HINT)
    if model.body.designs or model.cp_designs is not None:
        # several designed faces: the round-trip configuration and the CAD surface are one design's
        several = [f for f in formats if f in ("mesh", "step", "iges")]
        if several and strict:
            raise ExportError(f"export {', '.join(several)}: the model has {len(model.config.designs)} designed faces; "
                              "the exported body with its configuration and the CAD surface are written for a "
                              "model of one design so far (export stl)")
        for f in several:
            formats.remove(f)
            skipped[f] = "several designed faces (written for one design so far)"
            log.info("export: %s skipped (%s)", f.upper(), skipped[f])
    if model.body.chart is not None and not strict:
        # ϑ_α on a chart is not a graph over (x1, x2): the body's mesh and STL carry the designed face
        for f in ("step", "iges"):
            if f in formats:
                formats.remove(f)
                skipped[f] = f"the contact face lies on a {model.body.chart.kind} chart (the mesh and STL carry it)"
                log.info("export: %s skipped (%s)", f.upper(), skipped[f])
    coords = model.mesh.coordinates(alpha)        # MeshError for an invalid design, before any file
    outdir = Path(outdir)
    created = not outdir.exists()
    try:
        outdir.mkdir(parents=True, exist_ok=True)
        tmpdir = Path(tempfile.mkdtemp(prefix=".export.", suffix=".tmp", dir=outdir))
    except OSError as exc:
        raise write_error(outdir, exc) from exc
    files: dict[str, list[str]] = {}
    info = {}
    try:
        if "mesh" in formats:
            _, fmt, _, suffix = body_meshio(model, coords)
            name = "optimal_body" + suffix
            write_body_mesh(tmpdir / name, model, coords)
            import tomli_w

            from ..config import validate
            resolved = validate(roundtrip_config(model, str(tmpdir / name), model.surface.as_vector(alpha)),
                                "optimal_body.toml").to_dict()
            resolved["body"]["mesh"] = name        # relative to the configuration file
            atomic_write_text(tmpdir / "optimal_body.toml",
                              "# the optimal body exported by contactopt; its state at alpha = 0 is the optimal "
                              "design's\n# (body.initial_gap = 'mesh': the contact face's height in the mesh is "
                              "its gap)\n" + tomli_w.dumps(resolved))
            files["mesh"] = [name, "optimal_body.toml"]
            info["mesh_format"] = fmt
        if "stl" in formats:
            write_stl(tmpdir / "optimal_body.stl", model, coords,
                      header=f"contactopt {model.config.name} optimal body; units of the input mesh")
            files["stl"] = ["optimal_body.stl"]
        for f, ext in (("step", ".step"), ("iges", ".iges")):
            if f in formats:
                res = write_contact_surface(tmpdir / f"contact_surface{ext}", model, alpha, unit=unit)
                files[f] = [f"contact_surface{ext}"]
                info["surface_trimmed"] = res["trimmed"]
        for names in files.values():
            for name in names:
                try:
                    os.replace(tmpdir / name, outdir / name)
                except OSError as exc:
                    raise write_error(outdir / name, exc) from exc
        fsync_dir(outdir)
    except WriteError as exc:              # named by the file it was to be, not the temporary one
        shutil.rmtree(tmpdir, ignore_errors=True)
        if created and not any(outdir.iterdir()):
            outdir.rmdir()
        if exc.path.parent == tmpdir:
            raise WriteError(outdir / exc.path.name, exc.cause) from exc.cause
        raise
    except BaseException:
        shutil.rmtree(tmpdir, ignore_errors=True)
        if created and not any(outdir.iterdir()):
            outdir.rmdir()                    # a failed export leaves no empty directory behind
        raise
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
    return {"files": files, "skipped": skipped, "unit": unit,
            "cad_unit": "mm" if any(f in files for f in ("step", "iges")) else None, **info}
