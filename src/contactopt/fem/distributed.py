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
    blocks, row-major (0 for an entry outside the CSR pattern), the places of those outside)."""
    nnz = lcols.size
    tag = sp.csr_matrix((np.arange(1, nnz + 1, dtype=np.float64), lcols, indptr),
                        shape=(indptr.size - 1, n_cols))
    B = tag.tobsr(blocksize=(3, 3))
    del tag
    B.sort_indices()
    where = B.data.ravel()
    outside = np.flatnonzero(where == 0)               # an entry of a block outside the CSR pattern
    where = (where - 1).astype(np.int32 if nnz < 2**31 else np.int64)
    where[outside] = 0                                 # ... reads any value, then set to zero
    return B.indptr.astype(np.int32), nodes[B.indices].astype(np.int32), where, outside


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
            self._blocks = np.empty(self._bsr[2].size)
        data[self._drop] = 0.0
        return self._csr[0], self._csr[1], data

    def owned_blocks(self, data: np.ndarray):
        """The values ``data`` of :meth:`owned_stiffness` as 3×3 blocks of the owned rows: (block
        indptr, block columns (PETSc nodes), values, block-row-major, 9 per block), the form of a
        matrix of block size 3 (MPIBAIJ)."""
        bip, bcols, where, outside = self._bsr
        blocks = np.take(data, where, out=self._blocks)     # a buffer kept (overwritten by the next call):
        blocks[outside] = 0.0                               # fresh pages cost more than the copy
        return bip, bcols, blocks

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

    Assembly of the owned rows R: with D = diag(A(α), K_1, …) and T = I + E, E nonzero on the
    contact rows c only, (Tᵀ D T)[R] = D[R] + Δ[R], Δ = E_cᵀ D[c, :] + D[:, c] E_c + E_cᵀ D[c, c] E_c
    supported near the contact DOFs — the pyamg backend's form of the same system
    (:meth:`~contactopt.paths.coupled.FullSpaceCouple.system`). D[R] is copied from the body's
    stiffness on the elements at the owned and the contact nodes (a layer of the neighbours'
    elements and the contact face computed here too, with no communication) and from the
    counterparts' owned rows of K_f (K_f is formed with the model on every rank; the PETSc path then
    drops its assembler's work arrays); Δ[R] from small products of the contact rows. No
    product of the whole T is formed: a new design's rows take about twice their own bytes to form.
    The pattern is the structure of D[R] and of Δ[R] (every stored entry taken as 1: the structural
    product Tᵀ D T), formed once, so that every design fills the same one.

    ``petsc_of_free`` and ``free_vector`` map between u_loc (the couple's order: the body's free
    DOFs, then every counterpart's) and PETSc's; ``contact`` (p, 3) the PETSc DOFs of the contact
    nodes, per node (t1, t2, ν), where u_loc holds w."""

    def __init__(self, model, T, parts, size: int, rank: int, law_dofs=None, pinned=()):
        """``law_dofs`` the Newton system's contact DOFs in u_loc (the model's contact DOFs where
        None; with faces on several bodies also those of rows b on their carriers, and the pinned
        unknowns after all bodies', :mod:`contactopt.paths.coupled`); ``pinned`` per pinned unknown
        (its carrier's index in ``parts``, node, component): its PETSc DOF is that clamped component's."""
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
                                           in zip(self._new_of, bodies)]
                                          + [np.array([3 * self._new_of[1 + b][node] + c for b, node, c in pinned],
                                                      dtype=np.int64)]).astype(np.int64)
        self.n_free = self.dof_of_free.size
        self.fixed = np.ones(self.n, dtype=bool)
        self.fixed[self.dof_of_free] = False
        cd = np.asarray(model.contact_dofs if law_dofs is None else law_dofs, np.int64)
        self.contact = self.dof_of_free[cd].reshape(-1, 3)
        self.owns_contact = (self.contact[:, 0] >= self.rstart) & (self.contact[:, 0] < self.rend)
        n = self.n_free
        # T = I + E with E on the contact rows only: E_c = T[c] − I[c] (|c| × n)
        change = (sp.csr_matrix(T) - sp.identity(n, format="csr")).tocsr()
        change.eliminate_zeros()
        is_c = np.zeros(n, dtype=bool)
        is_c[cd] = True
        if not is_c[np.flatnonzero(np.diff(change.indptr))].all():
            raise ValueError("the change of unknowns differs from the identity outside the contact DOFs")
        self._Ec = sp.csr_matrix(change[cd])
        self._Ec.sort_indices()
        del change
        self._cd = cd
        # the owned rows R of u_loc, by PETSc DOF, and (E_c[:, R])ᵀ: the rows of Δ that E_cᵀ touches
        own = np.flatnonzero((self.dof_of_free >= self.rstart) & (self.dof_of_free < self.rend))
        self._R = own[np.argsort(self.dof_of_free[own], kind="stable")]
        self._row_of_R = (self.dof_of_free[self._R] - self.rstart).astype(np.int64)     # PETSc row − rstart
        self._EcT_R = sp.csr_matrix(self._Ec[:, self._R].T)
        # the body's rows of R and of the contact DOFs: the elements at those nodes
        n_body = asm.n_free
        body_R = self._R[self._R < n_body]
        self._body_c = np.flatnonzero(cd < n_body)     # the contact DOFs on the body (all, but for rows b)
        nodes_needed = np.zeros(asm.n_nodes, dtype=bool)
        nodes_needed[asm.free[np.concatenate([body_R, cd[self._body_c]])] // 3] = True
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
        self._sub_of_R = np.searchsorted(sub_full, asm.free[body_R])  # the sub-assembler's rows of R's body rows
        self._R_body = np.flatnonzero(self._R < n_body)               # ... their places in R
        self._sub_of_c = np.searchsorted(sub_full, asm.free[cd[self._body_c]])
        # the counterparts' rows of R (K_f, which does not change with α), in u_loc
        cp_R = self._R[self._R >= n_body] - n_body
        starts = np.concatenate([[0], np.cumsum([f.assembler.n_free for f in parts])]).astype(np.int64)
        blocks = []
        for f, a, b in zip(parts, starts[:-1], starts[1:]):
            k = cp_R[(cp_R >= a) & (cp_R < b)]
            blk = f.K[k - a].tocoo()
            blocks.append((k[blk.row] + n_body, blk.col + a + n_body, blk.data))
        mine = self._R[self._R >= n_body + starts[-1]]       # the pinned unknowns of rows b: a unit diagonal
        if mine.size:
            blocks.append((mine, mine, np.ones(mine.size)))
        r_f, c_f, v_f = np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        if blocks:                       # none with rigid counterparts only
            r_f, c_f, v_f = (np.concatenate(x) for x in zip(*blocks))
        self._off = self._off_contact_rows(parts, cd, n_body, starts) if self._body_c.size < cd.size else None
        self._rows_f, self._values_f = (r_f, c_f), v_f      # the rows and columns: until the pattern is formed
        # a clamped DOF's diagonal: the mean of the counterparts' stiffness diagonal, or the body's
        # Young's modulus with rigid counterparts only (the same on every rank; a scale, any value holds)
        self._fixed_value = float(np.mean(np.concatenate([f.K.diagonal() for f in parts]))) if parts else E
        self._fixed_rows = np.flatnonzero(self.fixed[self.rstart:self.rend]) + self.rstart
        self._fill = None                # the pattern and where its values come from (first design)
        # the design term: this rank's own elements of the body
        own_cells = cells[self._parts_of[0] == rank]
        self.n_elements = int(own_cells.shape[0])
        self.n_ghost_elements = int(touch.size - np.sum(self._parts_of[0][touch] == rank))
        onodes, olocal = np.unique(own_cells, return_inverse=True)
        self._own = (ElasticityAssembler(olocal.reshape(-1, cells.shape[1]), onodes.size, np.zeros(0, np.int64), E,
                                         nu, element=asm.element, formulation=asm.formulation), onodes)
        self._n_body_nodes = asm.n_nodes

    def _off_contact_rows(self, parts, cd, n_body, starts):
        """(D[c, :], D[R, c], D[c, c]) of the contact DOFs off the body (rows b on their carriers, whose
        K does not change with α, and the pinned unknowns' unit diagonal; zero on the body's rows), for
        Δ: (|c| × n), (|R| × |c|), (|c| × |c|)."""
        n, nc = self.n_free, cd.size
        c_of = np.full(n, -1, dtype=np.int64)
        c_of[cd] = np.arange(nc)
        rows, cols, vals, r_rows, r_cols, r_vals = [], [], [], [], [], []
        for f, a, b in zip(parts, starts[:-1], starts[1:]):
            lo, hi = n_body + a, n_body + b
            at = np.flatnonzero((cd >= lo) & (cd < hi))
            if at.size:
                blk = f.K[cd[at] - lo].tocoo()
                rows.append(at[blk.row])
                cols.append(blk.col + lo)
                vals.append(blk.data)
            pos = np.flatnonzero((self._R >= lo) & (self._R < hi))
            if pos.size:
                blk = f.K[self._R[pos] - lo].tocoo()
                keep = c_of[blk.col + lo] >= 0
                r_rows.append(pos[blk.row[keep]])
                r_cols.append(c_of[blk.col[keep] + lo])
                r_vals.append(blk.data[keep])
        at = np.flatnonzero(cd >= n_body + starts[-1])
        rows.append(at)
        cols.append(cd[at])
        vals.append(np.ones(at.size))
        pos = np.flatnonzero(self._R >= n_body + starts[-1])
        r_rows.append(pos)
        r_cols.append(c_of[self._R[pos]])
        r_vals.append(np.ones(pos.size))
        Dc = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nc, n))
        DRc = sp.csr_matrix((np.concatenate(r_vals), (np.concatenate(r_rows), np.concatenate(r_cols))),
                            shape=(self._R.size, nc))
        return Dc, DRc, sp.csr_matrix(Dc[:, cd])

    def _entries(self, K, sub_rows):
        """(positions in ``K.data``, row of each among ``sub_rows``, u_loc column) of the entries of D
        in the sub-assembler's rows ``sub_rows``: the clamped columns left out, a pinned DOF's row and
        column reduced to its diagonal."""
        # the rows of a copy of K's structure whose values are their places: int32 throughout
        S = sp.csr_matrix((np.arange(K.data.size, dtype=np.int32), K.indices, K.indptr), shape=K.shape)[sub_rows]
        at, sc = S.data, S.indices
        row = np.repeat(np.arange(sub_rows.size, dtype=np.int32), np.diff(S.indptr))
        del S
        free = self._sub_free.astype(np.int32)
        col = free[sc]
        keep = col >= 0
        if self._sub_pinned.any():
            keep &= ~((self._sub_pinned[sub_rows][row] | self._sub_pinned[sc]) & (free[sub_rows][row] != col))
        return at[keep], row[keep], col[keep]

    def owned_stiffness(self, coords: np.ndarray):
        """The owned rows of Tᵀ diag(A(α), K_f) T as CSR (indptr, PETSc columns, values), body
        coordinates ``coords`` in the model's node order; every contact node's 3×3 block in the
        pattern (the Newton systems add their Robin blocks there).

        With D = diag(A(α), K_f) and T = I + E (E_c = T[c] − I[c] on the contact rows c only), Tᵀ D T
        = D + Δ, Δ = E_cᵀ D[c, :] + D[:, c] E_c + E_cᵀ D[c, c] E_c: the owned rows are D[R], copied
        from the body's local stiffness and the counterparts' rows, plus Δ[R], which is supported near
        the contact DOFs (as the pyamg backend's :meth:`~contactopt.paths.coupled.FullSpaceCouple.system`)."""
        K = self._sub.stiffness(coords[self._sub_nodes])
        self._sub.release()               # its work arrays: made anew at the next design
        if self._fill is None:
            self._fill = self._structure(K)
        indptr, cols, src, d_keys, d_pos, sel = self._fill
        ext = np.empty(K.data.size + self._values_f.size + 2)
        ext[:K.data.size] = K.data
        ext[K.data.size:-2] = self._values_f
        ext[-2:] = 0.0, self._fixed_value
        data = ext.take(src)
        del ext
        delta = self._delta(K.data, sel).tocoo()
        if delta.nnz:
            keys = self._row_of_R[delta.row] * np.int64(self.n) + self.dof_of_free[delta.col]
            pos = np.searchsorted(d_keys, keys)
            if np.any(pos >= d_keys.size) or np.any(d_keys[np.minimum(pos, d_keys.size - 1)] != keys):
                raise RuntimeError("an entry of the two bodies' system is outside the pattern formed at the first "
                                   "design")
            data[d_pos[pos]] += delta.data
        return indptr, cols, data

    def _delta(self, values, sel, ones: bool = False) -> sp.csr_matrix:
        """Δ[R] = (E_c[:, R])ᵀ D[c, :] + D[R, c] E_c + (E_c[:, R])ᵀ D[c, c] E_c (|R| × n, u_loc
        columns) with the body's stiffness ``values`` (``K.data`` of the sub-assembler); ``ones``:
        its structure (every stored entry of D and E_c taken as 1: no cancellation)."""
        (at_c, row_c, col_c), (at_rc, row_rc, col_rc), cc = sel
        nc, n = self._cd.size, self.n_free
        v = (lambda at: np.ones(at.size)) if ones else (lambda at: values[at])
        Ec = _ones(self._Ec) if ones else self._Ec
        EcT_R = _ones(self._EcT_R) if ones else self._EcT_R
        Dc = sp.csr_matrix((v(at_c), (row_c, col_c)), shape=(nc, n))
        DRc = sp.csr_matrix((v(at_rc), (row_rc, col_rc)), shape=(self._R.size, nc))
        Dcc = sp.csr_matrix((v(at_c[cc]), (row_c[cc], self._c_of[col_c[cc]])), shape=(nc, nc))
        if self._off is not None:           # the contact DOFs off the body (faces on several bodies)
            Dc, DRc, Dcc = (M + (_ones(O) if ones else O) for M, O in zip((Dc, DRc, Dcc), self._off))
        return (EcT_R @ Dc + DRc @ Ec + EcT_R @ (Dcc @ Ec)).tocsr()

    def _structure(self, K):
        """The owned rows' pattern and where each of its values comes from, formed at the first design
        from the structures (every design fills the same pattern: a value that is an exact zero keeps
        its entry): (indptr, PETSc columns, ``src`` — the place of each entry's value in K.data, the
        counterparts' values, 0, the clamped diagonal —, the keys (row − rstart)·n + column of the
        entries of the rows Δ reaches, their places, the selections of D for Δ)."""
        n, nK = np.int64(self.n), K.data.size
        (r_f, c_f), v_f = self._rows_f, self._values_f
        del self._rows_f
        # D[R]: the body's rows and the counterparts', and the clamped DOFs' diagonals
        at_b, row_b, col_b = self._entries(K, self._sub_of_R)
        fixed = (self._fixed_rows - self.rstart).astype(np.int64)
        i32 = np.int32
        dof = self.dof_of_free.astype(i32)
        lrow = np.concatenate([self._row_of_R[self._R_body].astype(i32)[row_b], dof[r_f] - i32(self.rstart),
                               fixed.astype(i32)])
        lcol = np.concatenate([dof[col_b], dof[c_f], self._fixed_rows.astype(i32)])
        if nK + v_f.size + 2 >= 2**31:
            raise ValueError("the owned rows have more than 2^31 values: run on more ranks")
        src = np.concatenate([at_b.astype(i32), (nK + np.arange(v_f.size)).astype(i32),
                              np.full(fixed.size, nK + v_f.size + 1, dtype=i32)])
        # for Δ: D[c, :] (the body's contact rows), D[R, c] (of R's body rows), D[c, c]
        self._c_of = np.full(self.n_free, -1, dtype=np.int32)
        self._c_of[self._cd] = np.arange(self._cd.size)
        at_c, row_c, col_c = self._entries(K, self._sub_of_c)
        if self._off is not None:           # (the contact DOFs' places among all of them: rows b follow)
            row_c = self._body_c[row_c]
        in_c = self._c_of[col_b] >= 0
        sel = ((at_c, row_c, col_c), (at_b[in_c], self._R_body[row_b[in_c]], self._c_of[col_b[in_c]]),
               np.flatnonzero(self._c_of[col_c] >= 0))
        # the entries only Δ and the contact nodes' blocks add
        S = self._delta(None, sel, ones=True).tocoo()
        own = self.contact[self.owns_contact]
        extra = np.unique(np.concatenate([
            self._row_of_R[S.row] * n + self.dof_of_free[S.col],
            (np.repeat(own, 3, axis=1).ravel() - self.rstart) * n + np.tile(own, (1, 3)).ravel()]))
        rows = np.zeros(self.n_local, dtype=bool)
        rows[extra // n] = True
        near = rows[lrow]
        extra = np.setdiff1d(extra, lrow[near].astype(np.int64) * n + lcol[near])
        lrow = np.concatenate([lrow, (extra // n).astype(i32)])
        lcol = np.concatenate([lcol, (extra % n).astype(i32)])
        src = np.concatenate([src, np.full(extra.size, nK + v_f.size, dtype=i32)])
        count = src.size
        P = sp.csr_matrix((src, (lrow, lcol)), shape=(self.n_local, self.n))
        del lrow, lcol, src
        if P.nnz != count:
            raise RuntimeError("an entry of the two bodies' pattern is formed twice")
        P.sort_indices()
        indptr, cols = P.indptr.astype(np.int32, copy=False), P.indices.astype(np.int32, copy=False)
        # the pattern's entries in the rows Δ reaches, as sorted keys, and their places
        d_rows = np.flatnonzero(rows)
        d_pos = _ranges(indptr[d_rows], indptr[d_rows + 1] - indptr[d_rows])
        d_keys = np.repeat(d_rows, np.diff(indptr)[d_rows]) * n + cols[d_pos]
        self._bsr = block_pattern(indptr, cols, self.n, np.arange(self.n_nodes))
        self._blocks = np.empty(self._bsr[2].size)
        return indptr, cols, P.data, d_keys, d_pos, sel

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


def _ranges(starts, counts) -> np.ndarray:
    """The indices start_i, …, start_i + count_i − 1 of every i, one after the other."""
    counts = np.asarray(counts, dtype=np.int64)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.repeat(np.asarray(starts, dtype=np.int64) - first, counts) + np.arange(total)


def _ones(M) -> sp.csr_matrix:
    """``M``'s pattern with every stored entry 1 (explicit zeros included)."""
    M = sp.csr_matrix(M, copy=True)
    M.data[:] = 1.0
    return M
