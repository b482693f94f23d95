"""The PETSc backend of the full-space method and its adjoint (MPI).

The same method as :mod:`contactopt.contact.fullspace` — read its docstring for the problem, the
Alart–Curnier function, the Newton system G = (I − C_N)(A + K_t) on the rows I outside the
Dirichlet set D, the inexact-Newton tolerances and the line search — with the linear algebra on
PETSc: A(α) a matrix of block size 3 over the ranks (:mod:`contactopt.fem.distributed`), each
Newton system assembled explicitly (G and H = A + K_t have the pattern of A: a node's three rows
share their columns, so the friction coupling of a sliding node's normal row into its tangential
rows adds no entry; the rows and columns of D are unit rows and columns), solved by GMRES (right
preconditioning, so the tolerance is on the true residual) preconditioned by GAMG (smoothed
aggregation, the rigid-body modes as near-null space) built on H.

Storage: A, G and the Krylov operators are MPIBAIJ (3×3 blocks: one column index per block, and
PETSc's unrolled 3×3 kernel multiplies in half the time of the same matrix in MPIAIJ); GAMG takes
MPIAIJ only, so A is assembled a second time in MPIAIJ (``A_aij``) and H is of that type, filled
only when the coarse operators are formed anew. GAMG's finest smoother (Chebyshev) multiplies
with the operator the KSP had when they were formed — G, whose values follow the Newton systems
(an adjoint that forms none smooths with G, not Gᵀ: a preconditioner all the same) — so its
products are BAIJ products too; the finest residual of the V-cycle multiplies with H.

Conventions as everywhere: per contact node (t1, t2, ν), r = (A u − L)_c the contact force on the
body, λ = r_ν ≥ 0, τ = −r_t; a warm start is per node in the FCLIB order (N, T1, T2).

The hierarchy (:class:`PetscHierarchy`) is built on A(α_ref) of one design and kept: later Newton
systems and designs reuse its prolongations and its coarse operators, corrected by the Galerkin
products of the rows a Newton system changes (D, the Robin blocks), as the pyamg path does.
The per-node work of Newton (node classes, line search) is done on every rank on the contact
forces and displacements gathered from their owners (3p numbers per product): every rank takes
the same decisions, and the norms are global reductions. The iteration is the pyamg backend's
(:func:`.core.newton_loop`) on :class:`PetscBackend`.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp

from ...errors import SolverError
from ...fem.distributed import _ranges
from ...fem.krylov import KrylovNotConverged
from ..fallback import penetrating_start
from .core import FullSpaceResult, finish, known_adjoint_part, newton_loop, rho_of, sliding_frame, start, start_forces
from .pyamg import FullSpaceProblem

__all__ = ("PetscHierarchy", "PetscNewton", "PetscBackend")

log = logging.getLogger(__name__)


# The KSP's options unless [linear_solver] petsc_options sets them: GMRES's classical Gram–Schmidt
# orthogonalized twice (CGS2, as the pyamg path's GMRES; with PETSc's default of no refinement the
# Krylov basis lost orthogonality at 867k DOFs and GMRES stopped in a breakdown at residual 1.4e-5,
# 4.3e-7 asked); GAMG's prolongations kept if it is set up again (a preconditioner of the user's
# own choosing is, on every new D); a drop tolerance and a coarsest level of up to 2000 unknowns
# (solved directly) that made GAMG's Galerkin products 1.8× cheaper at 113k DOFs for the same
# iteration counts (docs/scaling.md)
KSP_DEFAULTS = {"ksp_gmres_cgs_refinement_type": "refine_always", "pc_gamg_reuse_interpolation": "true",
                "pc_gamg_threshold": "0.01", "pc_gamg_coarse_eq_limit": "2000"}


REFRESH_CHANGES = 0.01     # fraction of the contact DOFs whose change of D forms the coarse operators anew


def petsc():
    from petsc4py import PETSc
    return PETSc


class PetscHierarchy:
    """A KSP (GMRES, right-preconditioned) with GAMG built on ``H`` = A(α_ref) of one design (the
    rigid-body modes of ``coords`` — PETSc order, owned nodes — as near-null space, or the given
    ``modes_local``: the owned rows of orthonormal near-null vectors), ``G`` its operator at the
    build (GAMG's finest smoother multiplies with it, later with the values G takes).

    GAMG runs once. The coarse operators of a later Newton system with Dirichlet set D and Robin
    blocks K_t are those of H_ref = Π(A(α_ref) + K_t)Π + I_D (Π: the rows and columns of D
    zeroed), as the pyamg path's (:meth:`contactopt.fem.amg.ContactHierarchy.preconditioner`):
    A_1 = A_1,ref + P_0ᵀ Δ P_0 with Δ = H_ref − A(α_ref) supported on the rows and columns of D
    and the sliding nodes, and on down the levels, A_{l+1} = A_{l+1,ref} + P_lᵀ Δ_l P_l — Galerkin
    products of a few rows instead of the whole matrix, and coarse operators that depend on
    (α_ref, D, K_t) only, so a resumed run forms the same ones. ``contact_rows``: the PETSc DOFs
    of the contact nodes (every Dirichlet DOF of a Newton system is one of them). A user's
    ``-pc_type`` other than GAMG makes every refresh a set-up of that preconditioner on H."""

    def __init__(self, G, H, coords_local: np.ndarray | None, contact_rows: np.ndarray, restart: int = 60,
                 max_iter: int = 400, modes_local: np.ndarray | None = None):
        PETSc = petsc()
        t0 = time.perf_counter()
        if modes_local is None:
            xyz = H.createVecRight()
            xyz.setBlockSize(3)
            xyz.getArray()[:] = coords_local.ravel()
            H.setNearNullSpace(PETSc.NullSpace().createRigidBody(xyz))
        else:                               # given near-null vectors (owned rows; orthonormal over all ranks)
            vecs = []
            for column in np.asarray(modes_local, dtype=np.float64).T:
                v = H.createVecRight()
                v.getArray()[:] = column
                vecs.append(v)
            H.setNearNullSpace(PETSc.NullSpace().create(vectors=vecs, comm=H.getComm()))
        opts = PETSc.Options()
        for key, value in KSP_DEFAULTS.items():
            if not opts.hasName(key):
                opts.setValue(key, value)
        ksp = PETSc.KSP().create(H.getComm())
        ksp.setType("gmres")
        ksp.setGMRESRestart(restart)
        ksp.setPCSide(PETSc.PC.Side.RIGHT)
        ksp.getPC().setType("gamg")
        ksp.setTolerances(rtol=0.0, atol=0.0, max_it=max_iter)
        ksp.setInitialGuessNonzero(False)
        ksp.setFromOptions()                # -ksp_view, -pc_gamg_* ... of [linear_solver] petsc_options
        ksp.setOperators(G, H)
        ksp.setUp()
        self.ksp, self.H = ksp, H
        self.max_iter = max_iter
        self._levels = None
        pc = ksp.getPC()
        if pc.getType() == "gamg" and pc.getMGLevels() > 1:
            L = pc.getMGLevels()
            # from the level below the finest to the coarsest: the operators PCMG holds (updated in
            # place), their reference values, and the prolongation from each level to the one above
            self._levels = [(pc.getMGCoarseSolve() if lvl == 0 else pc.getMGSmoother(lvl)).getOperators()[0]
                            for lvl in range(L - 2, -1, -1)]
            self._ref = [M.duplicate(copy=True) for M in self._levels]
            self._P = [pc.getMGInterpolation(lvl) for lvl in range(L - 1, 0, -1)]
            self._contact_rows(np.asarray(contact_rows, dtype=np.int64).ravel())
            pc.setReusePreconditioner(True)
        self.setup_seconds = time.perf_counter() - t0
        self.uses = 0

    def _contact_rows(self, rows):
        """Keep H's owned rows at the DOFs ``rows`` (a CSR matrix by sorted global row ``_crow``)."""
        lo, hi = self.H.getOwnershipRange()
        rows = np.sort(rows[(rows >= lo) & (rows < hi)])
        ip, ind, val = self.H.getValuesCSR()
        owned = sp.csr_matrix((val, ind, ip), shape=(hi - lo, self.H.getSize()[1]))
        self._crow, self._cmat = rows, owned[rows - lo]

    def coarse(self, D: np.ndarray, robin=None) -> None:
        """Form the coarse operators of the Newton system with Dirichlet DOFs ``D`` (boolean over
        all PETSc DOFs, the same on every rank) and Robin blocks ``robin`` = (rows (m, 2), blocks
        (m, 2, 2)) of the owned sliding nodes' tangential DOFs (class docstring). Collective."""
        PETSc = petsc()
        if self._levels is None:
            return
        same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
        for M, ref in zip(self._levels, self._ref):
            ref.copy(M, structure=same)
        lo, hi = self.H.getOwnershipRange()
        d_own = np.flatnonzero(D[lo:hi]) + lo
        has_robin = robin is not None and len(robin[0]) > 0
        if not self.H.getComm().tompi4py().allreduce(bool(d_own.size or has_robin)):
            return
        # Δ = Y + Yᵀ with Y = −E_D + ½E_DD + ½I_D + ½K_t on the owned rows only (E_D: the rows of
        # D of A(α_ref), E_DD their columns in D; A(α_ref) and K_t are symmetric)
        k = np.searchsorted(self._crow, d_own)
        if np.any(k >= self._crow.size) or np.any(self._crow[np.minimum(k, self._crow.size - 1)] != d_own):
            raise SolverError("a Dirichlet DOF of a Newton system is not a contact DOF of the hierarchy")
        E = self._cmat[k].tocoo()
        rows = [d_own[E.row], d_own]
        cols = [E.col.astype(np.int64), d_own]
        vals = [-E.data * np.where(D[E.col], 0.5, 1.0), np.full(d_own.size, 0.5)]
        if has_robin:
            tt, blk = np.asarray(robin[0], dtype=np.int64), np.asarray(robin[1], dtype=np.float64)
            rows.append(np.repeat(tt, 2, axis=1).ravel())
            cols.append(np.tile(tt, (1, 2)).ravel())
            vals.append(0.5 * blk.ravel())
        n = self.H.getSize()[0]
        Y = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows) - lo, np.concatenate(cols))),
                          shape=(hi - lo, n))
        Y.sum_duplicates()
        Y.sort_indices()
        Ym = PETSc.Mat().createAIJ(size=self.H.getSizes(), comm=self.H.getComm())
        Ym.setPreallocationCSR((Y.indptr.astype(PETSc.IntType), Y.indices.astype(PETSc.IntType)))
        Ym.setValuesCSR(Y.indptr.astype(PETSc.IntType), Y.indices.astype(PETSc.IntType), Y.data)
        Ym.assemble()
        C = Ym.ptap(self._P[0])
        delta = PETSc.Mat()
        C.transpose(delta)
        delta.axpy(1.0, C, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        # destroyed here, not left to Python: a product keeps references to its factors inside
        # PETSc, so dropping the last Python reference frees none of them (0.07 GB a Newton system on
        # each of 2 ranks at 200k DOFs, docs/scaling.md)
        temporaries = [Ym, C, delta]
        for lvl, M in enumerate(self._levels):
            M.axpy(1.0, delta, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
            if lvl + 1 < len(self._levels):
                delta = delta.ptap(self._P[lvl + 1])
                temporaries.append(delta)
        for T in temporaries:
            T.destroy()

    def solve(self, Amat, b, x, atol: float, what: str, coarse=None) -> int:
        """x = Amat⁻¹ b to ‖b − Amat x‖ ≤ atol, preconditioned by the V-cycle; ``coarse`` =
        (D, robin) forms its coarse operators for that Newton system first (:meth:`coarse`),
        otherwise it keeps those of the last one."""
        if coarse is not None:
            if self._levels is None:
                self.ksp.getPC().setReusePreconditioner(False)
            else:
                self.coarse(*coarse)
        elif self._levels is None:
            self.ksp.getPC().setReusePreconditioner(True)
        self.uses += 1
        self.ksp.setOperators(Amat, self.H)
        self.ksp.setTolerances(rtol=0.0, atol=atol, max_it=self.max_iter)
        self.ksp.setConvergenceHistory(reset=True)
        self.ksp.solve(b, x)
        its = self.ksp.getIterationNumber()
        if self.ksp.getConvergedReason() <= 0:
            history = list(self.ksp.getConvergenceHistory())
            raise KrylovNotConverged(f"{what}: PETSc GMRES stopped ({_reason(self.ksp.getConvergedReason())}) "
                                     f"after {its} iterations at residual {self.ksp.getResidualNorm():.3e} "
                                     f"(asked {atol:.3e})", history)
        return its

    def destroy(self):
        for M in getattr(self, "_ref", ()):     # the reference copies are this hierarchy's own
            M.destroy()
        self.ksp.destroy()


def _reason(code: int) -> str:
    PETSc = petsc()
    names = {v: k for k, v in vars(PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
    return names.get(code, str(code))


class PetscNewton:
    """The Newton systems of one design on the distributed body ``dist``: A(α) twice, ``A``
    (MPIBAIJ, block size 3) for every product and ``A_aij`` (MPIAIJ, the same values; the caller
    assembles both) for GAMG, which takes AIJ only; ``G`` a matrix of A's type and pattern, H one
    of A_aij's (module docstring)."""

    def __init__(self, dist, A, A_aij, G):
        PETSc = petsc()
        self.dist, self.A, self.A_aij = dist, A, A_aij
        self.G, self.H = G, A_aij.duplicate()
        for M in (self.G, self.H):      # zeroed rows and columns stay in the pattern (GAMG reuses it)
            M.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        self.comm = A.getComm()
        cd = dist.contact
        self.cd = cd
        self.p = cd.shape[0]
        idx = PETSc.IS().createGeneral(cd.ravel().astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        self._cvec = PETSc.Vec().createSeq(cd.size, comm=PETSc.COMM_SELF)
        self._cscatter = PETSc.Scatter().create(A.createVecRight(), idx, self._cvec, None)
        self._all_scatter, self._all = PETSc.Scatter.toAll(A.createVecRight())
        self._d_signature = None      # D of the last Newton system whose coarse operators were formed
        self.refresh_pc = True
        self.coarse = None            # (D, Robin blocks) of the system whose coarse operators are due

    def refresh(self, indptr, cols, data):
        """Keep the normal rows of A(α) at the owned contact nodes (the friction coupling of the
        Newton systems) from the owned rows of a new design (CSR: PETSc columns, as assembled)."""
        d = self.dist
        own = np.flatnonzero(d.owns_contact)
        rows = self.cd[own, 2] - d.rstart
        count = np.zeros(self.p, dtype=np.int64)
        count[own] = indptr[rows + 1] - indptr[rows]
        self._nptr = np.concatenate([[0], np.cumsum(count)])
        take = _ranges(indptr[rows], count[own])
        self._ncols, self._nvals = cols[take], data[take]

    # ------------------------------------------------------------------ gathers
    def at_contact(self, vec) -> np.ndarray:
        """(p, 3) values of a PETSc vector at the contact DOFs, on every rank."""
        PETSc = petsc()
        self._cscatter.scatter(vec, self._cvec, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return self._cvec.getArray().reshape(self.p, 3).copy()

    def everywhere(self, vec) -> np.ndarray:
        """All entries of a PETSc vector, on every rank."""
        PETSc = petsc()
        self._all_scatter.scatter(vec, self._all, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return self._all.getArray().copy()

    def set_owned(self, vec, dofs: np.ndarray, values: np.ndarray) -> None:
        """vec[dofs] = values for the dofs (PETSc, any rank's) this rank owns."""
        dofs = np.asarray(dofs, dtype=np.int64)
        own = (dofs >= self.dist.rstart) & (dofs < self.dist.rend)
        arr = vec.getArray()
        arr[dofs[own] - self.dist.rstart] = np.broadcast_to(values, dofs.shape)[own]

    # ------------------------------------------------------------------ Newton systems
    def system(self, stick, slide, tvec, k, coupling):
        """Fill H = A + K_t and G = (I − C_N) H (rows and columns of D: a unit row) for the
        node classes of one Newton piece (nodes ``stick``, ``slide``; per sliding node its Robin
        block k t tᵀ and coupling c); returns the boolean D over all PETSc DOFs."""
        PETSc = petsc()
        d = self.dist
        cd = self.cd
        D = np.zeros(d.n, dtype=bool)
        D[cd[stick].ravel()] = True
        D[cd[slide, 2]] = True
        own = d.owns_contact[slide]
        sl = slide[own]
        blk = k[own, None, None] * tvec[own, :, None] * tvec[own, None, :]
        c = coupling[own]
        same, add = PETSc.Mat.Structure.SAME_NONZERO_PATTERN, PETSc.InsertMode.ADD
        # coarse operators of a D that differs in a few DOFs still precondition well (GMRES pays
        # about an iteration per DOF); more than REFRESH_CHANGES of them: form them anew. H is
        # GAMG's matrix only, so it is filled for a refresh only
        self.refresh_pc = (self._d_signature is None
                           or np.count_nonzero(self._d_signature != D) > REFRESH_CHANGES * cd.size)
        if self.refresh_pc:
            self._d_signature = D
        rows = (np.flatnonzero(D[d.rstart:d.rend]) + d.rstart).astype(PETSc.IntType)
        tt = cd[sl, :2].astype(PETSc.IntType)
        # the rows the sliding nodes change, owned rows only, as CSR: the Robin blocks k t tᵀ
        # (rows t1, t2; columns t1, t2) and, in G, the normal row times c (rows t1, t2)
        order = np.argsort(tt[:, 0], kind="stable")
        tt_o = tt[order]
        robin = self._local_csr(tt_o.ravel(), np.full(2 * sl.size, 2),
                                np.repeat(tt_o, 2, axis=0).ravel(), blk[order].ravel())
        n0, n1 = self._nptr[sl[order]], self._nptr[sl[order] + 1]
        take = _ranges(np.repeat(n0, 2), np.repeat(n1 - n0, 2))
        scale = np.repeat(-c[order].ravel(), np.repeat(n1 - n0, 2))
        coupling = self._local_csr(tt_o.ravel(), np.repeat(n1 - n0, 2), self._ncols[take],
                                   scale * self._nvals[take])
        for M, base in ((self.G, self.A), (self.H, self.A_aij)) if self.refresh_pc else ((self.G, self.A),):
            base.copy(M, structure=same)
            M.setValuesCSR(*robin, addv=add)
        self.G.setValuesCSR(*coupling, addv=add)
        for M in (self.G, self.H) if self.refresh_pc else (self.G,):
            M.assemble()
        self.G.zeroRowsColumns(rows, diag=1.0)
        if self.refresh_pc:
            self.H.zeroRowsColumns(rows, diag=1.0)
        self.coarse = (D, (tt, blk)) if self.refresh_pc else None
        return D

    def _local_csr(self, rows, lengths, cols, vals):
        """(indptr over the owned rows, columns, values) of the entries in ``rows`` (global, owned,
        increasing; ``lengths`` entries each, in that order): the form of ``Mat.setValuesCSR``."""
        PETSc = petsc()
        count = np.zeros(self.dist.n_local, dtype=np.int64)
        count[rows - self.dist.rstart] = lengths
        indptr = np.concatenate([[0], np.cumsum(count)]).astype(PETSc.IntType)
        return indptr, np.asarray(cols, dtype=PETSc.IntType), np.asarray(vals, dtype=np.float64)

    def plain(self):
        """G = A and H = A (the start solve's system and preconditioner); ``coarse`` their coarse
        operators' data (:meth:`PetscHierarchy.coarse`)."""
        PETSc = petsc()
        self._d_signature = None
        self.A.copy(self.G, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.A_aij.copy(self.H, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.coarse = (np.zeros(self.dist.n, dtype=bool), None)

    # ------------------------------------------------------------------ the state
    def solve(self, hier: PetscHierarchy, L, gap, friction, *, r0=None, u0=None, tol=1e-10, zone=None,
              rho_scale=0.5, max_steps=50, krylov_rtol=None, eta_max=1e-2, eta_factor=0.1,
              zone_margin=0.1, compliance=None, slip_ref=None, force_scale=None,
              raise_on_failure=True, polish_below=0.0, stall_forcing=None) -> FullSpaceResult:
        """The contact state of load ``L`` (PETSc Vec) and gaps ``gap`` (p,) from the warm start
        ``r0`` (p, 3; FCLIB order) or ``u0`` (a PETSc Vec); the arguments and the stopping rule as
        :func:`contactopt.contact.fullspace.solve_fullspace`, whose Newton loop
        (:func:`~contactopt.contact.fullspace.newton_loop`) runs here on :class:`PetscBackend`.
        ``compliance`` (p,): the part of the Delassus diagonal estimate beyond the local
        W_DIAG_FACTOR / mean(A_mm). ``slip_ref`` (p, 2): in a load step, u_t at the end of the
        previous step (the tangential law on u_t − slip_ref, as on the pyamg backend); None: the
        static problem. ``force_scale``: the residuals' scale when L = 0, as there. A failure raises
        :class:`~contactopt.errors.ContactNotConverged` unless ``raise_on_failure`` is False
        (:class:`PetscProblem` reads the result instead)."""
        t_start = time.perf_counter()
        p, cd = self.p, self.cd
        A = self.A
        st = start(friction, p, tol, krylov_rtol, zone)
        timings = st.timings
        Lnorm = L.norm() or force_scale or 1.0
        rho_all = rho_of(self._diag_at_contact(), 0.0 if compliance is None else compliance, rho_scale)
        u = A.createVecRight()

        t0 = time.perf_counter()
        krylov_its = []
        # the coarse operators are formed anew at the first Newton system of every solve and when D
        # changes, not for Newton steps of the same D: a solve depends on its own data only (and on
        # the hierarchy's prolongations), so a resumed run repeats the uninterrupted one
        self._d_signature = None
        if u0 is None:
            f = L.copy()
            if r0 is not None:
                rz = start_forces(r0, st.zone, p)
                arr = f.getArray()
                own = self.dist.owns_contact
                arr[cd[own].ravel() - self.dist.rstart] += rz[own].ravel()
            self.plain()
            eta0 = max(st.krylov_rtol, 1e-6)
            krylov_its.append(hier.solve(self.G, f, u, eta0 * f.norm(), "full-space start solve",
                                         coarse=self.coarse))
        else:
            u0.copy(u)
        timings["start"] = time.perf_counter() - t0

        shift = None if slip_ref is None else np.asarray(slip_ref, dtype=np.float64).reshape(p, 2)
        backend = PetscBackend(self, hier, L, gap, Lnorm, krylov_its, shift)
        out = newton_loop(backend, u, st.zone, gap=gap, mu_all=st.mu, rho_all=rho_all, tol=tol, max_steps=max_steps,
                          krylov_rtol=st.krylov_rtol, eta_max=eta_max, eta_factor=eta_factor, zone_margin=zone_margin,
                          timings=timings, t_start=t_start, shift=shift, polish_below=polish_below,
                          stall_forcing=stall_forcing)
        u_all = self.everywhere(u)
        return finish(backend, out, u_c=u_all[cd], tol=tol, t_start=t_start, timings=timings,
                      krylov_iterations=krylov_its, u_all=u_all, raise_on_failure=raise_on_failure)

    def _diag_at_contact(self) -> np.ndarray:
        d = self.A.getDiagonal()
        return self.at_contact(d)

    # ------------------------------------------------------------------ the adjoint (4.15)
    def adjoint(self, hier: PetscHierarchy, stick, slide, free_lam, u_c, lam, y_u, y_lam, friction, *,
                rtol: float):
        """(ṽ on all PETSc DOFs, v_u (3p), v_λ (p), GMRES iterations, (A ṽ)_c = S v_u (3p)) of the
        adjoint system (4.15) of a state whose nodes ``stick`` are of class M3+, ``slide`` of class
        M1, ``free_lam`` not of class L (after the degenerate choices); ``u_c`` (p, 3) the friction
        law's displacement per node (t1, t2, ν) (in a load step: the slip increment in t1, t2),
        whose tangential direction a sliding node's frame is; ``y_u`` ∂J/∂u_c (3p), or g = ∂J/∂u
        on every PETSc DOF (every rank holds it whole) for an objective of the whole displacement,
        whose interior rows then read (A ṽ)_i = −g_i. The transpose of the state's Newton system at
        the solution (:mod:`contactopt.sensitivity.adjoint_fullspace`, whose docstring derives
        it), solved with the transposed products of G and the same GAMG hierarchy (H is symmetric), to
        a residual ≤ ``rtol``·‖right-hand side‖."""
        cd, d = self.cd, self.dist
        tvec, k, coupling = sliding_frame(u_c, lam, slide, friction)
        D = self.system(stick, slide, tvec, k, coupling)
        v0c = known_adjoint_part(self.p, stick, slide, y_lam)
        v0, rhs, x, Av = (self.A.createVecRight() for _ in range(4))
        self.set_owned(v0, cd.ravel(), v0c.ravel())
        # rhs = −Bᵀy*_u − (A + K_t) v0 on I (K_t v0 = 0: v0 is zero on tangential DOFs); −g on
        # every owned row for y_u on every DOF
        self.A.mult(v0, rhs)
        rhs.scale(-1.0)
        arr = rhs.getArray()
        y_u = np.asarray(y_u, dtype=np.float64)
        if y_u.size == d.n:
            arr -= d.owned(y_u)
            y_u = y_u[cd.ravel()]
        else:
            own = d.owns_contact
            arr[cd[own].ravel() - d.rstart] -= y_u.reshape(-1, 3)[own].ravel()
        arr[D[d.rstart:d.rend]] = 0.0
        scale = max(rhs.norm(), 1e-300)
        # Gᵀ as G's transposed product (MatMultTranspose of a BAIJ matrix costs what its MatMult
        # does; PETSc 3.18's explicit MPIBAIJ transpose into an existing matrix is wrong on 2 ranks)
        Gt = petsc().Mat().createTranspose(self.G)
        its = hier.solve(Gt, rhs, x, rtol * scale, "full-space adjoint (4.15)", coarse=self.coarse)
        xa = x.getArray()
        xa[D[d.rstart:d.rend]] = 0.0
        # ṽ = lift(x) + v0: the normal DOF of a sliding node from its tangential ones, −cᵀx_t
        xc = self.at_contact(x)
        lift = -(coupling[:, 0] * xc[slide, 0] + coupling[:, 1] * xc[slide, 1])
        self.set_owned(x, cd[slide, 2], lift)
        x.axpy(1.0, v0)
        self.A.mult(x, Av)
        force = self.at_contact(Av).ravel()
        resid = force + y_u
        v_lam = np.where(free_lam, -resid[2::3], 0.0)
        v_all = self.everywhere(x)
        return v_all, v_all[cd].ravel(), v_lam, its, force

    def product(self, x_all: np.ndarray) -> np.ndarray:
        """A(α) x on every PETSc DOF, on every rank, for x on every PETSc DOF (every rank holds it)."""
        x, y = self.A.createVecRight(), self.A.createVecLeft()
        x.getArray()[:] = self.dist.owned(np.asarray(x_all, dtype=np.float64))
        self.A.mult(x, y)
        return self.everywhere(y)


class PetscProblem(FullSpaceProblem):
    """The PETSc backend's Newton method as a :class:`contactopt.contact.fallback.FallbackProblem`:
    the chain of :class:`FullSpaceProblem` (cold restart, continuation in F, continuation in the
    load) run with :meth:`PetscNewton.solve` on every rank. Every decision of the chain reads the
    converged flag and the error, which are global reductions, so all ranks take the same attempts.
    W is not formed under MPI: the diagnosis names a penetrating start and points to the
    full-space path's (one process) for the check of a rigid motion or an unbalanced load.

    Sign convention as the full-space method's: per contact node (t1, t2, ν), g ≥ 0 the initial
    clearance, λ ≥ 0 pressing the body off its counterpart."""

    def __init__(self, newton: "PetscNewton", hierarchy: "PetscHierarchy", L, gap, friction, **options):
        super().__init__(None, L, newton.cd, gap, friction, what="the contact state (PETSc)", **options)
        self.newton, self.hierarchy = newton, hierarchy
        self.first_name = self.first_name.replace("full-space Newton", "full-space Newton (PETSc)")

    def _solve(self, *, L=None, friction=None, **over):
        kw = {**self.options, **over, "raise_on_failure": False}
        return self.newton.solve(self.hierarchy, self.L if L is None else L, self.gap,
                                 self.friction if friction is None else friction, **kw)

    def scaled_load(self, t: float):
        """t·L as a new PETSc Vec (L itself is not changed)."""
        v = self.L.copy()
        v.scale(t)
        return v

    def diagnose(self, best) -> str:
        found = penetrating_start(np.asarray(self.gap, dtype=float))
        return "The model: " + "; ".join(found or [
            "no penetrating start; the PETSc path does not form W for the check of a rigid motion or an "
            "unbalanced load: solve the model with [linear_solver] path = \"fullspace\" in one process for that "
            "diagnosis, or check body.clamped, the loads and the initial gap"]) + "."


class PetscBackend:
    """:class:`~.core.NewtonBackend` on PETSc Vecs for one solve of
    ``newton`` (:class:`PetscNewton`): u and the directions are distributed Vecs, the Newton
    systems are assembled as G and H by :meth:`PetscNewton.system` and solved by ``hier``'s GMRES
    (appending their iterations to ``krylov_its``); per contact node the values are gathered on
    every rank in the order (t1, t2, ν), r = (A u − L)_c the contact force on the body, so every
    rank takes the same decisions. The update u ← u + t du is in place. ``shift`` (p, 2): a load
    step's reference u_t — a sticking node's u_t is held at it, a sliding node's Robin rows act on
    u_t − shift."""

    label = "full-space Newton (PETSc)"

    def __init__(self, newton, hier, L, gap, Lnorm, krylov_its, shift=None):
        self.newton, self.hier, self.L, self.gap, self.Lnorm = newton, hier, L, gap, Lnorm
        self.krylov_its, self.shift = krylov_its, shift
        self.n = newton.dist.n
        self.w, self.x, self.rhs, self.du, self.Adu, self.mask, self.e_t = (
            newton.A.createVecRight() for _ in range(7))

    def contact_force(self, u):
        """r(u) = (A u − L)_c per node (t1, t2, ν); A u − L stays in ``w``."""
        self.newton.A.mult(u, self.w)
        self.w.axpy(-1.0, self.L)
        return self.newton.at_contact(self.w)

    def residual(self, u, z):
        nw = self.newton
        self.mask.set(1.0)
        nw.set_owned(self.mask, nw.cd[z].ravel(), 0.0)
        rphys = self.contact_force(u)
        uc = nw.at_contact(u)
        e_other = self.w.copy()
        e_other.pointwiseMult(e_other, self.mask)
        e_norm = e_other.norm()
        return rphys, uc, e_other, 0.5 * e_norm ** 2, e_norm / self.Lnorm

    def newton_step(self, u, uc, stick, slide, tvec, k, coupling, eta, step):
        nw, gap, x, rhs = self.newton, self.gap, self.x, self.rhs
        cd, d = nw.cd, nw.dist
        t0 = time.perf_counter()
        D = nw.system(stick, slide, tvec, k, coupling)
        # x0: the current iterate with the Dirichlet values of D
        x0c = uc.copy()
        x0c[stick] = 0.0
        if self.shift is not None:
            x0c[stick, :2] = self.shift[stick]
        x0c[stick, 2] = -gap[stick]
        x0c[slide, 2] = -gap[slide]
        x0 = u.copy()
        nw.set_owned(x0, cd[stick].ravel(), x0c[stick].ravel())
        nw.set_owned(x0, cd[slide, 2], x0c[slide, 2])
        # rhs = (I − C_N)(L − A x0 − K_t (x0 − shift)) on I, 0 on D
        nw.A.mult(x0, rhs)
        rhs.aypx(-1.0, self.L)
        xk = x0c
        if self.shift is not None:
            xk = x0c.copy()
            xk[:, :2] -= self.shift
        self._robin_and_couple(rhs, xk, slide, tvec, k, coupling)
        arr = rhs.getArray()
        arr[D[d.rstart:d.rend]] = 0.0
        t1 = time.perf_counter()
        its = self.hier.solve(nw.G, rhs, x, eta * self.Lnorm, f"full-space Newton step {step}",
                              coarse=nw.coarse)
        xa = x.getArray()
        xa[D[d.rstart:d.rend]] = 0.0      # D rows are decoupled: exact zeros
        t2 = time.perf_counter()
        self.krylov_its.append(its)
        # du = x0 + x − u
        x0.axpy(1.0, x)
        x0.axpy(-1.0, u)
        x0.copy(self.du)
        return self.du, {"newton": t1 - t0, "krylov": t2 - t1}

    def _robin_and_couple(self, vec, xc, slide, tvec, k, coupling):
        """vec ← (I − C_N)(vec − K_t x) at the owned sliding nodes: ``xc`` x at the contact DOFs
        per node (t1, t2, ν); per sliding node its direction t (t1, t2), Robin k, coupling c = μn."""
        d, cd = self.newton.dist, self.newton.cd
        own = d.owns_contact[slide]
        if not own.any():
            return
        sl, tv, kk, c = slide[own], tvec[own], k[own], coupling[own]
        arr = vec.getArray()
        kt_x = kk[:, None] * tv * np.einsum("ij,ij->i", tv, xc[sl, :2])[:, None]
        for a in range(2):
            arr[cd[sl, a] - d.rstart] -= kt_x[:, a]
        vn = arr[cd[sl, 2] - d.rstart]
        for a in range(2):
            arr[cd[sl, a] - d.rstart] -= c[:, a] * vn

    def line(self, du, e_other):
        nw = self.newton
        nw.A.mult(du, self.Adu)
        dr = nw.at_contact(self.Adu)
        duc = nw.at_contact(du)
        de_other = self.Adu.copy()
        de_other.pointwiseMult(de_other, self.mask)
        e_t = self.e_t

        def theta_other(t):
            e_t.waxpy(t, de_other, e_other)
            return 0.5 * e_t.norm() ** 2
        return dr, duc, theta_other

    def advance(self, u, t, du):
        u.axpy(t, du)
        return u

    def max_abs(self, u) -> float:
        return float(u.norm(petsc().NormType.NORM_INFINITY))
