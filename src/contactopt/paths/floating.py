"""Counterparts held only by their contacts on the full-space path: an anchor on each one's
rigid motions, iterated until it carries no force.

In the two bodies' unknowns u_loc of :mod:`.coupled` the stiffness Tᵀ diag(A, K_1, …) T is singular
along Z = T⁻¹(0, R_b) for every counterpart b whose clamps leave its rigid motions R_b free
(:mod:`contactopt.mesh.rigid`): the body does not move, the relative displacement w of its pairs
changes by −Π_loc R_b. A Newton system whose Dirichlet rows on w hold the body (a sticking node
of its pairs and a normal one along each motion) is regular, but the start solve (no contact
rows) and the Newton systems of an open or sliding piece are not. As on the condensation path
(:mod:`.rigid`), the state is that of an *anchored* problem at the fixed point of its anchor:

    Tᵀ diag(A, K) T u − Tᵀ(L, f) + γ N (Nᵀu − β) = (contact rows),     β ← Nᵀu,

N (n × k, orthonormal columns) the counterpart's free rigid motions on the free DOFs of one of
its cells, the one nearest its centroid (γ N Nᵀ then lies in K's sparsity pattern, the cell's
3 × 3 node blocks, and the AMG hierarchy carries it to its coarse levels, whose near-null space
holds Z), γ = :data:`~contactopt.paths.rigid.GAMMA_FACTOR` times the mean diagonal of the
system there. For any β the anchored problem is an ordinary one (γ N Nᵀ is positive definite on
Z, NᵀZ has full rank since the cell's nodes are not on a line), solved by the full-space Newton
method unchanged; γ(Nᵀu − β) is the anchor's force, the load the contact forces leave unbalanced
on the body's rigid motions, and at β = Nᵀu(β) it vanishes: the state is that of the body held
only by its contacts, exactly. The iteration starts from β = Nᵀu₀ (the warm start; 0 without
one: the body where the mesh puts it) and stops as :func:`.rigid.held_state` does, on the anchor's
force relative to the larger of ‖L‖ and ‖r‖.

The adjoint (4.15) is the transposed Newton system of the unanchored stiffness at the solution
(nothing of γ, N or β enters ξ): regular where the contact holds the body, as the state's last
Newton system is; its V-cycle is the anchored hierarchy's.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..contact.state import RigidAnchor
from ..errors import SolverError
from .rigid import GAMMA_FACTOR, MAX_ANCHOR_STEPS, ROUNDOFF_FLOOR

log = logging.getLogger(__name__)

STIFFER = 100.0    # the retry's anchor: γ = 100 · GAMMA_FACTOR · the mean diagonal (1e-1)


@dataclass(frozen=True)
class FloatingAnchor:
    """The anchor of the counterparts held only by their contacts (module docstring): ``dofs``
    (m,) the anchored unknowns of u_loc, ``N`` (m, k) orthonormal columns per body (block
    diagonal over the bodies), ``gamma`` (k,) γ per column, ``names`` the motions, ``matrix`` γ N Nᵀ
    (n × n, sparse)."""

    dofs: np.ndarray
    N: np.ndarray
    gamma: np.ndarray
    names: list
    matrix: sp.csr_matrix

    def position(self, u: np.ndarray) -> np.ndarray:
        """Nᵀu (k,): the anchored bodies' rigid motions in u_loc."""
        return self.N.T @ np.asarray(u)[self.dofs]

    def load(self, beta: np.ndarray, n: int) -> np.ndarray:
        """γ N β on u_loc (n,): the anchor at β."""
        out = np.zeros(n)
        out[self.dofs] = self.N @ (self.gamma * beta)
        return out

    def stiffer(self) -> "FloatingAnchor":
        """The same anchor :data:`STIFFER` times as stiff: the retry of an anchored solve whose
        Newton method made no progress (module docstring)."""
        return FloatingAnchor(self.dofs, self.N, STIFFER * self.gamma, self.names, STIFFER * self.matrix)

    def anchored(self, A) -> sp.csr_matrix:
        """A + γ N Nᵀ (CSR, sorted indices) with every entry of A's pattern, its explicit zeros too
        (the contact nodes' blocks where the Newton system adds its Robin blocks, .coupled); a
        sparse sum would drop them."""
        a, m = sp.coo_matrix(A), self.matrix.tocoo()
        out = sp.coo_matrix((np.concatenate([a.data, m.data]), (np.concatenate([a.row, m.row]),
                                                                 np.concatenate([a.col, m.col]))), shape=A.shape).tocsr()
        out.sort_indices()
        return out


def floating_anchor(couple, diag: np.ndarray, face=None) -> FloatingAnchor | None:
    """The :class:`FloatingAnchor` of the bodies held only by their contacts: a
    :class:`~.coupled.FullSpaceCouple`'s counterparts (``part.rigid`` not None; ``couple`` None
    without elastic counterparts) and, given ``face`` (the model, whose ``body.rigid`` is not
    None), the face body itself; ``diag`` the diagonal of the Newton system (u_loc). The face
    body's cell is one with no contact node, so that its unknowns in u_loc are the body's own
    (the contact DOFs hold w); None when every body is held by its clamps."""
    dofs, blocks, gammas, names = [], [], [], []

    def add(ref, full_to_free, rigid, start, what, avoid=None):
        cells = np.asarray(ref.cells)
        centroid = ref.points.mean(axis=0)
        dist = np.linalg.norm(ref.points[cells].mean(axis=1) - centroid, axis=1)
        if avoid is not None:
            touched = np.zeros(ref.points.shape[0], bool)
            touched[avoid] = True
            dist[touched[cells].any(axis=1)] = np.inf
            if not np.isfinite(dist).any():
                raise SolverError(f"the anchor of {what} held only by contact: every cell has a contact node")
        cell = cells[np.argmin(dist)]
        full = (3 * cell[:, None] + np.arange(3)).ravel()
        free = full_to_free[full]
        keep = free >= 0
        V = rigid.vectors(ref.points[cell]).reshape(-1, rigid.count)[keep]
        Q, s, _ = np.linalg.svd(V, full_matrices=False)
        if s.size == 0 or s.min() <= 1e-9 * s.max():
            raise SolverError(f"the anchor of {what} held only by contact: its cell {cell.tolist()} "
                              "does not determine its free rigid motions")
        at = start + free[keep]
        dofs.append(at)
        blocks.append(Q)
        gammas.append(np.full(Q.shape[1], GAMMA_FACTOR * float(np.mean(diag[at]))))
        return rigid.names()

    if face is not None and face.body.rigid is not None:
        names += [f"{n} of the face body" for n in add(face.body.reference, face.assembler.full_to_free, face.body.rigid, 0,
                                                       "the face body", avoid=face.body.contact_nodes)]
    for b, part in enumerate([] if couple is None else couple.parts):
        if part.rigid is not None:
            start = couple.n_body + int(couple._starts[b])
            # the face nodes of rows b on this body (fem.faces): their unknowns hold w, not the body's
            mine = couple.cd[(couple.cd >= start) & (couple.cd < start + part.assembler.n_free)] - start
            names += add(part.mesh.reference, part.assembler.full_to_free, part.rigid, start, "a counterpart",
                         avoid=np.unique(part.assembler.free[mine] // 3) if mine.size else None)
    if not dofs:
        return None
    dofs_all = np.concatenate(dofs)
    N = np.asarray(sp.block_diag(blocks).toarray())
    gamma = np.concatenate(gammas)
    # γ N Nᵀ body by body: each anchored cell's own block (no entries between two bodies' cells,
    # which no stiffness couples: the PETSc path's pattern has none there)
    entries = []
    for at, Q, g in zip(dofs, blocks, gammas):
        rows, cols = np.meshgrid(at, at, indexing="ij")
        entries.append((((Q * g) @ Q.T).ravel(), rows.ravel(), cols.ravel()))
    vals, rows, cols = (np.concatenate(x) for x in zip(*entries))
    n = diag.size
    M = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    return FloatingAnchor(dofs_all, N, gamma, names, M)


def first_anchored_solve(solve, beta0, stiffen):
    """The first anchored solve of :func:`iterate_anchor`: ``solve(beta, last, fallbacks)`` at β₀
    with the soft anchor and no fallbacks (at most the caller's few Newton steps); where that makes
    no progress (a body pressed into two counterparts by an overlap: the soft anchor leaves the
    Newton steps' Krylov error free along its rigid motions), ``stiffen()`` makes the anchor
    :data:`STIFFER` times as stiff and the solve runs again with its fallbacks. Returns the result,
    its Krylov iterations and Newton steps those of both attempts."""
    first = solve(beta0, None, fallbacks=False)
    if first.converged:
        return first
    log.debug("body held only by its contacts: the anchored solve stopped (%s); a stiffer anchor", first.reason)
    spent, spent_steps = list(first.krylov_iterations), first.newton_steps
    stiffen()
    first = solve(beta0, None, fallbacks=True)
    first.krylov_iterations = spent + list(first.krylov_iterations)
    first.newton_steps += spent_steps
    return first


def anchor_imbalance(anchor: FloatingAnchor, u, beta, scale: float) -> float:
    """‖γ(Nᵀu − β)‖ / scale: the anchor's force relative to the problem's (module docstring)."""
    return float(np.linalg.norm(anchor.gamma * (anchor.position(u) - beta)) / max(scale, 1e-300))


def iterate_anchor(solve, anchor: FloatingAnchor, first, load_norm: float, tol: float):
    """The anchor's iteration from the result ``first`` of the anchored problem at β₀:
    ``solve(beta, previous)`` the full-space result of the anchored problem at β warm-started
    from ``previous``, β ← Nᵀu until the anchor's force is at most ``tol`` relative to
    max(``load_norm``, ‖r‖), or below :data:`~.rigid.ROUNDOFF_FLOOR` no longer halves. ``first``
    is (β₀, its result). Returns (the last result, its
    :class:`~contactopt.contact.state.RigidAnchor`, the Krylov iterations and the Newton steps of
    every solve)."""
    beta, res = first
    history, iterations, steps = [], [], 0
    for step in range(MAX_ANCHOR_STEPS):
        if step:
            res = solve(beta, res)
        iterations += list(res.krylov_iterations)
        steps += res.newton_steps
        rel = anchor_imbalance(anchor, res.u, beta, max(load_norm, float(np.linalg.norm(res.r))))
        history.append(rel)
        if rel <= tol or (rel <= ROUNDOFF_FLOOR and len(history) > 1 and rel >= 0.5 * history[-2]):
            break
        beta = anchor.position(res.u)
    else:
        raise SolverError(f"{', '.join(anchor.names)}: a body held only by its contacts: after "
                          f"{MAX_ANCHOR_STEPS} anchor steps the contact forces still leave {history[-1]:.3g} of the "
                          "load unbalanced on its free rigid motions (a load along a motion nothing holds, or near "
                          "the limit of what friction holds; check the body's clamps and loads)")
    log.debug("counterpart held only by its contacts: %d anchor step(s), unbalanced %.2e", len(history), history[-1])
    return res, RigidAnchor(iterations=len(history), residual=history[-1]), iterations, steps
