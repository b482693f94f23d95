"""An independent Q1 elasticity assembly on a clamped box: test matrices for the linear-solver layer.

A box [0, a] x [0, b] x [0, c] split into nx x ny x nz trilinear hexahedra, isotropic
linear elasticity (Young's modulus E, Poisson ratio nu), 2x2x2 Gauss quadrature. The face
x = 0 is clamped (its DOFs are eliminated); the "Schur" DOFs are the three DOFs (x, y, z) of
every bottom node (z = 0) not on x = 0, node by node in the order of increasing node number
(x fastest, then y).

Written apart from :mod:`contactopt.fem` (its own element routine and numbering), so that the
factorizations and the condensation are checked on matrices contactopt's assembly did not make
(tests/test_linsolve.py, benchmarks/bench_schur.py, benchmarks/bench_local.py).

Mesh sizes of the paper's examples:
    Example 1: 32 x 15 x 9 elements -> 15360 free DOFs, 1536 Schur DOFs;
    Example 2: 24 x 11 x 11 elements;
    fine:      64 x 30 x 18 elements -> about 110k free DOFs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

E_DEFAULT = 21.19
NU_DEFAULT = 0.277

# Reference-cube vertices of a Q1 hexahedron, in the same local order as `_element_nodes`.
_CORNERS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=float,
)


@dataclass
class Brick:
    """Assembled clamped brick: ``A`` (free DOFs only), Schur DOFs ``c`` and mesh data."""

    A: sp.csr_matrix
    c: np.ndarray
    shape: tuple[int, int, int]
    n_nodes: int
    free: np.ndarray  # full DOF index (3 * node + component) of every free DOF


def elasticity_matrix(E: float = E_DEFAULT, nu: float = NU_DEFAULT) -> np.ndarray:
    """6x6 isotropic Hooke matrix in Voigt order (xx, yy, zz, yz, xz, xy), engineering shear."""
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(3), np.arange(3)] += 2 * mu
    D[np.arange(3, 6), np.arange(3, 6)] = mu
    return D


def hex_stiffness(h: np.ndarray, E: float = E_DEFAULT, nu: float = NU_DEFAULT) -> np.ndarray:
    """24x24 stiffness of an axis-aligned hexahedron with edge lengths ``h`` (DOFs node-major)."""
    g = 1 / np.sqrt(3)
    pts = np.array(np.meshgrid([-g, g], [-g, g], [-g, g], indexing="ij")).reshape(3, -1).T
    # dN/dxi at every Gauss point: (q, 8 nodes, 3 directions)
    xi = pts[:, None, :] * _CORNERS[None, :, :]          # (q, 8, 3): xi_k * xi_k^node
    factors = 1 + xi                                       # (q, 8, 3)
    dN = np.empty_like(factors)
    for k in range(3):
        others = [m for m in range(3) if m != k]
        dN[:, :, k] = _CORNERS[None, :, k] * factors[:, :, others[0]] * factors[:, :, others[1]] / 8
    J = np.asarray(h, dtype=float) / 2                     # diagonal Jacobian
    dNdx = dN / J                                          # (q, 8, 3)
    detJ = np.prod(J)
    B = np.zeros((pts.shape[0], 6, 24))
    for k in range(3):
        B[:, k, k::3] = dNdx[:, :, k]
    B[:, 3, 1::3] = dNdx[:, :, 2]
    B[:, 3, 2::3] = dNdx[:, :, 1]
    B[:, 4, 0::3] = dNdx[:, :, 2]
    B[:, 4, 2::3] = dNdx[:, :, 0]
    B[:, 5, 0::3] = dNdx[:, :, 1]
    B[:, 5, 1::3] = dNdx[:, :, 0]
    D = elasticity_matrix(E, nu)
    return np.einsum("qia,ij,qjb->ab", B, D, B) * detJ     # unit Gauss weights


def _element_nodes(nx: int, ny: int, nz: int) -> np.ndarray:
    """(ne, 8) node numbers of every element; node (i, j, k) has number i + (nx+1)(j + (ny+1)k)."""
    i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    i, j, k = (v.ravel(order="F") for v in (i, j, k))

    def node(di, dj, dk):
        return (i + di) + (nx + 1) * ((j + dj) + (ny + 1) * (k + dk))

    corners = ((_CORNERS + 1) / 2).astype(int)
    return np.stack([node(*cr) for cr in corners], axis=1)


def brick(nx: int, ny: int, nz: int, a: float = 2.0, b: float = 1.0, c: float = 1.0,
          E: float = E_DEFAULT, nu: float = NU_DEFAULT) -> Brick:
    """Assemble the clamped Q1 elasticity stiffness of the box; see the module docstring."""
    n_nodes = (nx + 1) * (ny + 1) * (nz + 1)
    Ke = hex_stiffness(np.array([a / nx, b / ny, c / nz]), E, nu)
    enodes = _element_nodes(nx, ny, nz)
    edofs = (3 * enodes[:, :, None] + np.arange(3)).reshape(len(enodes), 24)
    rows = np.repeat(edofs, 24, axis=1).ravel()
    cols = np.tile(edofs, (1, 24)).ravel()
    vals = np.broadcast_to(Ke.ravel(), (len(enodes), 576)).ravel()
    K = sp.csr_matrix((vals, (rows, cols)), shape=(3 * n_nodes, 3 * n_nodes))

    node_i = np.arange(n_nodes) % (nx + 1)
    node_k = np.arange(n_nodes) // ((nx + 1) * (ny + 1))
    free_node = node_i > 0
    free = (3 * np.flatnonzero(free_node)[:, None] + np.arange(3)).ravel()
    full_to_free = -np.ones(3 * n_nodes, dtype=np.int64)
    full_to_free[free] = np.arange(len(free))
    contact_nodes = np.flatnonzero(free_node & (node_k == 0))
    c_dofs = full_to_free[(3 * contact_nodes[:, None] + np.arange(3)).ravel()]
    A = K[free][:, free].tocsr()
    A.sort_indices()
    return Brick(A=A, c=c_dofs, shape=(nx, ny, nz), n_nodes=n_nodes, free=free)


EXAMPLE1 = (32, 15, 9)
EXAMPLE2 = (24, 11, 11)
FINE = (64, 30, 18)
