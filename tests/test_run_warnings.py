"""Every run warns in run.log and summary.json when F exceeds the uniqueness estimate (3.16)."""

import json

import pytest

from contactopt.config import load_config
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization


def small(F):
    return load_config("example1").with_updates({"mesh": {"nx": 8, "ny": 4, "nz": 3},
                                                 "friction": {"coefficient": F}})


@pytest.mark.integration
def test_friction_above_the_uniqueness_estimate_is_warned_in_summary_and_log(tmp_path):
    cfg = small(0.3)
    problem = ShapeProblem(cfg)
    bound = problem.uniqueness_bound(problem.model.initial_design())
    assert 0 < bound < 0.3            # (3.16) is pessimistic: F = 0.3 is above it on this mesh
    out = tmp_path / "run"
    summary = run_optimization(cfg, out, max_iter=2).summary
    saved = json.loads((out / "summary.json").read_text())
    assert saved["warnings"] == summary["warnings"] and len(saved["warnings"]) == 1
    assert f"{bound:.3g}" in saved["warnings"][0] and "F = 0.3" in saved["warnings"][0]
    log = (out / "run.log").read_text()
    assert "WARNING" in log and "uniqueness estimate (3.16)" in log
    # a resumed run repeats the warning (from a separate problem: its own state is untouched)
    resumed = run_optimization(cfg, out, max_iter=4, resume=True).summary
    assert resumed["warnings"] == saved["warnings"]
    assert resumed["iterations"] == 4


@pytest.mark.parametrize("F", [0.0, 1e-4])
def test_friction_below_the_estimate_has_no_warning(tmp_path, F):
    out = tmp_path / "run"
    run_optimization(small(F), out, max_iter=1)
    assert json.loads((out / "summary.json").read_text())["warnings"] == []
    assert "uniqueness" not in (out / "run.log").read_text()
