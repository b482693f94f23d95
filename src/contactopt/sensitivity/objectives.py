"""Objectives J(α, y) as pluggable pieces with value and partial gradients.

An objective sees the state (λ, τ, u_c; conventions in :mod:`contactopt.contact.state`: per
contact node the order (t1, t2, ν), λ = r_ν ≥ 0, τ = −r_t) and the system of the design, and
returns a :class:`~contactopt.sensitivity.partials.Partials` record: the value and

    ∂J/∂u_c (3p, per node (t1, t2, ν)),  ∂J/∂λ (p,),  ∂J/∂α at fixed (u_c, λ) (n_design,).

An objective of the whole displacement (``full_space``: the peak stress, the friction work)
returns ∂J/∂u on every DOF (3·n_nodes, DOF 3n + m) in place of ∂J/∂u_c, and ∂J/∂α at fixed u;
the record's ``space`` says which (each solver path's adjoint takes either,
:meth:`contactopt.paths.base.SolverPath.adjoint`).

The adjoint (:mod:`contactopt.sensitivity.adjoint`) turns these into a Clarke subgradient of
Θ(α) = J(α, S(α)). To add an objective, subclass :class:`Objective` and register it in
``OBJECTIVES``; nothing in the solver changes. An objective holds the model (for the geometry
and the design terms) and, for a 'design' target, a function that solves the state of a design
— not the problem itself.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..fem.stress import von_mises_gradients, von_mises_points
from .partials import CONTACT, FULL, Derivatives, Partials, add_solve
from .steps import choice_of

log = logging.getLogger(__name__)

class Objective:
    """Base class: ``evaluate(state, system) -> Partials`` of one solve (its ``space`` the DOFs of
    ∂J/∂u: ``FULL`` where ``full_space``, else ``CONTACT``)."""

    name = "objective"
    full_space = False       # True: ∂J/∂u is on every DOF (3·n_nodes), not on the contact DOFs only
    accumulates = False      # True: on a load path J sums over the solves (:meth:`evaluate_path`)
    loads = None             # the load set of the objective's load case (None: the configuration's)
    target = None            # the prescribed normal forces λ̄ of a target_normal_force term, else None

    def __init__(self, model, scale: float = 1.0):
        self.model = model
        self.scale = float(scale)

    def evaluate(self, state, cond, loads=None) -> Partials:
        """J of one solve and its :class:`Partials`; ``loads`` the load set the state was solved
        under (a load path's step; None: the objective's own, :attr:`loads`). Only an objective
        whose ∂J/∂α at fixed u holds ∂L/∂α (the compliance, the friction work) reads it: the
        load's derivative must be that of the loads the state was solved under."""
        raise NotImplementedError

    def resolve(self) -> None:
        """Compute now what the objective needs from other designs (a 'design' target solves a
        state, which must not come between a state and its adjoint); nothing by default."""

    def partials(self, value, du, dlam, dalpha) -> Partials:
        """The :class:`Partials` of one solve, ∂J/∂u on this objective's space."""
        return Partials(value, {0: Derivatives(du, dlam, dalpha, FULL if self.full_space else CONTACT)})

    def evaluate_path(self, states, systems, loads, memo=None) -> Partials:
        """J at the end of the last of the solves ``states`` of a load path (from the first, in
        order; ``systems`` and ``loads`` theirs), its derivatives keyed by each solve's index. An
        objective of the state alone: the last solve's :meth:`evaluate` under its loads.
        ``memo`` (a dict) keeps what the ends of several steps of one path share."""
        return self.evaluate(states[-1], systems[-1], loads[-1]).at_solve(len(states) - 1)


class TargetNormalForce(Objective):
    """J = Σ_i (λ̄_i − λ_i)², λ̄ a prescribed normal contact force per contact node (paper §5.2)."""

    name = "target_normal_force"

    def __init__(self, model, target_spec, scale: float = 1.0, case: int = 0, solve=None):
        super().__init__(model, scale)
        self.spec = target_spec
        self.case = case              # the load case whose state a 'design' target is
        self.solve = solve            # (alpha, case) -> λ of that design's state: a 'design' target
        self._target = None

    @property
    def target(self) -> np.ndarray:
        self.resolve()
        return self._target

    def resolve(self) -> None:
        if self._target is None:
            self._target = target_values(self.spec, self.model, self.case, self.solve)

    def evaluate(self, state, cond, loads=None):
        d = self.target - state.lam
        p = state.lam.size
        return self.partials(self.scale * float(d @ d), np.zeros(3 * p), -2.0 * self.scale * d,
                             np.zeros(state.alpha.size))


class PressureUniformity(Objective):
    """J = Σ_m a_m (p_m − p̄)² with p_m = λ_m/a_m and p̄ = Σλ/Σa: the spread of the contact pressure.

    a_m is the node's tributary area ∫N_m dS on the flat reference contact face (as for targets
    with ``per_area``; it does not change with α), so a uniform pressure p (λ_m = p a_m) gives
    J = 0 on any mesh. J = Σ λ_m²/a_m − (Σλ)²/Σa. Nodes of zero area (the corners of six-node
    triangles, whose consistent force is zero under any uniform pressure) are left out.
    """

    name = "pressure_uniformity"

    def __init__(self, model, scale: float = 1.0, contacts=()):
        super().__init__(model, scale)
        self.areas, self.used = node_areas(model, contacts)

    def evaluate(self, state, cond, loads=None):
        a, m = self.areas[self.used], self.used
        lam = state.lam[m]
        pbar = lam.sum() / a.sum()
        d = lam / a - pbar
        grad = np.zeros(state.lam.size)
        grad[m] = 2.0 * self.scale * d           # Σ a_m d_m = 0: p̄'s derivative drops out
        return self.partials(self.scale * float(a @ (d * d)), np.zeros(3 * state.lam.size), grad,
                             np.zeros(state.alpha.size))


def node_areas(model, contacts=(), key: str = "objective.contacts"):
    """(a (p,), the contact nodes of positive area): :meth:`ElasticModel.contact_areas`; with
    ``contacts`` (pair names or indices in ``[[contacts]]``) only the nodes of those pairs."""
    a = np.asarray(model.contact_areas(), float)
    used = np.flatnonzero(a > 1e-12 * a.max())
    if contacts:
        used = used[np.isin(pair_index_of(model)[used], pair_numbers(model, contacts, key))]
    return a, used


def pair_index_of(model) -> np.ndarray:
    """(p,) each contact node's pair, in ``[[contacts]]`` order (0 where the model has one pair)."""
    return np.zeros(model.n_contact, int) if model.pair_of is None else model.pair_of


def pair_numbers(model, contacts, key: str) -> list[int]:
    """The indices of the pairs ``contacts`` names (a name or an index in ``[[contacts]]``);
    ConfigError naming those that are none."""
    pairs = model.config.assembly.contacts
    names = [p.name for p in pairs]
    out, bad = [], []
    for c in contacts:
        if isinstance(c, int) and c < len(pairs):
            out.append(c)
        elif isinstance(c, str) and c in names:
            out.append(names.index(c))
        else:
            bad.append(repr(c))
    if bad:
        raise ConfigError([f"{model.config.source}: {key}: {', '.join(bad)} is no contact pair of the model (pairs: "
                           + ", ".join(f"{k} {n!r}" for k, n in enumerate(names)) + ")"])
    return out


MAX_TIE = 1e-9      # entries within this fraction of the largest attain it (the aggregate ``max``)


def aggregate(x: np.ndarray, kind: str, rho: float, p: float):
    """(value, weights ∂value/∂x) of the largest entry of x ≥ 0: ``max`` (the first index where
    the largest value is attained, within :data:`MAX_TIE` of it — the state's own accuracy, so that
    entries equal in exact arithmetic, two mirror elements of a symmetric design, give the same
    Clarke subgradient whatever the round-off of the path that solved the state), ``ks`` the Kreisselmeier–Steinhauser
    function max + ln Σ exp(ρ(x − max))/ρ (≥ max, at most ln(n)/ρ above it; ρ in 1/units of x),
    ``pnorm`` (Σ x^p)^(1/p) (≥ max, at most n^(1/p) times it)."""
    x = np.asarray(x, float)
    w = np.zeros_like(x)
    top = float(x.max())
    if kind == "max":
        tied = np.flatnonzero(x >= top - MAX_TIE * abs(top))
        w[int(tied[0]) if tied.size else int(np.argmax(x))] = 1.0
        return top, w
    if kind == "ks":
        e = np.exp(rho * (x - top))
        total = e.sum()
        return top + float(np.log(total)) / rho, e / total
    if kind == "pnorm":
        if top <= 0:
            return 0.0, w
        r = x / top
        norm = float(np.sum(r ** p) ** (1.0 / p))
        return top * norm, (r / norm) ** (p - 1.0)
    raise ValueError(f"unknown aggregate {kind!r}")


class MaxPressure(Objective):
    """The largest contact pressure p_m = λ_m/a_m (a_m as in :class:`PressureUniformity`),
    aggregated as ``aggregate`` says (:func:`aggregate`): the max is nonsmooth where two nodes
    share it; its subgradient comes from the first such node."""

    name = "max_pressure"

    def __init__(self, model, scale: float = 1.0, kind: str = "max", rho: float = 50.0, p: float = 8.0,
                 contacts=()):
        super().__init__(model, scale)
        self.areas, self.used = node_areas(model, contacts)
        self.kind, self.rho, self.p = kind, float(rho), float(p)

    def evaluate(self, state, cond, loads=None):
        a, m = self.areas[self.used], self.used
        value, w = aggregate(state.lam[m] / a, self.kind, self.rho, self.p)
        grad = np.zeros(state.lam.size)
        grad[m] = self.scale * w / a
        return self.partials(self.scale * value, np.zeros(3 * state.lam.size), grad, np.zeros(state.alpha.size))


class FrictionalDissipation(Objective):
    """J = Σ_m τ_m·u_t,m, the friction work of the state (τ the paper's tangential force, u_t the
    slip), a proxy for fretting wear.

    τ is not a variable of its own: τ = −(A u − L)_t on the contact DOFs (τ = −r_t), so
    J = −ũᵀ(A u − L) with ũ the vector of the tangential contact displacements (zero elsewhere).
    Its gradient is on the whole displacement, ∂J/∂u = τ̂ − A ũ (τ̂: τ on the tangential contact
    DOFs), and at fixed u ∂J/∂α = −ũᵀ(∂A/∂α u − ∂L/∂α).

    On an elastic foundation the slip is the relative one, w_t (the state's u_c is w), and
    w = u_c − Π q_f + C r with r = (A u − L)_c the contact force on the body, so J = −w_tᵀr_t is
    a function of the body's u through r in w as well: the same formulas hold with
    ũ = (w_t, 0) − C (τ, 0) per contact node (t1, t2, ν), all three components (docs/foundation.md).
    On a load path the increment's reference w_t^(k−1) is relative too: −τ^k·w_t^(k−1) =
    −τ̂^kᵀu^(k−1) − cᵀ(A u^(k−1) − L^(k−1)) with c = C (τ^k, 0) on the contact DOFs, so the solve
    before gets ∂/∂u^(k−1) = −τ̂^k − A c and ∂/∂α = −cᵀ(∂A u^(k−1) − ∂L^(k−1)) at fixed u^(k−1).
    """

    name = "frictional_dissipation"
    full_space = True            # ∂J/∂u is on every DOF (the paths' adjoints take it)
    accumulates = True           # on a load path: the work of every solve's slip increment

    def evaluate(self, state, cond, loads=None):
        return self.partials(*self._work(state, cond, self.loads if loads is None else loads)[:4])

    def _work(self, state, cond, loads):
        """(τ·Δu_t, ∂/∂u, 0 (p,), ∂/∂α at fixed u, ∂/∂u^(k−1) at fixed r^(k−1) (every DOF), c) of
        one solve, Δu_t = u_t − u_t^(k−1) its slip increment (u_t itself without ``slip_ref``): the
        work is −Δũᵀ(A u − L) with Δũ the increment on the tangential contact DOFs, so ∂/∂u =
        τ̂ − AΔũ and ∂/∂α = −Δũᵀ(∂A u − ∂L); through u_t^(k−1) = Δũ's reference, ∂/∂u^(k−1) = −τ̂.
        c (every DOF, None off a foundation): C (τ, 0) on the contact DOFs, by which the relative
        reference w_t^(k−1) depends on the contact force r^(k−1) (class docstring)."""
        model = self.model
        asm = model.assembler
        p = state.lam.size
        ut = np.asarray(state.u_c)[:, :2]
        if state.slip_ref is not None:
            ut = ut - state.slip_ref
        contact = (3 * model.contact_nodes[:, None] + np.arange(3)).ravel()
        tau3 = np.zeros((p, 3))
        tau3[:, :2] = state.tau
        slip3 = np.zeros((p, 3))
        slip3[:, :2] = ut
        u_t = np.zeros(asm.n_full)
        u_t[contact] = _global(model, slip3.ravel())
        c_ref = None
        if cond is not None and cond.relative:    # an elastic foundation (class docstring)
            c_ref = np.zeros(asm.n_full)
            c_ref[contact] = _global(model, cond.counterpart_compliance(tau3.ravel()))
            u_t -= c_ref
        tau = np.zeros(asm.n_full)
        tau[contact] = _global(model, tau3.ravel())
        dJ_du = tau - asm.to_full(stiffness_product(cond, asm, state.coords, u_t[asm.free]))
        dalpha = -model.design_contraction(state.coords, state.u, u_t, loads)
        value = float(np.sum(np.asarray(state.tau) * ut))
        return self.scale * value, self.scale * dJ_du, np.zeros(p), self.scale * dalpha, -self.scale * tau, c_ref

    def evaluate_path(self, states, systems, loads, memo=None):
        """The friction work along the path up to the last solve: Σ_k τ^k·Δu_t^k over the solves
        (substeps included), each increment's derivatives on its own solve and, through Δu_t^k's
        reference u_t^(k−1), on the solve before it (on an elastic foundation also through the
        contact force r^(k−1) in the relative reference w_t^(k−1))."""
        memo = {} if memo is None else memo
        value, out = 0.0, {}
        for i, (st, cond, ld) in enumerate(zip(states, systems, loads)):
            key = (id(self), i)
            if key not in memo:
                memo[key] = self._work(st, cond, ld)
            v, y_u, y_lam, dalpha, y_prev, c_ref = memo[key]
            value += v
            add_solve(out, i, Derivatives(y_u, y_lam, dalpha, FULL))
            if i:
                add_solve(out, i - 1, self._previous(states[i - 1], systems[i - 1], loads[i - 1], y_prev, c_ref,
                                                     y_lam, dalpha))
        return Partials(value, out)

    def _previous(self, state, cond, loads, y_prev, c_ref, y_lam, dalpha) -> Derivatives:
        """The derivatives of an increment's work with respect to the solve before it (``state``,
        ``cond``, ``loads`` that solve's): −τ̂ on its tangential contact DOFs and, on an elastic
        foundation, −A c on every DOF and −cᵀ(∂A u − ∂L) at fixed u (class docstring)."""
        if c_ref is None:
            return Derivatives(y_prev, np.zeros_like(y_lam), np.zeros_like(dalpha), FULL)
        asm = self.model.assembler
        c = self.scale * c_ref
        du = y_prev - asm.to_full(stiffness_product(cond, asm, state.coords, c[asm.free]))
        da = -self.model.design_contraction(state.coords, state.u, c, loads)
        return Derivatives(du, np.zeros_like(y_lam), da, FULL)


def stiffness_product(cond, asm, coords, x) -> np.ndarray:
    """A(α) x on the free DOFs: by the system's own ``product`` where A(α) is not formed on this
    process (the PETSc path multiplies on its ranks), else with the system's A(α), else with A
    assembled at ``coords``."""
    product = None if cond is None else cond.product
    if product is not None:
        return product(x)
    A = cond.assembled.A if cond is not None and hasattr(cond, "assembled") else asm.stiffness(coords)
    return A @ x


class PeakStress(Objective):
    """The largest von Mises stress over a region, at the quadrature points of the stiffness rule
    (:mod:`contactopt.fem.stress`), aggregated as ``aggregate`` says (:func:`aggregate`).

    ``region``: a part of the body (a name or a predicate table); its elements are those with
    every node in the part, or, for a part no element lies in (a boundary face), those with a
    node in it. None: the whole body. ∂J/∂u is on every DOF; ∂J/∂α at fixed u moves the
    quadrature points with the mesh (x3 of every node moves with α by the morph).
    """

    name = "peak_stress"
    full_space = True

    def __init__(self, model, scale: float = 1.0, kind: str = "max", rho: float = 50.0, p: float = 8.0,
                 region=None, key: str = "objective.region"):
        super().__init__(model, scale)
        self.kind, self.rho, self.p = kind, float(rho), float(p)
        self.cells = region_cells(model, region, key)

    def values(self, state) -> np.ndarray:
        """σ_vM (len(cells), Q) of the state."""
        return von_mises_points(self.model.assembler, state.coords, state.u, self.cells)

    def evaluate(self, state, cond, loads=None):
        model = self.model
        vm = self.values(state)
        value, w = aggregate(vm.ravel(), self.kind, self.rho, self.p)
        w = w.reshape(vm.shape)
        rows = np.flatnonzero(np.any(w != 0, axis=1))     # the max: one element only
        g_u, g_x = von_mises_gradients(model.assembler, state.coords, state.u, self.cells[rows], w[rows])
        dalpha = model.mesh.contract_dx(g_x)
        return self.partials(self.scale * value, self.scale * g_u, np.zeros(state.lam.size), self.scale * dalpha)


class CounterpartPeakStress(Objective):
    """The largest von Mises stress over a region of a counterpart body (``region = "<body>"`` or
    ``"<body>.<part>"`` of a body other than the face body), aggregated as :class:`PeakStress`.

    A counterpart body held by its clamps has the displacement u_o = K_o⁻¹(f_o − Π_oᵀ r_o) on its free
    DOFs (:meth:`~contactopt.fem.foundation.Foundation.displacement`, plus its prescribed
    translation), r_o the contact forces of its pairs per node frame (t1, t2, ν) = (−τ, λ): linear in
    r alone, its mesh fixed. So ∂J/∂r_o = −Π_o K_o⁻¹ ∂J/∂u_o, and since r = (A u − L) on the body's
    contact DOFs (in global components, ŷ = Q ∂J/∂r there and zero elsewhere), J is a function of
    the body's u: ∂J/∂u = A ŷ on every DOF and, at fixed u, ∂J/∂α = ŷᵀ(∂A/∂α u − ∂L/∂α), as the
    friction work passes its τ (:class:`FrictionalDissipation`). A counterpart held only by its
    contacts (its u_o depends on the relative displacement as well) is refused by name."""

    name = "peak_stress"
    full_space = True

    def __init__(self, model, body: int, cells: np.ndarray, scale: float = 1.0, kind: str = "max",
                 rho: float = 50.0, p: float = 8.0):
        super().__init__(model, scale)
        self.kind, self.rho, self.p = kind, float(rho), float(p)
        self.part, self.cells = model.foundation.parts[body], np.asarray(cells)
        self.rows = model.foundation.rows[body]

    def displacement(self, state) -> np.ndarray:
        """u_o (3·n_o,) of the state, from its contact forces."""
        r = np.c_[-np.asarray(state.tau), state.lam][self.rows]
        return self.part.displacement(r.ravel())

    def values(self, state) -> np.ndarray:
        """σ_vM (len(cells), Q) of the counterpart in the state."""
        f = self.part
        return von_mises_points(f.assembler, f.mesh.reference.points, self.displacement(state), self.cells)

    def evaluate(self, state, cond, loads=None):
        model, f = self.model, self.part
        asm = model.assembler
        u_o = self.displacement(state)
        vm = von_mises_points(f.assembler, f.mesh.reference.points, u_o, self.cells)
        value, w = aggregate(vm.ravel(), self.kind, self.rho, self.p)
        w = w.reshape(vm.shape)
        rows = np.flatnonzero(np.any(w != 0, axis=1))
        g_o, _ = von_mises_gradients(f.assembler, f.mesh.reference.points, u_o, self.cells[rows], w[rows])
        x = f.condensation.solve(g_o[f.assembler.free])
        y = np.zeros((state.lam.size, 3))
        y[self.rows] = -(f.P @ x[f._support_free]).reshape(-1, 3)          # ∂J/∂r per node frame
        contact = (3 * model.contact_nodes[:, None] + np.arange(3)).ravel()
        yhat = np.zeros(asm.n_full)
        yhat[contact] = _global(model, y.ravel())
        yhat = model.unpin(yhat)
        dJ_du = asm.to_full(stiffness_product(cond, asm, state.coords, yhat[asm.free]))
        dalpha = model.design_contraction(state.coords, state.u, yhat, self.loads if loads is None else loads)
        return self.partials(self.scale * value, self.scale * dJ_du, np.zeros(state.lam.size), self.scale * dalpha)


def counterpart_region(model, region, key: str):
    """(counterpart body index, its elements) of a peak-stress region on a counterpart body
    (``"<body>.<part>"``, or ``"<body>"`` where the face body has no part of that name: a name
    without a dot is the face body's part first), or None for a region of the face body. ConfigError naming ``key`` where the counterpart's stress
    is not taken: a counterpart held only by its contacts, or not condensed (the full-space path)."""
    assembly = model.config.assembly
    if not (assembly.spelled and isinstance(region, str) and region):
        return None
    name, dot, part = region.partition(".")
    if name not in assembly.bodies or name == assembly.bodies[0]:
        return None
    if not dot and name in model.body.reference.parts:      # a name without a dot: the face body's part first
        return None
    fnd = model.foundation
    src = model.config.source
    if not model.config.pairs:
        raise ConfigError([f"{src}: {key} = {region!r}: the peak stress of a counterpart body takes a model of "
                           "several pairs so far, not the elastic foundation of one pair"])
    names = [assembly.contacts[pairs[0]].counterpart.split(".")[0] for pairs in fnd.pairs]
    b = names.index(name)
    f = fnd.parts[b]
    if f.rigid is not None:
        raise ConfigError([f"{src}: {key} = {region!r}: body {name!r} is held only by its contacts; the peak stress "
                           "of a counterpart is taken on one held by its clamps (its displacement a function of "
                           "the contact forces alone)"])
    if f.condensation is None:
        raise ConfigError([f"{src}: {key} = {region!r}: the peak stress of a counterpart body is computed on its "
                           "condensation; use linear_solver.path = 'condensation'"])
    ref = f.mesh.reference
    cells = f.assembler.elements
    if not part:
        return b, np.arange(cells.shape[0])
    if part not in ref.parts:
        raise ConfigError([f"{src}: {key} = {region!r}: body {name!r} has no part {part!r} (parts: "
                           f"{', '.join(sorted(ref.parts))})"])
    inside = np.zeros(ref.n_nodes, bool)
    inside[ref.parts[part].nodes] = True
    found = np.flatnonzero(inside[cells].all(axis=1))
    if found.size == 0:
        found = np.flatnonzero(inside[cells].any(axis=1))
    return b, found


def region_cells(model, region, key: str) -> np.ndarray:
    """The elements of a region (:class:`PeakStress`); ConfigError naming ``key`` if it has none.
    In a model written as an assembly the region may name its body, ``"<body>"`` (all of it) or
    ``"<body>.<part>"``: the body that carries the contact faces (the stress of a counterpart body
    is not an objective yet); a name without a dot is a part of that body."""
    cells = model.assembler.elements
    assembly = model.config.assembly
    if assembly.spelled and isinstance(region, str) and region:
        body, dot, part = region.partition(".")
        if dot and body in assembly.bodies and body != assembly.bodies[0]:
            raise ConfigError([f"{model.config.source}: {key} = {region!r}: the peak stress is taken on the body that "
                               f"carries the contact faces ({assembly.bodies[0]!r}); the stress of a counterpart body "
                               "is not an objective yet"])
        if body == assembly.bodies[0]:
            region = part
    if region in (None, "", {}):
        return np.arange(cells.shape[0])
    try:
        part = model.body.part(region)
    except ConfigError as exc:
        raise ConfigError([f"{key}: {p}" for p in exc.problems]) from None
    inside = np.zeros(model.assembler.n_nodes, bool)
    inside[part.nodes] = True
    found = np.flatnonzero(inside[cells].all(axis=1))
    if found.size == 0:
        found = np.flatnonzero(inside[cells].any(axis=1))
    if found.size == 0:
        raise ConfigError([f"{key}: the part has no element of the body"])
    return found


class Compliance(Objective):
    """J = L(α)ᵀu: work of the external load on the equilibrium displacement.

    In condensed form J = ℓᵀu_c + L_iᵀA_ii⁻¹L_i, so ∂J/∂u_c = ℓ and, with ẑ = (0, A_ii⁻¹L_i) and
    u the full displacement, ∂J/∂α|_{u_c} = −ĉ(ẑ, u) − ĉ(0, ẑ) where ĉ(a, b) = bᵀ(∂A a − ∂L).

    On an elastic foundation J is the body's compliance L(α)ᵀu and the state's u_c is the relative
    displacement w, with the body's contact displacement u_b = w + Πq_f − C r and r = S_eff w −
    ℓ_eff: ∂J/∂w = (I − S_eff C)ℓ = S_eff S⁻¹ℓ, and at fixed w the term −ℓᵀC d(S_eff w − ℓ_eff) =
    z̃ᵀ(∂A u − ∂L) with z = −S⁻¹S_eff Cℓ (z̃ its A-harmonic extension) joins ∂J/∂α (docs/foundation.md).

    ∂L is the derivative of the loads the state was solved under: a load case's, or on a load path
    the step's L_k (J_k = L_kᵀu_k at the step's end); a body force or a pressure on a face that moves
    with α has ∂L ≠ 0.
    """

    name = "compliance"

    def evaluate(self, state, cond, loads=None):
        model = self.model
        asm = cond.assembled
        value = float(asm.L_full @ state.u)
        zhat = model.assembler.to_full(cond.factor.recover(asm.L, np.zeros(3 * state.lam.size)))
        loads = self.loads if loads is None else loads

        def dc(coords, u, v):
            return model.design_contraction(coords, u, v, loads)

        dalpha = -dc(asm.coords, zhat, state.u) - dc(asm.coords, np.zeros_like(zhat), zhat)
        dw = cond.ell.copy()
        coupling = cond.coupling
        if coupling is not None:                  # an elastic foundation (class docstring)
            dw = coupling.to_eff(cond.ell)
            z = -coupling.adjoint_z(coupling.foundation.C @ cond.ell)
            if cond.basis is not None:   # transformed nodal values back to the nodes'
                z = cond.basis.back(z)
            z = _global(model, z)        # the nodes' frames back to global components
            dalpha += dc(asm.coords, state.u, model.assembler.to_full(cond.factor.extend(z)))
        return self.partials(self.scale * value, self.scale * dw, np.zeros(state.lam.size), self.scale * dalpha)

    def evaluate_full(self, state, cond, loads=None):
        """The same J = L(α)ᵀu with ∂J/∂u = L on every DOF and ∂J/∂α = uᵀ∂L/∂α at fixed u: the form a
        sum with an objective of the whole displacement takes on an elastic foundation, whose
        adjoint maps ∂J/∂u of the body to the state's w itself (:class:`WeightedSum`); ``loads``
        as in :meth:`evaluate`."""
        asm = cond.assembled
        loads = self.loads if loads is None else loads
        dalpha = -self.model.design_contraction(asm.coords, np.zeros_like(state.u), state.u, loads)
        return Partials(self.scale * float(asm.L_full @ state.u),
                        {0: Derivatives(self.scale * np.asarray(asm.L_full, float), np.zeros(state.lam.size),
                                        self.scale * dalpha, FULL)})


def _global(model, v: np.ndarray) -> np.ndarray:
    """A (3p,) contact vector per node frame (t1, t2, n) in global components, Q v (the model's
    frames; unchanged where the frames are the axes)."""
    if model.frames is None:
        return np.asarray(v, float)
    from ..paths.transforms import from_frames
    return from_frames(np.asarray(v, float), model.frames)


class WeightedSum(Objective):
    """J = Σ_k w_k J_k over the ``[[objective.terms]]`` (each an objective of its own keys).

    A term whose ∂J/∂u is on the contact DOFs only is put on every DOF (zero off the contact
    DOFs) when another term's is on every DOF; the adjoint is then solved once for the sum.
    The :class:`~contactopt.sensitivity.partials.Partials` it returns carry the terms' own values
    (unweighted, without ``scale``) in ``terms``.
    """

    name = "sum"

    def __init__(self, model, terms, scale: float = 1.0):
        super().__init__(model, scale)
        self.terms = terms                      # [(name, weight, objective)]
        self.full_space = any(o.full_space for _, _, o in terms)
        self.accumulates = any(o.accumulates for _, _, o in terms)

    def resolve(self) -> None:
        for _, _, o in self.terms:
            o.resolve()

    @property
    def target(self):
        """The target of the first target_normal_force term, else None (every term's is computed)."""
        self.resolve()
        targets = [o.target for _, _, o in self.terms if isinstance(o, TargetNormalForce)]
        return targets[0] if targets else None

    @property
    def loads(self):
        return self.terms[0][2].loads if self.terms else None

    @loads.setter
    def loads(self, value):
        for _, _, o in self.terms:
            o.loads = value

    def evaluate(self, state, cond, loads=None):
        """Σ_k w_k J_k of one solve, each term under ``loads`` (None: its own)."""
        p = state.lam.size
        n = self.model.assembler.n_full
        value, dlam, dalpha = 0.0, np.zeros(p), np.zeros(state.alpha.size)
        du = np.zeros(n if self.full_space else 3 * p)
        contact = (3 * self.model.contact_nodes[:, None] + np.arange(3)).ravel()
        terms = {}
        for name, w, obj in self.terms:
            full = self._whole_body(obj, cond)
            part = obj.evaluate_full(state, cond, loads) if full else obj.evaluate(state, cond, loads)
            d = part.derivatives
            terms[name] = float(part.value)
            value += w * part.value
            if d.space == FULL or not self.full_space:
                du += w * d.du
            else:                               # a contact-only gradient in a full-space sum
                du[contact] += w * d.du
            dlam += w * d.dlam
            dalpha += w * d.dalpha
        out = self.partials(self.scale * value, self.scale * du, self.scale * dlam, self.scale * dalpha)
        return Partials(out.value, out.solves, terms)

    def _whole_body(self, obj, cond) -> bool:
        """Whether term ``obj`` joins in its whole-body form: on an elastic foundation ∂J/∂u_c of a
        contact-only term is on the state's w, not on the body's u_c, so in a sum on every DOF
        the compliance (the one such term with ∂J/∂u_c ≠ 0) gives ∂J/∂u = L on the body."""
        return (self.full_space and cond is not None and cond.coupling is not None
                and isinstance(obj, Compliance))

    def evaluate_path(self, states, systems, loads, memo=None):
        """Σ_k w_k J_k with each term on the path (:meth:`Objective.evaluate_path`): a term of the
        state at the last solve (under its loads), the friction work summed over the solves."""
        if not self.accumulates:
            return super().evaluate_path(states, systems, loads, memo)
        memo = {} if memo is None else memo
        contact = (3 * self.model.contact_nodes[:, None] + np.arange(3)).ravel()
        n = self.model.assembler.n_full
        value, out, terms = 0.0, {}, {}
        last = len(states) - 1
        for name, w, obj in self.terms:
            if self._whole_body(obj, systems[last]):
                part = obj.evaluate_full(states[last], systems[last], loads[last]).at_solve(last)
            else:
                part = obj.evaluate_path(states, systems, loads, memo)
            terms[name] = float(part.value)
            value += w * part.value
            for i, d in part.solves.items():
                add_solve(out, i, d.on_every_dof(contact, n).scaled(self.scale * w))
        return Partials(self.scale * value, out, terms)


OBJECTIVES = {"target_normal_force": TargetNormalForce, "pressure_uniformity": PressureUniformity,
              "compliance": Compliance, "max_pressure": MaxPressure,
              "frictional_dissipation": FrictionalDissipation, "peak_stress": PeakStress}


def make_objective(config, model, *, target=None, case: int = 0, solve=None, loads=None) -> Objective:
    """The objective of ``[objective]``; ``target`` (a load case's own) replaces objective.target,
    ``case`` is the load case it belongs to (:mod:`contactopt.sensitivity.cases`), ``solve(alpha,
    case)`` returns λ of a design's state (for a 'design' target), ``loads`` the case's load set
    (None: the configuration's [loads]) for objectives whose design term has the load's derivative."""
    obj = config.objective
    if obj.terms:
        names, terms = {}, []
        for k, table in enumerate(obj.terms):
            kind = table.type
            names[kind] = names.get(kind, 0) + 1
            name = kind if names[kind] == 1 else f"{kind}_{names[kind]}"
            one = _one_objective(model, table, 1.0, f"objective.terms[{k}]", target, case, solve)
            terms.append((name, float(table.weight), one))
        out = WeightedSum(model, terms, obj.scale)
    else:
        out = _one_objective(model, obj, obj.scale, "objective", target, case, solve)
    out.loads = loads
    return out


def _one_objective(model, table, scale, key, target, case, solve) -> Objective:
    """One objective of ``table`` (:class:`~contactopt.config.Objective` or one of its terms)."""
    cls = OBJECTIVES[table.type]
    if cls is TargetNormalForce:
        return cls(model, table.target if target is None else target, scale, case, solve)
    agg = (table.aggregate, table.rho, table.p)
    if table.contacts and cls not in (MaxPressure, PressureUniformity):
        raise ConfigError([f"{model.config.source}: {key}.contacts: the pressure objectives (max_pressure, "
                           f"pressure_uniformity) take a subset of the pairs; {table.type} acts on every pair"])
    if cls is MaxPressure:
        return cls(model, scale, *agg, contacts=table.contacts)
    if cls is PressureUniformity:
        return cls(model, scale, contacts=table.contacts)
    if cls is PeakStress:
        on = counterpart_region(model, table.region or None, f"{key}.region")
        if on is not None:
            return CounterpartPeakStress(model, *on, scale, *agg)
        return cls(model, scale, *agg, region=table.region or None, key=f"{key}.region")
    return cls(model, scale)


PRESSURE_TYPES = ("pressure_uniformity", "max_pressure")    # responses of p_m = λ_m/a_m


def pressure_responses(config) -> list[str]:
    """The keys of the objective (or its terms) and the ``[[constraints]]`` that read the contact
    pressure p_m = λ_m/a_m: ``pressure_uniformity``, ``max_pressure``, and a target normal force
    per unit area (``per_area = true``: a pressure p̄ as the forces p̄·a_m), in the objective, a
    term or a load case."""
    obj, out = config.objective, []
    tables = [(f"objective.terms[{k}]", t) for k, t in enumerate(obj.terms)] or [("objective", obj)]
    for key, t in tables:
        if t.type in PRESSURE_TYPES:
            out.append(f"{key}.type = {t.type!r}")
        elif t.type == "target_normal_force":
            own = t.target if t is not obj else None
            targets = [(f"{key}.target", own) if own is not None else ("objective.target", obj.target)]
            targets += [(f"load_cases[{k}].target", c.target) for k, c in enumerate(config.load_cases)
                        if c.target is not None]
            out += [f"{where}.per_area = true" for where, tg in targets if tg.kind == "step" and tg.per_area]
    out += [f"constraints[{k}].type = {c.type!r}" for k, c in enumerate(config.constraints)
            if c.type in PRESSURE_TYPES]
    return list(dict.fromkeys(out))


def linear_tetrahedra_pressure(config, model) -> str | None:
    """The warning of a response of the contact pressure (:func:`pressure_responses`) on a contact
    face of linear tetrahedra, whose nodal pressure is coarse: 3.2 % rms of p0 at h = a/10 on Gmsh's
    tetrahedra in the Hertz benchmark, against 0.62 % with ten-node tetrahedra (docs/mortar.md,
    "Hertz on tetrahedra"); None where it does not apply."""
    if model.body.reference.cell_type != "tetra":
        return None
    keys = pressure_responses(config)
    if not keys:
        return None
    return (f"{config.source}: {', '.join(keys)} read{'s' if len(keys) == 1 else ''} the contact pressure on a "
            "contact face of linear tetrahedra (tetra), whose nodal pressure is coarse: 3.2 % rms of the peak "
            "pressure p0 at element size a/10 (a the contact radius) in the Hertz benchmark on Gmsh's tetrahedra, "
            "against 0.62 % with ten-node tetrahedra; mesh the body with tetra10 (Gmsh: Mesh.ElementOrder = 2) "
            "or hexahedra")


def warn_pressure_on_linear_tetrahedra(config, model) -> None:
    """Log :func:`linear_tetrahedra_pressure` where it applies (once, at the problem's set-up)."""
    message = linear_tetrahedra_pressure(config, model)
    if message:
        log.warning("%s", message)


def objective_types(config) -> set:
    """The objective types a configuration uses (its type, or those of its terms)."""
    return config.objective.types


def constraint_types(config) -> set:
    """The types of the configuration's [[constraints]] (empty without)."""
    return {t.type for t in config.constraints}


@dataclass
class Constraint:
    """One of the ``[[constraints]]``: the response ``objectives[k]`` (an :class:`Objective` of
    load case k, built as the objective of that type is) must stay ≤ ``limit``; ``tol`` the
    relative violation (value − limit)/limit a result may keep; ``steps`` the steps of a load path
    it holds at (a :class:`~contactopt.sensitivity.steps.StepChoice`, in place of ``[objective]
    steps``). A constraint is an objective with a limit: its value and subgradient come from the
    same code (adjoint included)."""

    name: str
    type: str
    limit: float
    tol: float
    objectives: list
    steps: object = None


def make_constraints(config, model, cases, solve=None) -> list:
    """The :class:`Constraint` list of ``[[constraints]]`` (:class:`~contactopt.config.ResponseConstraint`
    records), one objective per load case in ``cases`` (each with the case's loads)."""
    out, names = [], {}
    for n, table in enumerate(config.constraints):
        names[table.type] = names.get(table.type, 0) + 1
        objs = []
        for k, case in enumerate(cases):
            one = _one_objective(model, table, 1.0, f"constraints[{n}]", None, k, solve)
            one.loads = case.loads
            objs.append(one)
        name = table.type if names[table.type] == 1 else f"{table.type}_{names[table.type]}"
        out.append(Constraint(name, table.type, float(table.max), float(table.tol), objs,
                              choice_of(table.steps)))
    return out


FULL_SPACE = frozenset({"peak_stress", "frictional_dissipation"})   # ∂J/∂u on every DOF


def target_values(spec, model, case: int = 0, solve=None) -> np.ndarray:
    """Target normal force λ̄ per contact node from a target (:class:`~contactopt.config.Target`)
    of the configuration.

    kinds: ``constant`` (value), ``step`` (default, then regions {x1 = [lo, hi], x2 = [lo, hi], value}
    applied in order, bounds inclusive, later regions win; with ``per_area = true`` the values are
    contact stresses, multiplied by the nodes' tributary areas), ``values`` (one number per contact node),
    ``design`` (manufactured target λ̄ = λ(α*) for the given control points α*, under the loads
    of load case ``case``, by ``solve(alpha, case)``).
    """
    xy = model.mesh.contact_points()
    if xy.shape[0] < model.n_contact:     # the rows of faces on other bodies (fem.faces), at their nodes
        xy = np.vstack([xy, model.foundation.off_points[:, :2]])
    p = xy.shape[0]
    kind = spec.kind
    if kind == "constant":
        return np.full(p, float(spec.value))
    if kind == "step":
        out = np.full(p, float(spec.default))
        eps = 1e-12
        for reg in spec.regions:
            lo1, hi1 = reg.x1
            lo2, hi2 = reg.x2
            inside = ((xy[:, 0] >= lo1 - eps) & (xy[:, 0] <= hi1 + eps)
                      & (xy[:, 1] >= lo2 - eps) & (xy[:, 1] <= hi2 + eps))
            out[inside] = float(reg.value)
        if spec.per_area:
            out *= model.contact_areas()           # values are contact stresses
        return out
    if kind == "values":
        vals = np.asarray(spec.values, float)
        if vals.size != p:
            raise ConfigError([f"objective.target.values: has {vals.size} numbers, the mesh has {p} contact nodes"])
        return vals
    if kind == "design":
        alpha_star = model.surface.as_vector(spec.alpha) if not np.isscalar(spec.alpha) \
            else np.full(model.n_design, float(spec.alpha))
        return np.array(solve(alpha_star, case), dtype=float)
    raise ConfigError([f"objective.target.kind = {kind!r} is not known"])
