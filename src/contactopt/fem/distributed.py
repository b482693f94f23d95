"""The body's mesh split over MPI ranks for the PETSc path: partition, numbering, A(α) on PETSc.

Partition: recursive coordinate bisection of the element centroids (split along the axis of
largest extent, in proportion to the ranks on each side). It needs no graph partitioner (the
Debian PETSc's ParMETIS/PT-Scotch are optional and differ between versions), it is deterministic
(the same mesh and number of ranks give the same split, so a resumed run repeats itself), and on
the bodies here — plates and pads of nearly uniform elements — it gives compact parts with
balanced element counts and interfaces of the order of a cut plane. The contact face x3 = 0 is
cut along x1/x2 like the rest, so the contact nodes are spread over the ranks.

Numbering: a node belongs to the lowest rank among its elements' ranks; nodes are renumbered by
owner (stable), so rank r owns a contiguous range of nodes and the PETSc DOF of node n,
component c is 3·new(n) + c: block size 3, every DOF of a node on one rank. All 3·N DOFs are in
the PETSc matrix; a clamped DOF keeps its diagonal entry and nothing else (its row and column are
zero otherwise), so its value stays 0 and the other rows are those of A on the free DOFs.

Assembly: each rank computes the stiffness of every element at one of its nodes (the serial pair
assembler of :mod:`contactopt.fem.elasticity` on those elements: a layer of the neighbours'
elements is computed twice, and assembly needs no communication) and takes its owned rows, in
CSR for the MPIAIJ matrix and in 3×3 blocks for the MPIBAIJ one. The mesh itself (points, cells)
is held by every rank; only the matrices, the multigrid hierarchy and the Krylov vectors are
distributed (docs/scaling.md). Nodes bisected on their own coordinates instead (owned rows equal
to a row, against 3 % more on rank 0 at 113k DOFs on 2 ranks) split the cut plane irregularly:
GAMG took 4 % more iterations and an evaluation 8 % longer.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError
from .elasticity import ElasticityAssembler

__all__ = ["rcb_partition", "element_owners", "DistributedBody", "DistributedBodies"]


def rcb_partition(centroids: np.ndarray, n_parts: int) -> np.ndarray:
    """Part (0..n_parts − 1) of every element by recursive coordinate bisection of ``centroids``
    (E, 3); parts differ in size by at most one element per level."""
    part = np.zeros(centroids.shape[0], dtype=np.int64)

    def split(idx, first, n):
        if n == 1 or idx.size == 0:
            part[idx] = first
            return
        pts = centroids[idx]
        axis = int(np.argmax(pts.max(axis=0) - pts.min(axis=0)))
        order = idx[np.argsort(pts[:, axis], kind="stable")]
        n1 = n // 2
        cut = int(round(idx.size * n1 / n))
        split(order[:cut], first, n1)
        split(order[cut:], first + n1, n - n1)

    split(np.arange(centroids.shape[0]), 0, n_parts)
    return part


def element_owners(cells: np.ndarray, n_nodes: int, points: np.ndarray, size: int):
    """(part of every element by :func:`rcb_partition` of their centroids, owner of every node: the
    lowest part among its elements, 0 for a node in no element)."""
    part = rcb_partition(points[cells].mean(axis=1), size)
    owner = np.full(n_nodes, size, dtype=np.int64)
    np.minimum.at(owner, cells.ravel(), np.repeat(part, cells.shape[1]))
    owner[owner == size] = 0                        # a node in no element (none in practice)
    return part, owner


def block_pattern(indptr, lcols, n_cols, nodes):
    """(block indptr, block columns (PETSc nodes), the position in the values of the owned
    rows (``indptr``, local columns ``lcols``: rows 3·node + c) of every entry of the 3×3
    blocks, row-major)."""
    nnz = lcols.size
    tag = sp.csr_matrix((np.arange(1, nnz + 1, dtype=np.float64), lcols, indptr),
                        shape=(indptr.size - 1, n_cols))
    B = tag.tobsr(blocksize=(3, 3))
    B.sort_indices()
    where = B.data.ravel().astype(np.int64) - 1       # −1: an entry outside the CSR pattern
    where[where < 0] = nnz                             # ... reads the zero kept at the end of the buffer
    return B.indptr.astype(np.int32), nodes[B.indices].astype(np.int32), where


class DistributedBody:
    """The model's mesh over ``size`` ranks, seen from rank ``rank`` (module docstring).

    ``dof_of_free`` maps the model's free-DOF order to PETSc DOFs; ``contact`` (p, 3) the PETSc
    DOFs of the contact nodes, per node (t1, t2, ν); ``rstart``/``rend`` this rank's DOF range."""

    def __init__(self, model, size: int, rank: int):
        asm = model.assembler
        cells = np.asarray(asm.elements, dtype=np.int64)
        n_nodes = asm.n_nodes
        if size > cells.shape[0]:
            raise ConfigError([f"{size} MPI ranks: the mesh has {cells.shape[0]} elements, fewer than the "
                               "ranks it would be split over; run on fewer ranks"])
        coords = model.body.reference.points
        part, owner = element_owners(cells, n_nodes, coords, size)
        counts = np.bincount(owner, minlength=size)
        if np.any(counts == 0):
            raise ConfigError([f"{size} MPI ranks: the mesh ({n_nodes} nodes, {cells.shape[0]} elements) "
                               f"cannot be split so that every rank owns nodes ({int(np.sum(counts == 0))} "
                               "would own none); run on fewer ranks"])
        self.size, self.rank = size, rank
        self.n_nodes = n_nodes
        self.n = 3 * n_nodes
        order = np.argsort(owner, kind="stable")        # new node -> old node
        self.new_of = np.empty(n_nodes, dtype=np.int64)
        self.new_of[order] = np.arange(n_nodes)
        starts = np.concatenate([[0], np.cumsum(counts)])
        self.node_range = (int(starts[rank]), int(starts[rank + 1]))
        self.rstart, self.rend = 3 * self.node_range[0], 3 * self.node_range[1]
        self.n_local = self.rend - self.rstart
        self.ranges = 3 * starts                        # DOF ranges of all ranks
        full = np.arange(self.n)
        self.dof_of_full = 3 * self.new_of[full // 3] + full % 3
        self.dof_of_free = self.dof_of_full[asm.free]
        self.fixed = np.ones(self.n, dtype=bool)        # by PETSc DOF
        self.fixed[self.dof_of_free] = False
        # rows and columns reduced to the diagonal: the clamped DOFs and the pinned contact DOFs
        # (clamped tangential components of contact nodes, :class:`~contactopt.fem.model.ElasticModel`)
        self.decoupled = self.fixed.copy()
        self.decoupled[self.dof_of_full[np.asarray(getattr(model, "pinned_dofs", ()), np.int64)]] = True
        self.contact = self.dof_of_free[np.asarray(model.contact_dofs)].reshape(-1, 3)
        self.owns_contact = (self.contact[:, 0] >= self.rstart) & (self.contact[:, 0] < self.rend)
        self.old_of = order
        new_cells = self.new_of[cells]
        lo, hi = self.node_range
        E, nu = model.config.material.E, model.config.material.nu
        self._formulation = asm.formulation           # B-bar is per element: the sub-meshes take it as they are
        # the stiffness of the owned rows: every element at an owned node (a layer of elements of
        # the neighbouring ranks computed here too, so assembly needs no communication)
        touch = np.flatnonzero(((new_cells >= lo) & (new_cells < hi)).any(axis=1))
        self.n_ghost_elements = int(np.sum(part[touch] != rank))
        self._stiff = self._local(new_cells[touch], E, nu, asm.element)
        nodes = self._stiff[1]
        first = int(np.searchsorted(nodes, lo))
        self._owned_rows = slice(3 * first, 3 * (first + hi - lo))
        # the design term: this rank's own elements only (each element counted on one rank)
        self.n_elements = int(np.sum(part == rank))
        self._own = self._local(new_cells[part == rank], E, nu, asm.element)
        self._csr = None
        self._bsr = None

    def _local(self, new_cells, E, nu, element):
        """(assembler on the nodes of ``new_cells``, those nodes' new numbers (sorted), their
        PETSc DOFs)."""
        nodes, local = np.unique(new_cells, return_inverse=True)
        sub = ElasticityAssembler(local.reshape(new_cells.shape), nodes.size, np.zeros(0, np.int64), E, nu,
                                  element=element, formulation=self._formulation)
        return sub, nodes, (3 * nodes[:, None] + np.arange(3)).ravel()

    # ------------------------------------------------------------------ the matrix
    def owned_stiffness(self, coords: np.ndarray):
        """The owned rows of A(α) as CSR (indptr, PETSc columns, values), coordinates ``coords``
        in the model's node order; clamped and pinned DOFs keep only their diagonal entries."""
        sub, nodes, ldofs = self._stiff
        K = sub.stiffness(coords[self.old_of[nodes]])
        K.sort_indices()
        # the owned rows, a contiguous range: views of K's arrays (scipy's row slice copies and
        # checks every column, 0.16 s at 113k DOFs on 2 ranks)
        a, b = self._owned_rows.start, self._owned_rows.stop
        lo, hi = K.indptr[a], K.indptr[b]
        data = K.data[lo:hi]
        if self._csr is None:
            indptr = K.indptr[a:b + 1] - lo
            rows = np.repeat(np.arange(self.rstart, self.rend), np.diff(indptr))
            cols = ldofs[K.indices[lo:hi]]
            self._drop = (self.decoupled[rows] | self.decoupled[cols]) & (rows != cols)
            self._csr = (indptr.astype(np.int32), cols.astype(np.int32))
            self._bsr = block_pattern(self._csr[0], K.indices[lo:hi], K.shape[1], nodes)
            self._ext = np.zeros(data.size + 1)
            self._blocks = np.empty(self._bsr[2].size)
        data[self._drop] = 0.0
        return self._csr[0], self._csr[1], data

    def owned_blocks(self, data: np.ndarray):
        """The values ``data`` of :meth:`owned_stiffness` as 3×3 blocks of the owned rows: (block
        indptr, block columns (PETSc nodes), values, block-row-major, 9 per block), the form of a
        matrix of block size 3 (MPIBAIJ)."""
        bip, bcols, where = self._bsr
        self._ext[:-1] = data         # buffers kept (overwritten by the next call): fresh pages
        return bip, bcols, np.take(self._ext, where, out=self._blocks)     # cost more than the copy

    def owned(self, v_full_petsc: np.ndarray) -> np.ndarray:
        return v_full_petsc[self.rstart:self.rend]

    def petsc_of_free(self, v_free: np.ndarray) -> np.ndarray:
        """A vector on the model's free DOFs in PETSc order, all DOFs (0 on clamped DOFs)."""
        out = np.zeros(self.n)
        out[self.dof_of_free] = v_free
        return out

    def free_vector(self, v_all: np.ndarray) -> np.ndarray:
        """A vector on all PETSc DOFs in the model's free-DOF order."""
        return v_all[self.dof_of_free]

    def coordinates(self, coords: np.ndarray) -> np.ndarray:
        """The owned nodes' coordinates (n_owned, 3), PETSc order."""
        return coords[self.old_of[self.node_range[0]:self.node_range[1]]]

    def contraction(self, model, coords, u_full, v_full) -> np.ndarray:
        """This rank's own elements' part of vᵀ(∂A/∂α_k)u (stiffness only; u, v full-length in the
        model's order), contracted with ∂x3/∂α (:meth:`~contactopt.fem.model.ElasticModel.design_contraction`)."""
        sub, nodes, _ = self._own
        old = self.old_of[nodes]
        uu, vv = u_full.reshape(-1, 3)[old].ravel(), v_full.reshape(-1, 3)[old].ravel()
        d = sub.stiffness_shape_contraction(coords[old], uu, vv)
        dx = np.zeros((self.n_nodes, 3))
        dx[old] = d
        return model.mesh.contract_dx(dx)


class DistributedBodies:
    """The body and its elastic counterparts over ``size`` ranks, for the PETSc path's form of two
    bodies and more (:mod:`contactopt.paths.coupled`): the Newton system Tᵀ diag(A(α), K_1, …, K_B) T
    in the unknowns u_loc (the contact DOFs hold the relative displacement w), seen from ``rank``.

    Partition and numbering: each body's elements are bisected as :class:`DistributedBody` does,
    every body into ``size`` parts, so that each rank holds a part of every body; a node belongs to
    the lowest rank among its elements', and rank r owns the nodes of every body it owns, the
    body's first and the counterparts' after, one contiguous range of PETSc DOFs 3·node + c. The
    DOFs outside u_loc (the clamped ones) keep a diagonal entry and nothing else.

    Assembly of the owned rows R: (Tᵀ D T)[R] = T[need, R]ᵀ D[need] T, with ``need`` = R and the
    contact DOFs (T differs from the identity there only). D[need]: the body's rows from the
    elements at the owned and the contact nodes (a layer of the neighbours' elements and the
    contact face's computed here too, with no communication), the counterparts' rows from their
    stiffness K_f, which every rank holds (it is computed with the model; only the PETSc matrices,
    the hierarchy and the Krylov vectors are distributed). The pattern is the structural product,
    formed once, so that every design fills the same one.

    ``petsc_of_free`` and ``free_vector`` map between u_loc (the couple's order: the body's free
    DOFs, then every counterpart's) and PETSc's; ``contact`` (p, 3) the PETSc DOFs of the contact
    nodes, per node (t1, t2, ν), where u_loc holds w."""

    def __init__(self, model, T, parts, size: int, rank: int):
        asm = model.assembler
        self.size, self.rank = size, rank
        bodies = [(np.asarray(asm.elements, np.int64), asm.n_nodes, model.body.reference.points, asm.free)]
        bodies += [(np.asarray(f.assembler.elements, np.int64), f.assembler.n_nodes, f.mesh.reference.points,
                    f.assembler.free) for f in parts]
        owners, self._parts_of = [], []
        for cells, n_nodes, points, _ in bodies:
            if size > cells.shape[0]:
                raise ConfigError([f"{size} MPI ranks: a body's mesh has {cells.shape[0]} elements, fewer than "
                                   "the ranks it would be split over; run on fewer ranks"])
            part, owner = element_owners(cells, n_nodes, points, size)
            owners.append(owner)
            self._parts_of.append(part)
        body_of = np.concatenate([np.full(o.size, b) for b, o in enumerate(owners)])
        owner = np.concatenate(owners)
        counts = np.bincount(owner, minlength=size)
        if np.any(counts == 0):
            raise ConfigError([f"{size} MPI ranks: the bodies cannot be split so that every rank owns nodes; "
                               "run on fewer ranks"])
        order = np.lexsort((np.arange(owner.size), body_of, owner))     # new node -> (body, node), by rank
        new_of = np.empty(owner.size, dtype=np.int64)
        new_of[order] = np.arange(owner.size)
        node_starts = np.concatenate([[0], np.cumsum([o.size for o in owners])])
        self.n_nodes = int(owner.size)
        self.n = 3 * self.n_nodes
        starts = np.concatenate([[0], np.cumsum(counts)])
        self.node_range = (int(starts[rank]), int(starts[rank + 1]))
        self.rstart, self.rend = 3 * self.node_range[0], 3 * self.node_range[1]
        self.n_local = self.rend - self.rstart
        self.ranges = 3 * starts
        # u_loc -> PETSc: every body's free DOFs, in the couple's order
        self._new_of = [new_of[a:b] for a, b in zip(node_starts[:-1], node_starts[1:])]
        self.dof_of_free = np.concatenate([3 * nb[free // 3] + free % 3 for nb, (_, _, _, free)
                                           in zip(self._new_of, bodies)]).astype(np.int64)
        self.n_free = self.dof_of_free.size
        self.fixed = np.ones(self.n, dtype=bool)
        self.fixed[self.dof_of_free] = False
        cd = np.asarray(model.contact_dofs, np.int64)
        self.contact = self.dof_of_free[cd].reshape(-1, 3)
        self.owns_contact = (self.contact[:, 0] >= self.rstart) & (self.contact[:, 0] < self.rend)
        self._T, self._cd = sp.csr_matrix(T), cd
        # the owned rows of u_loc, by PETSc DOF, and the rows of D they need
        own = np.flatnonzero((self.dof_of_free >= self.rstart) & (self.dof_of_free < self.rend))
        self._R = own[np.argsort(self.dof_of_free[own], kind="stable")]
        self._need = np.union1d(self._R, cd)
        # the body's rows of ``need``: the elements at those nodes
        n_body = asm.n_free
        body_need = self._need[self._need < n_body]
        nodes_needed = np.zeros(asm.n_nodes, dtype=bool)
        nodes_needed[asm.free[body_need] // 3] = True
        cells = bodies[0][0]
        touch = np.flatnonzero(nodes_needed[cells].any(axis=1))
        nodes, local = np.unique(cells[touch], return_inverse=True)
        E, nu = model.config.material.E, model.config.material.nu
        self._sub = ElasticityAssembler(local.reshape(-1, cells.shape[1]), nodes.size, np.zeros(0, np.int64), E, nu,
                                        element=asm.element, formulation=asm.formulation)
        self._sub_nodes = nodes
        sub_full = (3 * nodes[:, None] + np.arange(3)).ravel()       # the sub-assembler's DOFs, body-full
        pinned = np.zeros(asm.n_full, dtype=bool)
        pinned[np.asarray(model.pinned_dofs, np.int64)] = True
        self._sub_free = asm.full_to_free[sub_full]                  # −1 on a clamped DOF
        self._sub_pinned = pinned[sub_full]
        self._body_rows = np.searchsorted(sub_full, asm.free[body_need])
        self._body_need = body_need
        # the counterparts' rows of ``need`` (owned ones only: the contact DOFs are the body's)
        cp_need = self._need[self._need >= n_body] - n_body
        starts = np.concatenate([[0], np.cumsum([f.assembler.n_free for f in parts])]).astype(np.int64)
        blocks = []
        for f, a, b in zip(parts, starts[:-1], starts[1:]):
            k = cp_need[(cp_need >= a) & (cp_need < b)]
            blk = f.K[k - a].tocoo()
            blocks.append((k[blk.row] + n_body, blk.col + a + n_body, blk.data))
        r_f, c_f, v_f = np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        if blocks:                       # none with rigid counterparts only
            r_f, c_f, v_f = (np.concatenate(x) for x in zip(*blocks))
        self._rows_f = (np.searchsorted(self._need, r_f), c_f, v_f)
        # a clamped DOF's diagonal: the mean of the counterparts' stiffness diagonal, or the body's
        # Young's modulus with rigid counterparts only (the same on every rank; a scale, any value holds)
        self._fixed_value = float(np.mean(np.concatenate([f.K.diagonal() for f in parts]))) if parts else E
        self._fixed_rows = np.flatnonzero(self.fixed[self.rstart:self.rend]) + self.rstart
        self._pattern = None
        self._last = None                # (indptr, indices, places in the pattern) of the last product
        # the design term: this rank's own elements of the body
        own_cells = cells[self._parts_of[0] == rank]
        self.n_elements = int(own_cells.shape[0])
        self.n_ghost_elements = int(touch.size - np.sum(self._parts_of[0][touch] == rank))
        onodes, olocal = np.unique(own_cells, return_inverse=True)
        self._own = (ElasticityAssembler(olocal.reshape(-1, cells.shape[1]), onodes.size, np.zeros(0, np.int64), E,
                                         nu, element=asm.element, formulation=asm.formulation), onodes)
        self._n_body_nodes = asm.n_nodes

    def _rows(self, coords: np.ndarray) -> sp.csr_matrix:
        """D[need] (|need| × n, u_loc columns) of the body at ``coords`` and the counterparts."""
        K = self._sub.stiffness(coords[self._sub_nodes]).tocsr()
        K = K[self._body_rows].tocoo()
        rf, cf = self._sub_free[self._body_rows[K.row]], self._sub_free[K.col]
        keep = cf >= 0
        pin = (self._sub_pinned[self._body_rows[K.row]] | self._sub_pinned[K.col]) & (rf != cf)
        keep &= ~pin
        rows = np.searchsorted(self._need, rf[keep])
        n = self._T.shape[0]
        r_f, c_f, v_f = self._rows_f
        return sp.csr_matrix((np.concatenate([K.data[keep], v_f]),
                              (np.concatenate([rows, r_f]), np.concatenate([cf[keep], c_f]))),
                             shape=(self._need.size, n))

    def owned_stiffness(self, coords: np.ndarray):
        """The owned rows of Tᵀ diag(A(α), K_f) T as CSR (indptr, PETSc columns, values), body
        coordinates ``coords`` in the model's node order; every contact node's 3×3 block in the
        pattern (the Newton systems add their Robin blocks there)."""
        D = self._rows(coords)
        Tsub = self._T[self._need][:, self._R]
        law = (Tsub.T @ D @ self._T).tocsr()
        if self._pattern is None:
            self._pattern = self._structure(Tsub, D)
        keys, indptr, cols, diag_at = self._pattern
        law.sort_indices()
        last = self._last
        if last is not None and np.array_equal(last[0], law.indptr) and np.array_equal(last[1], law.indices):
            pos = last[2]                # the product's pattern of the last design: its places kept
        else:
            got = self._keys(law)
            pos = np.searchsorted(keys, got)
            if np.any(pos >= keys.size) or np.any(keys[np.minimum(pos, keys.size - 1)] != got):
                raise RuntimeError("an entry of the two bodies' system is outside the pattern formed at the first "
                                   "design")
            self._last = (law.indptr.copy(), law.indices.copy(), pos)
        data = np.zeros(keys.size)
        data[pos] = law.data
        data[diag_at] = self._fixed_value
        return indptr, cols, data

    def _keys(self, law) -> np.ndarray:
        """Sorted keys (PETSc row − rstart)·n + PETSc column of the entries of owned rows ``law``."""
        rows = self.dof_of_free[self._R][np.repeat(np.arange(law.shape[0]), np.diff(law.indptr))] - self.rstart
        return rows * np.int64(self.n) + self.dof_of_free[law.indices]

    def _structure(self, Tsub, D):
        """(sorted keys, indptr, PETSc columns, positions of the clamped DOFs' diagonals) of the owned
        rows' pattern: the product of the patterns (every stored entry 1: no cancellation, and no
        entry lost where a design's value is an exact zero), the contact blocks and the clamped diagonals."""
        S = (_ones(Tsub).T @ _ones(D) @ _ones(self._T)).tocsr()
        S.sort_indices()
        keys = [self._keys(S)]
        cd = self.contact
        own = cd[self.owns_contact]
        r = np.repeat(own, 3, axis=1).ravel() - self.rstart
        c = np.tile(own, (1, 3)).ravel()
        keys.append(r * np.int64(self.n) + c)
        fixed = self._fixed_rows - self.rstart
        keys.append(fixed * np.int64(self.n) + self._fixed_rows)
        keys = np.unique(np.concatenate(keys))
        rows = keys // self.n
        indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=self.n_local))]).astype(np.int32)
        cols = (keys % self.n).astype(np.int32)
        diag_at = np.searchsorted(keys, fixed * np.int64(self.n) + self._fixed_rows)
        self._bsr = block_pattern(indptr, cols, self.n, np.arange(self.n_nodes))
        self._ext = np.zeros(keys.size + 1)
        self._blocks = np.empty(self._bsr[2].size)
        return keys, indptr, cols, diag_at

    owned_blocks = DistributedBody.owned_blocks
    owned = DistributedBody.owned
    petsc_of_free = DistributedBody.petsc_of_free
    free_vector = DistributedBody.free_vector

    def contraction(self, model, coords, u_full, v_full) -> np.ndarray:
        """This rank's own elements of the body: their part of vᵀ(∂A/∂α_k)u (u, v the body's
        full-length displacement and adjoint extension, model order), as
        :meth:`DistributedBody.contraction` (∂A/∂α touches the body's block only)."""
        sub, nodes = self._own
        uu, vv = u_full.reshape(-1, 3)[nodes].ravel(), v_full.reshape(-1, 3)[nodes].ravel()
        d = sub.stiffness_shape_contraction(coords[nodes], uu, vv)
        dx = np.zeros((self._n_body_nodes, 3))
        dx[nodes] = d
        return model.mesh.contract_dx(dx)


def _ones(M) -> sp.csr_matrix:
    """``M``'s pattern with every stored entry 1 (explicit zeros included)."""
    M = sp.csr_matrix(M, copy=True)
    M.data[:] = 1.0
    return M
