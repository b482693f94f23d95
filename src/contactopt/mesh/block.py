"""The paper's block [0,a]×[0,b]×[0,c] on a structured grid of Q1 hexahedra: one mesh source.

Reference mesh of the block with its contact face on x3 = 0 (DESIGN.md §1, §9):

    node n = i + (nx+1)·(j + (ny+1)·k)  at  (a·i/nx, b·j/ny, c·k/nz),

hexahedra with vertices at the offsets (0,0,0), (1,0,0), (1,1,0), (0,1,0), (0,0,1), (1,0,1),
(1,1,1), (0,1,1) (meshio/VTK order), element e = i + nx·(j + ny·k) ordered i fastest.
Named parts: ``clamped`` (x1 = 0, Γ_u), ``top`` (x3 = c), ``right`` (x1 = a), ``front``
(x2 = 0), ``back`` (x2 = b) and ``contact`` (x3 = 0). The morph of the block (harmonic weight,
:mod:`contactopt.mesh.morph`) is w = 1 − x3/c, which turns it into the paper's vertical map
x3 = ϑ_α + (c − ϑ_α)·s, s = k/nz.
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshError
from .reference import Part, ReferenceMesh

# local (i, j, k) offsets of the 8 vertices of a Q1 hexahedron (meshio/VTK order)
HEX_OFFSETS = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                        (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])


def block_mesh(a: float, b: float, c: float, nx: int, ny: int, nz: int) -> ReferenceMesh:
    """Reference mesh of the block (see the module docstring)."""
    if min(nx, ny, nz) < 1:
        raise MeshError(f"mesh needs at least one element per direction, got {nx}×{ny}×{nz}")
    k, j, i = np.meshgrid(np.arange(nz + 1), np.arange(ny + 1), np.arange(nx + 1), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    points = np.column_stack([a * i / nx, b * j / ny, c * (k / nz)])
    ei, ej, ek = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    ei, ej, ek = (v.ravel(order="F") for v in (ei, ej, ek))

    def node_id(ii, jj, kk):
        return ii + (nx + 1) * (jj + (ny + 1) * kk)

    cells = np.column_stack([node_id(ei + di, ej + dj, ek + dk) for di, dj, dk in HEX_OFFSETS])
    mesh = ReferenceMesh(points, cells, "hexahedron", source=f"block {nx}×{ny}×{nz}")
    for name, on in (("clamped", i == 0), ("top", k == nz), ("right", i == nx), ("front", j == 0),
                     ("back", j == ny), ("contact", k == 0)):
        nodes = np.flatnonzero(on)
        mesh.parts[name] = Part(name, nodes, mesh.faces_within(nodes), "block")
    return mesh
