"""Sweeps (contactopt sweep): settings, validation, a LocalCluster, a scheduler with two worker
processes, and a worker killed mid-sweep."""

import csv
import json
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from contactopt.cli import main
from contactopt.errors import ConfigError
from contactopt.studies import build_tasks, gather, parse_settings, run_sweep
from contactopt.studies.sweep import RESULT_COLUMNS

pytest.importorskip("distributed")

FRICTIONS = [0.0, 0.1, 0.2, 0.3]
SET_F = "friction.coefficient=0,0.1,0.2,0.3"


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------------------------ settings
def test_settings_are_toml_scalars_and_their_product_in_order():
    s = parse_settings(["friction.coefficient=0, 0.25", "state.method=newton,'fixed-point'",
                        "loads.right_traction=[0.05, 0, 0],[0, 0.05, 0]", "state.zone=true,false"])
    assert s[0] == ("friction.coefficient", [0, 0.25])
    assert s[1] == ("state.method", ["newton", "fixed-point"])
    assert s[2][1] == [[0.05, 0, 0], [0, 0.05, 0]]
    assert s[3][1] == [True, False]
    tasks = build_tasks("example1", [s[0], ("mesh.nx", [4, 6, 8])])
    assert len(tasks) == 6
    # first key slowest; values resolved by the configuration (0 -> 0.0 for a float key)
    assert [t.settings for t in tasks[:3]] == [(("friction.coefficient", 0.0), ("mesh.nx", n)) for n in (4, 6, 8)]
    assert tasks[4].config["friction"]["coefficient"] == 0.25 and tasks[4].config["mesh"]["nx"] == 6
    assert tasks[4].name == "friction.coefficient=0.25__mesh.nx=6"
    assert len({t.name for t in tasks}) == 6


def test_every_bad_setting_is_listed_in_one_error():
    with pytest.raises(ConfigError) as e:
        parse_settings(["friction.coefficient", "mesh.nx=4,,5", "a=1", "a=2", "state.tol=1e-8,[1"])
    text = str(e.value)
    for part in ("expected KEY=V1,V2", "empty value", "given twice", "not a TOML value"):
        assert part in text, part
    with pytest.raises(ConfigError) as e:
        build_tasks("example1", [("friction.coefficient", [0.1, -1.0, "x"]), ("mesh.nx", [0, 4]),
                                 ("mesh.size", [3]), ("design.C0", [0.5, 0.9]), ("geometry.c", [1.0, 0.8])])
    probs = e.value.problems
    assert any("friction.coefficient=-1.0" in p for p in probs)
    assert any("friction.coefficient=x" in p for p in probs)
    assert any("mesh.nx=0" in p for p in probs)
    assert any("mesh.size" in p and "unknown key" in p for p in probs)
    assert not any("design.C0=0.9" in p for p in probs)           # valid alone (c = 1)
    # ... but not with geometry.c = 0.8: found among the combinations once every value is valid
    with pytest.raises(ConfigError) as e:
        build_tasks("example1", [("design.C0", [0.5, 0.9]), ("geometry.c", [1.0, 0.8])])
    assert len(e.value.problems) == 1 and "task design.C0=0.9, geometry.c=0.8" in e.value.problems[0]
    with pytest.raises(ConfigError, match="more than once"):
        build_tasks("example1", [("friction.coefficient", [0, 0.0])])


def test_bad_sweep_exits_2_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "sw"
    code = main(["sweep", "example1", "--set", "friction.coefficient=0.1,-2", "--set", "mesh.nx=4,x",
                 "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert "friction.coefficient=-2" in err and "mesh.nx=x" in err
    assert not out.exists()


# ------------------------------------------------------------------------------ local cluster
def check_sweep_dir(out, n=4):
    rows = read_csv(out / "sweep.csv")
    assert list(rows[0]) == ["friction.coefficient"] + RESULT_COLUMNS
    assert [float(r["friction.coefficient"]) for r in rows] == FRICTIONS[:n]
    for r in rows:
        assert r["error"] == "", r
        J0, J = float(r["J0"]), float(r["J"])
        assert 0 < J <= J0 and abs(float(r["ratio"]) - J / J0) < 1e-12
        assert int(r["evaluations"]) >= 2
        summary = json.loads((out / r["run_dir"] / "summary.json").read_text())
        assert summary["J"] == J and summary["evaluations"] == int(r["evaluations"])
    return rows


@pytest.mark.integration
def test_sweep_on_a_local_cluster_then_gather_and_resume(tmp_path, capsys, config_file):
    out = tmp_path / "sw"
    code = main(["sweep", str(config_file()), "--set", SET_F, "--workers", "2", "--max-iter", "4",
                 "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "dashboard" in printed and printed.count("J/J0 =") == 4
    rows = check_sweep_dir(out)
    data = json.loads((out / "sweep.json").read_text())
    assert [d["status"] for d in data] == ["new"] * 4
    # F = 0.3 exceeds the (pessimistic) uniqueness estimate on this mesh; F = 0 never does
    assert data[0]["warnings"] == [] and "uniqueness" in data[3]["warnings"][0]
    for png in ("ratio.png", "surfaces.png", "lambda.png"):
        assert (out / png).stat().st_size > 1000
    # the tables can be rebuilt from the run directories alone
    (out / "sweep.csv").unlink()
    assert [r["J"] for r in gather(out).rows] == [float(r["J"]) for r in rows]
    assert read_csv(out / "sweep.csv") == rows
    # a non-empty sweep directory is refused without --resume; --resume reuses the finished runs
    assert main(["sweep", str(config_file()), "--set", SET_F, "--max-iter", "4", "--out", str(out)]) == 2
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("runs/*/summary.json")}
    res = run_sweep(config_file(), [("friction.coefficient", FRICTIONS)], out, workers=1, max_iter=4,
                    resume=True, plots=False)
    assert [r["status"] for r in res.rows] == ["reused"] * 4
    assert [r["J"] for r in res.rows] == [float(r["J"]) for r in rows]
    assert stamps == {p: p.stat().st_mtime_ns for p in out.glob("runs/*/summary.json")}


@pytest.mark.integration
def test_failed_task_is_recorded_and_the_others_go_on(tmp_path, config_file):
    # a contact solver allowed one iteration cannot converge: that task fails, the other runs
    out = tmp_path / "sw"
    res = run_sweep(config_file(), [("state.max_iter", [1, 200])], out, workers=2, max_iter=2,
                    plots=False)
    bad, good = res.rows
    assert res.n_failed == 1
    assert "not converge" in bad["error"] or "Not" in bad["error"], bad["error"]
    assert bad["J"] is None and bad["success"] is False
    assert good["error"] == "" and good["J"] > 0
    rows = read_csv(out / "sweep.csv")
    assert rows[0]["error"] == bad["error"] and rows[1]["J"] == repr(good["J"])


# ------------------------------------------------------------------------------ a real cluster
class Cluster:
    """A dask scheduler and worker processes on 127.0.0.1, started as separate processes."""

    def __init__(self, tmp_path, n_workers=2):
        self.tmp = tmp_path
        self.procs = []
        self.workers = []
        sched_file = tmp_path / "scheduler.json"
        env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
        self.env = env
        self.procs.append(self._start([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host",
                                       "127.0.0.1", "--port", "0", "--no-dashboard",
                                       "--scheduler-file", str(sched_file)], "scheduler"))
        deadline = time.time() + 60
        while not sched_file.exists():
            assert time.time() < deadline, "scheduler did not start"
            assert self.procs[0].poll() is None, "scheduler exited"
            time.sleep(0.1)
        time.sleep(0.2)      # the file is written in one go, but let it be complete
        self.address = json.loads(sched_file.read_text())["address"]
        for n in range(n_workers):
            # --no-nanny: killing the process kills the worker (a nanny would restart it)
            p = self._start([sys.executable, "-m", "distributed.cli.dask_worker", self.address,
                             "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1",
                             "--local-directory", str(tmp_path / f"w{n}"), "--name", f"w{n}"], f"worker{n}")
            self.procs.append(p)
            self.workers.append(p)
        from distributed import Client
        with Client(self.address, timeout="30s") as c:
            c.wait_for_workers(n_workers, timeout=60)

    def _start(self, cmd, name):
        log = open(self.tmp / f"{name}.log", "w")
        return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                start_new_session=True)

    def close(self):
        for p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(timeout=3)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    try:
        yield c
    finally:
        c.close()


@pytest.mark.integration
def test_sweep_through_a_scheduler_and_two_worker_processes(tmp_path, cluster, capsys, config_file):
    out = tmp_path / "sw"
    code = main(["sweep", str(config_file()), "--set", SET_F, "--scheduler", cluster.address,
                 "--max-iter", "4", "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert cluster.address in printed
    check_sweep_dir(out)
    workers = {r["worker"] for r in json.loads((out / "sweep.json").read_text())}
    assert len(workers) == 2 and all(w.startswith("tcp://127.0.0.1:") for w in workers)


@pytest.mark.integration
def test_killed_worker_has_its_task_resumed_elsewhere(tmp_path, cluster, config_file, small_config):
    """Kill the worker of a task that has a checkpoint: all 4 results come, that task resumed."""
    cfg = config_file(small_config(mesh={"nx": 12, "ny": 6, "nz": 4}))
    out = tmp_path / "sw"
    result = {}

    def sweep():
        result["res"] = run_sweep(cfg, [("friction.coefficient", FRICTIONS)], out, scheduler=cluster.address,
                                  max_iter=40, eps=1e-8, plots=False,
                                  on_client=lambda client, dash: result.setdefault("client", client))

    th = threading.Thread(target=sweep)
    th.start()
    killed = None
    deadline = time.time() + 120
    while "client" not in result and time.time() < deadline:
        time.sleep(0.02)
    client = result["client"]                  # the sweep's own client, used from this thread
    pids = client.run(os.getpid)
    while killed is None and time.time() < deadline and th.is_alive():
        for run in out.glob("runs/*"):
            if (run / "checkpoint.npz").exists() and not (run / "summary.json").exists():
                for addr, keys in client.processing().items():
                    if any(run.name in str(k) for k in keys):
                        next(p for p in cluster.workers if p.pid == pids[addr]).kill()
                        killed = run.name
                        break
            if killed:
                break
        time.sleep(0.02)
    assert killed, "no task was caught mid-run"
    th.join(timeout=180)
    assert not th.is_alive()
    res = result["res"]
    assert res.n_failed == 0 and len(res.rows) == 4
    row = next(r for r in res.rows if r["run_dir"].endswith(killed))
    assert row["status"] == "resumed"
    assert "resuming" in (out / row["run_dir"] / "run.log").read_text()
    # it went on from its checkpoint (not from α0): resumed at iteration k ≥ 1, each evaluation
    # in history.csv once, and all 40 iterations done. (J itself is not compared with a run in
    # this process: MKL's rounding differs between processes and 40 nonsmooth steps amplify it.)
    log = (out / row["run_dir"] / "run.log").read_text()
    k = int(log.split("at iteration ")[1].split()[0])
    assert 1 <= k < 40
    hist = read_csv(out / row["run_dir"] / "history.csv")
    assert [int(h["evaluation"]) for h in hist] == list(range(1, row["evaluations"] + 1))
    assert row["iterations"] == 40
    check_sweep_dir(out)


@pytest.mark.integration
def test_task_in_a_directory_without_checkpoint_starts_afresh(tmp_path, config_file):
    """A worker that died before the first checkpoint leaves a run directory without one: the
    rerun starts the run anew there (run_optimization(resume=True) would refuse it)."""
    from contactopt.studies.sweep import TaskSpec, run_task
    task = build_tasks(config_file(), [("friction.coefficient", [0.2])])[0]
    run = tmp_path / "sw" / "runs" / task.name
    run.mkdir(parents=True)
    (run / "run.log").write_text("an attempt that died\n")
    (run / "config.toml").write_text("# partial\n")
    spec = TaskSpec(task, str(run), str(tmp_path / "sw"), 2, None, {"local": os.cpu_count()})
    row = run_task(spec)
    assert row["status"] == "restarted" and row["error"] == "" and row["J"] > 0
    assert "an attempt that died" not in (run / "run.log").read_text()
    again = run_task(spec)                         # finished: reused as it is
    assert again["status"] == "reused" and again["J"] == row["J"]
    # a different stopping parameter is another task: it continues from the checkpoint
    more = run_task(TaskSpec(task, str(run), str(tmp_path / "sw"), 4, None, {"local": os.cpu_count()}))
    assert more["status"] == "resumed" and more["iterations"] == 4


def test_the_surfaces_of_runs_on_a_chart_are_cut_at_the_middle_of_its_coordinates(tmp_path, monkeypatch):
    """surface.csv holds the chart's ξ (on a cylinder ξ2 ∈ [−L/2, L/2]): the sections are named ξ1, ξ2
    and cut at the middle of the other coordinate, not at half its largest value; the paper's map keeps
    x1, x2 at b/2 and a/2."""
    from pathlib import Path

    import numpy as np

    from contactopt.studies import plots as sweep_plots
    drawn = {}
    monkeypatch.setattr(sweep_plots, "_save", lambda fig, path: drawn.setdefault(Path(path).name, fig))
    xi1, xi2 = np.meshgrid(np.linspace(-1.0, 1.0, 5), np.linspace(-0.5, 0.5, 5))
    theta = 1e-3 * (1.0 + xi1 ** 2) * (1.0 + 4.0 * xi2)       # ϑ at ξ2 = 0 is 1e-3 (1 + ξ1²)
    for name, description in (("cyl", "the cylinder of radius 1.5 ..."), ("paper", "the paper's map xi = (x1, x2)")):
        run = tmp_path / name / "run"
        run.mkdir(parents=True)
        (run / "surface.csv").write_text("x1,x2,theta\n" + "".join(
            f"{a:.17g},{b:.17g},{c:.17g}\n" for a, b, c in zip(xi1.ravel(), xi2.ravel(), theta.ravel())))
        (run / "summary.json").write_text(json.dumps({"chart": {"description": description, "axes": []}}))
        sweep_plots.plot_surfaces(tmp_path / f"{name}.png", tmp_path / name, ["k"], [{"run_dir": "run", "k": 1}])
    ax1, ax2 = drawn["cyl.png"].axes
    assert (ax1.get_xlabel(), ax2.get_xlabel()) == ("$\\xi_1$ (at the middle of $\\xi_2$)",
                                                    "$\\xi_2$ (at the middle of $\\xi_1$)")
    x, y = ax1.lines[0].get_data()
    assert np.allclose(y, 1e-3 * (1.0 + x ** 2), rtol=1e-12)            # the section at ξ2 = 0
    assert drawn["paper.png"].axes[0].get_xlabel() == "$x_1$ (at $x_2 = b/2$)"
