"""The PETSc path: the full-space semismooth Newton method and its adjoint under MPI (petsc4py).

``[linear_solver] path = "petsc"`` (or "auto" under ``mpiexec`` with more than one rank). The
method is the full-space path's (:mod:`contactopt.paths.fullspace`), its linear algebra PETSc's
(:mod:`contactopt.contact.fullspace_petsc`): the mesh split over the ranks by recursive coordinate
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
(α's mesh coordinates and loads, not matrices), then all ranks do the call together; states and
adjoints come back on every rank (the contact forces and displacements are gathered, u and ṽ
too), so the other ranks repeat rank 0's decisions and hold the same warm starts. A checkpoint
holds the same arrays as the pyamg path's (the displacement in the model's DOF order, the design
of the hierarchy), so a run resumes with any number of ranks. ``[linear_solver] petsc_options``
goes to PETSc's options database (``-ksp_view``, ``-log_view``, ``-pc_gamg_*``).
"""

from __future__ import annotations

import itertools
import logging
import time
from dataclasses import dataclass

import numpy as np

from ..errors import CheckpointError, ConfigError, SolverError
from ..fem import memory
from ..fem.model import Assembled
from .base import Context, SolverPath, check_design
from .fullspace import FULLSPACE_TOL

log = logging.getLogger(__name__)

_ids = itertools.count(1)
_pending = [None]          # the id the next PetscPath of a serving rank takes
_served: dict = {}         # id -> PetscPath on a serving rank


def _world():
    from mpi4py import MPI
    return MPI.COMM_WORLD


@dataclass
class PetscSystem:
    """One design's system of one load case: ``assembled`` (A(α) not formed: ``A`` is None), the
    load ``L`` as a PETSc Vec, the last state's u and adjoint ṽ on all PETSc DOFs (every rank)."""

    key: int
    assembled: Assembled
    gap: np.ndarray
    L: object
    timings: dict
    u_all: np.ndarray | None = None
    v_all: np.ndarray | None = None


@dataclass
class PetscContext(Context):
    """Also ``u_all``: the case's last displacement on all PETSc DOFs (Newton's warm start)."""

    key: int = 0
    u_all: np.ndarray | None = None


class PetscPath(SolverPath):
    """``[linear_solver] path = "petsc"`` (module docstring)."""

    name = "petsc"

    @classmethod
    def starting(cls, config) -> None:
        """Before rank 0 builds its model: the other ranks build theirs from ``config`` (a serving
        rank has its id from :func:`served_problem`)."""
        from .._mpi import world_rank, world_size
        if world_rank() == 0:
            _pending[0] = next(_ids)
            if world_size() > 1:
                _send(("problem", _pending[0], config))

    def __init__(self, model, settings):
        super().__init__(model, settings)
        from petsc4py import PETSc

        from ..contact.fullspace_petsc import PetscNewton
        from ..fem.distributed import DistributedBody
        self.library = "petsc"
        self.id = _pending[0] if _pending[0] is not None else next(_ids)
        _pending[0] = None
        comm = PETSc.COMM_WORLD
        self.size, self.rank = comm.getSize(), comm.getRank()
        self.leader = self.rank == 0 and self.size > 1
        _set_options(model.config.linear_solver.petsc_options)
        t0 = time.perf_counter()
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
        self._hier_alpha = None      # ... built at this design (checkpoints rebuild it)
        self._systems: dict = {}
        self._contexts: dict = {}
        self._keys = itertools.count(1)
        self._ctx_keys = itertools.count(1)
        self._design_key = None      # the design whose A(α) the matrix holds
        log.info("PETSc path on %d rank(s): %d DOFs, %d owned here, %d elements (+%d at the "
                 "interfaces), %.2f s", self.size, dist.n, dist.n_local, dist.n_elements,
                 dist.n_ghost_elements, time.perf_counter() - t0)
        if self.rank > 0:
            _served[self.id] = self

    @classmethod
    def memory_estimate(cls, body, **kw):
        return memory.estimate_evaluation(body, memory.fullspace_parts)

    def _call(self, name, *args):
        """Rank 0: the other ranks make the same call (:func:`contactopt.ranks.serve`); then this rank's."""
        if self.leader:
            _send(("call", self.id, name, args))
        return getattr(self, "_" + name)(*args)

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
        return self._call("prepare", key, asm.alpha, asm.coords, asm.L_full, asm.gap)

    def for_load(self, system, asm) -> PetscSystem:
        key = next(self._keys)
        return self._call("for_load", system.key, key, asm.L_full)

    def _prepare(self, key, alpha, coords, L_full, gap):
        t0 = time.perf_counter()
        self._assemble_matrix(coords)
        self._systems.clear()              # the systems of earlier designs are not asked again
        asm = Assembled(np.asarray(alpha), coords, None, L_full, self.model.free_load(L_full), gap)
        self._design_key = key
        system = PetscSystem(key, asm, gap, self._load(L_full), {})
        system.timings["petsc_assembly"] = time.perf_counter() - t0
        self._systems[key] = system
        return system

    def _for_load(self, base_key, key, L_full):
        base = self._systems[base_key]
        asm = Assembled(base.assembled.alpha, base.assembled.coords, None, L_full,
                        self.model.free_load(L_full), base.gap)
        system = PetscSystem(key, asm, base.gap, self._load(L_full), {})
        self._systems[key] = system
        return system

    def _assemble_matrix(self, coords, csr=None):
        """A(α) of ``coords`` into both of the Newton's matrices (block size 3: BAIJ for the
        products, AIJ for GAMG); ``csr`` the owned rows if already computed."""
        from petsc4py import PETSc
        indptr, cols, data = csr if csr is not None else self.dist.owned_stiffness(coords)
        nw = self.newton
        nw.A_aij.setValuesCSR(indptr, cols, data, addv=PETSc.InsertMode.INSERT)
        bip, bcols, bdata = self.dist.owned_blocks(data)
        nw.A.setValuesBlockedCSR(bip, bcols, bdata, addv=PETSc.InsertMode.INSERT)
        for M in (nw.A, nw.A_aij):
            M.assemble()
        nw.refresh(indptr, cols, data)

    def _load(self, L_full):
        v = self.newton.A.createVecRight()
        d = self.dist
        v.getArray()[:] = d.owned(d.petsc_of_free(self.model.free_load(L_full)))
        return v

    def _hierarchy(self, alpha, coords):
        """The GAMG hierarchy of the A(α) the matrix holds now."""
        from ..contact.fullspace_petsc import PetscHierarchy
        if self._hier is not None:
            self._hier.destroy()
        self.newton.plain()
        self._hier = PetscHierarchy(self.newton.G, self.newton.H, self.dist.coordinates(coords), self.dist.contact)
        self._hier_alpha = np.array(alpha, dtype=float)
        return self._hier.setup_seconds

    # ------------------------------------------------------------------ states
    def new_context(self) -> PetscContext:
        return PetscContext(None, self.all_nodes, key=next(self._ctx_keys))

    def _context(self, key) -> PetscContext:
        if key not in self._contexts:
            self._contexts[key] = PetscContext(None, self.all_nodes, key=key)
        return self._contexts[key]

    def solve_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label=""):
        """As the full-space path's (:meth:`contactopt.paths.fullspace.FullSpacePath.solve_state`)."""
        self._contexts.setdefault(ctx.key, ctx)
        return self._call("solve", system.key, ctx.key, np.asarray(alpha, dtype=float), bool(warm_start),
                          tol, label)

    def _solve(self, skey, ckey, alpha, warm_start, tol, label):
        s = self.settings
        system, ctx = self._systems[skey], self._context(ckey)
        t0 = time.perf_counter()
        t_setup = self._hierarchy(alpha, system.assembled.coords) if self._hier is None else 0.0
        warm = ctx.warm if warm_start else None
        u0 = None
        if warm_start and warm is not None and ctx.u_all is not None:
            u0 = self.newton.A.createVecRight()
            u0.getArray()[:] = self.dist.owned(ctx.u_all)
        res = self.newton.solve(self._hier, system.L, system.gap, s.friction, r0=warm, u0=u0,
                                tol=max(tol or s.tol, FULLSPACE_TOL),
                                zone=ctx.next_zone if s.use_zone and warm_start else None, zone_margin=s.zone_margin)
        system.u_all = res.u_all
        timings = dict(system.timings, **{f"fullspace_{k}": v for k, v in res.timings.items() if k != "total"})
        timings["fullspace_amg_setup"] += t_setup
        timings["contact"] = time.perf_counter() - t0
        r = np.column_stack((res.r[:, 1:], res.r[:, 0]))           # per node (t1, t2, ν): (−τ, λ)
        u_free = self.dist.free_vector(res.u_all)
        state = self.finish_state(ctx, alpha=alpha, coords=system.assembled.coords,
                                  u=self.model.assembler.to_full(u_free), u_c=res.u_c, r=r, gap=system.gap,
                                  load=system.assembled.L, method="fullspace",
                                  outcome=(res.newton_steps, res.error, res.converged), timings=timings,
                                  info={"backend": "petsc", "ranks": self.size, "zone_nodes": int(res.zone.size),
                                        "zone_misses": int(res.zone_growths), "delassus": "none",
                                        "krylov_iterations": int(sum(res.krylov_iterations))})
        ctx.warm, ctx.u_all = res.r.copy(), res.u_all
        log.debug("state%s: PETSc full-space Newton %d steps, %d GMRES iterations, error %.2e, %.2f s", label,
                  res.newton_steps, sum(res.krylov_iterations), res.error, timings["total"])
        return state

    # ------------------------------------------------------------------ adjoint and design terms
    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None):
        from ..sensitivity.adjoint import DEFAULT_CHOICES
        if {**DEFAULT_CHOICES, **(choices or {})} != DEFAULT_CHOICES:
            raise SolverError(f"the full-space adjoint implements the default degenerate choices "
                              f"{DEFAULT_CHOICES} only, got {choices}")
        v_u, v_lam, its = self._call("adjoint", system.key, np.asarray(state.classes), state.u_c, state.lam,
                                     np.asarray(y_u, dtype=float), np.asarray(y_lam, dtype=float))
        state.info["adjoint_krylov"] = int(its)
        v_free = self.dist.free_vector(system.v_all)
        return v_u, v_lam, self.model.assembler.to_full(v_free)

    def _adjoint(self, skey, classes, u_c, lam, y_u, y_lam):
        from ..contact.state import CLASS_CODES as cc
        from ..sensitivity.adjoint import DEFAULT_CHOICES, effective_classes
        from ..sensitivity.adjoint_fullspace import ADJOINT_RTOL
        system = self._systems[skey]
        eff = effective_classes(classes, DEFAULT_CHOICES)
        v_all, v_u, v_lam, its = self.newton.adjoint(
            self._hier, np.flatnonzero(eff == cc["M3+"]), np.flatnonzero(eff == cc["M1"]), eff != cc["L"],
            u_c, lam, y_u, y_lam, self.settings.friction, rtol=ADJOINT_RTOL)
        system.v_all = v_all
        return v_u, v_lam, its

    def design_contraction(self, system, u_full, v_full, loads=None) -> np.ndarray:
        """vᵀ(∂A/∂α u − ∂L/∂α): the stiffness part per rank over its own elements, summed on rank 0."""
        part = self._call("contraction", system.key)
        m = self.model
        coords = system.assembled.coords
        v_full = m.unpin(v_full)            # the pinned DOFs are clamped (fem.model)
        return part - m.mesh.contract_dx3((loads or m.loads).shape_contraction(coords, v_full, m.assembler)[:, 2])

    def _contraction(self, skey):
        from mpi4py import MPI
        system = self._systems[skey]
        full = self.dist.dof_of_full
        m = self.model
        part = self.dist.contraction(m, system.assembled.coords, m.unpin(system.u_all[full]), m.unpin(system.v_all[full]))
        total = np.zeros_like(part)
        _world().Reduce(part, total, op=MPI.SUM, root=0)
        return total

    # ------------------------------------------------------------------ checkpoints
    def export_context(self, ctx) -> dict:
        out = super().export_context(ctx)
        a = self._hier_alpha
        out["jacobian_alpha"] = np.asarray(a if a is not None else np.zeros(0), dtype=float)
        out["jacobian_zone"] = np.asarray(ctx.next_zone if a is not None else np.zeros(0), dtype=np.int64)
        if ctx.u_all is not None:
            out["u_free"] = self.dist.free_vector(ctx.u_all)
        return out

    def import_context(self, ctx, arrays: dict, where: str, others=()) -> None:
        """Also the case's last displacement, and the GAMG hierarchy rebuilt at its design (the
        same arrays as the full-space path's: a checkpoint of either resumes on any number of ranks)."""
        self._contexts.setdefault(ctx.key, ctx)
        n_free = self.model.assembler.n_free
        u = arrays.get("u_free")
        if u is not None and (u.shape != (n_free,) or not np.all(np.isfinite(u))):
            raise CheckpointError(f"{where}: its displacement does not fit the mesh ({u.shape[0] if u.ndim else 0} "
                                  f"values for {n_free} free DOFs) or is not finite")
        a = arrays.get("jacobian_alpha")
        if a is not None and a.size:
            check_design(a, self.model.n_design, where, "AMG design")
        SolverPath.import_context(self, ctx, arrays, where)     # its checks, before any rank acts
        self._call("import", ctx.key, {k: v for k, v in arrays.items() if k in ("warm", "zone", "u_free",
                                                                                 "jacobian_alpha")}, where)

    def _import(self, ckey, arrays, where):
        ctx = self._context(ckey)
        SolverPath.import_context(self, ctx, arrays, where)
        if arrays.get("u_free") is not None:
            ctx.u_all = self.dist.petsc_of_free(arrays["u_free"])
        a = arrays.get("jacobian_alpha")
        if a is not None and a.size:
            alpha = np.asarray(a, dtype=float)
            if self._hier_alpha is None or not np.array_equal(self._hier_alpha, alpha):
                coords = self.model.mesh.coordinates(self.model.surface.as_vector(alpha))
                self._assemble_matrix(coords)
                self._design_key = None
                self._hierarchy(alpha, coords)


# ---------------------------------------------------------------------------- the other ranks
def _send(msg) -> None:
    """Rank 0: a message to every serving rank (a flag by a non-blocking broadcast, which the
    waiting ranks poll without spinning a core, then the pickled message)."""
    comm = _world()
    flag = np.ones(1, dtype=np.int64)
    comm.Ibcast(flag, root=0).Wait()
    comm.bcast(msg, root=0)


def receive():
    """A rank > 0: the next message of rank 0 (waiting without spinning a core)."""
    comm = _world()
    flag = np.zeros(1, dtype=np.int64)
    req = comm.Ibcast(flag, root=0)
    while not req.Test():
        time.sleep(0.002)
    return comm.bcast(None, root=0)


def make_call(msg) -> None:
    """A rank > 0: make the call of rank 0 that ``msg`` ("call", path id, name, arguments) names."""
    _, pid, name, args = msg
    getattr(_served[pid], "_" + name)(*args)


def served_problem(pid):
    """The id the next PetscPath built on this rank takes (:func:`contactopt.ranks.serve`)."""
    _pending[0] = pid


def stop_serving() -> None:
    """Rank 0: the serving ranks return from :func:`contactopt.ranks.serve`."""
    if _world().Get_size() > 1 and _world().Get_rank() == 0:
        _send(("stop",))


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
