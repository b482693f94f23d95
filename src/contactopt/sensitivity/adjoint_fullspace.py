"""The adjoint system (4.15) in full space: Clarke subgradients of Θ(α) for states solved by
:func:`contactopt.contact.fullspace.solve_fullspace`, with the same AMG hierarchy and GMRES.

:mod:`contactopt.sensitivity.adjoint` solves (4.15) on the condensed system: with S the Schur
complement on the contact DOFs and v_u ∈ R^{3p} (per node (t1, t2, ν)),

    L    (S v_u + y*_u)_i = 0 (3 rows),                          v_u^i free
    M1   (S v_u + y*_u)_t + C v_t = 0 (2 rows),                  v_ν = y*_λ + F âᵀv_t
    M3+  —                                                        v_u^i = (0, 0, y*_λ)

with â = u_t/‖u_t‖, C = Fλ/‖u_t‖ (I − ââᵀ); then v_λ = −(S v_u + y*_u)_ν on the nodes not of class L
and ξ = ∂J/∂α + ṽᵀ(∂A/∂α u − ∂L/∂α) + v_λᵀ ∂g/∂α with ṽ the A-harmonic extension of v_u.

In full space the unknown is ṽ itself on all free DOFs: S v_u = (A ṽ)_c for ṽ with (A ṽ)_j = 0 on
the non-contact rows j, so (4.15) is one sparse system

    [A(ṽ) + C ṽ]_I = −(Bᵀ y*_u)_I,   ṽ_D = v0 + F âᵀ ṽ_t (slide ν),

I the rows outside D = {all DOFs of M3+ nodes, the normal DOF of M1 nodes} — the same D as the
Newton system of the state at its solution, and the operator is exactly the transpose of that
Newton system's G_II (the Newton system's friction coupling R_n = μ R_N copies a normal *row* into
the tangential ones; here the tangential *unknowns* enter the normal DOF: n = −â, μ = F, and the
Robin block k t tᵀ at the solution is C). It is solved by GMRES preconditioned with the same
V-cycle (:class:`contactopt.fem.amg.ContactHierarchy`, symmetric, so it serves the
transpose as well), and ṽ comes out extended already: no extra solve for the design term.

Degenerate classes use the default choices of :mod:`contactopt.sensitivity.adjoint`
(M2 → L, M3− → M3+, M4 → L); the other choices are not implemented here.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .._threads import sequential_openblas
from ..contact.fullspace import NewtonSystem, sliding_frame
from ..contact.fullspace.core import known_adjoint_part
from ..contact.fullspace.pyamg import sorted_csr
from ..contact.state import CLASS_CODES, State, classify_nodes
from ..errors import SolverError
from ..fem.amg import ContactHierarchy
from ..fem.krylov import KrylovNotConverged, gmres
from .adjoint import DEFAULT_CHOICES, effective_classes
from .partials import FULL

__all__ = ["solve_adjoint_fullspace", "subgradient_fullspace", "FullSpaceAdjoint", "ADJOINT_RTOL"]

# GMRES tolerance of (4.15), relative to its right-hand side, on the pyamg and the PETSc path. The
# subgradient feeds the bundle method, whose trajectory amplifies its error (nearly parallel cutting
# planes): with 1e-10, the subgradients of two solvers (one process, 2 ranks) at the same design
# differed by 7e-10 and J after ten iterations of example1_fine by 5e-4; with 1e-13, by ≤ 6e-8, for
# a few more GMRES iterations (docs/scaling.md "The same answer on any number of ranks").
ADJOINT_RTOL = 1e-13


@dataclass
class FullSpaceAdjoint:
    """``v`` (free DOFs: ṽ, the A-harmonic extension of v_u), ``v_u`` (3p, per node (t1, t2, ν)),
    ``v_lam`` (p,), GMRES ``iterations`` / ``history``, ``timings``."""

    v: np.ndarray
    v_u: np.ndarray
    v_lam: np.ndarray
    iterations: int
    history: list
    timings: dict = field(default_factory=dict)


def solve_adjoint_fullspace(A, contact_dofs, classes, u_c, lam, y_u, y_lam, friction, *,
                            hierarchy: ContactHierarchy, rtol: float = ADJOINT_RTOL, restart: int = 60,
                            max_iter: int = 400, choices=None, v0=None) -> FullSpaceAdjoint:
    """Solve (4.15) in full space (module docstring) for a state with Table 4.1 ``classes``
    (codes of :data:`contactopt.contact.state.CLASS_CODES`), ``u_c`` (p, 3), ``lam`` (p,),
    and the objective's partial gradients ``y_u`` (3p,, or on every free DOF for an objective of
    the whole displacement: the interior rows then read (A ṽ)_i = −g_i) and ``y_lam`` (p,). GMRES stops at
    ‖residual‖ ≤ rtol·‖right-hand side‖; it raises KrylovNotConverged (a SolverError) with its
    history otherwise. ``v0``: a warm start for ṽ (free DOFs), e.g. the adjoint of the previous
    design (its values on the fixed DOFs are ignored)."""
    with sequential_openblas():
        return _solve_adjoint(A, contact_dofs, classes, u_c, lam, y_u, y_lam, friction, hierarchy, rtol,
                              restart, max_iter, choices, v0)


def check_default_choices(choices) -> None:
    """The full-space adjoint (either backend) takes the default degenerate choices only."""
    ch = {**DEFAULT_CHOICES, **(choices or {})}
    if ch != DEFAULT_CHOICES:
        raise SolverError(f"the full-space adjoint implements the default degenerate choices "
                          f"{DEFAULT_CHOICES} only, got {ch}")


def adjoint_classes(classes):
    """(M3+ nodes, M1 nodes, the nodes whose v_λ is free — not of class L) of a state's Table 4.1
    ``classes`` after the default degenerate choices: what the full-space adjoint of either
    backend is set up from."""
    cc = CLASS_CODES
    eff = effective_classes(np.asarray(classes), DEFAULT_CHOICES)
    return np.flatnonzero(eff == cc["M3+"]), np.flatnonzero(eff == cc["M1"]), eff != cc["L"]


def _solve_adjoint(A, contact_dofs, classes, u_c, lam, y_u, y_lam, friction, hierarchy, rtol, restart,
                   max_iter, choices, warm):
    check_default_choices(choices)
    t0 = time.perf_counter()
    A = sorted_csr(A)
    n = A.shape[0]
    cd = np.asarray(contact_dofs, dtype=np.int64).reshape(-1, 3)
    stick, slide, free_lam = adjoint_classes(classes)
    tvec, k, coupling = sliding_frame(u_c, lam, slide, friction)
    # the transpose of the state's Newton system at the solution: n = −â, μ = F, K_t = C
    system = NewtonSystem(A, cd, stick, slide, tvec, k, coupling)
    dirichlet, kt, D = system.dirichlet, system.kt, system.D
    H = system.fine_matrix(hierarchy)            # A + C for the V-cycle
    v0 = np.zeros(n)
    v0[cd.ravel()] = known_adjoint_part(cd.shape[0], stick, slide, y_lam).ravel()
    y_u = np.asarray(y_u, dtype=np.float64)
    if y_u.size == n:                  # ∂J/∂u on every free DOF: the interior rows get −g_i
        f = -y_u.copy()
        y_u = y_u[cd.ravel()]
    else:
        f = np.zeros(n)
        f[cd.ravel()] = -y_u
    rhs = f - A @ v0 - kt @ v0
    rhs[D] = 0.0

    t1 = time.perf_counter()
    M = hierarchy.preconditioner(H, dirichlet, kt)
    t2 = time.perf_counter()
    scale = max(float(np.linalg.norm(rhs)), 1e-300)
    try:
        x0 = None
        if warm is not None:
            x0 = np.array(warm, dtype=np.float64)
            x0[D] = 0.0
        res = gmres(system.apply_transpose, rhs, M, x0=x0, atol=rtol * scale, restart=restart, max_iter=max_iter, scale=scale)
    except KrylovNotConverged as exc:
        exc.args = (f"full-space adjoint (4.15): {exc.args[0]}",)
        raise
    t3 = time.perf_counter()
    v = system.lift(res.x) + v0             # ṽ − v0: the normal DOF of M1 nodes from v_t
    resid = (A @ v)[cd.ravel()] + y_u
    v_lam = np.where(free_lam, -resid[2::3], 0.0)
    return FullSpaceAdjoint(v=v, v_u=v[cd.ravel()].copy(), v_lam=v_lam, iterations=res.iterations,
                            history=res.history, timings={"setup": t1 - t0, "preconditioner": t2 - t1,
                                                          "krylov": t3 - t2, "total": time.perf_counter() - t0})


def subgradient_fullspace(model, objective, alpha, asm, result, friction, *, loads=None, rtol=ADJOINT_RTOL,
                          **kw):
    """Θ(α) and one Clarke subgradient from a full-space state ``result`` (a
    :class:`~contactopt.contact.fullspace.FullSpaceResult` of A(α), L(α) in ``asm``):
    (value, gradient, state, adjoint, timings). ``objective`` is a
    :class:`~contactopt.sensitivity.objectives.Objective` that needs no condensed system (its
    ``evaluate(state, None)``), e.g. the examples' target normal force."""
    t0 = time.perf_counter()
    lam, tau, u_c = result.lam, result.tau, result.u_c
    u_full = model.assembler.to_full(result.u)
    classes = classify_nodes(u_c, lam, tau, asm.gap, friction, u=u_full)
    state = State(alpha=np.asarray(alpha, dtype=float), coords=asm.coords, u=u_full, u_c=u_c, lam=lam,
                  tau=tau, gap=asm.gap, classes=classes, friction=friction, method="fullspace",
                  iterations=result.newton_steps, residual=result.error, complementarity=float("nan"),
                  converged=result.converged)
    part = objective.evaluate(state, None)
    value, d = part.value, part.derivatives
    y_u, y_lam, dJ = d.du, d.dlam, d.dalpha
    if d.space == FULL:                     # ∂J/∂u on every DOF: its free part
        y_u = np.asarray(y_u)[model.assembler.free]
    t1 = time.perf_counter()
    adj = solve_adjoint_fullspace(asm.A, model.contact_dofs, classes, u_c, lam, y_u, y_lam, friction,
                                  hierarchy=result.hierarchy, rtol=rtol, **kw)
    t2 = time.perf_counter()
    v_full = model.assembler.to_full(adj.v)
    xi = dJ + model.design_contraction(asm.coords, u_full, v_full, loads) + model.gap_matrix.T @ adj.v_lam
    t3 = time.perf_counter()
    if not np.all(np.isfinite(xi)):
        raise SolverError("subgradient has non-finite entries")
    return float(value), xi, state, adj, {"objective": t1 - t0, "adjoint": t2 - t1, "design_terms": t3 - t2}
