"""Every CLI command on every solver path (issue #21), with and without load cases.

`run`, `state`, `check-gradient` and `sweep` on ``[linear_solver] path = "condensation" |
"delassus" | "fullspace"``, on a tiny Example 2 mesh with one or two load cases: exit code 0, no
traceback or NaN in what the command prints, every output file present and strict JSON (no NaN or
Infinity), numbers that agree between the files. A quantity a path cannot compute (the uniqueness
estimate (3.16) without the condensed stiffness S) is null or absent with a reason, never NaN.
"""

import contextlib
import csv
import io
import json
import math
import os
import re

import numpy as np
import pytest
import tomli_w

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.fem.model import ElasticModel

PATHS = ("condensation", "delassus", "fullspace")
COMBOS = [(path, cases) for path in PATHS for cases in (False, True)]
IDS = [f"{path}-{'cases' if cases else 'single'}" for path, cases in COMBOS]
MESH = {"nx": 8, "ny": 4, "nz": 4}
CASES = [{"name": "pull", "right_traction": [5e-2, 0.0, 0.0]},
         {"name": "push", "right_traction": [-5e-2, 0.0, 0.0]}]
NON_FINITE = re.compile(r"\b(nan|inf|infinity)\b", re.IGNORECASE)


def write_config(directory, path: str, cases: bool):
    """Example 2 on MESH on the given path; with ``cases`` the side traction is the cases' own."""
    updates = {"name": f"{path}-{int(cases)}", "mesh": MESH, "linear_solver": {"path": path}}
    if cases:
        updates["loads"] = {"right_traction": [0.0, 0.0, 0.0]}
        updates["load_cases"] = CASES
    cfg = load_config("example2").with_updates(updates)
    assert cfg["linear_solver"]["path"] == path
    file = directory / f"{cfg.name}.toml"
    file.write_text(tomli_w.dumps(cfg.data))
    return file


def cli(*args) -> tuple[int, str, str]:
    """``contactopt ARGS`` in this process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue(), err.getvalue()


def assert_clean(code, out, err):
    """Exit 0, no traceback anywhere, no non-finite number printed."""
    assert code == 0, out + err
    assert "Traceback" not in out + err, out + err
    assert not NON_FINITE.search(out), out


def _reject(constant):
    raise ValueError(f"non-finite {constant} in JSON")


def strict_json(file):
    """The file's JSON, refusing NaN and Infinity (which json.dumps writes, and JSON has not)."""
    return json.loads(file.read_text(), parse_constant=_reject)


def all_json(directory) -> dict:
    """Every *.json file under ``directory``, parsed strictly (at least one)."""
    files = sorted(directory.rglob("*.json"))
    assert files, f"no JSON file in {directory}"
    return {f.relative_to(directory).as_posix(): strict_json(f) for f in files}


def finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def read_csv(file) -> list[dict]:
    with open(file, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``contactopt run --max-iter 3`` once per (path, cases), shared by the tests that read it."""
    root = tmp_path_factory.mktemp("runs")
    done = {}

    def get(path, cases):
        if (path, cases) not in done:
            cfg = write_config(root, path, cases)
            out = root / f"run-{cfg.stem}"
            done[path, cases] = (out, *cli("run", cfg, "--out", out, "--max-iter", 3))
        return done[path, cases]
    return get


# ---------------------------------------------------------------------------------- run
@pytest.mark.parametrize(("path", "cases"), COMBOS, ids=IDS)
def test_run(runs, path, cases):
    """A short run writes every output, strict JSON, and its tables agree with its summary."""
    out, code, stdout, stderr = runs(path, cases)
    assert_clean(code, stdout, stderr)
    for name in ("config.toml", "run.log", "history.csv", "iterations.csv", "checkpoint.npz", "summary.json",
                 "alpha.json", "surface.csv", "initial.vtu", "optimal.vtu", "bodies.pvd"):
        assert (out / name).stat().st_size > 0, name
    js = all_json(out)
    s, alpha = js["summary.json"], js["alpha.json"]
    assert s["iterations"] == 3 and s["evaluations"] >= 3
    assert finite(s["J0"]) and finite(s["J"]) and s["J0"] > 0
    assert s["ratio"] == s["J"] / s["J0"]
    assert s["admissible"] and np.isfinite(s["alpha"]).all()
    assert alpha["alpha"] == s["alpha"] and list(np.shape(alpha["alpha"])) == alpha["shape"]
    history = read_csv(out / "history.csv")
    assert [int(r["evaluation"]) for r in history] == list(range(1, s["evaluations"] + 1))
    assert all(math.isfinite(float(r["f"])) for r in history)
    # evaluation 1 is at α0 (warm-started, so equal to the summary's J0 to the solver's tolerance)
    assert float(history[0]["f"]) == pytest.approx(s["J0"], rel=1e-9)
    its = read_csv(out / "iterations.csv")
    assert [int(r["iteration"]) for r in its] == [1, 2, 3]
    assert float(its[-1]["J"]) == pytest.approx(s["J"], rel=1e-8)
    assert all(math.isfinite(float(r[k])) for r in its for k in ("J", "t", "stationarity"))
    if cases:
        lc = s["load_cases"]
        assert lc["names"] == ["pull", "push"] and set(lc["active"]) <= {"pull", "push"} and lc["active"]
        assert s["J0"] == max(lc["J0"].values()) and s["J"] == max(lc["J"].values())
        assert all(finite(v) for v in [*lc["J0"].values(), *lc["J"].values()])
        assert (out / "cases.png").stat().st_size > 0
        for r in history:
            assert float(r["f"]) == max(float(r["f_pull"]), float(r["f_push"])) > 0
            assert r["active_cases"] in ("pull", "push", "pull;push")
    else:
        assert "load_cases" not in s and "f_pull" not in history[0]


@pytest.mark.parametrize(("path", "cases"), COMBOS, ids=IDS)
def test_run_keeps_J_at_most_J0(runs, path, cases):
    """J is recomputed at the run's end: never above J0, and equal to it at the same design.

    The bundle method only moves on a decrease, so J > J0 would mean the optimum is worse than the
    start; a run of null steps only ends at α0, where J and J0 are the same computation."""
    out, code, stdout, stderr = runs(path, cases)
    assert code == 0, stdout + stderr
    s = strict_json(out / "summary.json")
    if s["serious_steps"] == 0:
        cfg = load_config(out / "config.toml")
        model = ElasticModel(cfg)
        alpha0 = model.surface.as_matrix(model.initial_design()).tolist()
        assert s["alpha"] == alpha0
        assert s["J"] == s["J0"], f"J = {s['J']!r} and J0 = {s['J0']!r} at the same design α0"
        if cases:
            assert s["load_cases"]["J"] == s["load_cases"]["J0"]
    assert s["J"] <= s["J0"]


# ---------------------------------------------------------------------------------- state
@pytest.mark.parametrize(("path", "cases"), COMBOS, ids=IDS)
def test_state(tmp_path, path, cases):
    """The state at α0: every file, strict JSON, and the uniqueness estimate a number only where
    the path forms S (the condensation), else null or absent with the reason."""
    cfg = write_config(tmp_path, path, cases)
    out = tmp_path / "state"
    code, stdout, stderr = cli("state", cfg, "--out", out)
    assert_clean(code, stdout, stderr)
    if cases:        # one directory per load case, listed in cases.json
        listing = all_json(out)["cases.json"]
        dirs = [out / c["directory"] for c in listing["cases"]]
        assert [c["name"] for c in listing["cases"]] == listing["names"] and len(dirs) == 2
    else:
        dirs = [out]
    for d in dirs:
        for name in ("state.json", "state.npz", "body.vtu", "lambda.png", "classes.png"):
            assert (d / name).stat().st_size > 0, name
        s = all_json(d)["state.json"]["summary"]
        assert s["converged"] and finite(s["total_normal_force"]) and s["total_normal_force"] > 0
        with np.load(d / "state.npz") as z:
            assert all(np.isfinite(z[k]).all() for k in ("u", "u_c", "lam", "tau", "gap"))
            assert float(z["lam"].sum()) == pytest.approx(s["total_normal_force"], rel=1e-12)
        if path == "condensation":
            assert finite(s["uniqueness_bound_F0"]) and s["uniqueness_bound_F0"] > 0
            assert "uniqueness_bound_F0_reason" not in s
            assert "uniqueness bound (3.16) F0" in stdout
        else:
            assert s.get("uniqueness_bound_F0") is None
            assert "does not form" in s["uniqueness_bound_F0_reason"]
            assert "not computed" in stdout


# ---------------------------------------------------------------------------------- check-gradient
@pytest.mark.parametrize(("path", "cases"), COMBOS, ids=IDS)
def test_check_gradient(tmp_path, path, cases):
    """The adjoint subgradient of every path agrees with finite differences (two directions)."""
    cfg = write_config(tmp_path, path, cases)
    code, stdout, stderr = cli("check-gradient", cfg, "--directions", 2)
    assert_clean(code, stdout, stderr)
    assert "PASSED" in stdout
    rows = [line.split() for line in stdout.splitlines() if re.match(r"\s+\d+\s+-?\d", line)]
    assert len(rows) == 2
    for _, fd, predicted, rel in rows:
        fd, predicted, rel = float(fd), float(predicted), float(rel)
        assert fd != 0 and abs(fd - predicted) <= 1e-6 * abs(fd) and rel < 1e-6


# ---------------------------------------------------------------------------------- sweep
@pytest.mark.integration
@pytest.mark.parametrize(("path", "cases"), COMBOS, ids=IDS)
def test_sweep(tmp_path, path, cases):
    """A two-task sweep (F = 0 and 0.3) on one local worker: both runs finish, the tables are strict
    JSON and repeat each run's summary; the workers' thread limits stay in the workers (this
    process's environment is as before)."""
    pytest.importorskip("distributed")
    cfg = write_config(tmp_path, path, cases)
    out = tmp_path / "sweep"
    threads = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
    before = {v: os.environ.get(v) for v in threads}
    code, stdout, stderr = cli("sweep", cfg, "--set", "friction.coefficient=0,0.3", "--workers", 1,
                               "--threads", 1, "--max-iter", 2, "--out", out)
    assert_clean(code, stdout, stderr)
    assert {v: os.environ.get(v) for v in threads} == before
    js = all_json(out)
    rows = js["sweep.json"]
    assert [r["friction.coefficient"] for r in rows] == [0.0, 0.3]
    for r in rows:
        assert r["error"] == "" and r["status"] == "new" and r["iterations"] == 2
        summary = js[f"{r['run_dir']}/summary.json"]
        assert (r["J0"], r["J"], r["evaluations"]) == (summary["J0"], summary["J"], summary["evaluations"])
        assert finite(r["J"]) and finite(r["J0"]) and r["J0"] > 0
        assert (summary["load_cases"]["names"] == ["pull", "push"]) if cases else "load_cases" not in summary
    table = read_csv(out / "sweep.csv")
    assert [float(t["J"]) for t in table] == [r["J"] for r in rows]


# ---------------------------------------------------------------------------------- console log
@pytest.mark.integration
def test_commands_in_one_process_print_each_warning_once(tmp_path):
    """The console log of a command is its own: a later command in the same process (these tests,
    a notebook) prints its warnings once, not once more per earlier command."""
    cfg = write_config(tmp_path, "condensation", False)       # F = 0.3 exceeds the estimate (3.16)
    err = io.StringIO()
    counts = []
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        for n in range(2):
            assert main(["run", str(cfg), "--out", str(tmp_path / f"r{n}"), "--max-iter", "1"]) == 0
            counts.append(err.getvalue().count("exceeds the uniqueness estimate"))
    assert counts == [1, 2]
