"""A run's outputs read the optimization's own solves: no state is solved after the last
evaluation, the summary's J0 and J are the history's values at α0 and at the returned design,
and a resumed run repeats the recorded solves bit for bit."""

import os
import subprocess
import sys
import time
from pathlib import Path

import meshio
import numpy as np
import pytest

from contactopt import runner
from contactopt.config import load_config
from contactopt.fem.model import ElasticModel
from contactopt.io import export
from contactopt.io.atomic import WriteError, atomic_output, atomic_write_text
from contactopt.io.forked import Forked
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
    s = runner.run_optimization(_config(kind), tmp_path / "run", max_iter=8, plots=False).summary
    assert s["J"] != s["J0"]                      # the optimum is another design than α0
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


def _write(path: Path, text: str):
    return lambda: atomic_write_text(path, text)


@pytest.mark.parametrize("fork", [True, False])
def test_forked_jobs_write_their_files_and_carry_their_errors(tmp_path, fork):
    with Forked([_write(tmp_path / "a.txt", "a"), _write(tmp_path / "b.txt", "b")], fork=fork) as jobs:
        assert (jobs.pid is not None) == fork
        jobs.join()
    assert (tmp_path / "a.txt").read_text() + (tmp_path / "b.txt").read_text() == "ab"
    # a write that fails in the child is the parent's WriteError, naming the file
    with pytest.raises(WriteError, match="nowhere"):
        with Forked([_write(tmp_path / "nowhere" / "c.txt", "c")], fork=fork) as jobs:
            jobs.join()

    def boom():
        raise ValueError("plot_history: rows [0] lack one of 'iteration'")
    with pytest.raises(ValueError, match="lack one of"):
        with Forked([boom], fork=fork) as jobs:
            jobs.join()


def test_a_cancelled_child_leaves_no_temporary_file(tmp_path):
    def slow():
        with atomic_output(tmp_path / "slow.png") as tmp:
            tmp.write_bytes(b"x")
            time.sleep(30)
    t = time.perf_counter()
    with pytest.raises(RuntimeError):
        with Forked([slow], fork=True):
            time.sleep(0.5)
            raise RuntimeError("the parent fails")
    assert time.perf_counter() - t < 10
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the figures are forked on Linux only")
def test_a_stalled_child_is_stopped_and_its_jobs_done_by_the_parent(tmp_path, caplog):
    """A child that finishes no job for ``stall`` seconds (here: one that hangs in its second job,
    holding a temporary file) is killed; the parent removes the temporary file and runs the jobs
    the child had not finished, and only those."""
    parent = os.getpid()

    def first():                      # records who ran it
        atomic_write_text(tmp_path / "a.txt", str(os.getpid()))

    def stuck():
        with atomic_output(tmp_path / "b.txt") as tmp:
            tmp.write_bytes(b"partial")
            end = time.time() + 30            # the child hangs (for 30 s: a broken watchdog fails, not hangs)
            while os.getpid() != parent and time.time() < end:
                time.sleep(0.5)
            tmp.write_bytes(b"b")

    t = time.perf_counter()
    with caplog.at_level("WARNING", logger="contactopt.io.forked"):
        with Forked([first, stuck, _write(tmp_path / "c.txt", "c")], fork=True, directory=tmp_path,
                    stall=1.5) as jobs:
            child = jobs.pid
            jobs.join()
    assert time.perf_counter() - t < 20
    assert _ended(child)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt", "c.txt"]
    assert (tmp_path / "a.txt").read_text() == str(child)            # not run again
    assert (tmp_path / "b.txt").read_text() + (tmp_path / "c.txt").read_text() == "bc"
    assert "(1 of 3 done)" in caplog.text


def test_the_block_is_exported_with_the_bytes_of_meshios_gmsh_writer(tmp_path):
    model = ElasticModel(load_config("example1").with_updates({"mesh": SMALL}))
    mesh, fmt, binary, _ = export.body_meshio(model, model.mesh.coordinates(model.initial_design() + 0.003))
    assert (fmt, binary) == ("gmsh22", False) and export._plain_gmsh(mesh)
    meshio.write(tmp_path / "meshio.msh", mesh, file_format="gmsh22", binary=False)
    export._write_gmsh22_ascii(tmp_path / "own.msh", mesh)
    assert (tmp_path / "own.msh").read_bytes() == (tmp_path / "meshio.msh").read_bytes()


def _ended(pid: int) -> bool:
    """Whether process ``pid`` is gone (or a zombie waiting for its new parent to reap it)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True
    return "\nState:\tZ" in status


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the figures are forked on Linux only")
def test_the_child_ends_with_its_parent_killed(tmp_path):
    """A run killed by SIGKILL during its outputs leaves no process drawing figures (which would
    hold the run directory's lock) and no temporary file."""
    script = (
        "import sys, time\n"
        "from pathlib import Path\n"
        "from contactopt.io.atomic import atomic_output\n"
        "from contactopt.io.forked import Forked\n"
        "def slow():\n"
        f"    with atomic_output(Path({str(tmp_path)!r}) / 'slow.png') as tmp:\n"
        "        tmp.write_bytes(b'x')\n"
        "        time.sleep(60)\n"
        "jobs = Forked([slow], fork=True)\n"
        "print(jobs.pid, flush=True)\n"
        "time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    child = int(proc.stdout.readline())
    time.sleep(1.0)
    proc.kill()
    proc.wait()
    deadline = time.time() + 20
    while not _ended(child) and time.time() < deadline:
        time.sleep(0.1)
    assert _ended(child)
    assert list(tmp_path.iterdir()) == []
