"""A run that meets a trial design whose state cannot be had goes on (a failed trial: no cut, a
shorter step, the reason in failed_trials.csv, history.csv and run.log), and its resume repeats the
uninterrupted run bit for bit. The unsolvable designs are injected: the state solve refuses every
design whose first control point lies in a band the optimizer's trial points cross."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

import contactopt.sensitivity.adjoint as adjoint
from contactopt.errors import ContactNotConverged
from contactopt.runner import run_optimization

BAND = (0.004, 0.008)


@pytest.fixture
def unsolvable_band(monkeypatch):
    solve = adjoint.subgradient

    def subgradient(problem, x, **kw):
        if BAND[0] < x[0] < BAND[1]:
            raise ContactNotConverged("no state: injected at this design")
        return solve(problem, x, **kw)
    monkeypatch.setattr(adjoint, "subgradient", subgradient)


def test_a_run_goes_on_past_unsolvable_trial_designs(tmp_path, small_config, unsolvable_band):
    cfg = small_config(optimizer={"max_iter": 12})
    s = run_optimization(cfg, tmp_path / "run").summary
    assert s["iterations"] == 12 and s["J"] < s["J0"]
    failed = s["failed_trials"]
    assert failed and all(f["reason"] == "no state: injected at this design" for f in failed)
    with open(tmp_path / "run" / "history.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == s["evaluations"]
    nan = [int(r["evaluation"]) for r in rows if math.isnan(float(r["f"]))]
    assert nan == [f["evaluation"] for f in failed]
    log = (tmp_path / "run" / "run.log").read_text()
    assert log.count("no state at this trial design (no state: injected at this design)") == len(failed)
    assert np.all((np.asarray(s["alpha"]).ravel()[0] <= BAND[0]) | (np.asarray(s["alpha"]).ravel()[0] >= BAND[1]))


@pytest.mark.integration
def test_a_run_with_failed_trials_resumes_bit_for_bit(tmp_path, small_config, unsolvable_band):
    cfg = small_config(optimizer={"max_iter": 12})
    ref = run_optimization(cfg, tmp_path / "ref").summary

    class Stop(BaseException):
        pass

    def stop_after_8(p):
        if p["iteration"] == 8:
            raise Stop
    with pytest.raises(Stop):
        run_optimization(cfg, tmp_path / "cut", progress=stop_after_8)
    res = run_optimization(cfg, tmp_path / "cut", resume=True).summary
    assert (res["iterations"], res["evaluations"], res["J"]) == (ref["iterations"], ref["evaluations"], ref["J"])
    assert res["alpha"] == ref["alpha"] and res["failed_trials"] == ref["failed_trials"]
    assert (tmp_path / "cut" / "history.csv").read_text().count("nan,nan") == len(ref["failed_trials"])
    assert json.loads((tmp_path / "cut" / "summary.json").read_text())["failed_trials"] == ref["failed_trials"]


def test_an_initial_design_without_state_stops_the_run_with_the_reason(tmp_path, small_config, monkeypatch):
    import contactopt.problem as problem

    def no_state(self, alpha, **kw):
        raise ContactNotConverged("no state: injected. The model: a rigid motion; check body.clamped")
    monkeypatch.setattr(problem.ShapeProblem, "evaluate_value", no_state)
    with pytest.raises(ContactNotConverged, match="check body.clamped"):
        run_optimization(small_config(), tmp_path / "run")
    assert not (tmp_path / "run" / "failed_trials.csv").exists()
