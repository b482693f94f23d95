"""The fallback chain on the PETSc path (contactopt.contact.fallback driving
contactopt.contact.fullspace.petsc.PetscProblem, one rank in this process): a Newton solve that
stalls is completed by a continuation to the state of an undisturbed solve, and the state's
statistics name it; when no attempt converges, the error names the attempts and what in the model
to check.

Convention: per contact node (t1, t2, ν), λ = r_ν ≥ 0 the normal force on the body, g ≥ 0 the
initial clearance."""

from __future__ import annotations

import numpy as np
import pytest

from contactopt._mpi import petsc_missing
from contactopt.config import load_config
from contactopt.errors import ContactNotConverged
from contactopt.problem import ShapeProblem

MISSING = petsc_missing()
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"PETSc path: {MISSING}")


def config(friction=0.3):
    return load_config("example1").with_updates({"mesh": {"nx": 12, "ny": 6, "nz": 4},
                                                 "friction": {"coefficient": friction},
                                                 "linear_solver": {"path": "petsc"}})


@pytest.fixture
def stall(monkeypatch):
    """Armed (``arm(n)``), the next Newton loop is cut to ``n`` steps (an injected stall); later
    ones run as asked. ``arm.calls`` counts the loops since."""
    import contactopt.contact.fullspace.petsc as backend
    loop = backend.newton_loop

    def arm(steps=1, times=1):
        arm.calls, arm.steps, arm.times = 0, steps, times

    def stalling(*args, **kw):
        if arm.calls is not None:
            arm.calls += 1
            if arm.calls <= arm.times:
                kw["max_steps"] = arm.steps
        return loop(*args, **kw)
    arm.calls = None
    monkeypatch.setattr(backend, "newton_loop", stalling)
    return arm


@pytest.mark.parametrize("friction, path", [(0.3, "friction continuation"), (0.0, "load continuation")])
def test_a_stalled_petsc_solve_is_completed_by_a_fallback_the_state_names(friction, path, stall):
    cfg = config(friction)
    pb = ShapeProblem(cfg)
    assert pb.path.name == "petsc"
    a = pb.model.initial_design()
    stall()
    st = pb.solve_state(a, warm_start=False)
    assert stall.calls >= 2
    assert st.converged and st.stats.extra["fallback"] == path
    ref = ShapeProblem(cfg).solve_state(a, warm_start=False)
    assert "fallback" not in ref.stats.extra
    np.testing.assert_allclose(st.lam, ref.lam, rtol=0, atol=1e-8 * np.abs(ref.lam).max())
    np.testing.assert_allclose(st.u_c, ref.u_c, rtol=0, atol=1e-8 * np.abs(ref.u_c).max())


def test_no_petsc_state_is_reported_with_the_attempts_and_what_to_check(stall):
    pb = ShapeProblem(config(0.3))
    stall(steps=0, times=100)          # no Newton step in any attempt
    with pytest.raises(ContactNotConverged) as err:
        pb.solve_state(pb.model.initial_design(), warm_start=False)
    text = str(err.value)
    assert "no path reached the tolerance" in text and "full-space Newton (PETSc): error" in text
    assert "friction continuation: error" in text and "load continuation: error" in text
    assert 'path = "fullspace"' in err.value.diagnosis
