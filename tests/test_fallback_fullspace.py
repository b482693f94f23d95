"""The fallback chain on the full-space path (contactopt.contact.fallback driving
contactopt.contact.fullspace.FullSpaceProblem): a Newton solve that fails is completed by a cold
restart, a continuation in the friction coefficient or in the load, to the state of an undisturbed
solve; when no path converges, the error names what in the model to check.

Convention: per contact node (t1, t2, ν), λ = r_ν ≥ 0 the normal force on the body."""

from __future__ import annotations

import numpy as np
import pytest

import contactopt.contact.fullspace.pyamg as fs
from contactopt.config import load_config
from contactopt.contact.fullspace import solve_fullspace, solve_fullspace_with_fallbacks
from contactopt.errors import ContactNotConverged
from contactopt.problem import ShapeProblem


def small(friction):
    pb = ShapeProblem(load_config("example1").with_updates({"friction": {"coefficient": friction},
                                                             "mesh": {"nx": 12, "ny": 6, "nz": 4}}))
    m = pb.model
    asm = m.assemble(m.initial_design(), pb.cases[0].loads)
    return pb, asm, dict(coords=asm.coords, free=m.assembler.free, tol=1e-11)


@pytest.fixture
def fail_first(monkeypatch):
    """Armed (``arm()``), the next Newton loop stops after one step (an injected stall); later ones
    run as asked. Returns ``arm``; ``arm.calls`` counts the loops since."""
    loop = fs.newton_loop

    def arm():
        arm.calls = 0

    def stalling(*args, **kw):
        if arm.calls is not None:
            arm.calls += 1
            if arm.calls == 1:
                kw["max_steps"] = 1
        return loop(*args, **kw)
    arm.calls = None
    monkeypatch.setattr(fs, "newton_loop", stalling)
    return arm


def same_state(res, ref):
    assert res.converged and res.error <= 1e-11 and res.equilibrium <= 1e-11
    scale = np.abs(ref.r).max()
    assert np.abs(res.r - ref.r).max() <= 1e-8 * scale
    assert np.abs(res.u_c - ref.u_c).max() <= 1e-8 * np.abs(ref.u_c).max()


@pytest.mark.parametrize("friction, warm, path", [(0.3, False, "friction continuation"),
                                                  (0.0, False, "load continuation"),
                                                  (0.3, True, "cold restart")])
def test_an_injected_newton_failure_is_completed_by_a_fallback_that_the_result_names(friction, warm, path, fail_first):
    pb, asm, kw = small(friction)
    cd = pb.model.contact_dofs
    ref = solve_fullspace(asm.A, asm.L, cd, asm.gap, friction, **kw)
    fail_first()
    with pytest.raises(ContactNotConverged):          # the injected stall
        solve_fullspace(asm.A, asm.L, cd, asm.gap, friction, **kw)
    fail_first()
    if warm:                              # a warm start far from this state: twice its forces
        kw = dict(kw, r0=2 * ref.r, u0=2 * ref.u)
    res = solve_fullspace_with_fallbacks(asm.A, asm.L, cd, asm.gap, friction, **kw)
    assert fail_first.calls >= 2 and res.fallback == path and res.fallback_iterations >= 1
    same_state(res, ref)


def test_a_solve_that_needs_no_fallback_is_the_methods_own():
    pb, asm, kw = small(0.3)
    cd = pb.model.contact_dofs
    np.random.seed(5)          # pyamg draws the start vectors of its spectral estimates from it
    a = solve_fullspace(asm.A, asm.L, cd, asm.gap, 0.3, **kw)
    np.random.seed(5)
    b = solve_fullspace_with_fallbacks(asm.A, asm.L, cd, asm.gap, 0.3, **kw)
    assert np.array_equal(a.r, b.r) and np.array_equal(a.u, b.u) and a.history == b.history
    assert b.fallback is None


def test_no_state_is_reported_with_what_in_the_model_to_check():
    # no Newton step allowed: every path fails; the model has no defect, and W (formed from a
    # factorization of A on this small mesh) says so
    pb, asm, kw = small(0.3)
    cd = pb.model.contact_dofs
    with pytest.raises(ContactNotConverged) as err:
        solve_fullspace_with_fallbacks(asm.A, asm.L, cd, asm.gap, 0.3, **kw, max_steps=0)
    text = str(err.value)
    assert "not converged: no path reached the tolerance" in text and "full-space Newton: error" in text
    assert "friction continuation: error" in text and "load continuation: error" in text
    assert "no defect found in the model (W positive definite" in err.value.diagnosis
    # a penetrating start is named
    gap = asm.gap.copy()
    gap[3] = -0.05
    with pytest.raises(ContactNotConverged) as err:
        solve_fullspace_with_fallbacks(asm.A, asm.L, cd, gap, 0.3, **kw, max_steps=0)
    assert "a penetrating start: 1 of" in err.value.diagnosis and "contact node 3" in err.value.diagnosis


def test_the_fullspace_path_names_the_fallback_in_the_states_statistics(fail_first):
    cfg = load_config("example1").with_updates({"mesh": {"nx": 12, "ny": 6, "nz": 4},
                                                 "linear_solver": {"path": "fullspace"}})
    pb = ShapeProblem(cfg)
    assert pb.path.name == "fullspace"
    a = pb.model.initial_design()
    fail_first()
    st = pb.solve_state(a, warm_start=False)
    assert st.converged and st.stats.extra["fallback"] == "friction continuation"
    ref = ShapeProblem(cfg).solve_state(a, warm_start=False)
    assert "fallback" not in ref.stats.extra
    np.testing.assert_allclose(st.lam, ref.lam, rtol=0, atol=1e-8 * np.abs(ref.lam).max())
