"""The paper's block as a morphed mesh: the structured source with the harmonic morph.

Reference block [0,a]×[0,b]×[0,c] (:func:`contactopt.mesh.block.block_mesh`; graded, the grid of
:func:`~contactopt.mesh.block.graded_block_mesh`, for which read x1[i], x2[j], x3[k] below) moved by the one
morph of :mod:`contactopt.mesh.morph`, x3 = c·s + ϑ_α(x1, x2)·w. The harmonic weight of the
block (w = 1 on the contact face x3 = 0, 0 on the top x3 = c, natural on the sides) is
w = 1 − s, so this is the paper's vertical map (docs/theory.md),

    x1 = a·i/nx,  x2 = b·j/ny,  x3 = ϑ_α(x1, x2) + (c − ϑ_α(x1, x2))·s,   s = k/nz,

with ∂x3/∂α_ij = β^i β^j(x1, x2)·(1 − s).

Numbering: node n = i + (nx+1)·(j + (ny+1)·k); DOF 3n + m for displacement component m ∈ {0,1,2}
(x1, x2, x3). Element vertices follow the usual Q1 order (0,0,0), (1,0,0), (1,1,0), (0,1,0),
(0,0,1), (1,0,1), (1,1,1), (0,1,1) in the local (i, j, k) offsets.

Named node sets: ``clamped`` (x1 = 0, Γ_u), ``top`` (x3 = c), ``right`` (x1 = a), ``front``,
``back``, ``bottom`` (the contact face, x3 = ϑ_α) and ``contact`` (bottom nodes not on Γ_u,
ordered by node number: i fastest, then j).
"""

from __future__ import annotations

import numpy as np

from .block import HEX_OFFSETS, block_mesh
from .morph import MorphedMesh

__all__ = ["HexMesh", "HEX_OFFSETS"]


class HexMesh(MorphedMesh):
    """Structured Q1 mesh of Ω(α) for a Bézier bottom surface (see the module docstring).

    Geometry only: the weight of the design's lift (a harmonic extension, computed by the FE
    layer) is given; :func:`contactopt.fem.weight.block_hexmesh` builds the block alone, and
    :class:`~contactopt.fem.model.ElasticModel` passes the reference mesh, weight and contact nodes
    of its body.
    """

    def __init__(self, nx, ny, nz, surface, c, *, weight, reference=None, contact_nodes=None,
                 fixed_shape=("top",), **chart):
        ref = reference if reference is not None else block_mesh(surface.a, surface.b, c, nx, ny, nz)
        if contact_nodes is None:
            contact_nodes = np.setdiff1d(ref.parts["contact"].nodes, ref.parts["clamped"].nodes)
        super().__init__(ref, surface, weight, contact_nodes, fixed_shape=fixed_shape, **chart)
        self.nx, self.ny, self.nz, self.c = nx, ny, nz, c

    @property
    def ref_coords(self) -> np.ndarray:
        """(x1, x2, s) per node, s = x3_ref/c ∈ [0, 1]."""
        x = self.reference.points.copy()
        x[:, 2] /= self.c
        return x

    @property
    def node_sets(self) -> dict:
        p = self.reference.parts
        out = {name: p[name].nodes for name in ("clamped", "top", "right", "front", "back")}
        out["bottom"] = p["contact"].nodes
        out["contact"] = self.contact_nodes
        return out

    @property
    def faces(self) -> dict:
        return {name: part.faces for name, part in self.reference.parts.items()}

    def node_id(self, i, j, k):
        return i + (self.nx + 1) * (j + (self.ny + 1) * k)
