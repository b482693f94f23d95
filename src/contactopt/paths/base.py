"""The interface every solver path implements, and what the paths share.

A solver path turns one design's assembled system (A(α), L(α), the gap g = ϑ_α at the contact
nodes; :class:`~contactopt.fem.model.Assembled`) into the contact state of each load case and
the adjoint (4.15) of a state. :class:`~contactopt.problem.ShapeProblem` calls, per design,

    system = path.prepare(assembled)                   # what every load case shares
    system_k = path.for_load(system, assembled_k)      # another load case: L_k
    state = path.solve_state(system_k, context, ...)   # the Coulomb state (paper (3.17))
    v_u, v_λ, ṽ, krylov = path.adjoint(system_k, context, state, y*_u, y*_λ, choices)   # (4.15)

and a case's :class:`Context` carries what the path keeps from design to design (warm start,
contact zone, a kept Delassus block or AMG hierarchy): ``export_context`` gives it as arrays
(the checkpoint holds them) and ``import_context`` puts it back, so that a resumed run repeats
the uninterrupted one bit for bit.

Conventions: contact quantities per node m in the order (t1, t2, ν) = (x1, x2, x3); λ = r_ν ≥ 0
the normal force on the body, τ = −r_t; a warm start is per node in the FCLIB order (N, T1, T2).
"""

from __future__ import annotations

import logging
from contextlib import nullcontext
from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..contact import zone as zone_rules
from ..contact.state import (
    FoundationState,
    SolveStats,
    State,
    classify_nodes,
    contact_conditions_violation,
    displacement_scale,
)
from ..errors import CheckpointError, ProblemDataError
from ..fem.model import ElasticModel
from .transforms import Mechanics

log = logging.getLogger(__name__)


def _feature(label: str, refusal: str, default: bool = False):
    """A field of :class:`Capabilities`: ``label`` names the feature in a refusal's summary,
    ``refusal`` is the sentence of a path that lacks it (``str.format`` keys ``path``, the path
    asked for; ``detail``, what of the configuration needs it; ``takers``, ``on``, the paths that
    take it, as "'a' or 'b'" and "the 'a' or 'b' paths")."""
    return field(default=default, metadata={"label": label, "refusal": refusal})


@dataclass(frozen=True)
class Capabilities:
    """What a path takes, declared on its class (``SolverPath.capabilities``).

    Each boolean field is a feature a configuration may need (:func:`contactopt.paths.needs`):
    :func:`~contactopt.paths.select_path` keeps the paths that take every feature needed, and a
    refusal is the fields' ``refusal`` sentences. A new mechanic is one more field here (default
    False: no path takes it until it says so), one line in ``needs`` and ``True`` on the paths
    that take it. ``libraries``: what the path imports (checked when it is chosen); ``sparse``: its
    own linear-algebra library, else ``[linear_solver] library``; ``auto``: the runs
    ``path = "auto"`` gives it ("small": below ``crossover``, "large": from there, first the
    lowest ``auto_order`` whose ``libraries`` and ``auto_libraries`` are installed, "ranks": under
    mpiexec with more than one rank; "" never); ``auto_avoids``: features for which "auto" takes
    another path that has them where one fits (a path that takes them, but not as the first choice).

    Only what a path's linear algebra can do is a feature here: a force-controlled obstacle is an
    outer search over the translation of an obstacle (``contactopt.paths.force``), taken wherever the obstacle
    is, and rules between features of a configuration that no path takes (clamped contact nodes
    on an elastic foundation whose partners are free) are refused by
    :func:`contactopt.config.validation.check_interactions` before any path is asked."""

    foundation: bool = _feature(
        "an elastic [foundation]",
        "linear_solver.path = '{path}': {detail} is solved on {on} only; use path {takers} or 'auto'")
    pairs: bool = _feature(
        "several contact pairs",
        "linear_solver.path = '{path}': {detail} are solved on {on} only so far; use path {takers} or 'auto'")
    counterpart_force: bool = _feature(
        "an elastic counterpart pressed by a force",
        "linear_solver.path = '{path}': {detail} is solved on {on} only so far; use path {takers} or 'auto'")
    obstacle: bool = _feature(
        "a rigid [obstacle] other than the fixed plane",
        "linear_solver.path = '{path}': a {detail} [obstacle] is solved on {on} only (one process); "
        "use path {takers} or 'auto'")
    obstacle_steps: bool = _feature(
        "load steps on a rigid [obstacle] other than the fixed plane",
        "linear_solver.path = '{path}': load steps on a {detail} [obstacle] (the slip's reference per node "
        "frame) are solved on {on} only; use path {takers} or 'auto'")
    held_by_contact: bool = _feature(
        "a body held only by contact",
        "linear_solver.path = '{path}': body.clamped leaves rigid motions free ({detail}); a body held only "
        "by contact is solved on {on} only; use path {takers} or 'auto'")
    pinned: bool = _feature(
        "clamped tangential components of contact nodes",
        "linear_solver.path = '{path}': {detail} tangential component(s) of contact nodes are clamped (a "
        "symmetry plane through the contact face), which it does not take; use path {takers}")
    compliance: bool = _feature(
        "the compliance objective",
        "linear_solver.path = '{path}': the compliance objective needs the condensed load on every contact "
        "DOF; use path {takers} or 'auto'")
    whole_displacement: bool = _feature(
        "an objective of the whole displacement",
        "objective: {detail} needs ∂J/∂u on every DOF, which the adjoint on the '{path}' path does not take; "
        "use path {takers}")
    load_steps: bool = _feature(
        "load steps",
        "the '{path}' solver path does not take load steps; use linear_solver.path = {takers}")
    many_ranks: bool = _feature(
        "more than one MPI rank",
        "linear_solver.path = '{path}' runs on one process, and this run has {detail} MPI ranks: use path "
        "{takers} (or 'auto'), or run without mpiexec")
    libraries: tuple = ()
    sparse: str | None = None
    auto: str = ""
    auto_order: int = 0
    auto_libraries: tuple = ()
    auto_avoids: tuple = ()

    @classmethod
    def features(cls) -> tuple:
        """The names of the boolean fields: what a configuration may need."""
        return tuple(f.name for f in fields(cls) if "refusal" in f.metadata)

    @classmethod
    def label(cls, feature: str) -> str:
        return _metadata(feature)["label"]

    @classmethod
    def refusal(cls, feature: str) -> str:
        return _metadata(feature)["refusal"]

    def lacks(self, needs) -> list:
        """The features of ``needs`` (names) this path does not take, in the fields' order."""
        return [f for f in self.features() if f in needs and not getattr(self, f)]


def _metadata(feature: str):
    return next(f.metadata for f in fields(Capabilities) if f.name == feature)


class _Takes:
    """A class attribute read from the class's :class:`Capabilities` (``takes_steps``)."""

    def __init__(self, feature: str):
        self.feature = feature

    def __get__(self, obj, owner):
        return getattr(owner.capabilities, self.feature)


class SystemParts:
    """The optional parts the system of a design and load case may carry on any path, None where
    it has none (a path's system class declares those it can hold as fields): ``coupling`` the
    :class:`~contactopt.fem.foundation.Coupling` of an elastic foundation (S_eff, ℓ_eff), ``product``
    x ↦ A(α) x on the free DOFs where A(α) is not formed on this process, ``force`` a load step's
    |f| of a force-controlled obstacle (None: the model's), ``basis`` the transformed basis of
    six-node triangles with mortar partners (:class:`~contactopt.paths.transforms.Basis`)."""

    coupling = None
    couple = None
    product = None
    force = None
    basis = None

    @property
    def relative(self) -> bool:
        """Whether the state's u_c is the relative displacement w of an elastic counterpart (the
        condensation's ``coupling`` or the full space's ``couple``, :mod:`.coupled`)."""
        return self.coupling is not None or self.couple is not None

    def counterpart_compliance(self, x: np.ndarray) -> np.ndarray | None:
        """C x (3p, per node (t1, t2, ν)): the elastic counterpart's compliance on the contact
        forces x, from its condensed C or by a solve with its K_f; None without a counterpart."""
        if self.coupling is not None:
            return self.coupling.foundation.C @ np.ravel(x)
        if self.couple is not None:
            return self.couple.compliance(x)
        return None


class Adjoint(NamedTuple):
    """What :meth:`SolverPath.adjoint` computes: ``v_u`` (3p, per node (t1, t2, ν)), ``v_lam``
    (p,), ``v`` ṽ on all DOFs, and ``krylov`` the GMRES iterations it took (None where it was
    solved directly)."""

    v_u: np.ndarray
    v_lam: np.ndarray
    v: np.ndarray
    krylov: int | None = None


@dataclass(frozen=True)
class Start:
    """What a path is built with besides the model and the settings: ``first_loads`` the loads of
    the first load case (a checkpoint's design is assembled with them; None: the model's)."""

    first_loads: object = None


@dataclass
class Settings:
    """The ``[state]`` and ``[linear_solver]`` settings a path solves with."""

    friction: float
    method: str
    tol: float
    max_iter: int
    use_zone: bool
    zone_margin: float
    reuse_delassus: bool
    library: str
    threads: int = 0          # [linear_solver] threads: MKL's inside an evaluation (0: MKL's own)

    @classmethod
    def from_config(cls, state, friction, library: str, threads: int = 0) -> "Settings":
        """The settings of the sections ``[state]`` and ``[friction]`` of a configuration, and
        ``[linear_solver] threads``."""
        return cls(float(friction.coefficient), state.method, state.tol, state.max_iter,
                   bool(state.zone), float(state.zone_margin), bool(state.reuse_delassus), library,
                   int(threads))


@dataclass
class Context:
    """What one load case carries from design to design on every path: ``warm`` its last contact
    forces ((p, 3) per node (N, T1, T2)) and ``next_zone`` the zone of its next state solve."""

    warm: np.ndarray | None
    next_zone: np.ndarray


class SolverPath:
    """A way to solve a design's contact states and adjoints (module docstring).

    Subclasses set ``name`` (the value of ``[linear_solver] path``) and ``capabilities`` (what
    they take: :class:`Capabilities`), and implement :meth:`prepare`, :meth:`for_load`,
    :meth:`solve_state`, :meth:`adjoint` and ``memory_estimate``; those that keep more than
    the warm start and the zone extend ``new_context``, ``export_context`` and
    ``import_context``. Every method has the signature given here, on every path."""

    name = ""
    capabilities = Capabilities()
    takes_steps = _Takes("load_steps")    # whether solve_state takes ``slip_ref`` (sensitivity/steps.py)
    condenses_counterparts = True         # an elastic foundation condensed onto its support (fem.foundation)

    def __init__(self, model, settings: Settings, start: Start | None = None):
        self.model = model
        self.settings = settings
        self.start = start if start is not None else Start()
        self.library = settings.library
        self.all_nodes = np.arange(model.n_contact)
        self.n_zone_misses = 0     # zone problems solved again on a grown zone
        self.n_delassus = 0        # Delassus blocks W_Z formed (the others were reused)

    @cached_property
    def mechanics(self) -> Mechanics:
        """The transforms of the model's contact system (:mod:`.transforms`), built on first use."""
        return Mechanics.of(self.model)

    @property
    def friction(self):
        """The Coulomb coefficient F this path solves with: the model's ``contact_friction`` ((p,),
        per contact node in contact-node order) where set, else ``[friction] coefficient`` (a
        scalar). Every solve, classification and adjoint of the path reads it here."""
        return node_friction(self.model, self.settings.friction)

    @property
    def first_loads(self):
        """The loads of the first load case: a checkpoint's design is assembled with them."""
        return self.start.first_loads

    # ------------------------------------------------------------------ the interface
    @classmethod
    def memory_estimate(cls, body, counterparts=None, **kw):
        """Estimated peak memory of one evaluation (:class:`~contactopt.fem.memory.MemoryEstimate`)
        of a body (or model) with its elastic ``counterparts`` (sizes, :class:`~contactopt.fem.memory.CounterpartSize`;
        None: a model's own, :func:`counterpart_sizes`)."""
        raise NotImplementedError

    def assemble(self, alpha, loads=None):
        """A(α), L(α) and the gaps of a design (:meth:`contactopt.fem.model.ElasticModel.assemble`)."""
        return self.model.assemble(alpha, loads)

    @classmethod
    def library_threads(cls, threads: int):
        """Context manager: the libraries' threads inside the work done for this path (the model's
        construction, every evaluation) for ``[linear_solver] threads``; here: as they are (the
        condensation path: MKL's)."""
        return nullcontext()

    def evaluation_threads(self):
        """:meth:`library_threads` of this path's settings, around an evaluation's state solves
        and subgradient."""
        return self.library_threads(self.settings.threads)

    def prepare(self, asm):
        """The system of a design for its first load case (``asm`` holds L of that case)."""
        raise NotImplementedError

    def for_load(self, system, asm):
        """The system of another load case of the same design (``asm`` with that case's L)."""
        raise NotImplementedError

    def new_context(self) -> Context:
        return Context(None, self.all_nodes)

    def solve_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="",
                    slip_ref=None) -> State:
        """The contact state of one load case; ``shared`` is a dict the cases of one design share;
        ``slip_ref`` (p, 2) u_t at the end of the previous load step (paths with load steps).
        A path that takes an obstacle returns ``transformed_state``."""
        raise NotImplementedError

    def transformed_state(self, system, ctx, alpha, **kw) -> State:
        """The state through the outer transforms of the contact system (:mod:`.transforms`): the
        force search of a force-controlled obstacle around :meth:`fixed_state`, else that itself."""
        search = self.mechanics.search
        if search is None:
            return self.fixed_state(system, ctx, alpha, **kw)
        return search.solve(self, system, ctx, alpha, **kw)

    # ------------------------------------------------------------------ hooks of the transforms
    def fixed_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None) -> State:
        """The state with the obstacle where ``system`` puts it: the path's own solve."""
        raise NotImplementedError

    def translated(self, system, s: float, c: np.ndarray, e: np.ndarray):
        """``system`` with the obstacle translated by s f̂ (``contactopt.paths.force``): gap g − s c, tangential
        shift s e (3p per node frame, normal parts 0) added to the law's."""
        raise NotImplementedError

    def normal_stiffness(self, system) -> np.ndarray:
        """(p,) a stiffness per contact node along its normal (the force search's first step only)."""
        raise NotImplementedError

    def adjoint(self, system, ctx, state, y_u, y_lam, choices=None) -> Adjoint:
        """The :class:`Adjoint` (v_u (3p), v_λ (p), ṽ on all DOFs) of the adjoint system (4.15) of
        ``state``; it changes neither ``state`` nor the arguments.

        ``y_u`` is ∂J/∂u_c (3p, per node (t1, t2, ν)), or ∂J/∂u on every DOF (3·n_nodes) for an
        objective of the whole displacement. Then J depends on u_c also through the interior
        displacement u_i = A_ii⁻¹(L_i − A_ic u_c): (4.15) holds with y*_u = g_c − A_ci A_ii⁻¹ g_i
        (g = ∂J/∂u on the free DOFs), and ṽ = (v_u, −A_ii⁻¹(A_ic v_u + g_i)) — the extension
        satisfies (A ṽ)_i = −g_i — so the design term ṽᵀ(∂A u − ∂L) needs no other change.

        A path whose systems hold an elastic foundation's ``coupling`` (the condensation path) also
        takes ``carry``: with ``y_u`` on every DOF, what a later load step passes down, a derivative
        with respect to the state's own contact unknown w (not the body's u_c; sensitivity/steps.py)."""
        raise NotImplementedError

    def force_terms(self, system, ctx, state, v_lam, loads=None, *, v=None, y_u=None):
        """∂Θ/∂s, ∂F/∂s, ∂F/∂α and the adjoint of F of a force-controlled obstacle at a state
        (:meth:`.force.ForceSearch.terms`)."""
        return self.mechanics.search.terms(self, system, ctx, state, v_lam, loads, v=v, y_u=y_u)

    def is_full(self, y_u) -> bool:
        """Whether ``y_u`` is ∂J/∂u on every DOF (:meth:`adjoint`), not on the contact DOFs."""
        size = np.asarray(y_u).size
        if size not in (3 * self.model.n_contact, self.model.assembler.n_full):
            raise ValueError(f"∂J/∂u has {size} entries: expected 3p = {3 * self.model.n_contact} or "
                             f"3·n_nodes = {self.model.assembler.n_full}")
        return size != 3 * self.model.n_contact

    def adjoint_force(self, system, ctx, v_u) -> np.ndarray:
        """S v_u (3p, per node (t1, t2, ν)) of the last :meth:`adjoint` of ``ctx``: what a load
        step passes to the previous one (sensitivity/steps.py)."""
        raise NotImplementedError

    def global_contact(self, v) -> np.ndarray:
        """A (3p,) contact vector of the path's node frames in global components (the same on
        the plane; :mod:`.condensation` rotates it on an obstacle)."""
        return v

    def adjoint_carry(self, system, ctx, v_u, v_full, y_u) -> np.ndarray:
        """S v_u + ∂J/∂u_c (3p, per node (t1, t2, ν)) of the last :meth:`adjoint` of ``ctx``, with
        right-hand side ``y_u``: a load step's derivative passed to the previous step
        (sensitivity/steps.py). For ``y_u`` on every DOF, J sees u_c also through the interior,
        ∂J/∂u_c = g_c − A_ci A_ii⁻¹g_i, and since the extension ṽ has (A ṽ)_i = −g_i,
        S v_u + ∂J/∂u_c = (A ṽ)_c + g_c."""
        if not self.is_full(y_u):
            return self.adjoint_force(system, ctx, v_u) + y_u
        asm = self.model.assembler
        contact = (3 * self.model.contact_nodes[:, None] + np.arange(3)).ravel()
        Av = asm.to_full(system.assembled.A @ np.asarray(v_full)[asm.free])
        return Av[contact] + np.asarray(y_u, float)[contact]

    def design_contraction(self, system, u_full, v_full, loads=None) -> np.ndarray:
        """vᵀ(∂A/∂α_k u − ∂L/∂α_k) at the system's design (full-length u, v)."""
        return self.model.design_contraction(system.assembled.coords, u_full, v_full, loads)

    def uniqueness_bound(self, system):
        """(F0, None) of the bound (3.16), or (None, the reason) where the path cannot compute it."""
        return None, (f"the uniqueness estimate (3.16) needs the condensed stiffness S on all contact "
                      f"DOFs, which the {self.name} path does not form")

    def export_context(self, ctx) -> dict:
        """The arrays of ``ctx`` a checkpoint holds (names without the case prefix)."""
        return {"warm": np.asarray(ctx.warm if ctx.warm is not None else np.zeros(0)),
                "zone": np.asarray(ctx.next_zone)}

    def import_context(self, ctx, arrays: dict, where: str, others=()) -> None:
        """Put back what :meth:`export_context` gave, checked against the mesh (``where`` names
        the checkpoint in errors); ``others`` the contexts put back before, whose kept blocks
        ``ctx`` may share."""
        p = self.model.n_contact
        warm = arrays.get("warm")
        if warm is not None and warm.size:
            if warm.size != 3 * p or warm.ndim not in (1, 2):
                raise CheckpointError(f"{where}: its warm start has shape {warm.shape}, expected ({p}, 3)")
            ctx.warm = warm.reshape(p, 3)      # older checkpoints stored it flat, in the same order
        zone = arrays.get("zone")
        if zone is not None:
            ctx.next_zone = check_node_set(zone, p, where, "contact zone")

    # ------------------------------------------------------------------ shared by the paths
    def finish_state(self, ctx, *, alpha, coords, u, u_c, r, gap, load, method, outcome, timings,
                     stats, slip_ref=None, foundation: FoundationState | None = None) -> State:
        """The :class:`State` of contact forces ``r`` ((p, 3) per node (t1, t2, ν)) and
        displacements, with the node classes of Table 4.1; ``outcome`` the solver's (iterations,
        error, converged), ``stats`` the path's :class:`SolveStats` fields. The case's next zone is set from it. ``slip_ref`` (p, 2): in a load
        step, u_t at the end of the previous step; the classes see the slip increment."""
        pinned = self.model.contact_pinned
        if np.any(pinned):         # u = 0 and no contact force there, exactly (fem.model)
            r, u_c = np.where(pinned, 0.0, r), np.where(pinned, 0.0, u_c)
            u = self.model.unpin(u)
        lam, tau = r[:, 2].copy(), -r[:, :2]
        fscale = None
        if lam.max(initial=0) <= 0:     # nothing in contact: forces count as zero against the load scale
            load = load() if callable(load) else load       # (a function that forms the load: only here)
            fscale = max(np.abs(lam).max(initial=0.0), np.abs(load).max(initial=0.0))
        law_u = u_c
        if slip_ref is not None:        # the friction law's displacement: the slip increment
            law_u = u_c.copy()
            law_u[:, :2] -= slip_ref
        friction = self.friction
        classes = classify_nodes(law_u, lam, tau, gap, friction,
                                 force_scale=fscale, u=u)
        timings["total"] = sum(timings.values())
        state = State(alpha=alpha, coords=coords, u=u, u_c=u_c, lam=lam, tau=tau, gap=gap, classes=classes,
                      friction=friction, method=method, iterations=outcome[0],
                      residual=outcome[1],
                      complementarity=contact_conditions_violation(law_u, lam, tau, gap, friction),
                      converged=outcome[2], timings=timings, stats=SolveStats.of({"path": self.name, **stats}), slip_ref=slip_ref,
                      foundation=foundation)
        if self.settings.use_zone:
            ctx.next_zone = zone_rules.near_nodes(lam, u_c[:, 2] + gap, displacement_scale(u_c, gap),
                                                  self.settings.zone_margin)
        return state


def node_friction(model, coefficient: float):
    """F of ``model``'s contact: its ``contact_friction`` (p,) where set (checked: finite, ≥ 0, one
    per contact node), else the scalar ``coefficient``."""
    mu = model.contact_friction
    if mu is None:
        return coefficient
    mu = np.asarray(mu)
    p = model.n_contact
    if mu.shape != (p,) or not np.issubdtype(mu.dtype, np.number):
        raise ProblemDataError(f"contact_friction must hold one coefficient per contact node, shape ({p},); "
                               f"got shape {mu.shape} of {mu.dtype}")
    if not np.all(np.isfinite(mu)) or np.any(mu < 0):
        bad = np.flatnonzero(~np.isfinite(mu) | (mu < 0))
        raise ProblemDataError(f"contact_friction must be finite and ≥ 0: {bad.size} contact node(s) are not, "
                               f"the first {int(bad[0])} with F = {mu[bad[0]]}")
    return mu.astype(np.float64, copy=False)


def check_node_set(nodes, n_contact: int, where: str, what: str) -> np.ndarray:
    """``nodes`` as a non-empty, strictly increasing array of contact nodes 0..n_contact − 1."""
    nodes = np.asarray(nodes).astype(np.int64)
    ok = (nodes.ndim == 1 and nodes.size > 0 and nodes[0] >= 0 and nodes[-1] < n_contact and not np.any(np.diff(nodes) <= 0))
    if not ok:
        raise CheckpointError(f"{where}: its {what} is not a sorted set of contact nodes 0..{n_contact - 1}")
    return nodes


def check_design(alpha, n_design: int, where: str, what: str) -> np.ndarray:
    alpha = np.asarray(alpha)
    if alpha.shape != (n_design,) or not np.all(np.isfinite(alpha)):
        raise CheckpointError(f"{where}: its {what} has shape {alpha.shape} (expected ({n_design},), finite)")
    return alpha.astype(float)


def counterpart_sizes(body, given=None) -> list:
    """The sizes of the elastic counterparts a memory estimate counts: ``given``, else a model's
    own (:attr:`~contactopt.fem.counterparts.Counterparts.memory_sizes`), none for a body alone
    (its counterparts are counted as they are read, fem.model)."""
    if given is not None:
        return list(given)
    if isinstance(body, ElasticModel) and body.foundation is not None:
        return list(body.foundation.memory_sizes)
    return []
