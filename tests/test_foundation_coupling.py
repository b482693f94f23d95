"""The coupling of a body with elastic counterparts without S_eff (fem.foundation.Coupling): the
zone's problem and the adjoint in W-form on W = S⁻¹ + C against the same problems on
S_eff = (S⁻¹ + C)⁻¹, and what an evaluation of a clamped assembly factorizes.

Conventions: per contact node (t1, t2, ν); the zone's local problem in the FCLIB order (ν, t1, t2);
r the contact force on the body.
"""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.config import load_config
from contactopt.contact import zone as zone_module
from contactopt.contact.state import CLASS_CODES
from contactopt.contact.zone import CoupledZoneProblem, ZoneProblem
from contactopt.fem import foundation as foundation_module
from contactopt.fem.foundation import Coupling
from contactopt.paths import condensation
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import solve_adjoint, solve_adjoint_compliant

ROOT = Path(__file__).resolve().parents[1]
P_NODES = 10                     # contact nodes of the small systems
M_SUPPORT = 18                   # free support DOFs of their counterparts


def _spd(n, rng, shift=1.0):
    A = rng.standard_normal((n, n))
    return A @ A.T + shift * n * np.eye(n)


def _counterparts(rng, loads: bool):
    """A stand-in for the counterparts of several pairs: Π on m support DOFs, their condensed
    stiffness S_f, C = Π S_f⁻¹ Πᵀ, a translation q and (``loads``) their condensed loads ℓ_o."""
    n = 3 * P_NODES
    P = sp.csr_matrix(rng.random((n, M_SUPPORT)) * (rng.random((n, M_SUPPORT)) < 0.3))
    S_f = _spd(M_SUPPORT, rng)
    W_f = np.linalg.inv(S_f)
    ell_o = rng.standard_normal(M_SUPPORT) if loads else None
    out = SimpleNamespace(P=P, C=np.asarray(P @ W_f @ P.T), condensation=SimpleNamespace(S=S_f),
                          q_f=0.01 * rng.standard_normal(n), ell_o=ell_o, load_displacement=None,
                          support_compliance=lambda x: W_f @ x)
    out.C = 0.5 * (out.C + out.C.T)
    if loads:
        out.load_displacement = np.asarray(P @ (W_f @ ell_o))
    return out


@pytest.mark.parametrize("loads", [False, True])
def test_coupled_zone_problem_is_the_zone_problem_of_s_eff(loads):
    """q0, W_Z, the products and the displacements of the zone's problem on W = S⁻¹ + C with the
    free displacement S⁻¹ℓ − offset equal those on S_eff and ℓ_eff (Woodbury) to 1e-11, ordered or not."""
    rng = np.random.default_rng(3)
    S = _spd(3 * P_NODES, rng)
    f = _counterparts(rng, loads)
    ell = rng.standard_normal(3 * P_NODES)
    coupling = Coupling(S, f)
    S_eff = np.linalg.inv(np.linalg.inv(S) + f.C)
    assert np.allclose(coupling.S_eff, S_eff, rtol=0, atol=1e-11 * np.abs(S_eff).max())
    zone = np.array([1, 2, 4, 7, 8])
    ref = ZoneProblem(coupling.S_eff, coupling.ell_eff(ell), zone)
    r = rng.standard_normal(3 * zone.size)
    for ordered in (True, False):
        zp = CoupledZoneProblem(S, f.C, ell, coupling.offset, zone, ordered=ordered)
        scale = np.abs(ref.W).max()
        assert np.abs(zp.q0 - ref.q0).max() <= 1e-11 * np.abs(ref.q0).max()
        assert np.abs(zp.W - ref.W).max() <= 1e-11 * scale
        assert np.array_equal(zp.W, zp.W.T)
        assert np.abs(zp.product(r) - ref.product(r)).max() <= 1e-11 * np.abs(ref.product(r)).max()
        assert np.abs(zp.displacements(r) - ref.displacements(r)).max() <= 1e-11 * np.abs(ref.displacements(r)).max()
        grown = zp.grow(np.array([0, 9]))
        ref_grown = ZoneProblem(coupling.S_eff, coupling.ell_eff(ell), grown.zone)
        assert np.abs(grown.W - ref_grown.W).max() <= 1e-11 * np.abs(ref_grown.W).max()
    # the body's own compliance with the same factor
    x = rng.standard_normal(3 * P_NODES)
    assert np.allclose(zp.body_solve(x), np.linalg.solve(S, x), rtol=1e-12, atol=0)


def test_support_displacement_from_the_forces():
    """The counterparts' support displacement o = S_f⁻¹(ℓ_o − Pᵀr) from the state's forces equals
    the Woodbury form M⁻¹(Pᵀ(ℓ − S(w + q)) + ℓ_o) of the law's w = W(ℓ_eff + r) to 1e-11."""
    rng = np.random.default_rng(5)
    S = _spd(3 * P_NODES, rng)
    f = _counterparts(rng, loads=True)
    ell = rng.standard_normal(3 * P_NODES)
    r = rng.standard_normal(3 * P_NODES)
    coupling = Coupling(S, f)
    w = (np.linalg.inv(S) + f.C) @ (coupling.ell_eff(ell) + r)
    o_forces = coupling.support_displacement(w, ell, r)
    o_woodbury = coupling.support_displacement(w, ell)
    assert np.abs(o_forces - o_woodbury).max() <= 1e-11 * np.abs(o_woodbury).max()
    assert coupling._L is not None            # the second one needed M's factor


def _state(rng, p):
    """A contact state with nodes of every class the adjoint treats: L, M1, M3+, the limits of
    M2 and M3− (by the choices below), per node (t1, t2, ν)."""
    codes = ["L", "M1", "M3+", "M1", "M2", "M3-", "L", "M3+", "M1", "L"]
    classes = np.array([CLASS_CODES[c] for c in codes])
    lam = np.where(classes == CLASS_CODES["L"], 0.0, 0.5 + rng.random(p))
    ut = rng.standard_normal((p, 2))
    tau = 0.3 * lam[:, None] * ut / np.linalg.norm(ut, axis=1)[:, None]
    u_c = np.column_stack([ut, np.zeros(p)])
    return SimpleNamespace(lam=lam, classes=classes, friction=0.3, tau=tau, u_c=u_c, slip_increment=ut)


@pytest.mark.parametrize("known", [False, True])
def test_adjoint_in_w_form_is_the_adjoint_of_s_eff(known):
    """(4.15) solved directly in W-form on W = S⁻¹ + C gives the v_u, v_λ of the S-form adjoint on
    S_eff to 1e-10, s = S_eff v_u and x = S⁻¹ s (the design terms' S⁻¹ S_eff v_u); ``known``: a
    ∂J/∂u_c on the nodes of class L too (the known part of s)."""
    rng = np.random.default_rng(7)
    p = P_NODES
    S = _spd(3 * p, rng)
    f = _counterparts(rng, loads=False)
    W = np.linalg.inv(S) + f.C
    S_eff = np.linalg.inv(W)
    state = _state(rng, p)
    y_u = rng.standard_normal(3 * p)
    if not known:
        y_u.reshape(p, 3)[state.classes == CLASS_CODES["L"]] = 0.0
    y_lam = rng.standard_normal(p)
    choices = {"M2": "M1", "M3-": "M1"}
    v_ref, lam_ref = solve_adjoint(S_eff, state, y_u, y_lam, choices)

    def block(K):
        dof = (3 * K[:, None] + np.arange(3)).ravel()
        return W[np.ix_(dof, dof)]

    def apply(s):
        x = np.linalg.solve(S, s)
        return x + f.C @ s, x

    v_u, v_lam, s, x = solve_adjoint_compliant(block, apply, state, y_u, y_lam, choices)
    assert np.abs(v_u - v_ref).max() <= 1e-10 * np.abs(v_ref).max()
    assert np.abs(v_lam - lam_ref).max() <= 1e-10 * np.abs(lam_ref).max()
    assert np.abs(s - S_eff @ v_ref).max() <= 1e-10 * np.abs(s).max()
    assert np.abs(x - np.linalg.solve(S, S_eff @ v_ref)).max() <= 1e-10 * np.abs(x).max()


def test_an_evaluation_factorizes_the_body_alone(monkeypatch):
    """An evaluation (state and subgradient) of Example 1's block on two clamped slabs makes one
    dense Cholesky factorization, of the block's S (3p × 3p): none of M = S_f + PᵀSP on the
    slabs' support DOFs, none of S_eff; the coupling forms neither S_eff nor M."""
    pb = ShapeProblem(load_config(str(ROOT / "examples" / "block_two_slabs.toml")))
    p = pb.model.n_contact
    sizes = []
    real = zone_module.cholesky_lower

    def counted(a):
        sizes.append(a.shape[0])
        return real(a)

    couplings = []

    class Recorded(Coupling):
        def __init__(self, *args, **kw):
            super().__init__(*args, **kw)
            couplings.append(self)

    monkeypatch.setattr(zone_module, "cholesky_lower", counted)
    monkeypatch.setattr(foundation_module, "cholesky_lower", counted)
    monkeypatch.setattr(condensation, "Coupling", Recorded)
    value, xi = pb.evaluate(pb.model.initial_design())
    assert np.isfinite(value) and np.all(np.isfinite(xi))
    assert sizes == [3 * p]
    assert len(couplings) == 1 and couplings[0].compliant
    assert couplings[0]._S_eff is None and couplings[0]._L is None
