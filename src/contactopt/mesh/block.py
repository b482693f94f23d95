"""The paper's block [0,a]×[0,b]×[0,c] on a structured grid of Q1 hexahedra: one mesh source.

Reference mesh of the block with its contact face on x3 = 0 (docs/theory.md):

    node n = i + (nx+1)·(j + (ny+1)·k)  at  (a·i/nx, b·j/ny, c·k/nz),

or, graded, at (x1[i], x2[j], x3[k]) for given coordinates per direction (``[mesh] x1, x2, x3``),

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
    """Reference mesh of the block with equal elements (see the module docstring)."""
    if min(nx, ny, nz) < 1:
        raise MeshError(f"mesh needs at least one element per direction, got {nx}×{ny}×{nz}")
    return graded_block_mesh(a * np.arange(nx + 1) / nx, b * np.arange(ny + 1) / ny,
                             c * (np.arange(nz + 1) / nz), source=f"block {nx}×{ny}×{nz}")


def block_axes(geometry, mesh) -> tuple:
    """The node coordinates (x1, x2, x3) of the block of ``[geometry]`` and ``[mesh]``: a
    direction's list ``x1``/``x2``/``x3`` where given, else its count of equal elements."""
    out = []
    for ax, n, side in (("x1", "nx", "a"), ("x2", "ny", "b"), ("x3", "nz", "c")):
        given = getattr(mesh, ax) or []
        if given:
            out.append(np.asarray(given, float))
        else:
            L, k = getattr(geometry, side), getattr(mesh, n)
            out.append(L * (np.arange(k + 1) / k) if ax == "x3" else L * np.arange(k + 1) / k)
    return tuple(out)


def graded_block_mesh(x1, x2, x3, *, source=None) -> ReferenceMesh:
    """Reference mesh of the block [0, x1[-1]]×[0, x2[-1]]×[0, x3[-1]] with the nodes on the tensor
    grid x1 × x2 × x3 (each strictly increasing from 0); numbering, cells and parts as the block's."""
    axes = [np.asarray(x, float).reshape(-1) for x in (x1, x2, x3)]
    for name, x in zip(("x1", "x2", "x3"), axes):
        if x.size < 2 or not np.all(np.isfinite(x)) or not np.all(np.diff(x) > 0) or x[0] != 0:
            raise MeshError(f"block coordinates {name} must be finite and strictly increasing from 0, "
                            f"got {x.tolist()}")
    nx, ny, nz = (x.size - 1 for x in axes)
    k, j, i = np.meshgrid(np.arange(nz + 1), np.arange(ny + 1), np.arange(nx + 1), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    points = np.column_stack([axes[0][i], axes[1][j], axes[2][k]])
    ei, ej, ek = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    ei, ej, ek = (v.ravel(order="F") for v in (ei, ej, ek))

    def node_id(ii, jj, kk):
        return ii + (nx + 1) * (jj + (ny + 1) * kk)

    cells = np.column_stack([node_id(ei + di, ej + dj, ek + dk) for di, dj, dk in HEX_OFFSETS])
    mesh = ReferenceMesh(points, cells, "hexahedron", source=source or f"graded block {nx}×{ny}×{nz}")
    for name, on in (("clamped", i == 0), ("top", k == nz), ("right", i == nx), ("front", j == 0),
                     ("back", j == ny), ("contact", k == 0)):
        nodes = np.flatnonzero(on)
        mesh.parts[name] = Part(name, nodes, mesh.faces_within(nodes), "block")
    return mesh
