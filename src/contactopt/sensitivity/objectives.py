"""Objectives J(α, y) as pluggable pieces with value and partial gradients.

An objective sees the state (λ, τ, u_c; conventions in :mod:`contactopt.contact.state`) and the
condensed system of the design, and returns

    value,  ∂J/∂u_c (3p, per node (t1, t2, ν)),  ∂J/∂λ (p,),  ∂J/∂α at fixed (u_c, λ) (n_design,).

The adjoint (:mod:`contactopt.sensitivity.adjoint`) turns these into a Clarke subgradient of
Θ(α) = J(α, S(α)). To add an objective, subclass :class:`Objective` and register it in
``OBJECTIVES``; nothing in the solver changes. An objective holds the model (for the geometry
and the design terms) and, for a 'design' target, a function that solves the state of a design
— not the problem itself.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError


class Objective:
    """Base class: ``evaluate(state, cond) -> (value, dJ_du (3p,), dJ_dlam (p,), dJ_dalpha (n_design,))``."""

    name = "objective"

    def __init__(self, model, scale: float = 1.0):
        self.model = model
        self.scale = float(scale)

    def evaluate(self, state, cond):
        raise NotImplementedError


class TargetNormalForce(Objective):
    """J = Σ_i (λ̄_i − λ_i)², λ̄ a prescribed normal contact force per contact node (paper §5.2)."""

    name = "target_normal_force"

    def __init__(self, model, target_spec: dict, scale: float = 1.0, case: int = 0, solve=None):
        super().__init__(model, scale)
        self.spec = target_spec
        self.case = case              # the load case whose state a 'design' target is
        self.solve = solve            # (alpha, case) -> λ of that design's state: a 'design' target
        self._target = None

    @property
    def target(self) -> np.ndarray:
        if self._target is None:
            self._target = target_values(self.spec, self.model, self.case, self.solve)
        return self._target

    def evaluate(self, state, cond):
        d = self.target - state.lam
        p = state.lam.size
        return (self.scale * float(d @ d), np.zeros(3 * p), -2.0 * self.scale * d,
                np.zeros(state.alpha.size))


class PressureUniformity(Objective):
    """J = Σ_i (λ_i − mean λ)²: the spread of the normal contact forces (zero for uniform pressure)."""

    name = "pressure_uniformity"

    def evaluate(self, state, cond):
        d = state.lam - state.lam.mean()
        p = state.lam.size
        # Σ d_i = 0, so the derivative of the mean drops out
        return self.scale * float(d @ d), np.zeros(3 * p), 2.0 * self.scale * d, np.zeros(state.alpha.size)


class Compliance(Objective):
    """J = L(α)ᵀu: work of the external load on the equilibrium displacement.

    In condensed form J = ℓᵀu_c + L_iᵀA_ii⁻¹L_i, so ∂J/∂u_c = ℓ and, with ẑ = (0, A_ii⁻¹L_i) and
    u the full displacement, ∂J/∂α|_{u_c} = −ĉ(ẑ, u) − ĉ(0, ẑ) where ĉ(a, b) = bᵀ(∂A a − ∂L).

    On an elastic foundation J is the body's compliance L(α)ᵀu and the state's u_c is the relative
    displacement w, with the body's contact displacement u_b = w + Πq_f − C r and r = S_eff w −
    ℓ_eff: ∂J/∂w = (I − S_eff C)ℓ = S_eff S⁻¹ℓ, and at fixed w the term −ℓᵀC d(S_eff w − ℓ_eff) =
    z̃ᵀ(∂A u − ∂L) with z = −S⁻¹S_eff Cℓ (z̃ its A-harmonic extension) joins ∂J/∂α (docs/foundation.md).
    """

    name = "compliance"

    def evaluate(self, state, cond):
        model = self.model
        asm = cond.assembled
        value = float(asm.L_full @ state.u)
        zhat = model.assembler.to_full(cond.factor.recover(asm.L, np.zeros(3 * state.lam.size)))
        dc = model.design_contraction
        dalpha = -dc(asm.coords, zhat, state.u) - dc(asm.coords, np.zeros_like(zhat), zhat)
        dw = cond.ell.copy()
        coupling = getattr(cond, "coupling", None)
        if coupling is not None:                  # an elastic foundation (class docstring)
            dw = coupling.to_eff(cond.ell)
            z = -coupling.adjoint_z(coupling.foundation.C @ cond.ell)
            dalpha += dc(asm.coords, state.u, model.assembler.to_full(cond.factor.extend(z)))
        return (self.scale * value, self.scale * dw, np.zeros(state.lam.size), self.scale * dalpha)


OBJECTIVES = {"target_normal_force": TargetNormalForce, "pressure_uniformity": PressureUniformity,
              "compliance": Compliance}


def make_objective(config, model, *, target=None, case: int = 0, solve=None) -> Objective:
    """The objective of ``[objective]``; ``target`` (a load case's own) replaces objective.target,
    ``case`` is the load case it belongs to (:mod:`contactopt.sensitivity.cases`), ``solve(alpha,
    case)`` returns λ of a design's state (for a 'design' target)."""
    obj = config["objective"]
    cls = OBJECTIVES[obj["type"]]
    if cls is TargetNormalForce:
        return cls(model, obj["target"] if target is None else target, obj["scale"], case, solve)
    return cls(model, obj["scale"])


def target_values(spec: dict, model, case: int = 0, solve=None) -> np.ndarray:
    """Target normal force λ̄ per contact node from a target table of the configuration.

    kinds: ``constant`` (value), ``step`` (default, then regions {x1 = [lo, hi], x2 = [lo, hi], value}
    applied in order, bounds inclusive, later regions win; with ``per_area = true`` the values are
    contact stresses, multiplied by the nodes' tributary areas), ``values`` (one number per contact node),
    ``design`` (manufactured target λ̄ = λ(α*) for the given control points α*, under the loads
    of load case ``case``, by ``solve(alpha, case)``).
    """
    xy = model.mesh.contact_points()
    p = xy.shape[0]
    kind = spec["kind"]
    if kind == "constant":
        return np.full(p, float(spec.get("value", 0.0)))
    if kind == "step":
        out = np.full(p, float(spec.get("default", 0.0)))
        eps = 1e-12
        for reg in spec.get("regions", []):
            lo1, hi1 = reg.get("x1", [-np.inf, np.inf])
            lo2, hi2 = reg.get("x2", [-np.inf, np.inf])
            inside = ((xy[:, 0] >= lo1 - eps) & (xy[:, 0] <= hi1 + eps)
                      & (xy[:, 1] >= lo2 - eps) & (xy[:, 1] <= hi2 + eps))
            out[inside] = float(reg["value"])
        if spec.get("per_area", False):
            out *= model.contact_areas()           # values are contact stresses
        return out
    if kind == "values":
        vals = np.asarray(spec["values"], float)
        if vals.size != p:
            raise ConfigError([f"objective.target.values: has {vals.size} numbers, the mesh has {p} contact nodes"])
        return vals
    if kind == "design":
        alpha_star = model.surface.as_vector(spec["alpha"]) if not np.isscalar(spec["alpha"]) \
            else np.full(model.n_design, float(spec["alpha"]))
        return np.array(solve(alpha_star, case), dtype=float)
    raise ConfigError([f"objective.target.kind = {kind!r} is not known"])
