"""Vectorised linear elasticity: stiffness assembly and its design-derivative contractions.

One assembly layer for every element type of :mod:`contactopt.fem.elements` (Q1 hexahedra,
P1 and P2 tetrahedra): a type gives its reference shape functions and quadrature, the code here
is written once. Conventions: displacement DOF 3n + m (node n, component m ∈ {x1, x2, x3});
element-local DOF 3a + m for node a of the element. The stiffness is the matrix of
a(u, v) = ∫ σ(u):ε(v) dx (paper (2.8)) with isotropic Hooke's law σ = λ tr(ε) I + 2μ ε.
Dirichlet DOFs are eliminated: A acts on the free DOFs only.

Assembly per node pair: with T_ab = Σ_q w_q det J_q ∇N_a ∇N_bᵀ, the 3×3 block of nodes a, b is
λ T_ab + μ T_abᵀ + μ tr(T_ab) I — linear in T with one λ, μ for the body — so T is summed onto
the vertex and edge (node pair) blocks of the mesh by ``np.bincount`` and Hooke's law is
applied once per block; the CSR values are one gather from the blocks. The pattern (slots,
gather, CSR indices) is built once; a new design only recomputes values, in work arrays kept
between designs. Element matrices (:meth:`ElasticityAssembler.element_matrices`) remain for
tests and for :meth:`ElasticityAssembler.full_stiffness`.

B-bar (``formulation="bbar"``, hexahedra): the dilatation div u is replaced by its element mean
θ̄ = (1/|e|) ∫_e div u (Hughes' B-bar, the mean-dilatation form), so that
a(u, v) = Σ_e [ ∫_e 2μ dev ε(u):dev ε(v) dx + κ |e| θ̄(u) θ̄(v) ], κ = λ + 2μ/3 the bulk modulus.
Written as ∫ λ' div u div v + 2μ ε(u):ε(v) with λ' = −2μ/3 plus the element term κ m mᵀ/|e|
(m_(i,a) = ∫_e ∂N_a/∂x_i), it keeps the pair assembly (Hooke's law with λ' per block) and adds
one rank-one matrix per element. The near-incompressibility is then one constraint per element
instead of one at each of its eight Gauss points, so the element does not lock as ν → 1/2.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

from ..errors import MeshError
from .elements import GAUSS_1D, HEX8, ElementType, element_type, gauss_hex, hex_shape  # noqa: F401 (re-exported)

_CHUNK_MIN = 1024    # elements per assembly chunk, at least (smaller meshes: one chunk)
_CONTRACTION_CHUNK = 2048   # elements per chunk of the shape contraction (its temporaries in L2/L3)
_pool = None         # (pid, ThreadPoolExecutor): a forked child makes its own (threads do not fork)


def _assembly_chunks(n_elements: int) -> int:
    """Number of element chunks assembled in parallel: one per usable core (at most 4)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(4, cores, n_elements // _CHUNK_MIN))


def _assembly_pool() -> ThreadPoolExecutor:
    global _pool
    if _pool is None or _pool[0] != os.getpid():
        _pool = (os.getpid(), ThreadPoolExecutor(max_workers=4, thread_name_prefix="contactopt-assembly"))
    return _pool[1]


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé constants (λ, μ) from Young's modulus and Poisson's ratio."""
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


FORMULATIONS = ("standard", "bbar")
BBAR_AUTO_NU = 0.45      # from this ν on, "auto" takes B-bar on hexahedra


def resolve_formulation(formulation: str, element, nu: float) -> str:
    """The element formulation of ``[material] formulation`` for an element type and ν: ``auto``
    is B-bar on hexahedra from ν ≥ 0.45 and standard otherwise; B-bar is for hexahedra only
    (ValueError otherwise: tetrahedra keep their formulation)."""
    el = element_type(element)
    if formulation == "auto":
        return "bbar" if el is HEX8 and nu >= BBAR_AUTO_NU else "standard"
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation {formulation!r}: must be 'auto' or one of {', '.join(FORMULATIONS)}")
    if formulation == "bbar" and el is not HEX8:
        raise ValueError(f"formulation 'bbar' is for hexahedra, not {el.name}")
    return formulation


def hex_reference():
    """Q1 shape functions N (8 gp, 8), gradients dN/dξ (8 gp, 8, 3), weights (8,): 2×2×2 Gauss."""
    return HEX8.N, HEX8.dN, HEX8.w


def det_adj_3x3(J: np.ndarray):
    """Determinants and adjugates of 3×3 matrices stored component-first: J[m, n] is an array.

    Returns ``det`` and ``adj`` with ``adj[n, m] = det · (J⁻¹)[n, m]``; with J[m, n] contiguous,
    every product runs on whole contiguous arrays.
    """
    a, b, c = J[0, 0], J[0, 1], J[0, 2]
    d, e, f = J[1, 0], J[1, 1], J[1, 2]
    g, h, i = J[2, 0], J[2, 1], J[2, 2]
    adj = np.empty_like(J)
    np.subtract(e * i, f * h, out=adj[0, 0])
    np.subtract(f * g, d * i, out=adj[1, 0])
    np.subtract(d * h, e * g, out=adj[2, 0])
    det = a * adj[0, 0] + b * adj[1, 0] + c * adj[2, 0]
    np.subtract(c * h, b * i, out=adj[0, 1])
    np.subtract(b * f, c * e, out=adj[0, 2])
    np.subtract(a * i, c * g, out=adj[1, 1])
    np.subtract(c * d, a * f, out=adj[1, 2])
    np.subtract(b * g, a * h, out=adj[2, 1])
    np.subtract(a * e, b * d, out=adj[2, 2])
    return det, adj


def det_inv_3x3(J: np.ndarray):
    """Determinants and inverses of a stack of 3×3 matrices (..., 3, 3) by cofactors.

    About ten times faster than ``np.linalg.det``/``inv`` on the small stacks of element
    Jacobians; the inverse is only meaningful where the determinant is non-zero.
    """
    det, adj = det_adj_3x3(np.moveaxis(J, (-2, -1), (0, 1)))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.moveaxis(adj, (0, 1), (-2, -1)) / det[..., None, None]
    return det, inv


def require_positive_det(det: np.ndarray, element_axis: int = 0, first: int = 0) -> None:
    """Raise MeshError naming the elements with a Jacobian determinant ≤ 0 (inverted elements;
    ``first``: the number of the element at index 0 of ``det``)."""
    if not np.all(det > 0):
        bad = first + np.unique(np.nonzero(~(det > 0))[element_axis])
        raise MeshError(f"{bad.size} element(s) inverted or degenerate (det J ≤ 0), first: {bad[:5].tolist()}")


def element_geometry(X: np.ndarray, dN: np.ndarray, check: bool = True):
    """Physical gradients G = dN/dx (E, Q, k, 3) and det J (E, Q) for element coordinates X (E, k, 3).

    Raises MeshError if any Jacobian determinant is not positive (inverted element), unless
    ``check`` is false.
    """
    # J_mn = ∂x_m/∂ξ_n = Σ_a X_am dN_an, one BLAS product for all elements and points
    J = np.tensordot(X, dN, axes=([1], [1])).transpose(0, 2, 1, 3)
    det, Jinv = det_inv_3x3(J)
    if check:
        require_positive_det(det)
    G = np.matmul(dN[None], Jinv)                          # ∂N_a/∂x_m = Σ_n ∂N_a/∂ξ_n ∂ξ_n/∂x_m
    return G, det


class ElasticityAssembler:
    """Assembly of A on the free DOFs for a fixed topology (elements, Dirichlet set)."""

    def __init__(self, elements: np.ndarray, n_nodes: int, fixed_dofs: np.ndarray, E: float, nu: float,
                 element: ElementType | str = HEX8, formulation: str = "standard"):
        """``formulation``: ``"standard"`` or ``"bbar"`` (hexahedra, module docstring); ``"auto"``
        is resolved by :func:`resolve_formulation`."""
        self.element = element = element_type(element)
        try:
            self.formulation = resolve_formulation(formulation, element, nu)
        except ValueError as exc:
            raise MeshError(str(exc)) from None
        self.bbar = self.formulation == "bbar"
        self.elements = np.asarray(elements)
        k = element.n_nodes
        if self.elements.ndim != 2 or self.elements.shape[1] != k:
            raise MeshError(f"{element.name} elements need {k} nodes each, got an array of shape "
                            f"{self.elements.shape}")
        self.k = k
        self.n_nodes = int(n_nodes)
        self.n_full = 3 * self.n_nodes
        self.lam, self.mu = lame(E, nu)
        # the λ of the pointwise Hooke's law: λ itself, or −2μ/3 with B-bar (its volumetric part,
        # κ = λ + 2μ/3, acts on the element mean of div u alone)
        self.lam_point = -2.0 * self.mu / 3.0 if self.bbar else self.lam
        self.kappa = self.lam + 2.0 * self.mu / 3.0
        self.N, self.dN, self.w = element.N, element.dN, element.w
        fixed = np.zeros(self.n_full, bool)
        fixed[np.asarray(fixed_dofs, int)] = True
        self.free = np.flatnonzero(~fixed)
        self.full_to_free = np.full(self.n_full, -1)
        self.full_to_free[self.free] = np.arange(self.free.size)
        self.n_free = self.free.size
        d = 3 * k
        edofs = (3 * self.elements[:, :, None] + np.arange(3)).reshape(len(self.elements), d)
        self.edofs = edofs
        self._buffers = None       # work arrays of _element_blocks, reused: no page faults
        self._means = None         # B-bar: (m, |e|) of the last _element_blocks
        # dN by reference point: [a, (q, n)] for the Jacobians, [q, n, a] for the gradients
        self._dN_a = np.ascontiguousarray(self.dN.transpose(1, 0, 2).reshape(k, -1))
        self._dN_q = np.ascontiguousarray(self.dN.transpose(0, 2, 1))
        self._pattern = None       # CSR pattern of stiffness(), built at its first call
        self._pairs = k == 4 and self.w.size == 1      # linear tetrahedra: _LinearTetPairs

    # ------------------------------------------------------------------ stiffness
    def element_matrices(self, X: np.ndarray) -> np.ndarray:
        """Element stiffness matrices (E, 3k, 3k) for element coordinates X (E, k, 3), local DOF 3a + m."""
        K = self._element_blocks(X)
        d = 3 * self.k
        return K.transpose(0, 2, 1, 4, 3).reshape(X.shape[0], d, d)

    def _element_blocks(self, X: np.ndarray, hooke: bool = True) -> np.ndarray:
        """Element stiffness matrices in component-major layout K[e, i, a, j, b] (a work array).

        With g = ∇N (Gauss point q, weight w_q det J_q) and T[i,a,j,b] = Σ_q w_q det J_q
        g_a,i g_b,j, Hooke's law gives K[i,a,j,b] = λ T[i,a,j,b] + μ T[j,a,i,b] + μ δ_ij Σ_k
        T[k,a,k,b]. T is one batched product; √(w det J) is folded into the gradients. The
        returned array is overwritten by the next call. Large meshes are split into one chunk of
        elements per core (NumPy and BLAS release the GIL: the chunks run in parallel, and each
        element's matrix is computed by the same operations, so K does not depend on the split).
        With ``hooke=False`` the array returned is T (E, 3k, 3k), rows (i, a), columns (j, b).
        With B-bar, λ' = −2μ/3 takes the place of λ and K gains κ m mᵀ/|e|; ``self._means`` then
        holds (m (E, 3k), rows (i, a), |e| (E,)) of the last call (module docstring).
        """
        E, k = X.shape[0], self.k
        if self._buffers is None or self._buffers[0].shape[0] != E:
            self._buffers = (np.empty((E, 3 * k, 3 * k)), np.empty((E, 3, k, 3, k)), np.empty((E, k, k)))
            self._means = (np.empty((E, 3 * k)), np.empty(E)) if self.bbar else None
        T, K, lap = self._buffers
        cuts = np.linspace(0, E, _assembly_chunks(E) + 1).astype(int)
        means = self._means if self.bbar else None
        parts = [(X[i:j], T[i:j], K[i:j], lap[i:j], hooke, None if means is None else (means[0][i:j], means[1][i:j]))
                 for i, j in zip(cuts[:-1], cuts[1:])]
        if len(parts) == 1:
            dets = [self._blocks_into(*parts[0])]
        else:
            dets = list(_assembly_pool().map(lambda a: self._blocks_into(*a), parts))
        if not all(np.all(d > 0) for d in dets):
            require_positive_det(np.concatenate(dets, axis=1), element_axis=1)
        return K if hooke else T

    def _blocks_into(self, X, T, K, lap, hooke=True, means=None) -> np.ndarray:
        """Element matrices of the elements X into the work arrays T, K, lap (see
        :meth:`_element_blocks`); returns det J (q, e), early (K unset) if one is ≤ 0."""
        E, Q, k = X.shape[0], self.w.size, self.k
        # J[m, n, q, e] = ∂x_m/∂ξ_n: one BLAS product for all elements and points
        J = (X.transpose(2, 0, 1).reshape(3 * E, k) @ self._dN_a).reshape(3, E, Q, 3)
        J = np.ascontiguousarray(J.transpose(0, 3, 2, 1))
        det, adj = det_adj_3x3(J)
        if not np.all(det > 0):
            return det
        adj *= np.sqrt(det * self.w[:, None]) / det          # √(w det J) J⁻¹, [n, m, q, e]
        # √(w det J) ∂N_a/∂x_m = Σ_n dN[q, a, n] (...)[n, m]: per q, rows (m, e)
        Jq = adj.transpose(2, 1, 3, 0).reshape(Q, 3 * E, 3)
        G = np.matmul(Jq, self._dN_q).reshape(Q, 3, E, k)
        G = np.ascontiguousarray(G.transpose(2, 1, 3, 0)).reshape(E, 3 * k, Q)
        np.matmul(G, G.transpose(0, 2, 1), out=T)
        if means is not None:                       # m = Σ_q w det J ∇N, |e| = Σ_q w det J
            wd = np.sqrt(det * self.w[:, None])                   # (Q, E)
            np.einsum("erq,qe->er", G, wd, out=means[0])
            np.einsum("qe,qe->e", wd, wd, out=means[1])
        if not hooke:
            return det
        T5 = T.reshape(E, 3, k, 3, k)
        np.add(T5[:, 0, :, 0], T5[:, 1, :, 1], out=lap)
        lap += T5[:, 2, :, 2]
        lap *= self.mu
        np.multiply(T5.transpose(0, 3, 2, 1, 4), self.mu, out=K)
        T5 *= self.lam_point
        K += T5
        for k in range(3):
            K[:, k, :, k] += lap
        if means is not None:
            m = means[0] * np.sqrt(self.kappa / means[1])[:, None]
            K += (m[:, :, None] * m[:, None, :]).reshape(K.shape)
        return det

    def stiffness(self, coords: np.ndarray) -> sp.csr_matrix:
        """A on the free DOFs (CSR, symmetric positive definite when Γ_u is non-empty).

        Assembled per node pair (:class:`_PairPattern`): the element's T (see
        :meth:`_element_blocks`) is summed onto the vertex and edge blocks of A, Hooke's law is
        applied once per block; linear tetrahedra compute their T per edge directly
        (:class:`_LinearTetPairs`). The pattern is built at the first call.
        """
        if self._pattern is None:
            self._pattern = _LinearTetPairs(self) if self._pairs else _BlockPairs(self)
        return self._pattern.stiffness(coords)

    def release(self, pattern: bool = False) -> None:
        """Drop the work arrays of :meth:`stiffness` (and with ``pattern`` its pattern), made anew at
        its next call: for an assembler whose matrix is formed once, or once per design beside
        larger data (the PETSc path's ranks)."""
        self._buffers = self._means = None
        if pattern:
            self._pattern = None

    def full_stiffness(self, coords: np.ndarray) -> sp.csr_matrix:
        """A on all 3·n_nodes DOFs, without Dirichlet elimination (singular: 6 rigid modes)."""
        Ke = self.element_matrices(coords[self.elements])
        d = 3 * self.k
        r = np.repeat(self.edofs, d, axis=1).ravel()
        c = np.tile(self.edofs, (1, d)).ravel()
        return sp.csr_matrix((Ke.ravel(), (r, c)), shape=(self.n_full, self.n_full))

    def jacobian_determinants(self, coords: np.ndarray) -> np.ndarray:
        """det J (E, Q) at the quadrature points of the stiffness rule (no check: ≤ 0 marks an
        inverted element)."""
        return element_geometry(coords[self.elements], self.dN, check=False)[1]

    def cell_stresses(self, coords: np.ndarray, u_full: np.ndarray) -> np.ndarray:
        """Cauchy stress σ = λ tr(ε) I + 2μ ε of the displacement ``u_full`` (3·n_nodes), averaged
        over each cell's quadrature points (weights w det J): (E, 6) in Voigt order
        (xx, yy, zz, yz, xz, xy). Exact for a displacement linear in x on every element type. With
        B-bar too: its stress σ̄ has the same cell average (the mean of θ̄ − div u is zero)."""
        X = coords[self.elements]
        G, det = element_geometry(X, self.dN)
        ue = np.asarray(u_full, float).reshape(-1, 3)[self.elements]          # (E, k, 3)
        grad = np.einsum("eqam,eai->eqim", G, ue)                           # ∂u_i/∂x_m
        eps = 0.5 * (grad + grad.transpose(0, 1, 3, 2))
        wq = det * self.w
        eps = np.einsum("eqij,eq->eij", eps, wq) / wq.sum(axis=1)[:, None, None]
        sig = 2.0 * self.mu * eps
        sig[:, [0, 1, 2], [0, 1, 2]] += (self.lam * np.trace(eps, axis1=1, axis2=2))[:, None]
        return np.stack([sig[:, 0, 0], sig[:, 1, 1], sig[:, 2, 2], sig[:, 1, 2], sig[:, 0, 2], sig[:, 0, 1]], axis=1)

    def scalar_laplacian(self, coords: np.ndarray) -> sp.csr_matrix:
        """Matrix of ∫∇φ_a·∇φ_b dx (n_nodes × n_nodes, CSR) with the element's shape functions
        and stiffness rule: the operator of the harmonic morph weight (docs/theory.md)."""
        G, det = element_geometry(coords[self.elements], self.dN)
        Ke = np.einsum("eqam,eqbm,eq->eab", G, G, det * self.w)
        rows = np.broadcast_to(self.elements[:, :, None], Ke.shape).ravel()
        cols = np.broadcast_to(self.elements[:, None, :], Ke.shape).ravel()
        n = self.n_nodes
        return sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(n, n))

    # ------------------------------------------------------------------ vectors
    def to_full(self, u_free: np.ndarray) -> np.ndarray:
        """Extend a free-DOF vector by zeros on the Dirichlet DOFs."""
        u = np.zeros(self.n_full)
        u[self.free] = u_free
        return u

    # ------------------------------------------------------------------ design derivatives
    def stiffness_shape_contraction(self, coords: np.ndarray, u_full: np.ndarray, v_full: np.ndarray) -> np.ndarray:
        """vᵀ (∂A/∂x_{c,m}) u for every node c and coordinate m: array (n_nodes, 3).

        Shape derivative of a(u, v) = ∫ C∇u:∇v for the nodal mesh velocity V = N_c e_m:
            ∫ [ (σ(u):∇v) div V − σ(u):(∇v ∇V) − σ(v):(∇u ∇V) ] dx,
        evaluated element by element with the element's stiffness rule, so it is the exact
        derivative of the assembled matrix. Every product runs component by
        component on arrays over (quadrature point, element).
        """
        # element chunks whose temporaries (some 20 arrays over (quadrature point, element)) stay
        # in the cache: one pass over memory instead of one per product (2–3× faster, docs/scaling.md)
        E = self.elements.shape[0]
        de = np.empty((3, self.k, E))                                    # [m, a, e]
        u3, v3 = u_full.reshape(-1, 3), v_full.reshape(-1, 3)
        for lo in range(0, E, _CONTRACTION_CHUNK):
            el = self.elements[lo:lo + _CONTRACTION_CHUNK]
            de[:, :, lo:lo + el.shape[0]] = self._shape_contraction_chunk(coords[el], u3[el], v3[el], lo)
        idx = self.elements.T.ravel()
        out = np.empty((self.n_nodes, 3))
        for m in range(3):
            out[:, m] = np.bincount(idx, weights=de[m].ravel(), minlength=self.n_nodes)
        return out

    def _shape_contraction_chunk(self, X, U, V, first) -> np.ndarray:
        """The elements' parts de[m, a, e] of :meth:`stiffness_shape_contraction` for element
        coordinates X and nodal values U, V (E, k, 3) of the elements from number ``first`` on."""
        G, det = self._gradients(X, first)                                    # G[m, a, q, e]
        wd = det * self.w[:, None]                                       # (Q, E)
        ue = np.ascontiguousarray(U.transpose(2, 1, 0))                  # [i, a, e]
        ve = np.ascontiguousarray(V.transpose(2, 1, 0))
        Q, E = wd.shape
        Hu, Hv = np.zeros((3, 3, Q, E)), np.zeros((3, 3, Q, E))       # H[i, j] = ∂u_i/∂x_j
        for i in range(3):
            for a in range(self.k):
                Hu[i] += ue[i, a] * G[:, a]
                Hv[i] += ve[i, a] * G[:, a]
        su, sv = self._stress_cm(Hu), self._stress_cm(Hv)
        energy = (su * Hv).sum(axis=(0, 1))
        # R[m, n] = w det J (energy δ_mn − M[m, n]) with M = ∇vᵀ σ(u) + ∇uᵀ σ(v)
        R = np.zeros((3, 3, Q, E))
        for m in range(3):
            for kk in range(3):
                R[m] -= Hv[kk, m] * su[kk] + Hu[kk, m] * sv[kk]
            R[m, m] += energy
        if self.bbar:
            self._bbar_contraction(Hu, Hv, wd, R)
        R *= wd
        de = np.zeros((3, self.k, E))                                    # [m, a, e]
        for m in range(3):
            for n in range(3):
                de[m] += (G[n] * R[m, n]).sum(axis=1)
        return de

    def _bbar_contraction(self, Hu, Hv, wd, R) -> None:
        """Adds to R[m, n] (before its factor w det J) the shape derivative of the B-bar term
        κ I_u I_v/|e|, I_u = ∫_e div u: with V = N_c e_m, δI_u = ∫ (div u div V − tr(∇u ∇V)) and
        δ|e| = ∫ div V, so δ(I_u I_v/|e|) = ∫ ∇N_c · r_m with
        r_m,n = (I_v (div u δ_mn − ∂u_n/∂x_m) + I_u (div v δ_mn − ∂v_n/∂x_m) − I_u I_v/|e| δ_mn)/|e|."""
        du, dv = Hu[0, 0] + Hu[1, 1] + Hu[2, 2], Hv[0, 0] + Hv[1, 1] + Hv[2, 2]       # (Q, E)
        vol = wd.sum(axis=0)
        Iu, Iv = (du * wd).sum(axis=0), (dv * wd).sum(axis=0)
        cu, cv = self.kappa * Iv / vol, self.kappa * Iu / vol
        diag = cu * du + cv * dv - self.kappa * Iu * Iv / vol ** 2
        for m in range(3):
            for n in range(3):
                R[m, n] -= cu * Hu[n, m] + cv * Hv[n, m]
            R[m, m] += diag

    def _gradients(self, X: np.ndarray, first: int = 0):
        """∂N_a/∂x_m as G[m, a, q, e] and det J (Q, E) for element coordinates X (E, k, 3);
        MeshError naming the inverted elements."""
        E, Q, k = X.shape[0], self.w.size, self.k
        J = (X.transpose(2, 0, 1).reshape(3 * E, k) @ self._dN_a).reshape(3, E, Q, 3)
        J = np.ascontiguousarray(J.transpose(0, 3, 2, 1))               # [m, n, q, e]
        det, adj = det_adj_3x3(J)
        require_positive_det(det, element_axis=1, first=first)
        adj /= det                                                        # J⁻¹[n, m]
        dN = self.dN.transpose(2, 1, 0)[..., None]                        # [n, a, q, 1]
        G = np.zeros((3, k, Q, E))
        for m in range(3):
            for n in range(3):
                G[m] += dN[n] * adj[n, m]
        return G, det

    def _stress_cm(self, H: np.ndarray) -> np.ndarray:
        """σ = λ tr(H) I + μ (H + Hᵀ) for H[i, j, ...] (component-major)."""
        s = self.mu * (H + H.swapaxes(0, 1))
        tr = self.lam_point * (H[0, 0] + H[1, 1] + H[2, 2])
        for i in range(3):
            s[i, i] += tr
        return s


class _PairPattern:
    """CSR of A on the free DOFs from 3×3 blocks per vertex and per edge (node pair) of the mesh.

    Hooke's law is linear in T_ab = Σ_q w_q det J_q g_a g_bᵀ with the same λ, μ everywhere:
    the block of nodes a, b is λ T_ab + μ T_abᵀ + μ tr(T_ab) I. So T is summed per global block
    first and the law applied once per block, instead of once per element and entry. An edge
    (lo, hi), lo < hi, stores its block for (lo, hi); the block (hi, lo) is its transpose. The
    CSR values are one gather from the vertex and edge blocks (a transposed block read by index).
    """

    def _build(self, asm: "ElasticityAssembler", lo: np.ndarray, hi: np.ndarray) -> None:
        """The CSR pattern and the gather ``src`` from the block values, stored component-major:
        vals[3i + j, s] for the slots s = [vertices 0..n−1 | edges n..n+n_edges−1]; the entry
        (i, j) of a transposed edge block is the entry (j, i) of the edge's."""
        self.asm = asm
        n = asm.n_nodes
        self.n_edges = lo.size
        self.n_slots = N = n + lo.size
        slot = np.concatenate([np.arange(n), n + np.arange(lo.size), n + np.arange(lo.size)])
        nodes_r = np.concatenate([np.arange(n), lo, hi])
        nodes_c = np.concatenate([np.arange(n), hi, lo])
        transposed = np.concatenate([np.zeros(N, bool), np.ones(lo.size, bool)])
        i, j = np.divmod(np.arange(9), 3)
        comp = np.where(transposed[:, None], 3 * j + i, 3 * i + j)
        src = (comp * N + slot[:, None]).ravel()
        fr = asm.full_to_free[(3 * nodes_r[:, None] + i).ravel()]
        fc = asm.full_to_free[(3 * nodes_c[:, None] + j).ravel()]
        keep = np.flatnonzero((fr >= 0) & (fc >= 0))
        fkey = fr[keep].astype(np.int64) * asm.n_free + fc[keep]
        order = np.argsort(fkey, kind="stable")
        self.src = src[keep[order]]
        fkey = fkey[order]
        self.indices = (fkey % asm.n_free).astype(np.int32)
        counts = np.bincount(fkey // asm.n_free, minlength=asm.n_free)
        self.indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
        self._vals = np.empty((9, N))

    def _csr(self, T: np.ndarray, M: np.ndarray | None = None) -> sp.csr_matrix:
        """A from the summed T of the slots, T[i, j, s] (3, 3, n + n_edges), plus the summed B-bar
        terms κ m mᵀ/|e| of the slots, M[i, j, s], if given."""
        asm = self.asm
        lam, mu = asm.lam_point, asm.mu
        vals = self._vals
        tr = mu * (T[0, 0] + T[1, 1] + T[2, 2])
        for i in range(3):
            for j in range(3):
                v = vals[3 * i + j]
                np.multiply(T[i, j], lam, out=v)
                v += mu * T[j, i]
                if M is not None:
                    v += M[i, j]
            vals[4 * i] += tr
        data = vals.ravel().take(self.src)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(asm.n_free, asm.n_free))


class _BlockPairs(_PairPattern):
    """Any element type: T of every element (E, 3k, 3k) from :meth:`ElasticityAssembler._element_blocks`
    summed onto the blocks by one ``np.bincount``. Entry (i, a, j, b) of an element goes to the
    vertex block of node a (a = b) or to component (i, j) of the edge (n_a, n_b) (component
    (j, i) when n_a > n_b); every edge entry arrives twice (as (a, b) and as (b, a)), so the edge
    sums are halved (exactly)."""

    def __init__(self, asm: "ElasticityAssembler"):
        cells = np.asarray(asm.elements, np.int64)
        E, k, n = cells.shape[0], asm.k, asm.n_nodes
        na = np.broadcast_to(cells[:, :, None], (E, k, k))
        nb = np.broadcast_to(cells[:, None, :], (E, k, k))
        off = na != nb
        ekey = np.minimum(na, nb)[off] * n + np.maximum(na, nb)[off]
        ukey, edge = np.unique(ekey, return_inverse=True)
        super()._build(asm, ukey // n, ukey % n)
        base = np.empty((E, k, k), np.int64)
        base[~off] = na[~off]
        base[off] = n + edge.ravel()
        swap = na > nb
        N = self.n_slots
        slot = np.empty((E, 3, k, 3, k), np.int64)
        for i in range(3):
            for j in range(3):
                slot[:, i, :, j, :] = base + N * np.where(swap, 3 * j + i, 3 * i + j)
        self.slot = slot.reshape(-1).astype(np.intp)

    def stiffness(self, coords: np.ndarray) -> sp.csr_matrix:
        asm = self.asm
        T = asm._element_blocks(coords[asm.elements], hooke=False)
        s = np.bincount(self.slot, weights=T.reshape(-1), minlength=9 * self.n_slots).reshape(3, 3, -1)
        s[:, :, asm.n_nodes:] *= 0.5
        if not asm.bbar:
            return self._csr(s)
        m, vol = asm._means
        m = m * np.sqrt(asm.kappa / vol)[:, None]
        np.multiply(m[:, :, None], m[:, None, :], out=T)       # T's buffer: κ m mᵀ/|e|, same layout
        M = np.bincount(self.slot, weights=T.reshape(-1), minlength=9 * self.n_slots).reshape(3, 3, -1)
        M[:, :, asm.n_nodes:] *= 0.5
        return self._csr(s, M)


class _LinearTetPairs(_PairPattern):
    """Linear tetrahedra: one quadrature point, T_ab = V g_a g_bᵀ (g = ∇λ, V the volume),
    computed directly per vertex (6 components) and edge (9) of every element — 78 numbers
    instead of the 144 of T — each component one ``np.bincount``. Local nodes are taken in
    increasing global number, so the element's pair (a, b), a < b, is the edge (n_a, n_b)."""

    _EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    _SYM = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))

    def __init__(self, asm: "ElasticityAssembler"):
        cells = np.asarray(asm.elements, np.int64)
        E, n = cells.shape[0], asm.n_nodes
        perm = np.argsort(cells, axis=1, kind="stable")
        self.cells = np.ascontiguousarray(np.take_along_axis(cells, perm, axis=1).T)      # (4, E)
        if np.any(self.cells[1:] == self.cells[:-1]):
            bad = np.flatnonzero(np.any(self.cells[1:] == self.cells[:-1], axis=0))
            raise MeshError(f"{bad.size} tetrahedra repeat a node, first: {bad[:5].tolist()}")
        # parity of the sort: det J of the sorted order times it is det J of the element's order
        inv = np.zeros(E, np.int64)
        for i in range(4):
            for j in range(i + 1, 4):
                inv += perm[:, i] > perm[:, j]
        self.parity = np.where(inv % 2, -1.0, 1.0)
        a, b = self._EDGES.T
        key = self.cells[a] * n + self.cells[b]                                       # (6, E)
        ukey, inverse = np.unique(key.ravel(), return_inverse=True)
        super()._build(asm, ukey // n, ukey % n)
        self.edge_index = inverse.reshape(-1).astype(np.intp)
        self.vertex_index = self.cells.astype(np.intp).ravel()
        self._work = None

    def _geometry(self, coords: np.ndarray):
        """√V ∇λ_a per component, g[m, a, e] (sorted local order), and det J (E,) of the element
        order; g is left unset if an element is inverted."""
        E = self.cells.shape[1]
        if self._work is None:
            self._work = {"x": np.empty((3, 4, E)), "d": np.empty((3, 3, E)), "g": np.empty((3, 4, E)),
                          "t": np.empty((2, E)), "bv": np.empty((4, E)), "be": np.empty((6, E))}
        w = self._work
        x, d, g, t = w["x"], w["d"], w["g"], w["t"]
        ct = np.ascontiguousarray(coords.T)
        for m in range(3):
            np.take(ct[m], self.cells, out=x[m])
        np.subtract(x[:, 1:], x[:, :1], out=d)                   # d[m, b−1, e] = x_b − x_0
        for b, (p, q) in zip((1, 2, 3), ((1, 2), (2, 0), (0, 1))):     # ∇λ_b ∝ d_p × d_q
            for m, (u, v) in enumerate(((1, 2), (2, 0), (0, 1))):
                np.multiply(d[u, p], d[v, q], out=t[0])
                np.multiply(d[v, p], d[u, q], out=t[1])
                np.subtract(t[0], t[1], out=g[m, b])
        det = np.einsum("me,me->e", d[:, 0], g[:, 1])             # d_0 · (d_1 × d_2)
        det_elem = det * self.parity
        if not np.all(det_elem > 0):
            return det_elem
        scale = np.sqrt(np.abs(det) / 6.0) / det                  # √V / det
        g[:, 1:] *= scale
        np.add(g[:, 1], g[:, 2], out=g[:, 0])
        g[:, 0] += g[:, 3]
        np.negative(g[:, 0], out=g[:, 0])
        return det_elem

    def stiffness(self, coords: np.ndarray) -> sp.csr_matrix:
        det = self._geometry(coords)
        if not np.all(det > 0):
            require_positive_det(det)
        g, bv, be = self._work["g"], self._work["bv"], self._work["be"]
        n, ne = self.asm.n_nodes, self.n_edges
        T = np.empty((3, 3, n + ne))
        for i, j in self._SYM:
            np.multiply(g[i], g[j], out=bv)
            T[i, j, :n] = np.bincount(self.vertex_index, weights=bv.ravel(), minlength=n)
            T[j, i, :n] = T[i, j, :n]
        for i in range(3):
            for j in range(3):
                for k, (a, b) in enumerate(self._EDGES):
                    np.multiply(g[i, a], g[j, b], out=be[k])
                T[i, j, n:] = np.bincount(self.edge_index, weights=be.ravel(), minlength=ne)
        return self._csr(T)
