"""Tetrahedral meshes from hexahedral ones: the six-tetrahedron split and P2 midside nodes.

:func:`hex_to_tets` splits every hexahedron (meshio/VTK vertex order) into the six tetrahedra
around its diagonal 0–6 (the Kuhn/Freudenthal split). On a structured grid whose cells share one
orientation (the block of :mod:`contactopt.mesh.block`) the split is conforming: neighbouring
cells cut their common face along the same diagonal. :func:`tet4_to_tet10` adds the midpoints of
the edges, numbered after the existing nodes, in meshio's tetra10 order (edges 01, 12, 02, 03, 13,
23).
"""

from __future__ import annotations

import numpy as np

# the six monotone paths (0,0,0) → (1,1,1) through the cube, as VTK hexahedron vertices
_KUHN = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]])
TET10_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])


def hex_to_tets(cells: np.ndarray, points: np.ndarray | None = None) -> np.ndarray:
    """(6E, 4) tetrahedra of the hexahedra ``cells`` (E, 8); with ``points`` each is oriented
    positively (det(x1 − x0, x2 − x0, x3 − x0) > 0), else as for a right-handed cell."""
    cells = np.asarray(cells)
    tets = cells[:, _KUHN].reshape(-1, 4)
    if points is None:
        # orientation of each path in the unit cube (vertex coordinates in VTK order)
        cube = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)], float)
        X = cube[_KUHN]
        flip = np.tile(np.linalg.det(X[:, 1:] - X[:, :1]) < 0, cells.shape[0])
    else:
        X = np.asarray(points)[tets]
        flip = np.linalg.det(X[:, 1:] - X[:, :1]) < 0
    tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    return tets


def tet4_to_tet10(points: np.ndarray, cells: np.ndarray):
    """(points with edge midpoints appended, (E, 10) cells): linear tetrahedra made quadratic."""
    cells = np.asarray(cells)
    edges = np.sort(cells[:, TET10_EDGES].reshape(-1, 2), axis=1)
    uniq, inv = np.unique(edges, axis=0, return_inverse=True)
    mid = 0.5 * (points[uniq[:, 0]] + points[uniq[:, 1]])
    new = np.vstack([points, mid])
    cells10 = np.hstack([cells, points.shape[0] + inv.reshape(-1, 6)])
    return new, cells10
