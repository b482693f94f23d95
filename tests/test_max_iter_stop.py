"""A run capped at max_iter = N ends as the uncapped run does when that run stops after N
iterations: the stopping tests at the start of iteration N + 1 need no evaluation, so an iterate
that passes one is a converged run, not one cut short (contactopt.optimize.bundle)."""

import numpy as np
import pytest

from contactopt.optimize import minimize_bundle
from contactopt.optimize.gallery import PROBLEMS


@pytest.mark.parametrize("name, kw", [
    ("Shor", dict(eps=1e-4, ftol=0.0)),                 # certified (status 0)
    ("Shor", dict(eps=1e-12, ftol=1e-6)),               # predicted decrease (status 4)
    ("CB2", dict(eps=1e-7)),                            # minimize_bundle's defaults
    ("Rosen-Suzuki", dict(eps=1e-6, metric="bfgs", ftol=5e-4)),   # contactopt run's kind of options
])
def test_a_run_capped_where_it_stops_reports_its_stop_not_max_iter(name, kw):
    prob = PROBLEMS[name]
    free = minimize_bundle(prob, prob.x0, max_iter=2000, **prob.constraints(), **kw)
    assert free.success and free.status in (0, 4, 5) and free.nit < 2000, free.message
    capped = minimize_bundle(prob, prob.x0, max_iter=free.nit, **prob.constraints(), **kw)
    assert capped.success and capped.status == free.status and capped.criterion == free.criterion
    assert capped.message == free.message
    assert capped.nit == free.nit and capped.nfev == free.nfev
    assert np.array_equal(capped.x, free.x) and capped.fun == free.fun
    assert capped.stationarity == free.stationarity


def test_a_run_capped_before_it_stops_reports_max_iter_and_resumes_bit_for_bit():
    prob = PROBLEMS["Shor"]
    kw = dict(eps=1e-4, ftol=0.0)
    free = minimize_bundle(prob, prob.x0, max_iter=2000, **kw)
    short = minimize_bundle(prob, prob.x0, max_iter=free.nit - 1, **kw)
    assert short.status == 1 and not short.success and short.criterion == "max_iter"
    assert short.message == f"max_iter reached ({free.nit - 1} iterations)"
    # the tests made at the cap leave the state as it was: the resumed run is the uncapped one
    resumed = minimize_bundle(prob, None, max_iter=2000, state=short.state, **kw)
    assert resumed.message == free.message and resumed.nfev == free.nfev
    assert np.array_equal(resumed.x, free.x)
