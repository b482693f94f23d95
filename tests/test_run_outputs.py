"""A run's outputs read the optimization's own solves: no state is solved after the last
evaluation, the summary's J0 and J are the history's values at α0 and at the returned design,
and a resumed run repeats the recorded solves bit for bit."""

from pathlib import Path

import meshio
import numpy as np
import pytest

from contactopt import runner
from contactopt.config import load_config
from contactopt.sensitivity import solution as solution_module

ROOT = Path(__file__).parent.parent
SMALL = {"nx": 8, "ny": 4, "nz": 3}


def _config(kind: str):
    base = load_config("example1").with_updates({"mesh": SMALL, "name": kind})
    if kind == "plain":
        return base
    if kind == "symmetric_constrained":    # the reduction α = P β + α_fixed and a constraint
        return base.with_updates({"design": {"symmetry": ["x2"]},
                                  "constraints": [{"type": "max_pressure", "max": 0.02}]})
    if kind == "load_cases":
        return load_config(ROOT / "examples" / "example1_two_cases.toml").with_updates({"mesh": SMALL})
    if kind == "terms_on_foundation":      # [[objective.terms]] and the elastic foundation
        return load_config(ROOT / "examples" / "example1_elastic_dissipation.toml").with_updates({"mesh": SMALL})
    raise ValueError(kind)


def _count_solves(monkeypatch) -> dict:
    """Counts of solve_design calls: all of them, and those made inside runner._finish."""
    counts = {"all": 0, "finish": 0}
    inside = {"on": False}
    real_solve, real_finish = solution_module.solve_design, runner._finish

    def solve(*args, **kwargs):
        counts["all"] += 1
        counts["finish"] += inside["on"]
        return real_solve(*args, **kwargs)

    def finish(*args, **kwargs):
        inside["on"] = True
        try:
            return real_finish(*args, **kwargs)
        finally:
            inside["on"] = False
    monkeypatch.setattr(solution_module, "solve_design", solve)
    monkeypatch.setattr(runner, "_finish", finish)
    return counts


def _history_values(out: Path) -> list[float]:
    rows = (out / "history.csv").read_text().splitlines()
    col = rows[0].split(",").index("f")
    return [float(r.split(",")[col]) for r in rows[1:]]


@pytest.mark.parametrize("kind", ["plain", "symmetric_constrained", "load_cases", "terms_on_foundation"])
def test_outputs_solve_no_state_beyond_the_optimization(tmp_path, monkeypatch, kind):
    counts = _count_solves(monkeypatch)
    s = runner.run_optimization(_config(kind), tmp_path / "run", max_iter=3, plots=False).summary
    assert counts["finish"] == 0, counts
    # one solve per evaluation (the first one also gives the scale Θ(α0))
    assert counts["all"] == s["evaluations"], (counts, s["evaluations"])
    f = _history_values(tmp_path / "run")
    assert s["J0"] == f[0] and s["J"] in f


def _arrays(out: Path) -> dict:
    data = {}
    for name in ("initial.vtu", "optimal.vtu"):
        m = meshio.read(out / name)
        data.update({f"{name}:{k}": v for k, v in m.point_data.items()})
        data.update({f"{name}:cell:{k}": np.concatenate(v) for k, v in m.cell_data.items()})
    return data


def _numbers(summary: dict) -> dict:
    state = {k: v for k, v in summary["final_state"].items() if k != "timings_s"}
    return {"J0": summary["J0"], "J": summary["J"], "alpha": summary["alpha"], "final_state": state,
            "objective": summary.get("objective"), "constraints": summary.get("constraints")}


@pytest.mark.parametrize("kind", ["plain", "symmetric_constrained"])
def test_a_resumed_run_repeats_the_recorded_solves_bit_for_bit(tmp_path, monkeypatch, kind):
    """A finished run resumed (its outputs written again) and a run stopped early and resumed to
    the same iteration count give the uninterrupted run's numbers and VTU arrays exactly."""
    cfg = _config(kind)
    ref = runner.run_optimization(cfg, tmp_path / "ref", max_iter=10, plots=False).summary
    want, arrays = _numbers(ref), _arrays(tmp_path / "ref")
    counts = _count_solves(monkeypatch)
    again = runner.run_optimization(cfg, tmp_path / "ref", max_iter=10, resume=True, plots=False).summary
    assert counts["finish"] <= 2                    # the recorded solves of α0 and of the optimum, repeated
    part = tmp_path / "part"
    runner.run_optimization(cfg, part, max_iter=9, plots=False)
    resumed = runner.run_optimization(cfg, part, max_iter=10, resume=True, plots=False).summary
    for got, where in ((again, tmp_path / "ref"), (resumed, part)):
        assert _numbers(got) == want
        other = _arrays(where)
        assert other.keys() == arrays.keys()
        for k, v in arrays.items():
            assert np.array_equal(other[k], v), k
