"""A force-controlled obstacle on every path that takes one: its translation and its subgradient.

A force-controlled obstacle (``[obstacle] control = "force"``, :mod:`contactopt.mesh.obstacle`)
translates by s f̂ along its force f: the gap is g − s c, c_m = f̂·n_m, and the obstacle moves
under the node by s e_m, e_m = (b_m)_t the tangential part of b_m = R_mᵀ f̂ (per node frame
(t1, t2, n)), so that the contact law sees w = u_c − s e. The translation s solves

    F(s) = Σ_m b_m·r_m − |f| = 0        (r_m = (−τ_m, λ_m), the force on the body in the node's frame),

the resultant along f̂ the obstacle exerts on the body, by Brent's method on a bracket from the
first touch, one state solve per step (:meth:`ForceSearch.solve`). A path gives only the system
moved by s (``translated``), the state of a fixed obstacle (``fixed_state``) and a normal stiffness
per node for the bracket's first step (``normal_stiffness``; :class:`~.base.SolverPath`).
On a load path (condensation path, ``contactopt.sensitivity.steps``) every solve has its own |f|
(the system's ``force``: a step's ``obstacle_force``, ramped over its substeps) and its own s.

The subgradient adds the dependence of s on α (implicit function theorem on F(α, s) = 0):

    ξ = ξ_s − (∂Θ/∂s)(∂F/∂s)⁻¹ ∂F/∂α,

ξ_s the subgradient at fixed s. F is linear in the whole displacement: F = ẽᵀ(A u − L) with ẽ the
vector of free DOFs holding Q b at the contact DOFs (Q = diag(R_m)) and 0 elsewhere, so it is an
objective of the whole displacement with ∂F/∂u = A ẽ and explicit design term ẽᵀ(∂A u − ∂L);
its adjoint (w_u, w_λ, w̃) on any path gives z = w̃ + ẽ, the A-harmonic extension of Q(b + w_u),
hence S(b + w_u) = Qᵀ(A z)_c with no S formed. With S e the change of the contact law's load
per unit s:

    ∂F/∂α = zᵀ(∂A u − ∂L) + (∂g/∂α)ᵀ w_λ,   ∂F/∂s = S(b + w_u)·e − w_λ·c,
    ∂Θ/∂s = Qᵀ(A ṽ)_c·e − v_λ·c                 (J of the state's u_c = w and λ),
    ∂Θ/∂s = Qᵀ(A ṽ + g)_c·e − v_λ·c             (J of the body's whole displacement, g = ∂J/∂u),

ṽ the objective's adjoint extended to every DOF: (A ṽ)_c = S v_u where ṽ is A-harmonic, and
(A ṽ)_c = S v_u − A_ci A_ii⁻¹ g_i for an objective of the whole displacement, whose body
displacement u_c = w + s e moves with s also at fixed w: y*_u·e with y*_u = g_c − A_ci A_ii⁻¹ g_i.

Through a load path's solves s_k depends also on the previous solve's slip w_(k−1) (the reference
of the law): with μ_k = (∂Θ/∂s_k)/(∂F_k/∂s_k), ξ gains −μ_k ∂F_k/∂α and what solve k passes to
solve k − 1 gains −μ_k P_t(S w_u + ∂F_k/∂u_c), F_k's own carry (:meth:`ForceSearch.terms`,
:func:`contactopt.sensitivity.subgradient.case_subgradient`; docs/load_paths.md).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

from ..contact.state import ObstacleControl
from ..errors import ContactNotConverged, SolverError

log = logging.getLogger(__name__)

TANGENTIAL = np.array([1.0, 1.0, 0.0])


@dataclass(frozen=True)
class ForceSearch:
    """The translation of a force-controlled obstacle and its subgradient (module docstring): an
    outer search around the state solve of any path that takes an obstacle. ``force`` the
    obstacle's ``contactopt.fem.model.ObstacleForce`` (the force's magnitude, b_m and c_m per
    contact node). The
    path gives three hooks: ``fixed_state`` (its own solve with the obstacle where a system puts
    it), ``translated`` (a system with the obstacle moved by s f̂) and ``normal_stiffness``."""

    force: object

    # ------------------------------------------------------------------ state
    def solve(self, path, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None):
        """The state with the translation s that balances the force, found by Brent's method
        (module docstring): the state's ``obstacle`` holds s, the resultant and the solves."""
        kw = dict(method=method, warm_start=warm_start, tol=tol, shared=shared, label=label, slip_ref=slip_ref)
        c, b, f = self.force.gap_rate, self.force.b, self.force.magnitude
        if system.force is not None:      # a load step's own force (sensitivity/steps.py)
            f = system.force
        e = self.force.slip
        states = {}

        def excess(s):
            moved = path.translated(system, s, c, e)
            try:
                st = path.fixed_state(moved, ctx, alpha, **kw)
            except ContactNotConverged:
                if not warm_start and ctx.warm is None:
                    raise
                # the full-space Newton can stall where a tangential translation drags the face, from
                # nothing or from a state at another translation: once more the other way (the same
                # state, to its tolerance)
                log.debug("no state at the translation %.6e %s: solved again %s", s,
                          *(("warm-started", "from nothing") if warm_start else ("from nothing", "warm-started")))
                st = path.fixed_state(moved, ctx, alpha, **{**kw, "warm_start": not warm_start})
            states[s] = st
            return excess_of(st, b, f)

        touch = float(np.min(system.gap[c > 0] / c[c > 0]))
        step = f / float(np.max(path.normal_stiffness(system)[c > 0] * c[c > 0] ** 2))
        # lo just past the first touch: with every gap open and no load the frictionless local
        # solver does not converge on r = 0 (it does not on the plane either)
        lo, hi = touch + 1e-3 * step, touch + step
        f_lo, f_hi = excess(lo), excess(hi)
        for _ in range(200):
            if f_lo <= 0 < f_hi:
                break
            if f_lo > 0:
                lo, hi, f_hi = lo - step, lo, f_lo
                f_lo = excess(lo)
            else:
                lo, f_lo, hi = hi, f_hi, hi + step
                f_hi = excess(hi)
            step *= 2.0
        else:
            raise SolverError(f"obstacle.force = {f:g}: no translation of the obstacle balances it")
        if f_lo == 0:
            s = lo
        else:
            s = brentq(excess, lo, hi, xtol=1e-15 * (abs(lo) + abs(hi)), rtol=4 * np.finfo(float).eps, maxiter=200)
        if s not in states:
            excess(s)
        st = states[s]
        st.obstacle = ObstacleControl(translation=s, resultant=f + excess_of(st, b, f), solves=len(states))
        log.debug("force-controlled obstacle: translation %.6e after %d state solves", s, len(states))
        return st

    # ------------------------------------------------------------------ subgradient
    def terms(self, path, system, ctx, state, v_lam, loads=None, *, v=None, y_u=None) -> "ForceTerms":
        """∂Θ/∂s, ∂F/∂s, ∂F/∂α and the adjoint of F (module docstring) at a state; ``v`` ṽ of the
        objective's adjoint on every DOF, ``y_u`` the objective's own ∂J/∂u (on every DOF, it moves
        with s at fixed w; on a load path without what later steps pass down)."""
        m = path.model
        c, b = self.force.gap_rate, self.force.b
        e = self.force.slip
        asm = m.assembler
        # A(α) x on the free DOFs: the matrix, or its product on the ranks where it is not formed here
        Ax = system.product if system.product is not None else system.assembled.A.__matmul__
        frames = m.frames
        dT_ds = -float(v_lam @ c)
        if np.any(e):
            force = Ax(np.asarray(v)[asm.free])[m.contact_dofs]       # (A ṽ)_c
            if y_u is not None and path.is_full(y_u):                    # J of the body's u = w + s e
                force = force + np.asarray(y_u, float)[asm.free][m.contact_dofs]
            if frames is not None:
                force = np.einsum("mij,mi->mj", frames, force.reshape(-1, 3)).ravel()
            dT_ds += float(force @ e)
        if path.mechanics.couple is not None:
            # an elastic foundation pressed by the force: F = bᵀ(S_eff w − ℓ_eff) of the law's w
            # relative to the partners; its adjoint on the law, its design term through the
            # body's contact displacement S⁻¹S_eff (b + w_u) extended (paths/condensation.py)
            S_law = system.contact_S
            y_F = S_law @ b.ravel()                   # ∂F/∂w
            w = path.adjoint(system, ctx, state, y_F, np.zeros(c.size))
            z = w.v + path.law_extension(system, b.ravel())
            dF_da = path.design_contraction(system, state.u, z, loads) + m.gap_matrix.T @ w.v_lam
            dF_ds = float((S_law @ (b.ravel() + w.v_u)) @ e - w.v_lam @ c)
            return ForceTerms(dT_ds, dF_ds, dF_da, w, y_F)
        bg = b.ravel() if frames is None else np.einsum("mij,mj->mi", frames, b).ravel()
        e_free = np.zeros(asm.n_free)
        e_free[m.contact_dofs] = bg
        y_F = asm.to_full(Ax(e_free))                 # ∂F/∂u on every DOF
        w = path.adjoint(system, ctx, state, y_F, np.zeros(c.size))
        z = w.v + asm.to_full(e_free)                 # the A-harmonic extension of Q(b + w_u)
        Sz = Ax(z[asm.free])[m.contact_dofs]
        if frames is not None:
            Sz = np.einsum("mij,mi->mj", frames, Sz.reshape(-1, 3)).ravel()
        dF_da = path.design_contraction(system, state.u, z, loads) + m.gap_matrix.T @ w.v_lam
        dF_ds = float(Sz @ e - w.v_lam @ c)
        return ForceTerms(dT_ds, dF_ds, dF_da, w, y_F)


class ForceTerms(NamedTuple):
    """What :meth:`ForceSearch.terms` gives: ∂Θ/∂s, ∂F/∂s, ∂F/∂α, the adjoint of F
    (:class:`~contactopt.paths.base.Adjoint`) and its right-hand side ∂F/∂u on every DOF (what a
    load step passes to the previous one is that adjoint's :meth:`adjoint_carry`)."""

    dT_ds: float
    dF_ds: float
    dF_da: np.ndarray
    adjoint: object
    y_F: np.ndarray


def excess_of(state, b: np.ndarray, force: float) -> float:
    """Σ_m b_m·r_m − |f| of a state (r_m = (−τ, λ) per node in its frame)."""
    return float(np.sum(b[:, :2] * -state.tau) + b[:, 2] @ state.lam) - force


def normal_stiffness(A, contact_dofs: np.ndarray, frames) -> np.ndarray:
    """(p,) n_mᵀ A_mm n_m, the diagonal stiffness of each contact node along its normal (the
    third column of its frame, e3 without frames): an upper bound of S's, for a first step."""
    cd = np.asarray(contact_dofs).reshape(-1, 3)
    n = np.broadcast_to([0.0, 0.0, 1.0], cd.shape) if frames is None else frames[:, :, 2]
    rows, cols = np.repeat(cd, 3, axis=1), np.tile(cd, (1, 3))
    block = np.asarray(A[rows.ravel(), cols.ravel()]).reshape(-1, 3, 3)
    return np.einsum("mi,mij,mj->m", n, block, n)
