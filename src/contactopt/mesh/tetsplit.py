"""Tetrahedral meshes from hexahedral ones: the Kuhn split, P2 midside nodes, matching faces.

Used to compare P1/P2 tetrahedra with Q1 hexahedra on the same grid (tests, block refinement
studies) and to give a tetrahedral mesh of any structured hexahedral source.

Node orders are meshio's (= VTK's): ``hexahedron`` vertices at the offsets (0,0,0), (1,0,0),
(1,1,0), (0,1,0), (0,0,1), (1,0,1), (1,1,1), (0,1,1) (:data:`contactopt.mesh.block.HEX_OFFSETS`);
``tetra10`` = the 4 vertices, then the midpoints of the edges 01, 12, 02, 03, 13, 23 (Gmsh
numbers the last two the other way round; meshio converts on reading, so meshio/VTK order is
the one used throughout contactopt); ``triangle6`` = the 3 vertices, then the midpoints of the
edges 01, 12, 20.
"""

from __future__ import annotations

from itertools import permutations

import numpy as np

from ..errors import MeshError

# vertex offsets of a hexahedron in meshio/VTK order (= mesh.block.HEX_OFFSETS)
_HEX_OFFSETS = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                         (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
TET10_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])
TRI6_EDGES = np.array([[0, 1], [1, 2], [2, 0]])


def _kuhn_local() -> np.ndarray:
    """The six Kuhn tetrahedra of the reference cube as local hexahedron vertices (6, 4).

    Tetrahedron σ walks from (0,0,0) to (1,1,1) along the axes in the order σ; all six share
    the diagonal 0–6. Each is listed with positive orientation (det[v1−v0, v2−v0, v3−v0] > 0).
    """
    index = {tuple(o): a for a, o in enumerate(_HEX_OFFSETS)}
    tets = []
    for order in permutations(range(3)):
        p = np.zeros(3, int)
        path = [index[tuple(p)]]
        for axis in order:
            p[axis] = 1
            path.append(index[tuple(p)])
        v = _HEX_OFFSETS[path].astype(float)
        if np.linalg.det(v[1:] - v[0]) < 0:
            path[1], path[2] = path[2], path[1]
        tets.append(path)
    return np.array(tets)


KUHN_TETS = _kuhn_local()


def hex_to_tets(cells: np.ndarray, points: np.ndarray | None = None) -> np.ndarray:
    """Split every hexahedron (E, 8) into six tetrahedra (6E, 4) around its diagonal 0–6.

    Tetrahedra of hexahedron e are rows 6e … 6e+5. Without ``points`` each is listed with the
    orientation it has in a right-handed (det J > 0) hexahedron; with ``points`` each is oriented
    positively (det[x1 − x0, x2 − x0, x3 − x0] > 0) by its own coordinates. The split of a face
    is the diagonal through its vertex of smallest offset sum, so the result is conforming
    whenever neighbouring hexahedra have the same local orientation (every structured grid,
    e.g. :func:`contactopt.mesh.block.block_mesh`); a mesh whose hexahedra meet with other
    orientations may get non-matching face diagonals.
    """
    cells = np.asarray(cells)
    if cells.ndim != 2 or cells.shape[1] != 8:
        raise MeshError(f"hex_to_tets needs hexahedra (E, 8), got an array of shape {cells.shape}")
    tets = cells[:, KUHN_TETS].reshape(-1, 4)
    if points is not None:
        X = np.asarray(points, float)[tets]
        flip = np.linalg.det(X[:, 1:] - X[:, :1]) < 0
        tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    return tets


def _edge_nodes(points: np.ndarray, edges: np.ndarray):
    """Midpoint node numbers of the edges (n, 2) (one node per distinct edge, numbered after the
    existing points in order of first appearance) and the new point array."""
    key = np.sort(edges, axis=1)
    uniq, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    # number the new nodes by first appearance: a reproducible order that follows the cells
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    mid = 0.5 * (points[uniq[order, 0]] + points[uniq[order, 1]])
    return points.shape[0] + rank[inverse.ravel()], np.vstack([points, mid])


def tet4_to_tet10(points: np.ndarray, cells: np.ndarray, faces: np.ndarray | None = None):
    """P2 tetrahedra from P1 ones: a node at the midpoint of every edge (shared by its cells).

    Returns ``(points10, cells10)`` with ``cells10`` (E, 10) in meshio/VTK ``tetra10`` order,
    or ``(points10, cells10, faces6)`` when boundary triangles ``faces`` (F, 3) are given
    (``triangle6``, the same midside nodes; a face edge that is no cell edge is a MeshError).
    """
    points = np.asarray(points, float)
    cells = np.asarray(cells)
    if cells.ndim != 2 or cells.shape[1] != 4:
        raise MeshError(f"tet4_to_tet10 needs tetrahedra (E, 4), got an array of shape {cells.shape}")
    E = cells.shape[0]
    edges = cells[:, TET10_EDGES].reshape(-1, 2)
    mid, points10 = _edge_nodes(points, edges)
    cells10 = np.hstack([cells, mid.reshape(E, 6)])
    if faces is None:
        return points10, cells10
    faces = np.asarray(faces)
    fe = np.sort(faces[:, TRI6_EDGES].reshape(-1, 2), axis=1)
    ce = np.sort(edges, axis=1)
    n = points.shape[0]
    ckey = ce[:, 0].astype(np.int64) * n + ce[:, 1]
    fkey = fe[:, 0].astype(np.int64) * n + fe[:, 1]
    srt = np.argsort(ckey, kind="stable")
    pos = np.searchsorted(ckey[srt], fkey)
    pos = np.minimum(pos, ckey.size - 1)
    hit = ckey[srt][pos] == fkey
    if not np.all(hit):
        bad = np.flatnonzero(~hit.reshape(-1, 3).all(axis=1))
        raise MeshError(f"{bad.size} triangle(s) have an edge that is no tetrahedron edge, first: {bad[:5].tolist()}")
    faces6 = np.hstack([faces, mid[srt[pos]].reshape(-1, 3)])
    return points10, cells10, faces6


def tet_boundary_faces(cells: np.ndarray) -> np.ndarray:
    """Boundary triangles (F, 3) of a tetrahedral mesh, each listed with its outward normal
    (right-hand rule), in order of the cells."""
    local = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    tri = np.asarray(cells)[:, local].reshape(-1, 3)
    _, inverse, count = np.unique(np.sort(tri, axis=1), axis=0, return_inverse=True, return_counts=True)
    return tri[count[inverse.ravel()] == 1]


def quads_to_triangles(quads: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The two boundary triangles of the tetrahedral mesh ``tets`` on each quadrilateral (F, 4).

    Returns (2F, 3), rows 2f and 2f+1 for quadrilateral f, ordered like the quadrilateral (an
    outward quadrilateral gives outward triangles). Whichever diagonal the split chose is found
    from the tetrahedra; a quadrilateral that is not split into two of their boundary faces
    is a MeshError.
    """
    quads = np.asarray(quads)
    bnd = np.sort(tet_boundary_faces(tets), axis=1)
    n = int(max(quads.max(initial=0), np.asarray(tets).max(initial=0))) + 1

    def key(t):
        s = np.sort(t, axis=1).astype(np.int64)
        return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]

    have = np.sort(key(bnd))

    def present(t):
        k = key(t)
        pos = np.minimum(np.searchsorted(have, k), have.size - 1)
        return have[pos] == k

    a = (quads[:, [0, 1, 2]], quads[:, [0, 2, 3]])       # diagonal 0–2
    b = (quads[:, [0, 1, 3]], quads[:, [1, 2, 3]])       # diagonal 1–3
    use_a = present(a[0]) & present(a[1])
    use_b = present(b[0]) & present(b[1])
    if not np.all(use_a | use_b):
        bad = np.flatnonzero(~(use_a | use_b))
        raise MeshError(f"{bad.size} quadrilateral(s) are not two boundary triangles of the tetrahedra, "
                        f"first: {bad[:5].tolist()}")
    first = np.where(use_a[:, None], a[0], b[0])
    second = np.where(use_a[:, None], a[1], b[1])
    return np.stack([first, second], axis=1).reshape(-1, 3)
