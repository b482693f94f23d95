"""The PETSc path: the full-space semismooth Newton method and its adjoint under MPI (petsc4py).

``[linear_solver] path = "petsc"`` (or "auto" under ``mpiexec`` with more than one rank). The
method is the full-space path's (:mod:`contactopt.paths.fullspace`), its linear algebra PETSc's
(:mod:`contactopt.contact.fullspace.petsc`, the PETSc backend of the one full-space method): the mesh split over the ranks by recursive coordinate
bisection (:mod:`contactopt.fem.distributed`), each rank assembling the rows of its nodes into an
MPIBAIJ matrix of block size 3 (and an MPIAIJ copy for GAMG), GMRES with GAMG (rigid-body
near-null space) whose prolongations are kept from the design they were built at, the adjoint
(4.15) by the transposed products of the Newton matrix, and the design terms ṽᵀ(∂A/∂α)u summed per rank over its own elements and reduced.
Contact conventions as everywhere: per node (t1, t2, ν), λ = r_ν ≥ 0 on the body, warm starts
per node (N, T1, T2).

How the ranks share one optimization: rank 0 runs everything above the path interface (the
bundle method, the objective, the run directory) as on one process; the other ranks run
:func:`contactopt.ranks.serve`. Every call of rank 0 on this path that needs the other ranks (prepare, for_load,
solve_state, adjoint, the design terms, a checkpoint's context) first sends them its arguments
(α's mesh coordinates and loads, a load step's slip reference u_t^(k−1), not matrices), then all
ranks do the call together; states and adjoints come back on every rank (the contact forces and
displacements are gathered, u and ṽ too), so the other ranks repeat rank 0's decisions and hold the same warm starts. A checkpoint
holds the same arrays as the pyamg path's (the displacement in the model's DOF order, the design
of the hierarchy; on a load path those of every step), so a run resumes with any number of ranks.
Load steps as on the pyamg path (:mod:`contactopt.sensitivity.steps`): the Newton holds a sticking
node's u_t at the previous step's and its Robin rows act on the slip increment, the adjoint's
sliding frames are the slip increment's, and (A ṽ)_c of each adjoint carries back to the step
before. An objective of the whole displacement (peak stress, friction work) is evaluated on rank 0
from the gathered u; its ∂J/∂u = g, on every DOF, goes to the ranks with the adjoint call (each
subtracts its rows of g), the carry to the previous step is (A ṽ)_c + g_c, and the friction work's
A(α) ũ is multiplied on the ranks (``PetscSystem.product``). ``[linear_solver] petsc_options``
goes to PETSc's options database (``-ksp_view``, ``-log_view``, ``-pc_gamg_*``).
"""

from __future__ import annotations

import itertools
import logging
import time
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np

from ..contact.fallback import run_chain
from ..contact.fullspace.petsc import PetscHierarchy, PetscNewton, PetscProblem
from ..contact.state import RigidAnchor
from ..errors import ConfigError, SolverError
from ..fem.distributed import DistributedBodies, DistributedBody
from ..fem.model import Assembled
from ..sensitivity.adjoint_fullspace import ADJOINT_RTOL, adjoint_classes, check_default_choices
from .base import Adjoint, Capabilities, Context, SolverPath, SystemParts
from .coupled import FullSpaceCouple
from .coupled import force_terms as coupled_force_terms
from .floating import first_anchored_solve, floating_anchor, iterate_anchor
from .fullspace import COUPLED_FORCING, FREE_NEWTON_STEPS, SOFT_ANCHOR_STEPS, FullSpaceCommon, refuse_counterparts
from .protocol import Call, Command, Problem, new_path_id, send
from .transforms import FrameChange

log = logging.getLogger(__name__)


def _world():
    from mpi4py import MPI
    return MPI.COMM_WORLD


@dataclass
class PetscSystem(SystemParts):
    """One design's system of one load case: ``assembled`` (A(α) not formed: ``A`` is None), the
    load ``L`` as a PETSc Vec, the last state's u and adjoint ṽ on all PETSc DOFs (every rank);
    on rank 0 ``product``, x ↦ A(α) x on the free DOFs computed on the ranks (what an objective
    of the whole displacement asks of A(α): the friction work's A ũ)."""

    key: int
    assembled: Assembled
    gap: np.ndarray
    L: object
    timings: dict
    u_all: np.ndarray | None = None
    v_all: np.ndarray | None = None
    product: object = None
    couple: FullSpaceCouple | None = None   # elastic counterparts in the Newton system (.coupled)
    shift: np.ndarray | None = None    # a force-controlled counterpart's tangential translation (p, 2), or None
    moved: float = 0.0                 # ... its translation s (.force)
    normal: np.ndarray | None = None   # (p,) the Newton matrix's diagonal at the contact nodes' normal DOFs
    anchor: object = None              # counterparts held only by their contacts (.floating), or None


@dataclass
class PetscContext(Context):
    """Also ``u_all``: the case's last displacement on all PETSc DOFs (Newton's warm start), and
    (rank 0) ``adjoint_force`` = (A ṽ)_c of its last adjoint, what a load step passes back."""

    key: int = 0
    u_all: np.ndarray | None = None
    adjoint_force: np.ndarray | None = None
    adjoint_rhs_c: np.ndarray | None = None   # with counterparts: the contact part of Tᵀ(∂J/∂u, 0)


class PetscPath(FullSpaceCommon):
    """``[linear_solver] path = "petsc"`` (module docstring)."""

    name = "petsc"
    newton_label = "PETSc full-space Newton"
    capabilities = Capabilities(foundation=True, pairs=True, counterpart_force=True, obstacle=True, pinned=True,
                                whole_displacement=True, many_ranks=True, load_steps=True, held_by_contact=True,
                                libraries=("petsc4py",),
                                sparse="petsc", auto="ranks")
    condenses_counterparts = False      # elastic counterparts join the Newton system (.coupled)

    def __init__(self, model, settings, start=None):
        """On rank 0 under mpiexec the other ranks first build the problem of the model's
        configuration (:class:`~contactopt.paths.protocol.Problem`): the PETSc objects are made by
        all ranks."""
        super().__init__(model, settings, start)
        from petsc4py import PETSc

        self.library = "petsc"
        self.id = new_path_id()
        comm = PETSc.COMM_WORLD
        self.size, self.rank = comm.getSize(), comm.getRank()
        self.leader = self.rank == 0 and self.size > 1
        if self.leader:
            send(Problem(self.id, model.config))
        _set_options(model.config.linear_solver.petsc_options)
        t0 = time.perf_counter()
        # the change of unknowns u = T u_loc of the Newton system: elastic counterparts' (.coupled: both
        # bodies), an obstacle's nodes' frames (.transforms.FrameChange), or none (the plane)
        self.couple = self.change = None
        if model.foundation is not None:
            refuse_counterparts(model, self.name)
            self.couple = self.change = FullSpaceCouple(model.foundation, model.contact_dofs, model.assembler.n_free,
                                                        self.mechanics.frames)
        elif self.mechanics.frames is not None:
            self.change = FrameChange(model.contact_dofs, self.mechanics.frames, model.assembler.n_free)
        if self.change is not None:
            self.dist = dist = DistributedBodies(model, self.change.T, list(self.change.parts), self.size, self.rank,
                                                 law_dofs=self.change.cd, pinned=self.change.pinned_nodes)
            for part in self.change.parts:    # K_f, formed with the model, is not formed again here
                part.assembler.release(pattern=True)
            self._T_inv = None          # T⁻¹, for A(α) x of an objective (built on first use)
        else:
            self.dist = dist = DistributedBody(model, self.size, self.rank)
        coords = model.body.reference.points
        indptr, cols, data = dist.owned_stiffness(coords)
        size = ((dist.n_local, dist.n), (dist.n_local, dist.n))
        A_aij = PETSc.Mat().createAIJ(size=size, bsize=3, comm=comm)
        A_aij.setPreallocationCSR((indptr, cols))
        bip, bcols, _ = dist.owned_blocks(data)
        # A and G made alike, not G by MatDuplicate: PETSc 3.18's duplicate of a BAIJ matrix
        # multiplies with the general block kernel, 3× slower than the 3×3 one
        A, G = (PETSc.Mat().createBAIJ(size=size, bsize=3, csr=(bip, bcols), comm=comm) for _ in range(2))
        for M in (A, A_aij, G):
            M.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        self.newton = PetscNewton(dist, A, A_aij, G)
        self._assemble_matrix(coords, (indptr, cols, data))
        self._hier = None            # the GAMG hierarchy ...
        self.hierarchy_alpha = None  # ... built at this design (checkpoints rebuild it)
        self._systems: dict = {}
        self._contexts: dict = {}
        self._keys = itertools.count(1)
        self._ctx_keys = itertools.count(1)
        self._design_key = None      # the design whose A(α) the matrix holds
        log.info("PETSc path on %d rank(s): %d DOFs, %d owned here, %d elements (+%d at the "
                 "interfaces), %.2f s", self.size, dist.n, dist.n_local, dist.n_elements,
                 dist.n_ghost_elements, time.perf_counter() - t0)

    def _call(self, command: Command, *args):
        """Rank 0: the other ranks make the same call (:func:`contactopt.ranks.serve`); then this rank's."""
        if self.leader:
            send(Call(self.id, command, args))
        return self.handlers[command](self, *args)

    # ------------------------------------------------------------------ designs and loads
    def assemble(self, alpha, loads=None) -> Assembled:
        """The design's coordinates, load and gaps; A(α) is assembled on the ranks by :meth:`prepare`."""
        m = self.model
        alpha = m.surface.as_vector(alpha)
        coords = m.mesh.coordinates(alpha)
        L_full = m.load_vector(coords, loads)
        return Assembled(alpha, coords, None, L_full, m.free_load(L_full), m.gap_matrix @ alpha + m.gap0)

    def prepare(self, asm) -> PetscSystem:
        key = next(self._keys)
        return self._with_product(self._call(Command.PREPARE, key, asm.alpha, asm.coords, asm.L_full, asm.gap))

    def for_load(self, system, asm) -> PetscSystem:
        key = next(self._keys)
        return self._with_product(self._call(Command.FOR_LOAD, system.key, key, asm.L_full))

    def _with_product(self, system):
        system.product = lambda x_free: self.stiffness_product(system, x_free)
        return system

    def stiffness_product(self, system, x_free) -> np.ndarray:
        """A(α) x (free DOFs, the model's order) of the system's design, multiplied on the ranks;
        with elastic counterparts as T⁻ᵀ (Tᵀ diag(A, K_f) T) T⁻¹ (x, 0), the body's rows."""
        d = self.dist
        x = np.asarray(x_free, dtype=float)
        if self.change is None:
            return d.free_vector(self._call(Command.PRODUCT, system.key, d.petsc_of_free(x)))
        if self._T_inv is None:
            self._T_inv = self.change.inverse()
        x_loc = self._T_inv @ np.concatenate([x, np.zeros(self.change.n - x.size)])
        y_loc = d.free_vector(self._call(Command.PRODUCT, system.key, d.petsc_of_free(x_loc)))
        return (self._T_inv.T @ y_loc)[:x.size]

    @property
    def n_unknowns(self) -> int:
        """The Newton system's unknowns: the body's free DOFs, and the counterparts' with them."""
        return self.model.assembler.n_free if self.change is None else self.change.n

    def _product(self, skey, x_all):
        if self._design_key is None or skey not in self._systems:
            raise RuntimeError("the PETSc matrix no longer holds the design of this system")
        return self.newton.product(x_all)

    def _prepare(self, key, alpha, coords, L_full, gap):
        t0 = time.perf_counter()
        self._assemble_matrix(coords)
        self._systems.clear()              # the systems of earlier designs are not asked again
        asm = Assembled(np.asarray(alpha), coords, None, L_full, self.model.free_load(L_full), gap)
        self._design_key = key
        shift = None if self.mechanics.shift is None else self.mechanics.shift.tangential
        system = PetscSystem(key, asm, gap, self._load(L_full), {}, couple=self.couple, shift=shift,
                             normal=self.newton._diag_at_contact()[:, 2],     # collective: every rank
                             anchor=self._anchor())
        system.timings["petsc_assembly"] = time.perf_counter() - t0
        self._systems[key] = system
        return system

    def _for_load(self, base_key, key, L_full):
        base = self._systems[base_key]
        asm = Assembled(base.assembled.alpha, base.assembled.coords, None, L_full,
                        self.model.free_load(L_full), base.gap)
        system = PetscSystem(key, asm, base.gap, self._load(L_full), {}, couple=self.couple, shift=base.shift,
                             normal=base.normal, anchor=base.anchor)
        self._systems[key] = system
        return system

    def _assemble_matrix(self, coords, csr=None):
        """A(α) of ``coords`` into both of the Newton's matrices (block size 3: BAIJ for the
        products, AIJ for GAMG); ``csr`` the owned rows if already computed."""
        indptr, cols, data = csr if csr is not None else self.dist.owned_stiffness(coords)
        self._owned, self._anchor_on = (indptr, cols, data), None
        self._insert(indptr, cols, data)

    def _insert(self, indptr, cols, data):
        """Owned rows (CSR, PETSc columns) into both Newton matrices."""
        from petsc4py import PETSc
        nw = self.newton
        nw.A_aij.setValuesCSR(indptr, cols, data, addv=PETSc.InsertMode.INSERT)
        bip, bcols, bdata = self.dist.owned_blocks(data)
        nw.A.setValuesBlockedCSR(bip, bcols, bdata, addv=PETSc.InsertMode.INSERT)
        for M in (nw.A, nw.A_aij):
            M.assemble()
        nw.refresh(indptr, cols, data)

    def _load(self, L_full):
        """L on the free DOFs as a PETSc Vec; with elastic counterparts Tᵀ(L, f_f) (.coupled)."""
        v = self.newton.A.createVecRight()
        d = self.dist
        L = self.model.free_load(L_full)
        if self.change is not None:
            L = self.change.T.T @ self.change.load(L)
        v.getArray()[:] = d.owned(d.petsc_of_free(L))
        return v

    # ------------------------------------------------------------------ counterparts held only by their contacts
    @property
    def _floating(self) -> bool:
        """Whether a body moves on its own: the face body or a counterpart held only by its contacts."""
        return self.mechanics.anchor is not None or (
            self.couple is not None and any(part.rigid is not None for part in self.couple.parts))

    def _anchor(self):
        """The anchor of the bodies held only by their contacts (:mod:`.floating`: the face body's,
        the counterparts') at the design the matrix holds, or None (every rank: the diagonal is
        gathered)."""
        if not self._floating:
            return None
        nw = self.newton
        return floating_anchor(self.couple, self.dist.free_vector(nw.everywhere(nw.A.getDiagonal())),
                               self.model if self.mechanics.anchor is not None else None)

    def _anchored(self, anchor, on: bool) -> None:
        """The Newton matrices with (``on``) or without the anchor's γ N Nᵀ (every rank, its owned rows)."""
        if (self._anchor_on is anchor) if on else (self._anchor_on is None):
            return
        indptr, cols, data = self._owned
        if on:
            d, M = self.dist, anchor.matrix.tocoo()
            rows, cc = d.dof_of_free[M.row], d.dof_of_free[M.col]
            own = (rows >= d.rstart) & (rows < d.rend)
            keys = np.repeat(np.arange(indptr.size - 1, dtype=np.int64), np.diff(indptr)) * d.n + cols
            want = (rows[own] - d.rstart) * np.int64(d.n) + cc[own]
            pos = np.searchsorted(keys, want)
            if np.any(pos >= keys.size) or np.any(keys[np.minimum(pos, keys.size - 1)] != want):
                raise RuntimeError("the anchor of a counterpart held only by its contacts is outside the pattern")
            data = data.copy()
            np.add.at(data, pos, M.data[own])
        self._insert(indptr, cols, data)
        self._anchor_on = anchor if on else None

    def _hierarchy(self, alpha, coords):
        """The GAMG hierarchy of the A(α) the matrix holds now."""
        if self._hier is not None:
            self._hier.destroy()
        self.newton.plain()
        if self.change is None:
            self._hier = PetscHierarchy(self.newton.G, self.newton.H, self.dist.coordinates(coords), self.dist.contact)
        else:
            self._hier = PetscHierarchy(self.newton.G, self.newton.H, None, self.dist.contact,
                                        modes_local=self._modes(coords))
        self.hierarchy_alpha = np.array(alpha, dtype=float)
        return self._hier.setup_seconds

    def _modes(self, coords) -> np.ndarray:
        """The owned rows of GAMG's near-null space in u_loc: the rigid modes of all bodies moving
        as one (:meth:`~.coupled.FullSpaceCouple.joint_modes`), orthonormalized over all DOFs (every
        rank holds them whole and takes the same QR)."""
        d = self.dist
        # a counterpart held only by its contacts moves on its own: its own six columns (measured on
        # two slabs, one held only by its contacts: 654 Krylov iterations of a state against 4027)
        M = (self.change.modes if self._floating else self.change.joint_modes)(coords, self.model.assembler.free)
        full = np.zeros((d.n, M.shape[1]))
        full[d.dof_of_free] = M
        Q, _ = np.linalg.qr(full)
        return Q[d.rstart:d.rend]

    # ------------------------------------------------------------------ states
    def new_context(self) -> PetscContext:
        return PetscContext(None, self.all_nodes, key=next(self._ctx_keys))

    def _context(self, key) -> PetscContext:
        if key not in self._contexts:
            self._contexts[key] = PetscContext(None, self.all_nodes, key=key)
        return self._contexts[key]

    def solve_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None):
        """As the full-space path's (:meth:`contactopt.paths.fullspace.FullSpacePath.solve_state`):
        through the force search of a counterpart pressed by a force, else :meth:`fixed_state`."""
        return self.transformed_state(system, ctx, alpha, method=method, warm_start=warm_start, tol=tol,
                                      shared=shared, label=label, slip_ref=slip_ref)

    def fixed_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None):
        """The state with the counterparts where ``system`` puts them; ``slip_ref`` (p, 2), a load
        step's reference u_t, the system's gaps and a translated counterpart's shift go to every
        rank with the call."""
        self._contexts.setdefault(ctx.key, ctx)
        ref = None if slip_ref is None else np.asarray(slip_ref, dtype=float)
        moved = (system.gap, system.shift, system.moved) if system.moved or system.shift is not None else None
        return self._call(Command.SOLVE, system.key, ctx.key, np.asarray(alpha, dtype=float), bool(warm_start),
                          tol, label, ref, moved)

    def normal_stiffness(self, system):
        """The Newton system's own diagonal at the normal DOFs (in u_loc, with counterparts)."""
        return system.normal

    def force_terms(self, system, ctx, state, v_lam, loads=None, *, v=None, y_u=None):
        """As :meth:`SolverPath.force_terms`; a counterpart pressed by a force in the unknowns of
        all bodies (:func:`.coupled.force_terms`)."""
        if system.couple is None:
            return super().force_terms(system, ctx, state, v_lam, loads, v=v, y_u=y_u)
        return coupled_force_terms(self, system, ctx, state, v_lam, loads, y_u)

    def _solve(self, skey, ckey, alpha, warm_start, tol, label, slip_ref=None, moved=None):
        stored, ctx = self._systems[skey], self._context(ckey)
        system = stored
        if moved is not None:            # a translated counterpart (.force): its gaps, shift and s
            system = replace(stored, gap=moved[0], shift=moved[1], moved=moved[2])
        t0 = time.perf_counter()
        if system.anchor is not None:    # the hierarchy of the anchored matrix (.floating)
            self._anchored(system.anchor, True)
        t_setup = self._hierarchy(alpha, system.assembled.coords) if self._hier is None else 0.0
        warm = ctx.warm if warm_start else None
        u0 = None
        if warm_start and warm is not None and ctx.u_all is not None:
            u0 = self.newton.A.createVecRight()
            u0.getArray()[:] = self.dist.owned(ctx.u_all)
        # the counterparts' translation q: gap g − q_ν, the slip's reference q_t; an obstacle's or a
        # pressed counterpart's tangential translation (the system's shift) joins the reference too
        gap, shift, forcing = system.gap, system.shift, {}
        if self.couple is not None:
            q = self.couple.offset
            gap = gap - q[:, 2]
            if np.any(q[:, :2]):
                shift = q[:, :2] if shift is None else shift + q[:, :2]
            forcing = COUPLED_FORCING
        if system.anchor is not None:    # (the Krylov error along a rigid motion the anchor barely holds)
            forcing = COUPLED_FORCING
        law_ref = slip_ref if shift is None else (shift if slip_ref is None else slip_ref + shift)
        scale = self.fit_scale(system.L.norm(), self.newton._diag_at_contact, gap,      # collective: every rank
                               held=system.anchor is not None)
        options = dict(slip_ref=law_ref, force_scale=scale, **self.newton_options(ctx, tol, warm_start), **forcing)
        held = None
        if system.anchor is None:
            res = run_chain(PetscProblem(self.newton, self._hier, system.L, gap, self.friction, r0=warm, u0=u0,
                                         **options))
        else:
            res, held = self._held_solve(system, gap, warm, u0, None if u0 is None else self.dist.free_vector(ctx.u_all),
                                         options)
        stored.u_all = system.u_all = ctx.u_all = res.u_all
        u_free, u_c, found = self.dist.free_vector(res.u_all), None, None
        if self.change is not None:
            u_free, u_f = self.change.split(u_free)
        if self.couple is not None:
            u_c = res.u_c - self.couple.offset          # the law's w
            found = self._foundation_state(self.couple, u_free, u_f, u_c, system.moved)
        if system.shift is not None:
            u_c = (res.u_c if u_c is None else u_c).copy()
            u_c[:, :2] -= system.shift
        state = self.state_of(ctx, system, alpha, res, u_free=u_free, u_c=u_c, t0=t0,
                              t_setup=t_setup, stats={"backend": "petsc", "ranks": self.size,
                                                      **({"fallback": res.fallback} if res.fallback else {})},
                              label=label, slip_ref=slip_ref, foundation=found)
        if held is not None:
            state.rigid = held
        return state

    def _held_solve(self, system, gap, warm, u0, u0_loc, options):
        """As the pyamg backend's :meth:`~.fullspace.FullSpacePath.held_solve` (:mod:`.floating`):
        the anchored problem at β₀ = Nᵀu₀, then from its state the Newton method on the unanchored
        matrix (at most ``FREE_NEWTON_STEPS`` steps), else the anchor's iteration; the matrices
        hold the unanchored values when it returns (the adjoint's and the products'). ``u0`` the
        warm start (a Vec) and ``u0_loc`` the same in u_loc, or None. Every rank."""
        an, d, nw = system.anchor, self.dist, self.newton

        def vec(x_loc):
            v = nw.A.createVecRight()
            v.getArray()[:] = d.owned(d.petsc_of_free(x_loc))
            return v

        current = [an]

        def solve(beta, last, fallbacks=True):
            self._anchored(current[0], True)
            L = system.L.copy()
            L.axpy(1.0, vec(current[0].load(beta, self.n_unknowns)))
            kw = dict(options, r0=warm, u0=u0)
            if last is not None:
                kw.update(r0=last.r, u0=vec(last.u), zone=last.zone)
            if fallbacks:
                res = run_chain(PetscProblem(nw, self._hier, L, gap, self.friction, **kw))
            else:
                res = nw.solve(self._hier, L, gap, self.friction, **dict(kw, max_steps=SOFT_ANCHOR_STEPS,
                                                                            raise_on_failure=False))
            return replace(res, u=d.free_vector(res.u_all))      # u_loc: what the anchor reads

        beta0 = np.zeros(an.N.shape[1]) if u0_loc is None else an.position(u0_loc)

        def stiffen():
            current[0] = current[0].stiffer()
        first = first_anchored_solve(solve, beta0, stiffen)
        an = current[0]
        self._anchored(an, False)
        try:
            free = nw.solve(self._hier, system.L, gap, self.friction, **dict(
                options, r0=first.r, u0=vec(first.u), zone=first.zone, max_steps=FREE_NEWTON_STEPS,
                raise_on_failure=False))
        except SolverError:              # a Newton system the contact does not hold: singular
            free = None
        if free is not None and free.converged:
            free.krylov_iterations = list(first.krylov_iterations) + list(free.krylov_iterations)
            free.newton_steps += first.newton_steps
            return free, RigidAnchor(iterations=1, residual=float(free.equilibrium))
        load_norm = system.L.norm() or options.get("force_scale") or 1.0
        res, held, iterations, steps = iterate_anchor(solve, an, (beta0, first), load_norm, options["tol"])
        self._anchored(an, False)
        spent = [] if free is None else list(free.krylov_iterations)
        res.krylov_iterations, res.newton_steps = iterations + spent, steps + (0 if free is None else free.newton_steps)
        return res, held

    # ------------------------------------------------------------------ adjoint and design terms
    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None, carry=None):
        """As :meth:`SolverPath.adjoint`; with elastic counterparts in the unknowns u_loc of all
        bodies (.coupled), ``carry`` (∂J/∂w of a later load step, with ∂J/∂u on every DOF of the
        body) joining at the contact DOFs, which hold w, and ṽ = (T ṽ_loc) on the body."""
        check_default_choices(choices)
        u_law = self.law_displacement(state)
        y_u = np.asarray(y_u, dtype=float)
        if self.is_full(y_u):            # ∂J/∂u on every DOF: its free part, in PETSc's order
            y_u = y_u[self.model.assembler.free]
            if self.change is not None:  # ... of the body, into u_loc
                y_u = self.change.extend(y_u)
                ctx.adjoint_rhs_c = y_u[self.change.cd].copy()
                if carry is not None:
                    y_u[self.change.cd] += carry
            y_u = self.dist.petsc_of_free(y_u)
        return self._adjoint_of(system, ctx, state, u_law, y_u, y_lam)

    def _adjoint_of(self, system, ctx, state, u_law, y_u, y_lam) -> Adjoint:
        """The adjoint call on every rank: ``y_u`` on the contact DOFs or on every PETSc DOF."""
        v_u, v_lam, its, force = self._call(Command.ADJOINT, system.key, np.asarray(state.classes), u_law,
                                            state.lam, y_u, np.asarray(y_lam, dtype=float))
        ctx.adjoint_force = force
        return Adjoint(v_u, v_lam, self.model.assembler.to_full(self._body_free(system.v_all)), int(its))

    # the hooks of :func:`.coupled.force_terms` (u_loc in the couple's order)
    def local_adjoint(self, system, ctx, state, y_loc, y_lam) -> Adjoint:
        """The adjoint of a right-hand side ``y_loc`` on every unknown of the Newton system."""
        return self._adjoint_of(system, ctx, state, self.law_displacement(state),
                                self.dist.petsc_of_free(np.asarray(y_loc, float)), y_lam)

    def law_product(self, system, x_loc) -> np.ndarray:
        d = self.dist
        return d.free_vector(self._call(Command.PRODUCT, system.key, d.petsc_of_free(np.asarray(x_loc, float))))

    def last_adjoint(self, system, ctx) -> np.ndarray:
        return self.dist.free_vector(system.v_all)

    def _body_free(self, x_all) -> np.ndarray:
        """The body's free DOFs of a vector on all PETSc DOFs (with counterparts: of T x_loc)."""
        x = self.dist.free_vector(x_all)
        return x if self.change is None else self.change.split(x)[0]

    def adjoint_force(self, system, ctx, v_u):
        """S v_u = (A ṽ)_c of the last adjoint of ``ctx`` (gathered on every rank by the adjoint)."""
        return ctx.adjoint_force

    def adjoint_carry(self, system, ctx, v_u, v_full, y_u):
        """As :meth:`SolverPath.adjoint_carry`: (A ṽ)_c + ∂J/∂u_c, (A ṽ)_c of the last adjoint of
        ``ctx`` (A(α) is not formed on rank 0)."""
        if not self.is_full(y_u):
            return ctx.adjoint_force + y_u
        if self.couple is not None:      # in u_loc, where the contact DOFs hold w (.fullspace)
            return ctx.adjoint_force + ctx.adjoint_rhs_c
        contact = (3 * self.model.contact_nodes[:, None] + np.arange(3)).ravel()
        return ctx.adjoint_force + np.asarray(y_u, float)[contact]

    def _adjoint(self, skey, classes, u_law, lam, y_u, y_lam):
        system = self._systems[skey]
        v_all, v_u, v_lam, its, force = self.newton.adjoint(self._hier, *adjoint_classes(classes), u_law, lam, y_u,
                                                            y_lam, self.friction, rtol=ADJOINT_RTOL)
        system.v_all = v_all
        return v_u, v_lam, its, force

    def design_contraction(self, system, u_full, v_full, loads=None) -> np.ndarray:
        """vᵀ(∂A/∂α u − ∂L/∂α): the stiffness part per rank over its own elements, summed on rank 0
        (u, v, the body's on every DOF, go with the call: a force search's last solve need not be
        the state's, and a force's adjoint term is of z = w̃ + ẽ)."""
        m = self.model
        u_full, v_full = m.unpin(np.asarray(u_full, float)), m.unpin(np.asarray(v_full, float))   # pinned: clamped
        part = self._call(Command.CONTRACTION, system.key, u_full, v_full)
        return part - m.mesh.contract_dx((loads or m.loads).shape_contraction(system.assembled.coords, v_full,
                                                                                m.assembler))

    def _contraction(self, skey, u_full, v_full):
        """This rank's part of vᵀ(∂A/∂α)u (the body's u, v on every DOF, model order), summed on rank 0."""
        from mpi4py import MPI
        system = self._systems[skey]
        part = self.dist.contraction(self.model, system.assembled.coords, u_full, v_full)
        total = np.zeros_like(part)
        _world().Reduce(part, total, op=MPI.SUM, root=0)
        return total

    # ------------------------------------------------------------------ checkpoints
    def last_displacement(self, ctx):
        return None if ctx.u_all is None else self.dist.free_vector(ctx.u_all)

    def restore(self, ctx, arrays, u_free, alpha, where):
        """Every rank puts back the case's displacement and rebuilds the GAMG hierarchy at its
        design (the arrays checked on rank 0 before any rank acts)."""
        self._contexts.setdefault(ctx.key, ctx)
        self._call(Command.IMPORT, ctx.key, {k: v for k, v in arrays.items() if k in ("warm", "zone", "u_free",
                                                                                 "jacobian_alpha")}, where)

    def _import(self, ckey, arrays, where):
        ctx = self._context(ckey)
        SolverPath.import_context(self, ctx, arrays, where)
        if arrays.get("u_free") is not None:
            ctx.u_all = self.dist.petsc_of_free(arrays["u_free"])
        a = arrays.get("jacobian_alpha")
        if a is not None and a.size:
            alpha = np.asarray(a, dtype=float)
            if self.hierarchy_alpha is None or not np.array_equal(self.hierarchy_alpha, alpha):
                coords = self.model.mesh.coordinates(self.model.surface.as_vector(alpha))
                self._assemble_matrix(coords)
                self._design_key = None
                anchor = self._anchor()      # the hierarchy of the anchored matrix, as when it was built
                if anchor is not None:
                    self._anchored(anchor, True)
                self._hierarchy(alpha, coords)
                if anchor is not None:
                    self._anchored(anchor, False)

    handlers = MappingProxyType({Command.PREPARE: _prepare, Command.FOR_LOAD: _for_load, Command.SOLVE: _solve,
                                 Command.ADJOINT: _adjoint, Command.CONTRACTION: _contraction,
                                 Command.PRODUCT: _product, Command.IMPORT: _import})   # what each rank runs for a command


def _set_options(text: str) -> None:
    """``[linear_solver] petsc_options`` ("-ksp_view -pc_gamg_threshold 0.01") into PETSc's
    options database."""
    if not text:
        return
    from petsc4py import PETSc
    opts = PETSc.Options()
    tokens = text.split()
    i = 0
    while i < len(tokens):
        key = tokens[i]
        if not key.startswith("-"):
            raise ConfigError([f"linear_solver.petsc_options: {key!r} is not an option (options start with '-')"])
        value = None
        if i + 1 < len(tokens) and not _is_option(tokens[i + 1]):
            value = tokens[i + 1]
            i += 1
        opts.setValue(key.lstrip("-"), value if value is not None else "")
        if key.startswith("-log_view"):
            PETSc.Log.begin()           # -log_view after PETSc's start: the events from here on
        i += 1


def _is_option(tok: str) -> bool:
    if not tok.startswith("-"):
        return False
    try:
        float(tok)
        return False
    except ValueError:
        return True
