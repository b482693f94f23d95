"""A killed run resumed with ``--resume`` ends exactly where the uninterrupted run ends, on every
solver path (issue #21).

Per path, ``contactopt run`` runs uninterrupted in a subprocess, then again killed with SIGKILL
(after 5, 20 and 40 iterations, before its first checkpoint, and at three seeded random moments:
a random delay of up to one iteration's share of the wall time after a random iteration, so mostly
mid-evaluation) and continued with ``--resume`` as a
user would (no ``--max-iter``: the checkpoint's is kept). J (summary.json), α (alpha.json) and the
trajectory (iterations.csv) must be bit-identical to the uninterrupted run's. The processes get the
environment users have (thread counts not forced), the same for every run.

A run killed before its first checkpoint cannot be resumed: ``--resume`` exits 2 saying there is
no checkpoint and leaves the directory as it is (runner.py); the run is then started anew with
``--overwrite`` and must give the same result too.

The kill moments are found from the progress lines ``it N`` that ``contactopt run`` prints right
after writing the checkpoint of iteration N (iterations.csv is written only when the run ends).
Run with ``pytest -m slow tests/test_resume_paths.py -s`` to see the kill points and timings.
"""

import csv
import json
import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import tomli_w

import contactopt
from contactopt.config import load_config
from contactopt.io.checkpoint import Checkpoint

pytestmark = pytest.mark.slow

# path -> (configuration updates of Example 1, --max-iter); the full-space path on the mesh of the
# issue, the others on a smaller one (a run of seconds). ftol = 0 and a tiny ε: the run goes on to
# --max-iter, so there are iterations after the last kill.
RUNS = {
    "condensation": ({"mesh": {"nx": 16, "ny": 8, "nz": 5}}, 50),
    "delassus": ({"mesh": {"nx": 16, "ny": 8, "nz": 5}}, 50),
    "fullspace": ({"mesh": {"nx": 24, "ny": 15, "nz": 9}}, 45),
}
KILL_AFTER_ITERATIONS = (5, 20, 40)
N_RANDOM_KILLS = 3
TIMEOUT = 600.0          # seconds for one process, a hang rather than a slow machine
PROGRESS = re.compile(r"^it\s+(\d+)\s")


def environment() -> dict:
    """The environment of every run: the user's, with this contactopt first on the path."""
    src = str(Path(contactopt.__file__).resolve().parents[1])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([src] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def command(cfg, out, *args) -> list[str]:
    return [sys.executable, "-m", "contactopt.cli", "run", str(cfg), "--out", str(out), *map(str, args)]


def finish(cmd, env, log: Path) -> tuple[int, str, float]:
    """Run to its end: (exit code, stdout + stderr, wall time)."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, check=False, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=TIMEOUT)
    wall = time.perf_counter() - t0
    log.write_text(proc.stdout)
    return proc.returncode, proc.stdout, wall


def kill_when(cmd, env, log: Path, *, iteration=None, seconds=None, first_evaluation=None, delay=0.0) -> str:
    """Start a run and SIGKILL it ``delay`` seconds after its progress line of ``iteration``, after
    ``seconds``, or once history.csv in ``first_evaluation`` (the run directory) has its first row.
    Returns what happened: 'killed' or 'finished' (it ended before the moment came)."""
    with open(log, "w") as fh:
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=fh, text=True)
        watchdog = threading.Timer(TIMEOUT, proc.kill)
        watchdog.start()
        try:
            if iteration is not None:
                for line in proc.stdout:
                    fh.write(line)
                    m = PROGRESS.match(line)
                    if m and int(m.group(1)) >= iteration:
                        break
                if delay:
                    try:
                        proc.wait(timeout=delay)
                    except subprocess.TimeoutExpired:
                        pass
            elif seconds is not None:
                try:
                    proc.wait(timeout=seconds)
                except subprocess.TimeoutExpired:
                    pass
            else:
                hist = first_evaluation / "history.csv"
                while proc.poll() is None:
                    if hist.exists() and len(hist.read_text().splitlines()) >= 2:
                        break
                    time.sleep(0.005)
            if proc.poll() is not None:
                fh.write(proc.stdout.read())
                return "finished"
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
            return "killed"
        finally:
            watchdog.cancel()
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            proc.stdout.close()


def checkpoint_position(out: Path):
    """(iteration, evaluations) of the run directory's checkpoint, or None without one."""
    ckpt = out / "checkpoint.npz"
    if not ckpt.exists():
        return None
    ckpt = Checkpoint.read(ckpt)
    return ckpt.bundle.nit, ckpt.evaluations


def read_rows(file: Path) -> list[list[str]]:
    with open(file, newline="") as fh:
        return list(csv.reader(fh))


def first_difference(ref: Path, out: Path) -> str:
    """Where the resumed run leaves the uninterrupted one: first iteration and evaluation that differ."""
    notes = []
    for name, key, drop in (("iterations.csv", "iteration", ()), ("history.csv", "evaluation", ("time_s",))):
        if not (out / name).exists():
            notes.append(f"{name} missing")
            continue
        a, b = read_rows(ref / name), read_rows(out / name)
        keep = [i for i, h in enumerate(a[0]) if h not in drop]
        for ra, rb in zip(a[1:], b[1:]):
            if [ra[i] for i in keep] != [rb[i] for i in keep if i < len(rb)]:
                notes.append(f"{name}: first difference at {key} {ra[0]}: {ra} vs {rb}")
                break
        else:
            notes.append(f"{name}: {len(a) - 1} vs {len(b) - 1} rows, the common ones equal")
    return "; ".join(notes)


def result(out: Path) -> dict:
    s = json.loads((out / "summary.json").read_text())
    return {"J": s["J"], "J0": s["J0"], "iterations": s["iterations"], "evaluations": s["evaluations"],
            "alpha": (out / "alpha.json").read_text(), "trajectory": (out / "iterations.csv").read_text()}


def compare(ref: dict, got: dict) -> list[str]:
    """The ways ``got`` is not bit-identical to ``ref`` (empty: identical)."""
    bad = []
    if got["J"] != ref["J"]:
        bad.append(f"J {got['J']!r} ({float(got['J']).hex()}) vs {ref['J']!r} ({float(ref['J']).hex()})")
    if got["alpha"] != ref["alpha"]:
        a, b = (np.array(json.loads(x)["alpha"]) for x in (ref["alpha"], got["alpha"]))
        bad.append(f"alpha differs, max |Δα| = {np.abs(a - b).max():.3e}")
    if (got["iterations"], got["evaluations"]) != (ref["iterations"], ref["evaluations"]):
        bad.append(f"iterations/evaluations {got['iterations']}/{got['evaluations']} vs "
                   f"{ref['iterations']}/{ref['evaluations']}")
    if got["J0"] != ref["J0"]:
        bad.append(f"J0 {got['J0']!r} vs {ref['J0']!r}")
    if got["trajectory"] != ref["trajectory"]:
        bad.append("iterations.csv differs")
    return bad


@pytest.mark.parametrize("path", list(RUNS))
def test_killed_and_resumed_run_is_bit_identical(tmp_path, path):
    """SIGKILL at 7 moments, then --resume: J, α and the trajectory equal the uninterrupted run's."""
    updates, max_iter = RUNS[path]
    cfg = load_config("example1").with_updates({
        "name": f"resume-{path}", **updates, "linear_solver": {"path": path},
        "optimizer": {"ftol": 0.0, "eps": 1e-8}})
    cfg_file = tmp_path / f"{cfg.name}.toml"
    cfg_file.write_text(tomli_w.dumps(cfg.data))
    env = environment()

    ref_dir = tmp_path / "uninterrupted"
    code, text, ref_wall = finish(command(cfg_file, ref_dir, "--max-iter", max_iter), env, tmp_path / "ref.log")
    assert code == 0 and "Traceback" not in text, text
    ref = result(ref_dir)
    assert ref["iterations"] == max_iter >= 45 and ref["J"] < ref["J0"]
    print(f"\n[{path}] uninterrupted: {ref['iterations']} iterations, {ref['evaluations']} evaluations, "
          f"{ref_wall:.1f} s wall, J = {ref['J']!r}")

    rng = random.Random(f"resume-{path}")
    moments = [("iteration", n) for n in KILL_AFTER_ITERATIONS] + [("before the first checkpoint", None)]
    # random moments inside the optimization, mostly mid-evaluation: a random delay of up to one
    # iteration's share of the wall time after the progress line of a random iteration
    per_iteration = ref_wall / max_iter
    moments += [("random", (rng.randint(1, max_iter - 2), round(rng.uniform(0.0, per_iteration), 3)))
                for _ in range(N_RANDOM_KILLS)]
    failures = []
    for n, (kind, when) in enumerate(moments):
        out = tmp_path / f"kill{n}"
        start = command(cfg_file, out, "--max-iter", max_iter)
        log = tmp_path / f"kill{n}.log"
        t0 = time.perf_counter()
        if kind == "iteration":
            what = kill_when(start, env, log, iteration=when)
        elif kind == "random":
            what = kill_when(start, env, log, iteration=when[0], delay=when[1])
        else:
            what = kill_when(start, env, log, first_evaluation=out)
        t_kill = time.perf_counter() - t0
        position = checkpoint_position(out)
        code, text, wall = finish(command(cfg_file, out, "--resume"), env, tmp_path / f"resume{n}.log")
        assert "Traceback" not in text, text
        if position is None:
            # documented: no checkpoint, nothing to resume (exit 2, the directory untouched) ...
            assert code == 2 and "no checkpoint" in text, text
            assert not (out / "summary.json").exists()
            # ... the run starts anew
            code, text, wall = finish(start + ["--overwrite"], env, tmp_path / f"restart{n}.log")
            how = "no checkpoint: resume refused (exit 2), restarted with --overwrite"
        else:
            how = f"resumed at iteration {position[0]} ({position[1]} evaluations)"
            assert f"at iteration {position[0]} ({position[1]} evaluations)" in (out / "run.log").read_text()
        assert code == 0, text
        if kind in ("iteration", "random") and what == "killed":
            assert position is not None and position[0] >= (when if kind == "iteration" else when[0])
        got = result(out)
        bad = compare(ref, got)
        label = (f"iteration {when[0]} + {when[1]} s" if kind == "random" else f"{kind} {when}" if when is not None
                 else kind)
        print(f"[{path}] kill at {label} ({what} after {t_kill:.2f} s): {how}; continued in {wall:.1f} s: "
              + ("bit-identical" if not bad else "DIFFERS: " + "; ".join(bad)))
        if bad:
            failures.append(f"{label} ({how}): " + "; ".join(bad) + " — " + first_difference(ref_dir, out))
    assert not failures, f"{path}: resumed runs differ from the uninterrupted one:\n" + "\n".join(failures)
