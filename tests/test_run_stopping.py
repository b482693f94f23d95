"""A shape-optimization run that has converged stops by itself and says why (summary.json)."""

import json
import re

import numpy as np
import pytest

from contactopt.optimize import minimize_bundle
from contactopt.runner import run_optimization


@pytest.mark.integration
def test_run_stops_when_the_model_predicts_no_decrease(tmp_path, small_config):
    cfg = small_config(optimizer={"max_iter": 200, "ftol": 1e-2})     # the coarse mesh's Θ is rough: ftol 1e-2
    rr = run_optimization(cfg, tmp_path / "run")
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["message"] == rr.summary["message"]
    assert s["success"] is True and s["status"] == 4 and s["iterations"] < 200
    stop = s["stopping"]
    assert stop["criterion"] == "predicted_decrease"
    assert stop["ftol"] == 1e-2 and stop["ftol_window"] == 5 and stop["eps"] == 1e-4
    m = re.fullmatch(r"converged: the model predicts a relative decrease (\S+) < ftol 1e-02 "
                     r"\(stationarity (\S+), eps 1e-04\)", s["message"])
    assert m, s["message"]
    assert float(m.group(1)) == float(f"{stop['J_tolerance']:.1e}")
    assert stop["J_tolerance"] <= 1e-2 < stop["stationarity"]
    assert stop["relative_decrease"] <= 5 * 1e-2
    # the rows of iterations.csv: the stop follows a serious step, after at least 5 of them
    rows = (tmp_path / "run" / "iterations.csv").read_text().strip().splitlines()[1:]
    steps = [r.split(",")[2] for r in rows]
    assert steps[-1] == "serious" and steps.count("serious") >= 5


def test_run_with_the_practical_stop_off_reports_max_iter(tmp_path, small_config):
    cfg = small_config(optimizer={"max_iter": 6, "ftol": 0.0})
    s = run_optimization(cfg, tmp_path / "run").summary
    assert s["success"] is False and s["status"] == 1 and s["iterations"] == 6
    assert s["stopping"]["criterion"] == "max_iter" and s["message"] == "max_iter reached (6 iterations)"
    assert s["stopping"]["stationarity"] > 1e-4


# the figures of REPRODUCTION.md: the built-in examples stop by themselves within 1.02x the best
# J known (long runs to a predicted decrease of 1e-5, REPRODUCTION.md), in at most 120 evaluations
# (measured with the BFGS metric under four OpenBLAS kernels: 94-117, J within 0.2 %,
# docs/stopping.md)
BEST_J = {"example1": 8.3545e-8, "example2": 1.3148e-6, "example3": 1.5325e-7}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BEST_J))
def test_examples_stop_by_themselves_near_the_best_known_optimum(name, tmp_path):
    s = run_optimization(name, tmp_path / name).summary
    assert s["success"] is True and s["status"] in (0, 4), s["message"]
    assert s["evaluations"] <= 120
    assert s["J"] <= 1.02 * BEST_J[name]


@pytest.mark.parametrize("status", [0, 4, 5, 1])
def test_a_finished_run_restored_from_its_checkpoint_keeps_its_verdict(tmp_path, status):
    """A resumed finished run reports the success of the uninterrupted one: statuses 0, 4 and 5
    are successes (minimize_bundle's SUCCESS_STATUS), 1 (max_iter) is not."""
    from contactopt.io.checkpoint import Checkpoint, SavedResult
    from contactopt.optimize import BundleState
    from contactopt.optimize.bundle import SUCCESS_STATUS
    from contactopt.optimize.gallery import PROBLEMS
    from contactopt.runner import _saved_result
    prob = PROBLEMS["Mifflin1"]
    saved = {}

    def keep(r):
        saved["state"] = r.state

    minimize_bundle(prob, prob.x0, max_iter=3, callback=keep)
    Checkpoint(bundle=saved["state"], evaluations=1, elapsed=0.0, scale=1.0, eps=1e-7, max_iter=3, config={},
               result=SavedResult(status, "m", "c", np.nan)).write(tmp_path / "c.npz")
    res = _saved_result(Checkpoint.read(tmp_path / "c.npz"), 3)
    assert isinstance(saved["state"], BundleState) and res.status == status
    assert res.success == (status in SUCCESS_STATUS) == (status != 1)
