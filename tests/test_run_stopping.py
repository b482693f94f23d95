"""A shape-optimization run that has converged stops by itself and says why (summary.json)."""

import json
import re

import pytest

from contactopt.config import load_config
from contactopt.runner import run_optimization


def small_config(**optimizer):
    return load_config("example1").with_updates(
        {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "name": "small", "optimizer": optimizer})


def test_run_stops_on_relative_decrease_before_max_iter(tmp_path):
    cfg = small_config(max_iter=200)                # built-in ftol = 1e-2 over 5 serious steps
    rr = run_optimization(cfg, tmp_path / "run")
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["message"] == rr.summary["message"]
    assert s["success"] is True and s["status"] == 4 and s["iterations"] < 200
    stop = s["stopping"]
    assert stop["criterion"] == "relative_decrease"
    assert stop["ftol"] == 1e-2 and stop["ftol_window"] == 5 and stop["eps"] == 1e-4
    m = re.fullmatch(r"converged: relative decrease of f (\S+) < ftol 1e-02 over the last 5 "
                     r"serious steps \(stationarity (\S+), eps 1e-04\)", s["message"])
    assert m, s["message"]
    assert float(m.group(1)) == float(f"{stop['relative_decrease']:.1e}")
    assert stop["relative_decrease"] < 1e-2 < stop["stationarity"] * 100
    # the test on the rows of iterations.csv: Θ of the last 6 serious steps
    rows = (tmp_path / "run" / "iterations.csv").read_text().strip().splitlines()[1:]
    serious = [float(r.split(",")[1]) for r in rows if r.split(",")[2] == "serious"]
    assert (serious[-6] - serious[-1]) / serious[-1] == pytest.approx(stop["relative_decrease"],
                                                                     rel=1e-9)


def test_run_with_the_practical_stop_off_reports_max_iter(tmp_path):
    cfg = small_config(max_iter=6, ftol=0.0)
    s = run_optimization(cfg, tmp_path / "run").summary
    assert s["success"] is False and s["status"] == 1 and s["iterations"] == 6
    assert s["stopping"]["criterion"] == "max_iter" and s["message"] == "max_iter reached (6 iterations)"
    assert s["stopping"]["stationarity"] > 1e-4


# the figures of REPRODUCTION.md: the built-in examples stop by themselves, within 150
# evaluations, no worse than 1.05 x the Jopt of the fixed-t runs (401/301/301 evaluations)
PREVIOUS_JOPT = {"example1": 8.3545e-8, "example2": 1.3148e-6, "example3": 1.5325e-7}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PREVIOUS_JOPT))
def test_examples_stop_by_themselves_within_150_evaluations(name, tmp_path):
    s = run_optimization(name, tmp_path / name).summary
    assert s["success"] is True and s["status"] in (0, 4), s["message"]
    assert s["evaluations"] <= 150
    assert s["J"] <= 1.05 * PREVIOUS_JOPT[name]
