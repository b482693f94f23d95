"""``contactopt state`` with load cases writes every case (issue #24), and the full-space path
reports its progress (AMG set-up, each Newton step) on large meshes as it goes."""

import json
import logging
from pathlib import Path

import numpy as np

from contactopt import _progress
from contactopt.cli import main
from contactopt.config import load_config
from contactopt.io.statefiles import STATE_FILES, read_state_npz
from contactopt.problem import ShapeProblem

SMALL = {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "state": {"tol": 1e-12}}


def test_state_writes_every_load_case(tmp_path, capsys):
    cfg = load_config(Path(__file__).parent.parent / "examples" / "example1_two_cases.toml").with_updates(SMALL)
    path = tmp_path / "two.toml"
    path.write_text(cfg.to_toml())
    out = tmp_path / "st"
    assert main(["state", str(path), "--out", str(out)]) == 0
    doc = json.loads((out / "cases.json").read_text())
    assert doc["names"] == ["pull", "push"]
    problem = ShapeProblem(cfg)
    states = problem.solve_states(problem.model.initial_design())
    for case, st in zip(doc["cases"], states):
        d = out / case["directory"]
        assert sorted(p.name for p in d.iterdir()) == sorted(STATE_FILES)
        saved = read_state_npz(d / "state.npz")
        assert np.allclose(saved.lam, st.lam, rtol=0, atol=1e-12 * st.lam.max())
        assert case["summary"]["total_normal_force"] == json.loads((d / "state.json").read_text())["summary"][
            "total_normal_force"]
    # the two cases differ (the side traction is reversed): not one state written twice
    assert not np.allclose(states[0].lam, states[1].lam)
    printed = capsys.readouterr().out
    assert "load case 'pull'" in printed and "load case 'push'" in printed


def test_full_space_progress_is_logged_on_large_meshes(caplog, monkeypatch):
    cfg = load_config("example1").with_updates({**SMALL, "linear_solver": {"path": "fullspace"}})
    problem = ShapeProblem(cfg)
    alpha = problem.model.initial_design()
    with caplog.at_level(logging.DEBUG, logger="contactopt"):
        caplog.clear()
        problem.solve_state(alpha)
        small = [r for r in caplog.records if r.name == "contactopt.progress"]
    assert small and all(r.levelno == logging.DEBUG for r in small)      # a small mesh: quiet
    monkeypatch.setattr(_progress, "PROGRESS_DOFS", 100)                 # as if it were large
    problem = ShapeProblem(cfg)
    with caplog.at_level(logging.INFO, logger="contactopt"):
        caplog.clear()
        problem.solve_state(alpha)
        msgs = [r.getMessage() for r in caplog.records if r.name == "contactopt.progress"]
    assert any("AMG hierarchy" in m and "set-up started" in m for m in msgs)
    assert any("AMG hierarchy" in m and "levels in" in m for m in msgs)
    newton = [m for m in msgs if m.startswith("full-space Newton")]
    assert len(newton) >= 2


def test_cli_shows_progress_without_verbose(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(_progress, "PROGRESS_DOFS", 100)
    cfg = load_config("example1").with_updates({**SMALL, "linear_solver": {"path": "fullspace"}})
    path = tmp_path / "c.toml"
    path.write_text(cfg.to_toml())
    root = logging.getLogger()
    before = list(root.handlers)
    try:
        assert main(["state", str(path), "--out", str(tmp_path / "s")]) == 0
    finally:
        for h in root.handlers[:]:
            if h not in before:
                root.removeHandler(h)
    err = capsys.readouterr().err
    assert "contactopt.progress: full-space Newton" in err
    assert "INFO contactopt.problem" not in err          # other INFO records stay in the log only
