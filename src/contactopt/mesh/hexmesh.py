"""Structured trilinear-hexahedron mesh of Ω(α) by the vertical map of the reference block.

Reference block [0,a]×[0,b]×[0,1] with nodes (i, j, k), 0 ≤ i ≤ nx, 0 ≤ j ≤ ny, 0 ≤ k ≤ nz,
mapped to Ω(α) by

    x1 = a·i/nx,  x2 = b·j/ny,  x3 = ϑ_α(x1, x2) + (c − ϑ_α(x1, x2))·s,   s = k/nz,

so node coordinates are affine in α and ∂x3/∂α_ij = β^i β^j(x1, x2)·(1 − s) (DESIGN.md §1).

Numbering: node n = i + (nx+1)·(j + (ny+1)·k); DOF 3n + m for displacement component m ∈ {0,1,2}
(x1, x2, x3). Element vertices follow the usual Q1 order (0,0,0), (1,0,0), (1,1,0), (0,1,0),
(0,0,1), (1,0,1), (1,1,1), (0,1,1) in the local (i, j, k) offsets.

Named node sets: ``clamped`` (x1 = 0, Γ_u), ``top`` (x3 = c), ``right`` (x1 = a), ``bottom``
(x3 = ϑ_α) and ``contact`` (bottom nodes not on Γ_u, ordered by node number: i fastest, then j).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..design.bezier import BezierSurface
from ..errors import MeshError

# local (i, j, k) offsets of the 8 vertices of a Q1 hexahedron
HEX_OFFSETS = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                        (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])


@dataclass
class HexMesh:
    """Structured Q1 mesh of Ω(α) for a Bézier bottom surface (see the module docstring)."""

    nx: int
    ny: int
    nz: int
    surface: BezierSurface
    c: float
    elements: np.ndarray = field(init=False, repr=False)
    ref_coords: np.ndarray = field(init=False, repr=False)   # (x1, x2, s) per node
    node_sets: dict = field(init=False, repr=False)
    faces: dict = field(init=False, repr=False)
    _basis: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        nx, ny, nz = self.nx, self.ny, self.nz
        if min(nx, ny, nz) < 1:
            raise MeshError(f"mesh needs at least one element per direction, got {nx}×{ny}×{nz}")
        a, b = self.surface.a, self.surface.b
        k, j, i = np.meshgrid(np.arange(nz + 1), np.arange(ny + 1), np.arange(nx + 1), indexing="ij")
        i, j, k = i.ravel(), j.ravel(), k.ravel()
        self.ref_coords = np.column_stack([a * i / nx, b * j / ny, k / nz])
        ei, ej, ek = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
        ei, ej, ek = (v.ravel(order="F") for v in (ei, ej, ek))
        self.elements = np.column_stack([
            self.node_id(ei + di, ej + dj, ek + dk) for di, dj, dk in HEX_OFFSETS])
        self.node_sets = {
            "clamped": np.flatnonzero(i == 0),
            "top": np.flatnonzero(k == nz),
            "right": np.flatnonzero(i == nx),
            "bottom": np.flatnonzero(k == 0),
            "contact": np.flatnonzero((k == 0) & (i > 0)),
        }
        self.faces = {"top": self._face_quads("top"), "right": self._face_quads("right")}
        self._basis = self.surface.basis_matrix(self.ref_coords[:, 0], self.ref_coords[:, 1])

    # ------------------------------------------------------------------ topology
    def node_id(self, i, j, k):
        return i + (self.nx + 1) * (j + (self.ny + 1) * k)

    @property
    def n_nodes(self) -> int:
        return (self.nx + 1) * (self.ny + 1) * (self.nz + 1)

    @property
    def n_elements(self) -> int:
        return self.nx * self.ny * self.nz

    def _face_quads(self, name: str) -> np.ndarray:
        """Boundary quadrilaterals (counter-clockwise seen from outside) of a named face."""
        nx, ny, nz = self.nx, self.ny, self.nz
        if name == "top":
            i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
            i, j = i.ravel(), j.ravel()
            return np.column_stack([self.node_id(i, j, nz), self.node_id(i + 1, j, nz),
                                    self.node_id(i + 1, j + 1, nz), self.node_id(i, j + 1, nz)])
        if name == "right":
            j, k = np.meshgrid(np.arange(ny), np.arange(nz), indexing="ij")
            j, k = j.ravel(), k.ravel()
            return np.column_stack([self.node_id(nx, j, k), self.node_id(nx, j + 1, k),
                                    self.node_id(nx, j + 1, k + 1), self.node_id(nx, j, k + 1)])
        raise KeyError(name)

    # ------------------------------------------------------------------ geometry
    def heights(self, alpha) -> np.ndarray:
        """ϑ_α at every node's (x1, x2)."""
        return self._basis @ self.surface.as_vector(alpha)

    def coordinates(self, alpha) -> np.ndarray:
        """Node coordinates (n_nodes, 3) of Ω(α); raises MeshError if the map would invert."""
        theta = self.heights(alpha)
        bad = theta >= self.c
        if np.any(bad):
            raise MeshError(
                f"the contact surface reaches the top face: max ϑ_α = {theta.max():.6g} ≥ c = "
                f"{self.c:.6g} at {int(bad.sum())} node(s); the mapped elements would invert")
        if not np.all(np.isfinite(theta)):
            raise MeshError("design produces non-finite surface heights")
        x = self.ref_coords.copy()
        s = self.ref_coords[:, 2]
        x[:, 2] = theta + (self.c - theta) * s
        return x

    def dx3_dalpha(self) -> np.ndarray:
        """∂x3/∂α for every node: (n_nodes, n_design) = β^i β^j(x1, x2)·(1 − s). Constant in α."""
        return self._basis * (1.0 - self.ref_coords[:, 2])[:, None]

    def contact_points(self) -> np.ndarray:
        """(x1, x2) of the contact nodes, in contact-node order."""
        return self.ref_coords[self.node_sets["contact"], :2]

    def contact_areas(self) -> np.ndarray:
        """Tributary areas of the contact nodes on the projected rectangle (halved on its edges),
        which turn a contact stress σ into nodal forces λ_i ≈ σ(x'_i)·A_i."""
        a, b = self.surface.a, self.surface.b
        x1, x2 = self.contact_points().T
        w1 = np.where(np.isclose(x1, a), 0.5, 1.0) * a / self.nx
        w2 = np.where(np.isclose(x2, 0.0) | np.isclose(x2, b), 0.5, 1.0) * b / self.ny
        return w1 * w2

    def gap_matrix(self) -> np.ndarray:
        """G with gap g = G α: the initial gap of contact node i is ϑ_α(x'_i) (foundation x3 ≤ 0)."""
        return self._basis[self.node_sets["contact"]]
