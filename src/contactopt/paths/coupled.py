"""Elastic counterparts in full space: two bodies and more as one Newton system, nothing condensed.

The condensation path condenses an elastic foundation onto its support once per run
(:mod:`contactopt.fem.foundation`: C = Π W_f Πᵀ, a dense matrix on the support). In full space the
foundation's DOFs join the body's instead (DESIGN §20): with the body's free DOFs u, the
foundation's u_f (its clamped DOFs eliminated) and, per contact node m, the relative displacement
in the node's frame R_m = (t1, t2, n)

    w_m = R_mᵀ u_c,m − (Π_loc u_f)_m − q_m,     Π_loc = R_mᵀ Π (:attr:`Foundation.P`),

the change of unknowns u_loc = (u_i, w + q, u_f) ↦ (u_i, u_c, u_f),

    u_c = Q (w + q + Π_loc u_f),   T = the identity but T[c, c] = Q, T[c, f] = Q Π_loc,

turns the energy of both bodies, ½ uᵀA u − Lᵀu + ½ u_fᵀK_f u_f − f_fᵀu_f, into one in u_loc with
the stiffness Tᵀ diag(A, K_f) T and the load Tᵀ(L, f_f). Its rows at the contact DOFs are the
contact force on the body in the node's frame, r = (Tᵀ(diag(A, K_f) u − (L, f_f)))_c — the body's
(A u − L)_c seen from w, the foundation's rows balance K_f u_f = f_f − Π_locᵀ r — so the
full-space Newton method of one body (:mod:`contactopt.contact.fullspace`) solves two bodies
unchanged: the contact law on w with the gap g − q_ν and the slip's reference q_t
(q = Π d, the prescribed translation d of the foundation in the nodes' frames; zero when it is
fixed). The AMG near-null space is T⁻¹ times both bodies' rigid-body modes; the adjoint (4.15) is
the transposed Newton system in u_loc, its extension T ṽ_loc, and ∂A/∂α touches the body's block
only.

Several pairs against counterpart bodies (:mod:`contactopt.fem.counterparts`) are the same with
u_f the bodies' DOFs one body after the other, diag(A, K_1, …, K_B) and Π stacked by contact node
(a body under several pairs takes all its pairs' rows); a rigid counterpart's pair has zero rows of
Π and no block of u_f, its translation R_mᵀ d in q. A counterpart held only by its contacts makes
the system singular along its rigid motions: :mod:`.floating` anchors them.

Contact convention: per contact node (t1, t2, ν), ν from the foundation to the body, r the
contact force on the body, λ = r_ν ≥ 0; the foundation carries −Π_locᵀ r.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._progress import task
from ..fem.amg import rigid_body_modes
from .force import ForceTerms


class FullSpaceCouple:
    """The change of unknowns T of a model with elastic counterparts (module docstring): one
    ``[foundation]``, or the counterpart bodies of several pairs (:mod:`contactopt.fem.counterparts`,
    each with its block of u_f, their Π stacked by contact node).

    ``n_body`` the body's free DOFs, ``n`` those of all bodies; ``T`` (n × n, sparse);
    ``offset`` (p, 3) q per node (t1, t2, ν): the counterparts' prescribed translations Π d."""

    def __init__(self, foundation, contact_dofs: np.ndarray, n_body: int, frames: np.ndarray | None):
        f = foundation
        # the bodies with DOFs: a rigid counterpart (fem.counterparts.RigidCounterpart) has none, its
        # pair's rows of Π are zero and its prescribed translation is in q
        self.foundation, self.parts = f, [part for part in f.parts if part.n_nodes]
        sizes = [part.assembler.n_free for part in self.parts]
        self._starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.n_body, self.n = n_body, n_body + int(self._starts[-1])
        self.n_f = int(self._starts[-1])              # the counterparts' unknowns (then the pinned ones of rows b)
        cols_f = self.n_body + np.concatenate([start + np.asarray(part._support_free, np.int64)
                                               for start, part in zip(self._starts, self.parts)]
                                              + [np.zeros(0, np.int64)])
        self.cd = np.asarray(contact_dofs, np.int64)
        self.n_pinned, self.pinned_nodes = 0, []
        if f.face_map is not None:                    # faces on several bodies: rows b on their carriers' DOFs
            self.cd, frames = self._face_rows_dofs(f, cols_f), f.frames
        p = self.cd.size // 3
        R = np.broadcast_to(np.eye(3), (p, 3, 3)) if frames is None else np.asarray(frames)
        Q = sp.block_diag(list(R), format="csr")
        Pf = sp.csr_matrix(f.P)                       # Π_loc on the counterparts' free support DOFs
        QP = (Q @ Pf).tocoo()
        other = np.setdiff1d(np.arange(self.n), self.cd)
        Qc = Q.tocoo()
        rows = np.concatenate([other, self.cd[Qc.row], self.cd[QP.row]])
        cols = np.concatenate([other, self.cd[Qc.col], cols_f[QP.col]])
        vals = np.concatenate([np.ones(other.size), Qc.data, QP.data])
        self.T = sp.csr_matrix((vals, (rows, cols)), shape=(self.n, self.n))
        self.T.sort_indices()
        eye_c = sp.csr_matrix((np.ones(self.cd.size), (np.arange(self.cd.size), self.cd)), shape=(self.cd.size, self.n))
        self._E = sp.csr_matrix(self.T[self.cd] - eye_c)     # E_c: T − I on the contact rows
        self._R, self._Pf, self._cols_f = R, Pf, cols_f
        q = np.zeros(3 * p) if f.q_f is None else np.asarray(f.q_f, float)
        self.offset = q.reshape(-1, 3).copy()
        self._kf_amg = [None] * len(self.parts)      # each K_f's AMG solver (compliance), built on first use

    def _face_rows_dofs(self, f, cols_f: np.ndarray) -> np.ndarray:
        """The Newton system's contact DOFs of every row (3p): the face body's (rows a), then per
        row b its face node's DOFs on the carrier body (:mod:`contactopt.fem.faces`), in global
        components as on the face body. A clamped component of such a node (a symmetry plane through
        the carrier's face) is no DOF of the carrier: it gets an unknown of its own after all bodies',
        a decoupled unit diagonal with no load (the pinned row of the law, u = r = 0 there), as a
        pinned DOF of the face body is; its partners lie on the plane, clamped alike, so that Π_loc
        has no entry in its row."""
        cols = np.asarray(f.off_columns, np.int64).ravel()
        pinned = cols < 0
        self.n_pinned = int(pinned.sum())
        # per pinned unknown (its carrier's index in ``parts``, node, component): the PETSc path's DOF of it
        at = [next(b for b, part in enumerate(self.parts) if part is f.parts[k]) for k in f.off_part]
        m, c = np.divmod(np.flatnonzero(pinned), 3)
        self.pinned_nodes = [(at[i], int(f.off_nodes[i]), int(j)) for i, j in zip(m, c)]
        law_b = np.empty(cols.size, np.int64)
        law_b[~pinned] = cols_f[cols[~pinned]]
        law_b[pinned] = self.n + np.arange(self.n_pinned)
        self.n += self.n_pinned
        return np.concatenate([self.cd, law_b])

    def inverse(self) -> sp.csr_matrix:
        """T⁻¹: the identity but at the contact DOFs, where w + q = Qᵀ u_c − Π_loc u_f."""
        other = np.setdiff1d(np.arange(self.n), self.cd)
        Qt = sp.block_diag([R.T for R in self._R], format="coo")
        Pf = self._Pf.tocoo()
        rows = np.concatenate([other, self.cd[Qt.row], self.cd[Pf.row]])
        cols = np.concatenate([other, self.cd[Qt.col], self._cols_f[Pf.col]])
        vals = np.concatenate([np.ones(other.size), Qt.data, -Pf.data])
        return sp.csr_matrix((vals, (rows, cols)), shape=(self.n, self.n))

    def system(self, A, L) -> tuple[sp.csr_matrix, np.ndarray]:
        """(Tᵀ diag(A, K_f) T, Tᵀ (L, f_f)): the Newton system of both bodies in u_loc.

        With T = I + E, E nonzero on the contact rows c only (E_c = T_c − I_c) and B = diag(A, K_f),
        Tᵀ B T = B + Δ, Δ = E_cᵀ B_c + B_{:c} E_c + E_cᵀ B_cc E_c, is supported near the contact
        DOFs: it is added into the arrays of A and the K_f without forming diag(A, K_f) or a product
        of the whole matrix — one matrix of the system's size beside A and the K_f (the products
        took three)."""
        with task(f"forming the Newton system of {1 + len(self.parts)} bodies ({self.n:,} unknowns)"):
            cd, E = self.cd, self._E
            if cd.size and cd.max() >= self.n_body:      # faces on several bodies: rows on the counterparts
                return self._chain_system(A), self.T.T @ self.load(L)
            A = sp.csr_matrix(A)
            A_rows = sp.hstack([A[cd], sp.csr_matrix((cd.size, self.n - self.n_body))], format="csr")
            A_cols = sp.vstack([A[:, cd], sp.csr_matrix((self.n - self.n_body, cd.size))], format="csr")
            delta = E.T @ A_rows + A_cols @ E + E.T @ (A[cd][:, cd] @ E)
            law_A = add_to_block_diagonal([A] + [part.K for part in self.parts], delta, self.cd)
        return law_A, self.T.T @ self.load(L)

    def _blocks(self, A) -> list:
        """The diagonal blocks of diag(A, K_1, …, I): the bodies' stiffnesses and the pinned unknowns'
        unit diagonal (:meth:`_face_rows_dofs`)."""
        pinned = [sp.identity(self.n_pinned, format="csr")] if self.n_pinned else []
        return [sp.csr_matrix(A)] + [sp.csr_matrix(part.K) for part in self.parts] + pinned

    def _chain_system(self, A) -> sp.csr_matrix:
        """Tᵀ B T with rows of the law on several bodies: Δ of :meth:`system` with B_c the rows of
        B = diag(A, K_1, …, I) at the contact DOFs of every body, taken block by block."""
        blocks, cd, E = self._blocks(A), self.cd, self._E
        starts = np.concatenate([[0], np.cumsum([B.shape[0] for B in blocks])])
        rows, cols, vals, rows_t, cols_t, vals_t = [], [], [], [], [], []
        for B, start, stop in zip(blocks, starts[:-1], starts[1:]):
            at = np.flatnonzero((cd >= start) & (cd < stop))
            if not at.size:
                continue
            Br = B[cd[at] - start].tocoo()            # B_c: rows at the contact DOFs
            rows.append(at[Br.row])
            cols.append(Br.col + start)
            vals.append(Br.data)
            Bc = B[:, cd[at] - start].tocoo()         # B_{:c}
            rows_t.append(Bc.row + start)
            cols_t.append(at[Bc.col])
            vals_t.append(Bc.data)
        B_rows = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                               shape=(cd.size, self.n))
        B_cols = sp.csr_matrix((np.concatenate(vals_t), (np.concatenate(rows_t), np.concatenate(cols_t))),
                               shape=(self.n, cd.size))
        delta = E.T @ B_rows + B_cols @ E + E.T @ (B_rows[:, cd] @ E)
        return add_to_block_diagonal(blocks, delta, cd)

    def load(self, L) -> np.ndarray:
        """(L, f_f) on both bodies' free DOFs (and no load on the pinned unknowns of rows b)."""
        return np.concatenate([np.asarray(L, float)] + [part.f_f for part in self.parts] + [np.zeros(self.n_pinned)])

    def modes(self, coords_body: np.ndarray, free_body: np.ndarray) -> np.ndarray:
        """T⁻¹ (each body's rigid-body modes) (n × 6(1 + B)): the AMG near-null space in u_loc. T⁻¹
        is the identity but at the contact DOFs, where w + q = Qᵀ u_c − Π_loc u_f. Six columns per
        body, each zero off its body: measured on Example 1's slab at 191k DOFs, 64 and 47 Krylov
        iterations of the state and the adjoint against 130 and 114 with one set of six for the
        bodies moving as one (twice the coarse unknowns, 36 s against 43 s an evaluation)."""
        blocks = [rigid_body_modes(coords_body, free_body)]
        blocks += [rigid_body_modes(part.mesh.reference.points, part.assembler.free) for part in self.parts]
        M = np.zeros((self.n, 6 * len(blocks)))
        starts = np.concatenate([[0], self.n_body + self._starts])
        for k, (B, start) in enumerate(zip(blocks, starts)):
            M[start:start + B.shape[0], 6 * k:6 * k + 6] = B
        return self._local(M)

    def joint_modes(self, coords_body: np.ndarray, free_body: np.ndarray) -> np.ndarray:
        """T⁻¹ (the rigid-body modes of all bodies moving as one) (n × 6): the PETSc path's GAMG
        near-null space. GAMG gives every aggregate all columns, so the six per body of
        :meth:`modes` double its coarse unknowns with columns zero off their body; with these six
        an evaluation of Example 1 on its slab at 25k DOFs took 3.7 s against 9.1 s (199 and 145
        Krylov iterations of the state and the adjoint against 123 and 119)."""
        points = [np.asarray(coords_body, float)] + [part.mesh.reference.points for part in self.parts]
        frees = [np.asarray(free_body, np.int64)] + [part.assembler.free for part in self.parts]
        offsets = np.cumsum([0] + [3 * x.shape[0] for x in points])
        free = np.concatenate([f + o for f, o in zip(frees, offsets[:-1])])
        M = rigid_body_modes(np.concatenate(points), free)
        if self.n_pinned:                   # the pinned unknowns of rows b: no motion
            M = np.vstack([M, np.zeros((self.n_pinned, M.shape[1]))])
        return self._local(M)

    def _local(self, M: np.ndarray) -> np.ndarray:
        """T⁻¹ M for M (n × k) on the bodies' free DOFs: at the contact DOFs Qᵀ u_c − Π_loc u_f."""
        k = M.shape[1]
        Mc = M[self.cd].reshape(-1, 3, k)
        local = np.einsum("mij,mik->mjk", self._R, Mc).reshape(-1, k)
        M[self.cd] = local - self._Pf @ M[self._cols_f]
        return M

    def split(self, u_loc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u on the body's free DOFs, u_f on the foundation's) of a solution in u_loc."""
        u = self.T @ u_loc
        return u[:self.n_body], u[self.n_body:self.n_body + self.n_f]

    def extend(self, y_body: np.ndarray) -> np.ndarray:
        """Tᵀ (y, 0): a derivative with respect to the body's free DOFs into u_loc."""
        return self.T.T @ np.concatenate([np.asarray(y_body, float), np.zeros(self.n - self.n_body)])

    def face_side(self, u_free: np.ndarray, u_f: np.ndarray) -> np.ndarray:
        """(p, 3) the face side's displacement of every row per node (t1, t2, ν): the face body's
        contact nodes, then the faces on other bodies (:mod:`contactopt.fem.faces`); zero on a
        pinned component."""
        u = np.concatenate([np.asarray(u_free, float), np.asarray(u_f, float), np.zeros(self.n_pinned)])
        return np.einsum("mij,mi->mj", self._R, u[self.cd].reshape(-1, 3))

    def foundation_displacement(self, u_f: np.ndarray, moved: float = 0.0) -> np.ndarray:
        """The counterparts' full displacements one body after the other (3·n_f each): u_f, zero
        on the clamps, plus each body's translation: d with control = 'displacement', s f̂ with
        control = 'force' (``moved`` = s)."""
        out = []
        for start, stop, part in zip(self._starts[:-1], self._starts[1:], self.parts):
            u = part.assembler.to_full(u_f[start:stop])
            if part.translation is not None:
                u = u + (1.0 if part.control == "displacement" else moved) * np.tile(part.translation, part.n_nodes)
            out.append(u)
        return np.concatenate(out + [np.zeros(0)])

    def compliance(self, x: np.ndarray) -> np.ndarray:
        """C x = Π_loc K_f⁻¹ Π_locᵀ x (3p, per node (t1, t2, ν)): the partners' displacement under
        the contact forces −x on the counterparts, by conjugate gradients on each K_f
        preconditioned by smoothed aggregation (built once), to a relative residual of 1e-13 — C
        itself, dense on the support, is never formed."""
        b = np.zeros(self.n_f)
        b[self._cols_f - self.n_body] = self._Pf.T @ np.ravel(x)
        y = np.zeros_like(b)
        for k, (start, stop, part) in enumerate(zip(self._starts[:-1], self._starts[1:], self.parts)):
            if not np.any(b[start:stop]):
                continue
            if self._kf_amg[k] is None:
                import pyamg
                self._kf_amg[k] = pyamg.smoothed_aggregation_solver(
                    part.K, B=rigid_body_modes(part.mesh.reference.points, part.assembler.free), max_coarse=500)
            y[start:stop] = self._kf_amg[k].solve(b[start:stop], tol=1e-13, accel="cg", maxiter=500)
        return self._Pf @ y[self._cols_f - self.n_body]

    def partner(self, u_f: np.ndarray, moved: float = 0.0) -> np.ndarray:
        """(p, 3) the partners' displacement Π_loc u_f + q per node (t1, t2, ν), and s Π f̂ of a
        foundation pressed by a force (``moved`` = s)."""
        out = (self._Pf @ u_f[self._cols_f - self.n_body]).reshape(-1, 3) + self.offset
        f = self.foundation
        if moved and f.motion is not None and f.control == "force":
            out = out + moved * f.motion.reshape(-1, 3)
        return out


def with_contact_blocks(A, contact_dofs: np.ndarray) -> sp.csr_matrix:
    """A (CSR, sorted indices) with every contact node's 3×3 block in its sparsity pattern:
    explicit zeros inserted where a product dropped exact zeros; the Newton system adds its Robin
    blocks there. The missing entries are inserted into A's arrays (one copy of them), not
    through a COO form of the whole matrix."""
    A = sp.csr_matrix(A)
    A.sort_indices()
    cd = np.asarray(contact_dofs, np.int64).reshape(-1, 3)
    r = np.repeat(cd, 3, axis=1).ravel()
    c = np.tile(cd, (1, 3)).ravel()
    n = np.int64(A.shape[1])
    rows = np.repeat(np.arange(A.shape[0], dtype=np.int64), np.diff(A.indptr))
    have = rows * n + A.indices                      # globally sorted: rows ascending, columns sorted
    want = np.unique(r * n + c)
    pos = np.searchsorted(have, want)
    found = (pos < have.size) & (have[np.minimum(pos, have.size - 1)] == want)
    if found.all():
        return A
    miss, at = want[~found], pos[~found]
    data = np.insert(A.data, at, 0.0)
    indices = np.insert(A.indices, at, (miss % n).astype(A.indices.dtype))
    extra = np.bincount(miss // n, minlength=A.shape[0])
    indptr = A.indptr + np.concatenate([[0], np.cumsum(extra)]).astype(A.indptr.dtype)
    out = sp.csr_matrix((data, indices, indptr), shape=A.shape)
    out.has_sorted_indices = True
    return out


def add_to_block_diagonal(blocks, delta, contact_dofs) -> sp.csr_matrix:
    """diag(blocks) + delta (CSR, sorted indices) with every contact node's 3×3 block in its
    pattern, built into one new pair of arrays: the blocks' entries copied, delta's added where
    the blocks have an entry and inserted where they have none (``delta`` sparse, near a few
    rows). diag(blocks) itself is never formed."""
    blocks = [sp.csr_matrix(B) for B in blocks]
    for B in blocks:
        B.sort_indices()
    sizes = np.array([B.shape[0] for B in blocks], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    nnzs = np.array([B.nnz for B in blocks], dtype=np.int64)
    n = int(starts[-1])
    bp = np.concatenate([[0]] + [B.indptr[1:].astype(np.int64) + off
                                 for B, off in zip(blocks, np.concatenate([[0], np.cumsum(nnzs)]))])
    # delta with explicit zeros at the contact blocks, canonical (sorted, summed)
    cdn = np.asarray(contact_dofs, np.int64).reshape(-1, 3)
    D = sp.coo_matrix(delta)
    rows = np.concatenate([D.row, np.repeat(cdn, 3, axis=1).ravel()])
    cols = np.concatenate([D.col, np.tile(cdn, (1, 3)).ravel()])
    vals = np.concatenate([D.data, np.zeros(9 * cdn.shape[0])])
    D = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    D.sum_duplicates()
    d_row = np.repeat(np.arange(n, dtype=np.int64), np.diff(D.indptr))
    # the blocks' entries of the rows delta touches, as sorted keys (row rank, column)
    touched = np.unique(d_row)
    lens = bp[touched + 1] - bp[touched]
    seg_start = np.concatenate([[0], np.cumsum(lens)])
    pos = np.repeat(bp[touched] - seg_start[:-1], lens) + np.arange(seg_start[-1])      # global positions
    which = np.searchsorted(np.concatenate([[0], np.cumsum(nnzs)]), pos, side="right") - 1
    seg_cols = np.empty(pos.size, dtype=np.int64)
    for k, B in enumerate(blocks):
        sel = which == k
        seg_cols[sel] = B.indices[pos[sel] - (bp[starts[k]])] + starts[k]
    rank = np.repeat(np.arange(touched.size, dtype=np.int64), lens)
    keys = rank * n + seg_cols
    d_rank = np.searchsorted(touched, d_row)
    at = np.searchsorted(keys, d_rank * n + D.indices)
    found = at < keys.size
    found[found] = keys[at[found]] == (d_rank * n + D.indices)[found]
    add_at = pos[at[found]]                                   # entries of the blocks that delta changes
    ins_at = bp[d_row[~found]] + (at[~found] - seg_start[d_rank[~found]])   # insert before this entry
    k_new = ins_at.size
    total = int(bp[-1]) + k_new
    new_pos = ins_at + np.arange(k_new)
    old = np.ones(total, dtype=bool)
    old[new_pos] = False
    dtype = np.result_type(*[B.dtype for B in blocks], D.dtype)
    data = np.empty(total, dtype=dtype)
    index_dtype = np.int32 if max(total, n) < 2**31 - 1 else np.int64
    indices = np.empty(total, dtype=index_dtype)
    ins_row = d_row[~found]
    cut = np.concatenate([[0], np.cumsum(nnzs) + np.searchsorted(ins_row, starts[1:])])
    for k, B in enumerate(blocks):
        a, b = int(cut[k]), int(cut[k + 1])
        data[a:b][old[a:b]] = B.data
        indices[a:b][old[a:b]] = B.indices + int(starts[k]) if starts[k] else B.indices
    data[new_pos] = D.data[~found]
    indices[new_pos] = D.indices[~found]
    data[add_at + np.searchsorted(ins_at, add_at, side="right")] += D.data[found]
    extra = np.bincount(ins_row, minlength=n)
    indptr = bp + np.concatenate([[0], np.cumsum(extra)])
    out = sp.csr_matrix((data, indices, indptr.astype(index_dtype)), shape=(n, n))
    out.has_sorted_indices = True
    return out


def force_terms(path, system, ctx, state, v_lam, loads, y_u):
    """∂Θ/∂s, ∂F/∂s, ∂F/∂α and F's adjoint of a foundation pressed by a force on a full-space
    backend (:mod:`.force`'s terms, in the two bodies' unknowns u_loc). F = bᵀr − |f| with r the
    Newton system's rows at the contact DOFs, linear in u_loc: ∂F/∂u_loc = Tᵀdiag(A, K_f)T ẽ, ẽ = b
    at the contact DOFs; its adjoint w̃ gives z = w̃ + ẽ, S(b + w_u) = (Tᵀ diag(A, K_f) T z)_c and
    the design term (T z)ᵀ(∂A u − ∂L) of the body. s enters the law only (gap g − s c, slip's
    reference s e), so at fixed u_loc ∂Θ/∂s = (Tᵀ diag(A, K_f) T ṽ + y)_c·e − v_λ·c with ṽ, y the
    objective's adjoint and right-hand side in u_loc (kept by the last adjoint).

    The backend gives four hooks: ``law_product(system, x)`` (Tᵀ diag(A, K_f) T x in u_loc),
    ``last_adjoint(system, ctx)`` (ṽ_loc of the last adjoint), ``local_adjoint`` (the adjoint of
    a right-hand side in u_loc) and ``local_contraction(system, state, z, loads)`` (the design term
    of (T z) on the body)."""
    m, cd = path.model, system.couple.cd
    f = m.obstacle_force
    c, e = f.gap_rate, f.slip
    dT_ds = -float(v_lam @ c)
    if np.any(e):
        force = path.law_product(system, path.last_adjoint(system, ctx))[cd]
        if y_u is not None and path.is_full(y_u):
            force = force + ctx.adjoint_rhs_c
        dT_ds += float(force @ e)
    e_loc = np.zeros(system.couple.n)
    e_loc[cd] = np.ravel(f.b)
    y_F = path.law_product(system, e_loc)
    w = path.local_adjoint(system, ctx, state, y_F, np.zeros(c.size))
    z_loc = path.last_adjoint(system, ctx) + e_loc
    dF_da = path.local_contraction(system, state, z_loc, loads) + m.gap_matrix.T @ w.v_lam
    dF_ds = float(path.law_product(system, z_loc)[cd] @ e - w.v_lam @ c)
    return ForceTerms(dT_ds, dF_ds, dF_da, w, None)
