"""A body held only by contact on the condensation path: the kernel of A(α) made explicit.

When the clamps leave rigid motions free (:mod:`contactopt.mesh.rigid`), A(α) is singular with
the kernel R (n_free × k), checked here as ‖A R‖ ≤ 1e-9 ‖A‖ ‖R‖. The contact face keeps every
contact DOF as a Schur DOF, so the interior block A_ii stays positive definite (the face holds the
body in place) and the condensation of the paper stays exact: S = A_cc − A_ci A_ii⁻¹ A_ic is
singular with the kernel R_c (R on the contact DOFs, in the nodes' frames), ℓ, the interior
recovery and the A-harmonic extension are as before. The state is

    S u_c − ℓ = r,  the Coulomb law on (u_c, r),  and therefore  R_cᵀ(ℓ + r) = Rᵀ(f + Bᵀr) = 0:

the contact forces balance the load on every free rigid motion (R_cᵀℓ = Rᵀf since A R = 0),
and u_c is determined by the contact law, not by a clamp.

Factorization: the sparse backends factor A + γ_A I_c (γ_A the mean diagonal of A on the contact
DOFs, added on those only). Adding a matrix on the Schur block changes S by exactly that matrix
and nothing else (ℓ, A_ii⁻¹, the recovery and the extension do not involve A_cc), so S is
S' − γ_A I: an identity, not a spring.

The state: the local solvers need a Delassus operator W = S⁻¹. With Q an orthonormal basis of
R_c and γ = 10⁻³ · mean diag S (10⁻¹ for the projected fixed-point solver), the *anchored* problem S_γ u − (ℓ + γQβ) = r, S_γ = S + γQQᵀ (positive
definite), is an ordinary contact problem for any anchor position β ∈ Rᵏ, and since QᵀS = 0 its
rows along Q read γ(Qᵀu − β) = Qᵀ(ℓ + r): the anchor's force. At the fixed point β = Qᵀu(β) that
force vanishes, the anchored state satisfies S u − ℓ = r exactly, and so it is the state of the
body held only by contact. The iteration β ← Qᵀu(β) (a proximal point iteration on the rigid
motions) starts from β = 0, the body where the mesh puts it; while contact holds a motion
(closed gaps, sticking nodes) u(β) hardly depends on β along it, and the iteration converges in
a few zone solves. It stops when ‖Qᵀ(ℓ + r)‖ ≤ tol · max(‖ℓ‖, ‖r‖) (``tol`` of ``[state]``), or
when that ratio, below :data:`ROUNDOFF_FLOOR`, no longer halves in a step (a tolerance under the
round-off of the zone solves, such as a gradient check's 1e-14, is met as far as it can be); the
state's ``rigid`` (:class:`~contactopt.contact.state.RigidAnchor`) holds the iterations and that ratio.

The adjoint (4.15) is solved with the singular S itself (the equation rows of
:func:`contactopt.sensitivity.adjoint.solve_adjoint` never invert S; its system on the nodes that
are not fixed is nonsingular when contact holds the rigid motions, as the state's is), so it is
the adjoint of the body held only by contact, equilibrium included; the design terms extend v_u
A-harmonically through A_ii, which stays regular. Nothing of γ, γ_A or β enters ξ.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from ..contact.state import RigidAnchor
from ..errors import SolverError

log = logging.getLogger(__name__)

ROUNDOFF_FLOOR = 1e-11    # an imbalance below it that stops falling is round-off: the state is held
MAX_ANCHOR_STEPS = 200
KERNEL_RTOL = 1e-9
GAMMA_FACTOR = 1e-3   # γ = GAMMA_FACTOR · mean diag S: a soft anchor, the iteration contracts by about γ/(γ + k)
GAMMA_FACTOR_FIXED_POINT = 1e-1   # the projected fixed-point solver slows down with W's eigenvalues 1/γ:
                                  # a stiffer anchor, more anchor steps (docs/obstacles.md)


@dataclass
class Anchor:
    """The kernel of S and the anchored stiffness of one design: ``R`` (3p, k) the free rigid
    motions on the contact DOFs per node frame (t1, t2, n), ``Q`` its orthonormal basis,
    ``gamma`` γ and ``S`` = S + γQQᵀ; ``names`` of the motions; ``factor`` = γ / mean diag S."""

    R: np.ndarray
    Q: np.ndarray
    gamma: float
    S: np.ndarray
    names: list
    factor: float = GAMMA_FACTOR


def anchored(S: np.ndarray, Rc: np.ndarray, Q: np.ndarray, names: list, factor: float) -> Anchor:
    """The :class:`Anchor` of the singular S with the anchor stiffness γ = factor · mean diag S."""
    gamma = factor * float(np.mean(np.diag(S)))
    Sg = S + gamma * (Q @ Q.T)
    return Anchor(Rc, Q, gamma, np.ascontiguousarray(0.5 * (Sg + Sg.T)), names, factor)


def with_contact_diagonal(A: sp.csr_matrix, contact: np.ndarray):
    """(A + γ_A I_c, γ_A): the matrix the sparse backends factor (module docstring); A's pattern kept."""
    A = sp.csr_matrix(A, copy=True)
    d = A.diagonal()
    gamma = float(np.mean(d[contact]))
    d[contact] += gamma
    A.setdiag(d)
    return A, gamma


def kernel_on_free(model, modes, coords) -> np.ndarray:
    """R (n_free, k): the free rigid motions of the design's coordinates on the free DOFs."""
    V = modes.vectors(coords).reshape(-1, modes.count)
    return V[model.assembler.free]


def anchor(model, modes, asm, S: np.ndarray, frames, basis=None, extra=None) -> Anchor:
    """The :class:`Anchor` of a design; SolverError when A R ≠ 0 (a clamp that moves with the
    design, for instance). ``frames``: the nodes' frames of the contact DOFs, ``basis`` their
    transformed basis (:class:`~contactopt.paths.transforms.Basis`), or None. ``extra``: (R, names)
    of counterparts held only by contact (their motions on the contact DOFs, in the nodes' frames,
    :meth:`contactopt.fem.counterparts.Counterparts.kernel`); ``modes`` None when the body is held."""
    if modes is None:
        R, names = extra
        Q, _ = np.linalg.qr(R)
        return anchored(S, R, Q, list(names), GAMMA_FACTOR)
    R_free = kernel_on_free(model, modes, asm.coords)
    AR = asm.A @ R_free
    bound = KERNEL_RTOL * abs(asm.A).max() * np.abs(R_free).max()
    if np.abs(AR).max() > bound:
        raise SolverError(f"the rigid motions the clamps leave free are not in the kernel of A(α): "
                          f"max |A R| = {np.abs(AR).max():.3g} > {bound:.3g}")
    Rc = R_free[model.contact_dofs]
    if frames is not None:
        Rc = np.einsum("mij,mik->mjk", frames, Rc.reshape(-1, 3, modes.count)).reshape(-1, modes.count)
    if basis is not None:           # rigid motions are displacements: û = V⁻ᵀ u
        Rc = np.column_stack([basis.displacement(Rc[:, k]) for k in range(modes.count)])
    if Rc.shape[0] < S.shape[0]:      # rows of faces on other bodies (fem.faces): the body's motion leaves them
        Rc = np.vstack([Rc, np.zeros((S.shape[0] - Rc.shape[0], Rc.shape[1]))])
    names = modes.names()
    if extra is not None:
        Rc, names = np.column_stack([Rc, extra[0]]), names + list(extra[1])
    Q, _ = np.linalg.qr(Rc)
    return anchored(S, Rc, Q, names, GAMMA_FACTOR)


def held_state(solve, system, tol: float, method: str = "newton"):
    """The state of a body held only by contact: ``solve(system)`` the zone state of an anchored
    system, iterated on the anchor β ← Qᵀu_c (module docstring); the projected fixed-point solver
    takes a stiffer anchor."""
    an = system.rigid
    factor = GAMMA_FACTOR_FIXED_POINT if method == "fixed-point" else GAMMA_FACTOR
    if factor != an.factor:
        an = anchored(system.contact_S, an.R, an.Q, an.names, factor)
        system = replace(system, rigid=an)
    ell = system.contact_ell
    beta = np.zeros(an.Q.shape[1])
    history = []
    for _ in range(MAX_ANCHOR_STEPS):
        st = solve(replace(system, beta=beta))
        r = np.c_[-st.tau, st.lam].ravel()
        unbalanced = an.Q.T @ (ell + r)                       # = γ(Qᵀu − β), the anchor's force
        rel = float(np.linalg.norm(unbalanced) / max(np.linalg.norm(ell), np.linalg.norm(r), 1e-300))
        history.append(rel)
        if rel <= tol or (rel <= ROUNDOFF_FLOOR and len(history) > 1 and rel >= 0.5 * history[-2]):
            break       # (below the floor, a step that no longer halves the imbalance: round-off)
        beta = an.Q.T @ np.ravel(st.u_c)
    else:
        worst = an.R.T @ (ell + r)
        k = int(np.argmax(np.abs(worst) / np.linalg.norm(an.R, axis=0)))
        raise SolverError(f"{an.names[k]} is not held: after {MAX_ANCHOR_STEPS} anchor steps the contact forces "
                          f"still leave {history[-1]:.3g} of the load unbalanced on the free rigid motions "
                          "(the load has a component along a rigid motion that nothing holds, or lies near the "
                          "limit of what friction holds; check body.clamped and the loads)")
    st.rigid = RigidAnchor(iterations=len(history), residual=history[-1])
    log.debug("body held only by contact: %d anchor step(s), unbalanced %.2e", len(history), history[-1])
    return st
