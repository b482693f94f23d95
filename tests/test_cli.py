"""The command-line interface end to end on small configurations."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config


def test_state_command_writes_every_output(tmp_path, capsys, config_file):
    cfg = config_file()
    out = tmp_path / "st"
    assert main(["state", str(cfg), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "uniqueness bound" in text
    for f in ("state.json", "state.npz", "body.vtu", "lambda.png", "classes.png"):
        assert (out / f).stat().st_size > 0, f
    data = json.loads((out / "state.json").read_text())
    assert data["summary"]["converged"] if "summary" in data else data["converged"]


def test_state_that_does_not_converge_exits_2_and_leaves_no_directory(tmp_path, capsys, config_file):
    out = tmp_path / "st"
    code = main(["state", str(config_file(state={"max_iter": 1})), "--out", str(out)])
    assert code == 2
    assert "not converged" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("case", ["bad_value", "unknown_key", "inverting_design", "inverted", "missing"])
def test_bad_input_exit_code_2_and_nothing_written(tmp_path, capsys, case, config_file):
    out = tmp_path / "out"
    args = []
    if case == "bad_value":
        args = [str(config_file(material={"E": -1.0}))]
    elif case == "unknown_key":
        p = tmp_path / "u.toml"
        p.write_text("[mesh]\nnx = 4\nsize = 3\n")
        args = [str(p)]
    elif case == "inverting_design":
        # a design outside U is solved with warnings (test_design_space); one above c = 1 inverts the mesh
        alpha = tmp_path / "a.json"
        alpha.write_text(json.dumps({"alpha": np.full((8, 4), 1.2).tolist()}))
        args = [str(config_file()), "--alpha", str(alpha)]
    elif case == "inverted":
        # C0 ≥ c would let the surface reach the top face and invert the mapped elements
        args = [str(config_file(geometry={"c": 0.5}))]
    elif case == "missing":
        args = [str(tmp_path / "nope.toml")]
    code = main(["state", *args, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("contactopt: error:") and len(err.splitlines()) >= 1
    assert not out.exists()
    if case == "inverted":
        assert "invert" in err


def test_inverted_mesh_is_refused_by_the_mesh():
    from contactopt.errors import MeshError
    from contactopt.fem.model import ElasticModel
    model = ElasticModel(load_config("example1").with_updates({"mesh": {"nx": 4, "ny": 2, "nz": 2}}))
    alpha = np.full(model.n_design, 0.01)
    alpha[:8] = 1.5                       # the edge x2 = 0 rises above c = 1
    with pytest.raises(MeshError, match="reaches the top face"):
        model.mesh.coordinates(alpha)


def test_solve_fclib_command(capsys):
    path = os.path.join(os.path.dirname(__file__), "data", "fclib", "local_problem_test.hdf5")
    assert main(["solve-fclib", path]) == 0
    assert "error" in capsys.readouterr().out


def test_run_small_example_end_to_end(tmp_path, capsys, config_file):
    cfg = config_file()
    out = tmp_path / "run"
    assert main(["run", str(cfg), "--out", str(out), "--max-iter", "4"]) == 0
    text = capsys.readouterr().out
    assert "it    1" in text and "J0 =" in text
    for f in ("config.toml", "run.log", "history.csv", "checkpoint.npz", "summary.json", "alpha.json",
              "surface.csv", "stress.png", "surface.png", "history.png", "classes.png",
              "initial.vtu", "optimal.vtu", "bodies.pvd", "iterations.csv"):
        assert (out / f).stat().st_size > 0, f
    s = json.loads((out / "summary.json").read_text())
    for k in ("J0", "J", "iterations", "evaluations", "serious_steps", "null_steps", "success", "message",
              "alpha", "wall_time_s", "time_breakdown_s"):
        assert k in s
    assert s["J"] <= s["J0"] and s["admissible"]
    rows = (out / "history.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + s["evaluations"]
    its = (out / "iterations.csv").read_text().strip().splitlines()
    assert len(its) == 1 + s["iterations"] and its[-1].split(",")[0] == str(s["iterations"])
    assert float(its[-1].split(",")[1]) == pytest.approx(s["J"], rel=1e-8)
    # refusing a non-empty directory without --overwrite/--resume
    assert main(["run", str(cfg), "--out", str(out), "--max-iter", "1"]) == 2
    assert "not empty" in capsys.readouterr().err


def test_run_without_plots_writes_every_other_output(tmp_path, capsys, config_file):
    """--no-plots (sweeps): the same run, summary and files, no PNG."""
    cfg = config_file()
    with_plots, without = tmp_path / "a", tmp_path / "b"
    assert main(["run", str(cfg), "--out", str(with_plots), "--max-iter", "2"]) == 0
    assert main(["run", str(cfg), "--out", str(without), "--max-iter", "2", "--no-plots"]) == 0
    assert not list(without.glob("*.png")) and len(list(with_plots.glob("*.png"))) >= 7
    assert {p.name for p in with_plots.iterdir() if p.suffix != ".png"} == {p.name for p in without.iterdir()}
    a, b = (json.loads((d / "summary.json").read_text()) for d in (with_plots, without))
    assert a["J"] == b["J"] and a["evaluations"] == b["evaluations"] and a["alpha"] == b["alpha"]


def test_corrupt_checkpoint_is_refused(tmp_path, capsys, config_file):
    cfg = config_file()
    out = tmp_path / "run"
    assert main(["run", str(cfg), "--out", str(out), "--max-iter", "2"]) == 0
    (out / "checkpoint.npz").write_bytes(b"not a zip file")
    assert main(["run", str(cfg), "--out", str(out), "--resume"]) == 2
    assert "corrupt" in capsys.readouterr().err


@pytest.mark.integration
def test_kill_and_resume_gives_the_uninterrupted_result(tmp_path, config_file):
    cfg = config_file()
    ref = tmp_path / "ref"
    assert main(["run", str(cfg), "--out", str(ref), "--max-iter", "16"]) == 0
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "contactopt.cli", "run", str(cfg), "--out", str(out),
                             "--max-iter", "16"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.time() + 120
    seen = 0
    for line in proc.stdout:
        if line.startswith("it ") and "serious" in line:
            seen += 1
        if seen >= 2 or time.time() > deadline:
            break
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert seen >= 2
    assert main(["run", str(cfg), "--out", str(out), "--resume"]) == 0
    a = json.loads((ref / "summary.json").read_text())
    b = json.loads((out / "summary.json").read_text())
    assert b["iterations"] == a["iterations"] and b["evaluations"] == a["evaluations"]
    assert np.allclose(b["alpha"], a["alpha"], rtol=0, atol=1e-12)
    assert b["J"] == pytest.approx(a["J"], rel=1e-10)
    # the history rows, iteration numbers included, are those of the uninterrupted run
    ha, hb = ((d / "history.csv").read_text().splitlines() for d in (ref, out))
    assert [r.split(",")[:3] for r in ha] == [r.split(",")[:3] for r in hb]


@pytest.mark.integration
def test_a_state_failure_at_a_trial_design_is_a_failed_trial_and_the_run_goes_on(tmp_path, capsys, monkeypatch,
                                                                                  config_file):
    """A state solve that does not converge mid-run, at a trial design: the run does not stop
    (a failed trial, optimize/_trials.py): exit 0, the evaluation named with its reason in run.log and
    failed_trials.csv, its history row f = nan, a summary, and a checkpoint that --resume reads.
    (A run stopped by its initial design: tests/test_failed_trials.py.)"""
    import contactopt.sensitivity.adjoint as adjoint
    from contactopt.errors import ContactNotConverged
    cfg = config_file()
    real = adjoint.subgradient
    calls = {"n": 0}

    def failing(problem, alpha, **kw):
        calls["n"] += 1
        if calls["n"] == 7:
            raise ContactNotConverged("Newton: not converged (test)", [1e-3, 1e-4])
        return real(problem, alpha, **kw)

    monkeypatch.setattr(adjoint, "subgradient", failing)
    out = tmp_path / "run"
    assert main(["run", str(cfg), "--out", str(out), "--max-iter", "8"]) == 0
    capsys.readouterr()
    log = (out / "run.log").read_text()
    assert "evaluation 7" in log and "not converged (test)" in log
    rows = (out / "failed_trials.csv").read_text().splitlines()
    assert rows[0] == "evaluation,iteration,reason" and len(rows) == 2 and rows[1].startswith("7,")
    history = (out / "history.csv").read_text().splitlines()
    assert history[7].split(",")[0] == "7" and history[7].split(",")[2] == "nan"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["iterations"] == 8 and np.isfinite(summary["J"])
    monkeypatch.setattr(adjoint, "subgradient", real)
    assert main(["run", str(cfg), "--out", str(out), "--resume"]) == 0


def test_unusable_output_directory_exit_2_and_nothing_written(tmp_path, capsys, config_file):
    """An output path that cannot be a directory (its parent is a file): exit 2, a clear message."""
    cfg = config_file()
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    assert main(["run", str(cfg), "--out", str(blocker / "run"), "--max-iter", "1"]) == 2
    err = capsys.readouterr().err
    assert "output directory" in err and str(blocker) in err
    assert blocker.read_text() == "x"
    assert main(["run", str(cfg), "--out", str(blocker), "--max-iter", "1"]) == 2
    assert "is not a directory" in capsys.readouterr().err


def test_resume_with_an_unusable_delassus_design_touches_nothing(tmp_path, capsys, config_file):
    cfg = config_file()
    out = tmp_path / "run"
    assert main(["run", str(cfg), "--out", str(out), "--max-iter", "3"]) == 0
    ckpt = out / "checkpoint.npz"
    with np.load(ckpt, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    assert data["case0/step0/jacobian_alpha"].size                       # the run kept a Delassus block
    data["case0/step0/jacobian_alpha"] = data["case0/step0/jacobian_alpha"] + 50.0   # the surface above the top face
    np.savez(ckpt, **data)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    assert main(["run", str(cfg), "--out", str(out), "--resume"]) == 2
    err = capsys.readouterr().err
    assert "checkpoint" in err and "Delassus design" in err and "top face" in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
