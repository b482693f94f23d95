"""Von Mises stress at the quadrature points and its derivatives in u and in the node coordinates.

At quadrature point q of element e, with H = ∇u = Σ_a u_a ⊗ ∇N_a (∇N = dN J⁻¹ at the reference
point ξ_q of the stiffness rule), ε = sym H, σ = λ tr(ε) I + 2μ ε and s = σ − tr(σ)/3 I:

    σ_vM = √(3/2 s:s).

Derivatives (σ_vM > 0): with P = 3μ s/σ_vM (symmetric, trace free, so C:∂σ_vM/∂σ = P),

    ∂σ_vM/∂u_{a,i} = Σ_j P_ij ∂N_a/∂x_j,
    ∂σ_vM/∂X_{c,m} = −Σ_ij P_ij H_im ∂N_c/∂x_j     (∂(∂N_a/∂x_j)/∂X_{c,m} = −∂N_a/∂x_m ∂N_c/∂x_j),

the second at fixed u and fixed reference point ξ_q: the exact derivative of the discrete
quantity when the mesh moves with the design. At σ_vM = 0 the zero vector is used (an element
of the subdifferential of the norm there). Conventions: displacement DOF 3n + m (node n,
component m ∈ {x1, x2, x3}); tension positive.
"""

from __future__ import annotations

import numpy as np

from .elasticity import element_geometry

_CHUNK = 8192        # elements per chunk of von_mises_points


def _fields(assembler, coords, u_full, cells):
    X = coords[assembler.elements[cells]]
    G, det = element_geometry(X, assembler.dN)                          # G[e, q, a, m]
    ue = np.asarray(u_full, float).reshape(-1, 3)[assembler.elements[cells]]   # (E, k, 3)
    H = np.einsum("eqam,eai->eqim", G, ue)                              # H[e, q, i, m] = ∂u_i/∂x_m
    eps = 0.5 * (H + H.transpose(0, 1, 3, 2))
    dev = eps - (np.trace(eps, axis1=2, axis2=3) / 3.0)[..., None, None] * np.eye(3)
    s = 2.0 * assembler.mu * dev                                         # deviatoric stress
    vm = np.sqrt(1.5 * np.einsum("eqij,eqij->eq", s, s))
    return G, H, s, vm


def von_mises_points(assembler, coords: np.ndarray, u_full: np.ndarray, cells=None) -> np.ndarray:
    """σ_vM at the quadrature points of the stiffness rule: (E, Q) for the elements ``cells``
    (all by default) of the displacement ``u_full`` (3·n_nodes) on the mesh ``coords``."""
    cells = np.arange(assembler.elements.shape[0]) if cells is None else np.asarray(cells)
    if cells.size <= _CHUNK:
        return _fields(assembler, coords, u_full, cells)[3]
    # in element chunks: the gradients (E, Q, k, 3) of a large mesh need not be held at once
    return np.concatenate([_fields(assembler, coords, u_full, cells[i:i + _CHUNK])[3]
                           for i in range(0, cells.size, _CHUNK)])


def von_mises_gradients(assembler, coords: np.ndarray, u_full: np.ndarray, cells, weights: np.ndarray):
    """(g_u (3·n_nodes,), g_x (n_nodes, 3)): Σ_{e,q} w_eq ∂σ_vM,eq/∂u and ∂/∂X (at fixed u) for
    the elements ``cells`` and weights (len(cells), Q) (module docstring)."""
    cells = np.asarray(cells)
    G, H, s, vm = _fields(assembler, coords, u_full, cells)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(vm > 0, 3.0 * assembler.mu * weights / vm, 0.0)
    P = s * f[..., None, None]                                           # w P[e, q, i, j]
    du = np.einsum("eqij,eqaj->eai", P, G)                               # (E, k, 3)
    M = np.einsum("eqim,eqij->eqmj", H, P)
    dx = -np.einsum("eqmj,eqcj->ecm", M, G)                              # (E, k, 3)
    nodes = assembler.elements[cells].ravel()
    n = assembler.n_nodes
    g_u = np.zeros((n, 3))
    g_x = np.zeros((n, 3))
    for m in range(3):
        g_u[:, m] = np.bincount(nodes, weights=du[:, :, m].ravel(), minlength=n)
        g_x[:, m] = np.bincount(nodes, weights=dx[:, :, m].ravel(), minlength=n)
    return g_u.ravel(), g_x


def quadrature_points(assembler, coords: np.ndarray, cells=None) -> np.ndarray:
    """Physical coordinates (E, Q, 3) of the stiffness rule's points in the elements ``cells``."""
    cells = np.arange(assembler.elements.shape[0]) if cells is None else np.asarray(cells)
    return np.einsum("qa,eam->eqm", assembler.N, coords[assembler.elements[cells]])
