"""The reference mesh of a body: plain data (points, volume cells, named parts).

Every mesh source (the structured block of :mod:`contactopt.mesh.block`, a mesh file read by
:mod:`contactopt.mesh.reader`) produces a :class:`ReferenceMesh`; the morph of
:mod:`contactopt.mesh.morph` lifts it by the design surface (docs/theory.md).

Cell types and node order are meshio's (= VTK's): ``hexahedron`` (Q1, 8 nodes), ``tetra``
(P1, 4 nodes), ``tetra10`` (P2, 10 nodes: 4 vertices, then the midpoints of the edges
01, 12, 02, 03, 13, 23). A boundary face is listed with its vertices ordered so that the
right-hand normal (T1 × T2 of the face parametrisation) points *out of* the body; faces are
``quad`` (4 nodes), ``triangle`` (3) or ``triangle6`` (3 vertices, then the midpoints of the
edges 01, 12, 20).

A :class:`Part` is a named set of nodes with, where it is a piece of the boundary, its boundary
faces. Parts come from the file (Gmsh physical groups, meshio cell and point sets) or from a
geometric predicate on the reference coordinates (:func:`select_part`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, MeshError

# local faces of each volume cell type, outward (right-hand rule), and the face cell type
CELL_FACES = {
    "hexahedron": ("quad", np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4],
                                     [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])),
    "tetra": ("triangle", np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])),
    "tetra10": ("triangle6", np.array([[0, 2, 1, 6, 5, 4], [0, 1, 3, 4, 8, 7],
                                       [1, 2, 3, 5, 9, 8], [0, 3, 2, 7, 9, 6]])),
}
FACE_CORNERS = {"quad": 4, "triangle": 3, "triangle6": 3}
CELL_CORNERS = {"hexahedron": 8, "tetra": 4, "tetra10": 4}
CELL_NODES = {"hexahedron": 8, "tetra": 4, "tetra10": 10}
SUPPORTED_CELLS = tuple(CELL_FACES)


@dataclass
class Part:
    """A named part: ``nodes`` (sorted unique indices) and its boundary ``faces`` (F, k), outward.

    ``faces`` is empty (shape (0, k)) for a part that is not a piece of the boundary (a volume
    group, a set of points). ``origin`` says where it came from (a group of the file, the
    block generator, or a predicate)."""

    name: str
    nodes: np.ndarray
    faces: np.ndarray
    origin: str = "file"


@dataclass
class ReferenceMesh:
    """Points (n, 3), volume cells (E, k) of one ``cell_type``, named parts, and the source."""

    points: np.ndarray
    cells: np.ndarray
    cell_type: str
    parts: dict = field(default_factory=dict)
    source: str = "<generated>"
    _boundary: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        if self.cell_type not in CELL_FACES:
            raise MeshError(f"{self.source}: volume cells of type {self.cell_type!r} are not supported "
                            f"(supported: {', '.join(SUPPORTED_CELLS)})")
        self.points = np.ascontiguousarray(self.points, dtype=float)
        self.cells = np.ascontiguousarray(self.cells, dtype=np.int64)
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise MeshError(f"{self.source}: points must be an (n, 3) array, got {self.points.shape}")
        if self.cells.ndim != 2 or self.cells.shape[1] != CELL_NODES[self.cell_type]:
            raise MeshError(f"{self.source}: {self.cell_type} cells need {CELL_NODES[self.cell_type]} nodes each, "
                            f"got an array of shape {self.cells.shape}")
        if self.cells.size == 0:
            raise MeshError(f"{self.source}: the mesh has no volume cells")
        if not np.all(np.isfinite(self.points)):
            raise MeshError(f"{self.source}: the mesh has non-finite point coordinates")
        if self.cells.min() < 0 or self.cells.max() >= self.points.shape[0]:
            raise MeshError(f"{self.source}: cells refer to nodes outside 0..{self.points.shape[0] - 1}")

    @property
    def n_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def n_cells(self) -> int:
        return self.cells.shape[0]

    @property
    def face_type(self) -> str:
        return CELL_FACES[self.cell_type][0]

    def used_nodes(self) -> np.ndarray:
        """Nodes that belong to some volume cell (a file may carry others, e.g. geometry points)."""
        return np.unique(self.cells)

    # ------------------------------------------------------------------ boundary
    def boundary_faces(self) -> np.ndarray:
        """All boundary faces (F, k) from the volume cells, oriented outward (computed once)."""
        if self._boundary is None:
            ftype, local = CELL_FACES[self.cell_type]
            faces = self.cells[:, local].reshape(-1, local.shape[1])
            key = np.sort(faces[:, :FACE_CORNERS[ftype]], axis=1)
            _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
            if np.any(count > 2):
                raise MeshError(f"{self.source}: {int(np.sum(count > 2))} face(s) are shared by more than two "
                                "cells: the mesh is not a manifold volume mesh")
            self._boundary = faces[np.sort(first[count == 1])]
        return self._boundary

    def match_faces(self, faces: np.ndarray, what: str) -> np.ndarray:
        """The boundary faces (outward, of the mesh's face type) with the corners of ``faces``.

        Face node order in a file is arbitrary: the orientation comes from the volume cell.
        Raises MeshError naming faces that are not on the boundary."""
        bnd = self.boundary_faces()
        nc = FACE_CORNERS[self.face_type]
        faces = np.asarray(faces, dtype=np.int64)
        if faces.shape[0] == 0:
            return bnd[:0]
        if faces.shape[1] < nc:
            raise MeshError(f"{self.source}: {what} has faces of {faces.shape[1]} nodes; the boundary of "
                            f"{self.cell_type} cells has {self.face_type} faces")
        want = np.sort(faces[:, :nc], axis=1)
        have = np.sort(bnd[:, :nc], axis=1)
        order = np.lexsort(have.T[::-1])
        have_sorted = have[order]
        pos = _rows_searchsorted(have_sorted, want)
        ok = (pos < len(have_sorted)) & np.all(have_sorted[np.minimum(pos, len(have_sorted) - 1)] == want, axis=1)
        if not np.all(ok):
            bad = faces[~ok][:3]
            raise MeshError(f"{self.source}: {what} has {int(np.sum(~ok))} face(s) that are not on the boundary "
                            f"of the volume mesh (first with nodes {bad.tolist()})")
        return bnd[np.unique(order[pos])]

    def faces_within(self, nodes: np.ndarray) -> np.ndarray:
        """Boundary faces whose corner nodes all lie in ``nodes``."""
        bnd = self.boundary_faces()
        inside = np.zeros(self.n_nodes, bool)
        inside[nodes] = True
        return bnd[np.all(inside[bnd[:, :FACE_CORNERS[self.face_type]]], axis=1)]

    def inverted_cells(self) -> np.ndarray:
        """Cells whose corner orientation is negative (det of the Jacobian at the cell centre ≤ 0):
        inverted as given, or numbered in another convention than meshio's."""
        X = self.points[self.cells[:, :CELL_CORNERS[self.cell_type]]]
        if self.cell_type == "hexahedron":
            s = 2.0 * np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                                (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)], float) - 1.0
            J = np.einsum("eam,an->emn", X, s) / 8.0          # ∂x_m/∂ξ_n at ξ = 0
            det = np.linalg.det(J)
        else:
            det = np.linalg.det(X[:, 1:] - X[:, :1])
        return np.flatnonzero(~(det > 0))

    def quality(self) -> np.ndarray:
        """Shape quality in (0, 1] per cell (1: a regular tetrahedron or a cube): the mean ratio
        12·(3V)^(2/3)/Σ l² of the corner tetrahedron for tetrahedra; for hexahedra the smallest
        over the eight corners of det J_corner/(Π of its three edge lengths)."""
        X = self.points[self.cells[:, :CELL_CORNERS[self.cell_type]]]
        if self.cell_type == "hexahedron":
            # corner a: its three edges in the right-handed order of the reference cube
            nb = np.array([[1, 3, 4], [2, 0, 5], [3, 1, 6], [0, 2, 7], [7, 5, 0], [4, 6, 1], [5, 7, 2], [6, 4, 3]])
            E = X[:, nb] - X[:, :, None, :]                       # (C, 8, 3 edges, 3)
            det = np.linalg.det(E)
            norms = np.prod(np.linalg.norm(E, axis=3), axis=2)
            return np.min(det / norms, axis=1)
        e = X[:, [1, 2, 3, 2, 3, 3]] - X[:, [0, 0, 0, 1, 1, 2]]
        vol = np.linalg.det(X[:, 1:] - X[:, :1]) / 6.0
        return 12.0 * np.cbrt(3.0 * vol) ** 2 / np.sum(e ** 2, axis=(1, 2))

    # ------------------------------------------------------------------ sizes
    def typical_size(self) -> float:
        """Median edge length of the boundary faces: the unit of geometric tolerances."""
        f = self.boundary_faces()[:, :FACE_CORNERS[self.face_type]]
        e = self.points[f] - self.points[np.roll(f, -1, axis=1)]
        h = float(np.median(np.linalg.norm(e, axis=2)))
        if not h > 0:
            raise MeshError(f"{self.source}: boundary faces of zero size")
        return h

    def part(self, name: str) -> Part:
        """The part of that name; MeshError lists the names that exist."""
        if name not in self.parts:
            known = ", ".join(sorted(self.parts)) or "none"
            raise MeshError(f"{self.source}: no part named {name!r} (the mesh has: {known})")
        return self.parts[name]


def _rows_searchsorted(sorted_rows: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Index of each row of ``rows`` in the lexicographically sorted ``sorted_rows``."""
    base = max(int(sorted_rows.max(initial=0)), int(rows.max(initial=0))) + 1
    k = sorted_rows.shape[1]
    if base ** k < 2 ** 62:
        w = base ** np.arange(k - 1, -1, -1, dtype=np.int64)
        return np.searchsorted(sorted_rows @ w, rows @ w)
    keys = np.ascontiguousarray(sorted_rows).view([("", sorted_rows.dtype)] * k).ravel()
    q = np.ascontiguousarray(rows).view([("", rows.dtype)] * k).ravel()
    return np.searchsorted(keys, q)


# ---------------------------------------------------------------------- predicates
PREDICATE_KEYS = ("x1", "x2", "x3", "box")


def describe_part(spec) -> str:
    """A part spec as the user wrote it, for messages."""
    if isinstance(spec, str):
        return repr(spec)
    if isinstance(spec, list):
        return " + ".join(describe_part(s) for s in spec)
    return "{" + ", ".join(f"{k} = {v}" for k, v in spec.items()) + "}"


class HasParts:
    """``part(spec)`` of a mesh with resolved parts (its ``reference`` and absolute ``tol``): a
    configuration's part spec (a name or a predicate table); ConfigError names the parts that exist."""

    def part(self, spec) -> Part:
        try:
            return select_part(self.reference, spec, self.tol)
        except MeshError as exc:
            raise ConfigError([str(exc)]) from None


def part_selector(mesh: ReferenceMesh, tol: float, prefix: str, problems: list):
    """``part(key, spec)``: :func:`select_part` of a configuration's key, its MeshError appended
    to ``problems`` as ``"{prefix}.{key}: …"`` (then None), so that every problem is listed at once."""
    def part(key, spec):
        try:
            return select_part(mesh, spec, tol)
        except MeshError as exc:
            problems.append(f"{prefix}.{key}: {exc}")
            return None
    return part


def select_part(mesh: ReferenceMesh, spec, tol: float, *, origin="predicate") -> Part:
    """The part named by ``spec``: a part name, or a predicate table on the reference coordinates.

    Predicates: ``{x1 = v}`` (and x2, x3): nodes on that plane; ``{box = [[lo, hi], [lo, hi],
    [lo, hi]]}``: nodes in the box (bounds inclusive). Several keys intersect. ``tol`` is an
    absolute distance (coordinates in files are rounded: never compared with ``==``). The faces
    are the boundary faces with every corner in the part.
    """
    if isinstance(spec, str):
        return mesh.part(spec)
    x = mesh.points
    inside = np.zeros(mesh.n_nodes, bool)
    inside[mesh.used_nodes()] = True
    for key, val in spec.items():
        if key in ("x1", "x2", "x3"):
            inside &= np.abs(x[:, int(key[1]) - 1] - float(val)) <= tol
        elif key == "box":
            for m, (lo, hi) in enumerate(val):
                inside &= (x[:, m] >= float(lo) - tol) & (x[:, m] <= float(hi) + tol)
        else:
            raise MeshError(f"part {describe_part(spec)}: unknown predicate {key!r} "
                            f"(allowed: {', '.join(PREDICATE_KEYS)})")
    nodes = np.flatnonzero(inside)
    if nodes.size == 0:
        raise MeshError(f"part {describe_part(spec)}: no node of the mesh lies there "
                        f"(tolerance {tol:.3g}; the mesh spans {_extent(mesh)})")
    return Part(describe_part(spec), nodes, mesh.faces_within(nodes), origin)


def _extent(mesh: ReferenceMesh) -> str:
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    return " × ".join(f"[{a:.4g}, {b:.4g}]" for a, b in zip(lo, hi))
