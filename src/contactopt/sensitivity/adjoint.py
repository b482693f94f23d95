"""Clarke subgradients of Θ(α) = J(α, S(α)) from the adjoint generalized equation (paper §4).

The GE (3.18) is 0 ∈ F(α)y − l(α) + Q(y) with y^i = (u_t^i, u_ν^i, λ^i). Its adjoint (4.3),
with the per-node linear subspaces L_i ⊂ Gr D*Φ of (4.4)–(4.14), is the linear system (4.15):

    0 = y* + F(α)ᵀ v + w,   (w^i, v^i) ∈ L_i,

and ξ = ∇_α J + (∇_α(F(α)ȳ − l(α)))ᵀ v is a subgradient (Theorem 4.1). Writing v = (v_u, v_λ),
v_u = (v_t, v_ν) ∈ R^{3p} (per node (t1, t2, ν)) and w = (w_u, w_λ), (4.15) reads

    y*_u + S v_u + (0, v_λ) + w_u = 0,      y*_λ − v_ν + w_λ = 0,

and per node class (â = u_t/‖u_t‖, w̄ = τ/(Fλ), C = Fλ/‖u_t‖ (I − ââᵀ)):

    L   (4.4)   w_u = 0, v_λ = 0                          → the 3 rows of node i hold, v_u^i free
    M1  (4.5)   w_t = C v_t, w_ν = 0, w_λ = F âᵀv_t       → v_ν = y*_λ + F âᵀv_t, 2 t-rows with C
    M3+ (4.6)   v_t = 0, w_ν = w_λ = 0                    → v_u^i = (0, 0, y*_λ) fixed
    M2  (4.10)  choice ``"L"``: b*_4 = 0 (as L), or ``"M1"``: the limit a_4 ↓ 0 of M1 (C = 0)
    M3− (4.14)  choice ``"M3+"``: b*_12 = 0 (as M3+), or ``"M1"``: the limit of M1 as u_t → 0,
                v_t = t w̄, w_t ⊥ w̄, w_λ = F t            → 1 unknown, the row w̄ᵀ(t-rows)
    M4          choice ``"L"`` or ``"M3+"`` (no formula in the paper; a single point of Gr Φ)

L, M1, M3+ give an exact element of ∂Θ; the degenerate classes (M2, M3−, M4) give a one-sided
limit, i.e. the gradient of Θ restricted to one adjacent smooth piece (paper remark after (4.15)).
Then v_λ = −(S v_u + y*_u)_ν where v_λ is free, and

    ξ_k = ∂J/∂α_k + ṽᵀ(∂A/∂α_k ũ − ∂L/∂α_k) + v_λᵀ ∂g/∂α_k,   ṽ = (v_u, −A_ii⁻¹A_ic v_u),

which needs no derivative of S (docs/theory.md).

With load cases (:mod:`contactopt.sensitivity.cases`), Θ = max_k w_k Θ_k or Σ_k w_k Θ_k and
ξ = Σ_k c_k ξ_k over the cases of nonzero coefficient c_k: for the max only the chosen active
case needs its adjoint, for the sum every case of positive weight. Each ξ_k is the above with
the case's state, ℓ_k and loads L_k (the term −ṽᵀ∂L_k/∂α is the case's).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..contact.state import CLASS_CODES, State
from ..errors import SolverError
from ..fem.dense import LUFactor
from ..fem.krylov import KrylovNotConverged, gmres

log = logging.getLogger(__name__)

DEFAULT_CHOICES = {"M2": "L", "M3-": "M3+", "M4": "L"}


@dataclass
class SubgradientResult:
    """Θ(α), one subgradient and what it was built from."""

    value: float
    gradient: np.ndarray
    state: State
    v_u: np.ndarray
    v_lam: np.ndarray
    n_degenerate: int
    exact: bool                       # True when no node is degenerate (ξ ∈ ∂Θ exactly)
    choices: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    case_values: np.ndarray | None = None   # Θ_k per load case (unweighted, in case order)
    case_names: tuple = ()
    active_cases: tuple = ()          # names of the cases active within [objective] active_tol
    case: str = ""                    # the case of ``state`` (max: whose subgradient is used)
    states: list = field(default_factory=list)   # the state of every case
    terms: dict = field(default_factory=dict)    # [[objective.terms]]: each term's value (of ``case``)

    @property
    def n_active(self) -> int:
        return len(self.active_cases)


def effective_classes(classes: np.ndarray, choices: dict) -> np.ndarray:
    """Map degenerate classes onto the subspace they use: returns codes among L, M1, M1lim, M3+, M3-lim."""
    eff = np.array(classes, copy=True)
    c = CLASS_CODES
    m2 = classes == c["M2"]
    eff[m2] = c["L"] if choices["M2"] == "L" else -1          # -1: M1 with C = 0
    m3 = classes == c["M3-"]
    eff[m3] = c["M3+"] if choices["M3-"] == "M3+" else -2     # -2: M1 limit, v_t ∥ w̄
    m4 = classes == c["M4"]
    eff[m4] = c["L"] if choices["M4"] == "L" else c["M3+"]
    return eff


def solve_adjoint(S: np.ndarray, state: State, y_u: np.ndarray, y_lam: np.ndarray, choices=None):
    """Solve the adjoint system (4.15) on the condensed contact system; returns (v_u, v_λ)."""
    choices = check_choices(choices)
    p = state.lam.size
    F = np.broadcast_to(np.asarray(state.friction, dtype=np.float64), (p,))     # F_i per node
    eff = effective_classes(state.classes, choices)
    c = CLASS_CODES
    ut = state.slip_increment      # u_t, or its increment in a load step (sensitivity/steps.py)
    nut = np.linalg.norm(ut, axis=1)
    v0 = np.zeros(3 * p)
    Zr, Zc, Zv = [], [], []        # v_u = Z z + v0
    Rr, Rc, Rv = [], [], []        # rows Rᵀ(·)
    Cblocks = []                   # (col indices, 2×2 block)
    nz = 0
    for i in range(p):
        e = eff[i]
        base = 3 * i
        if e == c["L"]:
            for m in range(3):
                Zr.append(base + m), Zc.append(nz + m), Zv.append(1.0)
                Rr.append(base + m), Rc.append(nz + m), Rv.append(1.0)
            nz += 3
            continue
        v0[base + 2] = y_lam[i]
        if e == c["M3+"]:
            continue
        if e in (c["M1"], -1):
            ahat = ut[i] / nut[i] if nut[i] > 0 else np.zeros(2)
            for m in range(2):
                Zr.append(base + m), Zc.append(nz + m), Zv.append(1.0)
                Zr.append(base + 2), Zc.append(nz + m), Zv.append(F[i] * ahat[m])
                Rr.append(base + m), Rc.append(nz + m), Rv.append(1.0)
            if e == c["M1"] and nut[i] > 0:      # u_t = 0 only without friction (C = 0)
                Cb = F[i] * state.lam[i] / nut[i] * (np.eye(2) - np.outer(ahat, ahat))
                Cblocks.append((nz, Cb))
            nz += 2
            continue
        if e == -2:
            wbar = state.tau[i] / (F[i] * state.lam[i])
            wbar = wbar / np.linalg.norm(wbar)
            for m in range(2):
                Zr.append(base + m), Zc.append(nz), Zv.append(wbar[m])
                Rr.append(base + m), Rc.append(nz), Rv.append(wbar[m])
            Zr.append(base + 2), Zc.append(nz), Zv.append(F[i])
            nz += 1
            continue
        raise AssertionError(e)
    Z = sp.csr_matrix((Zv, (Zr, Zc)), shape=(3 * p, nz))
    R = sp.csr_matrix((Rv, (Rr, Rc)), shape=(3 * p, nz))
    if nz:
        SZ = np.asarray((Z.T @ S).T)                    # S symmetric
        M = np.asarray(R.T @ SZ)
        for j, Cb in Cblocks:
            M[j:j + 2, j:j + 2] += Cb
        rhs = -np.asarray(R.T @ (S @ v0 + y_u)).ravel()
        try:
            lu = sla.lu_factor(M, check_finite=True)
            z = sla.lu_solve(lu, rhs)
        except (ValueError, sla.LinAlgError) as exc:
            raise SolverError(f"adjoint system (4.15) could not be solved: {exc}") from None
        if not np.all(np.isfinite(z)):
            raise SolverError("adjoint system (4.15) is singular (non-finite solution)")
        v_u = Z @ z + v0
    else:
        v_u = v0
    resid = S @ v_u + y_u
    free_lam = ~np.isin(eff, [c["L"]])
    v_lam = np.where(free_lam, -resid[2::3], 0.0)
    return v_u, v_lam


ADJOINT_RTOL = 1e-9      # relative residual of the W-form adjoint (Delassus path): the
                         # subgradient agrees with the Schur path's to ~1e-9 relative


def check_choices(choices):
    choices = {**DEFAULT_CHOICES, **(choices or {})}
    for k, allowed in (("M2", ("L", "M1")), ("M3-", ("M3+", "M1")), ("M4", ("L", "M3+"))):
        if choices[k] not in allowed:
            raise ValueError(f"degenerate choice for {k} must be one of {allowed}")
    return choices


def w_form(state: State, y_u: np.ndarray, y_lam: np.ndarray, choices=None):
    """The adjoint system (4.15) in W-form (:func:`solve_adjoint_delassus`): (K, s, E, D, h) with K
    the nodes not of class L, s (3p) the force S v_u with its known rows s_i = −y*_u,i on the nodes
    of class L and zero on K, and the 3×3 blocks E, D (k, 3, 3) and h (k, 3) per node of K of
    (E W_KK + D) s_K = h − E (W s)_K."""
    choices = check_choices(choices)
    p = state.lam.size
    c = CLASS_CODES
    eff = effective_classes(state.classes, choices)
    K = np.flatnonzero(eff != c["L"])
    FK = np.broadcast_to(np.asarray(state.friction, dtype=np.float64), (p,))[K]     # F per node of K
    s = -np.asarray(y_u, dtype=np.float64).copy()
    s.reshape(p, 3)[K] = 0.0
    k = K.size
    E = np.zeros((k, 3, 3))
    D = np.zeros((k, 3, 3))
    h = np.zeros((k, 3))
    yt = np.asarray(y_u).reshape(p, 3)[K, :2]
    yl = np.asarray(y_lam)[K]
    ek = eff[K]
    m3 = ek == c["M3+"]
    E[m3] = np.eye(3)
    h[m3, 2] = yl[m3]
    m1 = (ek == c["M1"]) | (ek == -1)
    if np.any(m1):
        ut = state.slip_increment[K[m1]]
        nut = np.linalg.norm(ut, axis=1)
        ahat = np.where(nut[:, None] > 0, ut / np.where(nut > 0, nut, 1.0)[:, None], 0.0)
        C = np.where((ek[m1] == c["M1"])[:, None, None],
                     (FK[m1] * state.lam[K[m1]] / np.where(nut > 0, nut, 1.0))[:, None, None]
                     * (np.eye(2) - ahat[:, :, None] * ahat[:, None, :]), 0.0)
        E1 = np.zeros((m1.sum(), 3, 3))
        E1[:, :2, :2] = C
        E1[:, 2, :2] = -FK[m1, None] * ahat
        E1[:, 2, 2] = 1.0
        E[m1] = E1
        D[m1, 0, 0] = D[m1, 1, 1] = 1.0
        h[m1, :2] = -yt[m1]
        h[m1, 2] = yl[m1]
    m3l = ek == -2
    if np.any(m3l):
        tau = state.tau[K[m3l]]
        wbar = tau / np.linalg.norm(tau, axis=1)[:, None]
        E3 = np.zeros((m3l.sum(), 3, 3))
        E3[:, 0, 0], E3[:, 0, 1] = -wbar[:, 1], wbar[:, 0]
        E3[:, 1, :2] = -FK[m3l, None] * wbar
        E3[:, 1, 2] = 1.0
        E[m3l] = E3
        D3 = np.zeros_like(E3)
        D3[:, 2, :2] = wbar
        D[m3l] = D3
        h[m3l, 1] = yl[m3l]
        h[m3l, 2] = -np.einsum("ij,ij->i", wbar, yt[m3l])
    return K, s, E, D, h


def solve_adjoint_compliant(block, apply, state: State, y_u: np.ndarray, y_lam: np.ndarray, choices=None):
    """The adjoint system (4.15) in W-form (:func:`solve_adjoint_delassus`), solved directly: for a
    law whose compliance W is cheap to apply and whose blocks are at hand but whose stiffness
    S = W⁻¹ is not formed (a body on elastic counterparts, W = S_body⁻¹ + C: paths/condensation.py).

    ``block(K)`` returns W_KK (3k × 3k, per node (t1, t2, ν)) of the nodes K not of class L,
    ``apply(s)`` returns (W s, x) for a force s (3p), x what the caller needs along with it (there
    S_body⁻¹ s, whose A-harmonic extension is the design terms' adjoint). The matrix E W_KK + D of
    the nodes of K is factorized by LU. Returns (v_u (3p), v_λ (p), s (3p), x) with v_u = W s,
    v_λ = −(s + y*_u)_ν on K, and x of ``apply`` at the solution s. The same v_u, v_λ as
    :func:`solve_adjoint` with S = W⁻¹, up to round-off."""
    K, s, E, D, h = w_form(state, y_u, y_lam, choices)
    p = state.lam.size
    k = K.size
    v_lam = np.zeros(p)
    if k:
        dofK = (3 * K[:, None] + np.arange(3)).ravel()
        rhs = h.ravel()
        if np.any(s):                     # y*_u = 0 (objectives of λ alone): no known part
            rhs = rhs - np.einsum("kij,kj->ki", E, apply(s)[0][dofK].reshape(k, 3)).ravel()
        W = block(K)
        M = np.einsum("kij,kjn->kin", E, W.reshape(k, 3, 3 * k)).reshape(3 * k, 3 * k)
        diag = (3 * np.arange(k)[:, None, None] + np.arange(3)[None, :, None],
                3 * np.arange(k)[:, None, None] + np.arange(3)[None, None, :])
        M[diag] += D
        if not np.all(np.isfinite(M)):
            raise SolverError("adjoint system (4.15) has non-finite entries")
        lu = LUFactor(np.ascontiguousarray(M))
        if lu.info != 0:
            raise SolverError(f"adjoint system (4.15) is singular (getrf info {lu.info})")
        s[dofK] = lu.solve(rhs)
        v_lam[K] = -(s + y_u)[3 * K + 2]
    v_u, x = apply(s)
    if not (np.all(np.isfinite(v_u)) and np.all(np.isfinite(x))):
        raise SolverError("adjoint system (4.15) has a non-finite solution")
    return v_u, v_lam, s, x


def solve_adjoint_delassus(apply, W_approx, state: State, y_u: np.ndarray, y_lam: np.ndarray,
                           choices=None, *, rtol: float | None = None, shift=None, out: dict | None = None):
    """The adjoint system (4.15) in W-form, for the Delassus path (no S on all contact DOFs).

    The unknown is the contact force s = S v_u (per node (t1, t2, ν)), so v_u = W s. The rows of
    (4.15) that hold on a node of class L fix s there: s_i = −y*_u,i; on the other nodes K
    (all in the contact zone: outside it every node is of class L) the per-class conditions of
    :func:`solve_adjoint` become, with v = W s,

        M3+            v_i = (0, 0, y*_λ)
        M1 (C; C = 0 for the limit of M2)   s_t + C v_t = −y*_t,   v_ν − F âᵀv_t = y*_λ
        M3− limit (w̄, w̄⊥ = (−w̄2, w̄1))       w̄⊥ᵀv_t = 0,  v_ν − F w̄ᵀv_t = y*_λ,  w̄ᵀs_t = −w̄ᵀy*_t

    i.e. (E W_KK + D) s_K = h − E (W s_L)_K with 3×3 blocks E, D per node. It is solved by GMRES
    whose products are exact (``apply(s)`` returns (W s, A⁻¹Bᵀs) by one sparse solve),
    preconditioned by the LU of the same matrix with ``W_approx`` (≈ W_KK, e.g. the kept Delassus
    block of an earlier design, per node (t1, t2, ν)); then v_λ = −(s + y*_u)_ν on K, and the
    A-harmonic extension of v_u is ṽ = A⁻¹Bᵀs, the by-product of the last product. Returns
    (v_u (3p), v_λ (p), ṽ on the free DOFs, GMRES result); ``out["force"]`` = s when ``out`` is given.

    ``shift`` = (d (3p), d_full (free DOFs)) for an objective of the whole displacement: then
    v_u = W s + d and ṽ = A⁻¹Bᵀs + d_full with d_full = −A⁻¹g₀ (g₀ = ∂J/∂u off the contact
    DOFs), and ``y_u`` is ∂J/∂u on the contact DOFs; the equations above hold with this v.
    """
    rtol = ADJOINT_RTOL if rtol is None else rtol
    K, s, E, D, h = w_form(state, y_u, y_lam, choices)
    p = state.lam.size
    k = K.size
    if shift is not None:
        plain = apply

        def apply(f):                     # noqa: F811 - the affine map s -> (W s + d, ṽ)
            v, vf = plain(f)
            return v + shift[0], vf + shift[1]
    if out is not None:
        out["force"] = s                  # filled in place below
    if k == 0:
        v_u, v_full = apply(s)
        return v_u, np.zeros(p), v_full, None
    dofK = (3 * K[:, None] + np.arange(3)).ravel()
    Eb = sp.block_diag(list(E), format="csr")
    Db = sp.block_diag(list(D), format="csr")
    rhs = h.ravel()
    if np.any(s) or shift is not None:   # y*_u = 0 (objectives of λ alone): no known part
        rhs = rhs - Eb @ apply(s)[0][dofK]
    linear = apply if shift is None else plain

    def Q(sK):
        f = np.zeros(3 * p)
        f[dofK] = sK
        return Eb @ linear(f)[0][dofK] + Db @ sK

    # the preconditioner only: single precision, as the Newton matrices of the kept block
    Qt = np.ascontiguousarray(Eb @ np.asarray(W_approx, dtype=np.float32), dtype=np.float32)
    blk = (3 * np.arange(k)[:, None, None] + np.arange(3)[None, :, None], 3 * np.arange(k)[:, None, None]
           + np.arange(3)[None, None, :])
    Qt[blk] += D.astype(np.float32)
    if not np.all(np.isfinite(Qt)):
        raise SolverError("adjoint system (4.15): its preconditioner has non-finite entries")
    lu = LUFactor(Qt)
    if lu.info != 0:
        raise SolverError(f"adjoint system (4.15): its preconditioner is singular (getrf info {lu.info})")
    res = gmres(Q, rhs, lu.solve, rtol=rtol, restart=60, max_iter=60, check=False)
    s[dofK] = res.x
    v_u, v_full = apply(s)
    if not (np.all(np.isfinite(v_u)) and np.all(np.isfinite(v_full))):
        raise SolverError("adjoint system (4.15) has a non-finite solution")
    # GMRES's estimate checked by the true residual, from the product at the solution
    # (relative to the larger of h and the right-hand side with the known part: h may be 0 when
    # the objective's gradient lies off the contact DOFs, e.g. a peak stress away from them)
    true = np.linalg.norm(Eb @ v_u[dofK] + Db @ res.x - h.ravel()) / max(np.linalg.norm(h), np.linalg.norm(rhs),
                                                                          1e-300)
    if not true <= 100 * rtol:
        raise KrylovNotConverged(f"adjoint system (4.15): GMRES estimate {res.history[-1]:.2e}, true "
                                 f"relative residual {true:.2e} > {100 * rtol:.0e}", res.history + [true])
    v_lam = np.zeros(p)
    v_lam[K] = -(s + y_u)[3 * K + 2]
    return v_u, v_lam, v_full, res


def subgradient(problem, alpha, *, choices=None) -> SubgradientResult:
    """Θ(α) and one Clarke subgradient of a :class:`contactopt.problem.ShapeProblem`
    (:meth:`~contactopt.problem.ShapeProblem.subgradient`)."""
    return problem.subgradient(alpha, choices=choices)
