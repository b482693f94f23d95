"""Faults a user meets: two writers in one directory, a full disk, an interruption.

Every fault must end with a clear message and its exit code (2 refused, 74 a failed write, 130
SIGINT, 143 SIGTERM), leave no file that a later reader (``--resume``, ``export``,
``studies.gather``) chokes on, and ``--resume`` must then finish with the uninterrupted run's J, α
and trajectory bit for bit.

Full disks are simulated two ways: a failing write injected at each file of a run and of a sweep
(``contactopt.io.atomic._finish``, where every file is moved into place; history.csv's appended
rows through the runner's ``open``, which writes half a row and then fails), and a real 3 MB tmpfs
where the machine lets the test mount one (root). To keep the default tier quick, the in-process
runs render no figures (``io.plots._save`` writes a stub PNG through the same atomic writer);
``-m slow`` runs the whole matrix with the real figures and the sweeps.
"""

import contextlib
import csv
import errno
import io
import json
import os
import random
import re
import shlex
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import meshio
import numpy as np
import pytest
import tomli_w

import contactopt
from contactopt.cli import main
from contactopt.config import load_config
from contactopt.io import atomic, lock
from contactopt.io.checkpoint import Checkpoint
from contactopt.io.lock import LOCK_NAME

MAX_ITER = 8
PNG = b"\x89PNG\r\n\x1a\n" + b"\0" * 64          # a stub figure (the figures are not under test here)
SRC = str(Path(contactopt.__file__).resolve().parents[1])


def write_config(path: Path, name="small") -> Path:
    cfg = load_config("example1").with_updates({"mesh": {"nx": 8, "ny": 4, "nz": 3}, "name": name,
                                                "optimizer": {"ftol": 0.0, "eps": 1e-8}})
    path.write_text(tomli_w.dumps(cfg.data))
    return path


def stub_save(fig, path):
    with atomic.atomic_output(path) as tmp:
        tmp.write_bytes(PNG)
    return Path(path)


@contextlib.contextmanager
def quick_figures(enabled=True):
    with pytest.MonkeyPatch.context() as mp:
        if enabled:
            from contactopt.io import plots
            mp.setattr(plots, "_save", stub_save)
        yield


def cli(*args) -> tuple[int, str]:
    """``contactopt ARGS`` in this process: (exit code, stdout + stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue() + err.getvalue()


def result(out: Path) -> dict:
    s = json.loads((out / "summary.json").read_text())
    return {"J": s["J"], "J0": s["J0"], "iterations": s["iterations"], "evaluations": s["evaluations"],
            "alpha": (out / "alpha.json").read_text(), "trajectory": (out / "iterations.csv").read_text()}


def assert_bit_identical(ref: dict, got: dict):
    assert got["J"] == ref["J"], (float(got["J"]).hex(), float(ref["J"]).hex())
    assert got["alpha"] == ref["alpha"]
    assert (got["iterations"], got["evaluations"], got["J0"]) == (ref["iterations"], ref["evaluations"], ref["J0"])
    assert got["trajectory"] == ref["trajectory"]


def assert_readable(out: Path) -> None:
    """What is in the run directory parses, no temporary file is left and the lock is released."""
    names = [p.name for p in out.iterdir()]
    assert not [n for n in names if ".tmp" in n or n.startswith(".export")], names
    assert LOCK_NAME not in names
    for p in out.iterdir():
        if p.suffix == ".json":
            json.loads(p.read_text())
        elif p.suffix == ".csv" and p.name != "history.csv":       # history: see --resume
            rows = list(csv.reader(p.read_text().splitlines()))
            assert rows and all(len(r) == len(rows[0]) for r in rows), p
        elif p.suffix == ".npz":
            with np.load(p, allow_pickle=False) as z:
                assert all(z[k] is not None for k in z.files)
        elif p.suffix == ".vtu":
            assert meshio.read(p).points.shape[1] == 3
        elif p.suffix == ".png":
            assert p.read_bytes()[:8] == PNG[:8]


def checkpoint_position(out: Path):
    if not (out / "checkpoint.npz").exists():
        return None
    ckpt = Checkpoint.read(out / "checkpoint.npz")
    return ckpt.bundle.nit, ckpt.evaluations


@pytest.fixture(scope="module", autouse=True)
def one_thread():
    """The in-process runs on one thread per library (see environment())."""
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=1):
        yield


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> Path:
    return write_config(tmp_path_factory.mktemp("cfg") / "small.toml")


@pytest.fixture(scope="module")
def reference(small, tmp_path_factory) -> dict:
    """The uninterrupted run, in this process, with stub figures."""
    out = tmp_path_factory.mktemp("ref") / "run"
    with quick_figures():
        code, text = cli("run", small, "--out", out, "--max-iter", MAX_ITER)
    assert code == 0, text
    return dict(result(out), dir=out)


@pytest.fixture(scope="module")
def real_reference(small, tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("ref") / "run"
    code, text = cli("run", small, "--out", out, "--max-iter", MAX_ITER)
    assert code == 0, text
    return dict(result(out), dir=out)


# ------------------------------------------------------------------------------ full disk
def enospc(monkeypatch, name: str, nth: int = 1, code: int = errno.ENOSPC) -> dict:
    """The ``nth`` write of file ``name`` fails (ENOSPC or ``code``); returns what happened."""
    seen = {"n": 0, "failed": False}
    if name == "history.csv row":
        from contactopt.io import rundir
        real_open = open

        class HalfWritten:
            def __init__(self, fh):
                self.fh = fh

            def write(self, text):
                self.fh.write(text[: len(text) // 2])
                self.fh.flush()
                raise OSError(code, os.strerror(code))

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.fh.close()

        def failing_open(file, mode="r", *args, **kwargs):
            fh = real_open(file, mode, *args, **kwargs)
            if Path(file).name == "history.csv" and mode == "a":
                seen["n"] += 1
                if seen["n"] == nth:
                    seen["failed"] = True
                    return HalfWritten(fh)
            return fh

        monkeypatch.setattr(rundir, "open", failing_open, raising=False)
        return seen
    real = atomic._finish

    def failing(tmp, path):
        if Path(path).name == name:
            seen["n"] += 1
            if seen["n"] == nth:
                seen["failed"] = True
                raise OSError(code, os.strerror(code), str(tmp))
        return real(tmp, path)

    monkeypatch.setattr(atomic, "_finish", failing)
    return seen


# (file, which of its writes fails); the first group runs in the default tier
RUN_WRITES_QUICK = [("config.toml", 1), ("history.csv row", 5), ("checkpoint.npz", 3), ("optimal.vtu", 1),
                    ("stress.png", 1), ("optimal_body.stl", 1), ("summary.json", 1)]
RUN_WRITES_SLOW = [("history.csv", 1), ("checkpoint.npz", 1), ("checkpoint.npz", MAX_ITER + 1), ("initial.vtu", 1),
                   ("bodies.pvd", 1), ("pressure.png", 1), ("surface.png", 1), ("classes.png", 1),
                   ("history.png", 1), ("iterations.csv", 1), ("alpha.json", 1), ("surface.csv", 1),
                   ("optimal_body.msh", 1), ("optimal_body.toml", 1), ("contact_surface.step", 1),
                   ("contact_surface.iges", 1)]


def full_disk_then_resume(small, ref, tmp_path, monkeypatch, name, nth, quick=True):
    out = tmp_path / "run"
    with monkeypatch.context() as mp:
        seen = enospc(mp, name, nth)
        with quick_figures(quick):
            code, text = cli("run", small, "--out", out, "--max-iter", MAX_ITER)
    if not seen["failed"]:
        pytest.skip(f"{name} is not written {nth} times here (no CAD kernel?)")
    assert code == 74, text
    assert "Traceback" not in text
    shown = name.split()[0]
    assert f"cannot write {out / shown}" in text, text
    assert "no space left on the device" in text
    position = checkpoint_position(out)
    assert_readable(out)
    assert not (out / "summary.json").exists() or json.loads((out / "summary.json").read_text())["J"]
    if position is None:
        assert "no checkpoint" in text and "--overwrite" in text, text
        again = ("run", small, "--out", out, "--max-iter", MAX_ITER, "--overwrite")
    else:
        assert re.search(rf"the checkpoint of (iteration|the finished optimization \(iteration) {position[0]}\b",
                         text), text
        assert f"continue with: contactopt run {small} --out {out} --resume" in text, text
        again = ("run", small, "--out", out, "--resume")
    with quick_figures(quick):
        code, text = cli(*again)
    assert code == 0, text
    assert_bit_identical(ref, result(out))
    assert_readable(out)
    rows = (out / "history.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == [str(k) for k in range(1, ref["evaluations"] + 1)]


@pytest.mark.parametrize("name, nth", RUN_WRITES_QUICK)
def test_full_disk_at_a_write_of_a_run(small, reference, tmp_path, monkeypatch, name, nth):
    full_disk_then_resume(small, reference, tmp_path, monkeypatch, name, nth)


@pytest.mark.slow
@pytest.mark.parametrize("name, nth", RUN_WRITES_QUICK + RUN_WRITES_SLOW)
def test_full_disk_at_every_write_of_a_run_with_its_figures(small, real_reference, tmp_path, monkeypatch, name, nth):
    full_disk_then_resume(small, real_reference, tmp_path, monkeypatch, name, nth, quick=False)


@pytest.mark.parametrize("code, words", [(errno.EROFS, "the file system is read-only"),
                                         (errno.EACCES, "permission denied")])
def test_read_only_or_forbidden_checkpoint(small, reference, tmp_path, monkeypatch, code, words):
    out = tmp_path / "run"
    with monkeypatch.context() as mp:
        enospc(mp, "checkpoint.npz", 4, code)
        with quick_figures():
            rc, text = cli("run", small, "--out", out, "--max-iter", MAX_ITER)
    assert rc == 74 and f"cannot write {out / 'checkpoint.npz'}: {words}" in text, text
    assert "the checkpoint of iteration 3 " in text and "--resume" in text
    with quick_figures():
        rc, text = cli("run", small, "--out", out, "--resume")
    assert rc == 0, text
    assert_bit_identical(reference, result(out))


def test_a_directory_in_the_way_of_the_summary(small, reference, tmp_path, monkeypatch):
    from contactopt import runner
    out = tmp_path / "run"
    real = runner.write_outputs

    def blocked(out_, *a, **kw):
        (out_ / "summary.json").mkdir()
        (out_ / "summary.json" / "x").write_text("in the way")
        return real(out_, *a, **kw)

    with quick_figures(), monkeypatch.context() as mp:
        mp.setattr(runner, "write_outputs", blocked)
        code, text = cli("run", small, "--out", out, "--max-iter", MAX_ITER)
    assert code == 74, text
    assert f"cannot write {out / 'summary.json'}: a directory is in the way" in text, text
    assert f"the checkpoint of the finished optimization (iteration {MAX_ITER}," in text
    shutil.rmtree(out / "summary.json")
    with quick_figures():
        code, text = cli("run", small, "--out", out, "--resume")
    assert code == 0, text
    assert_bit_identical(reference, result(out))
    assert "the optimization had finished, its results are written again" in (out / "run.log").read_text()


# ------------------------------------------------------------------------------ a real small disk
def mount_tmpfs(where: Path, size="3m") -> bool:
    where.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0 or not shutil.which("mount"):
        return False
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                          capture_output=True, text=True)
    return proc.returncode == 0


def free_bytes(path: Path) -> int:
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize


def environment() -> dict:
    """This contactopt first on the path; one thread per library, so that the last bits of a
    result do not depend on how a parallel reduction was split (between processes they may)."""
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join([SRC] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def contactopt_cmd(*args) -> list[str]:
    return [sys.executable, "-m", "contactopt.cli", *map(str, args)]


@pytest.mark.slow
@pytest.mark.parametrize("free_kb", [40, 120, 400, 800, 990])
def test_a_real_full_disk(small, tmp_path, free_kb):
    """The run's directory on a 3 MB tmpfs filled up to ``free_kb``: the run stops with exit 74
    wherever the space ends, and once there is space again --resume finishes the run as the
    uninterrupted one on the same disk."""
    disk = tmp_path / "disk"
    if not mount_tmpfs(disk):
        pytest.skip("cannot mount a tmpfs here (not root, or not permitted)")
    try:
        env = environment()
        ref = disk / "ref"
        proc = subprocess.run(contactopt_cmd("run", small, "--out", ref, "--max-iter", MAX_ITER), env=env,
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr
        expected = result(ref)
        shutil.rmtree(ref)
        filler = disk / "filler"
        with open(filler, "wb") as fh:
            fh.write(b"\0" * max(0, free_bytes(disk) - free_kb * 1024))
        out = disk / "run"
        proc = subprocess.run(contactopt_cmd("run", small, "--out", out, "--max-iter", MAX_ITER), env=env,
                              capture_output=True, text=True, timeout=600)
        text = proc.stdout + proc.stderr
        assert proc.returncode == 74, text
        assert "Traceback" not in text and "No space left on device" in text, text
        failed = re.search(r"cannot write (\S+):", text).group(1)
        print(f"\n{free_kb} kB free: stopped at {Path(failed).name} "
              f"(checkpoint {checkpoint_position(out)})")
        assert_readable(out)
        filler.unlink()
        again = ["run", small, "--out", out, "--resume"] if checkpoint_position(out) else \
            ["run", small, "--out", out, "--max-iter", MAX_ITER, "--overwrite"]
        proc = subprocess.run(contactopt_cmd(*again), env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert_bit_identical(expected, result(out))
    finally:
        subprocess.run(["umount", str(disk)], check=False)


# ------------------------------------------------------------------------------ two writers
HOLDER = textwrap.dedent("""
    import sys, time
    from contactopt.io.lock import acquire
    held = acquire(sys.argv[1])
    print("held", flush=True)
    time.sleep(600)
""")


@contextlib.contextmanager
def held(directory: Path):
    """Another live process holding ``directory``'s lock."""
    directory.mkdir(parents=True, exist_ok=True)
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(directory)], env=environment(),
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "held"
        yield proc
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def test_a_second_writer_is_refused_naming_the_holder(small, reference, tmp_path):
    run = reference["dir"]
    target = tmp_path / "busy"
    with held(target) as holder:
        (target / "mine.txt").write_text("the holder's")
        for args in (("run", small, "--out", target, "--max-iter", 2),
                     ("run", small, "--out", target, "--max-iter", 2, "--overwrite"),
                     ("run", small, "--out", target, "--resume"),
                     ("export", run, "--out", target, "--format", "stl"),
                     ("sweep", small, "--set", "friction.coefficient=0,0.1", "--out", target, "--resume")):
            t0 = time.perf_counter()
            code, text = cli(*args)
            assert code == 2, (args, text)
            assert f"in use by another contactopt process (PID {holder.pid} on " in text, text
            assert time.perf_counter() - t0 < 5.0, args        # refused before any set-up
            assert sorted(p.name for p in target.iterdir()) == [LOCK_NAME, "mine.txt"], args
            assert (target / "mine.txt").read_text() == "the holder's"
    # the holder is gone: its lock is stale, and the next writer takes it over
    code, text = cli("export", run, "--out", target, "--format", "stl")
    assert code == 0, text
    assert sorted(p.name for p in target.iterdir()) == ["mine.txt", "optimal_body.stl"]


def test_overwrite_never_removes_a_directory_another_process_holds_below(tmp_path):
    sweep = tmp_path / "sw"
    (sweep / "runs" / "a").mkdir(parents=True)
    (sweep / "sweep.toml").write_text("x")
    with held(sweep / "runs" / "a") as holder:
        from contactopt.io.rundir import OutputDirError, claim_output_dir
        with pytest.raises(OutputDirError, match=f"PID {holder.pid}.*nothing was removed"):
            claim_output_dir(sweep, overwrite=True, what="sweep")
        assert (sweep / "sweep.toml").exists() and (sweep / "runs" / "a" / LOCK_NAME).exists()
    claim_output_dir(sweep, overwrite=True, what="sweep").release()
    assert list(sweep.iterdir()) == []


def test_stale_lock_of_a_killed_run_is_taken_over_with_a_note(small, reference, tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen(contactopt_cmd("run", small, "--out", out, "--max-iter", MAX_ITER), env=environment(),
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    for line in proc.stdout:
        if line.startswith("it    2"):
            break
    proc.kill()
    proc.wait()
    proc.stdout.close()
    stale = json.loads((out / LOCK_NAME).read_text())
    assert stale["pid"] == proc.pid
    with quick_figures():
        code, text = cli("run", small, "--out", out, "--resume")
    assert code == 0, text
    log = (out / "run.log").read_text()
    assert f"took over the lock of {out} from a writer that no longer runs (PID {proc.pid} on " in log
    assert not (out / LOCK_NAME).exists()
    # the killed process ran elsewhere (a subprocess, MKL's rounding may differ): the trajectory
    # up to its checkpoint came from there, so only the run's completion is compared here
    assert result(out)["iterations"] == MAX_ITER


def test_without_flock_a_dead_pid_on_this_host_is_stale_and_a_live_one_is_not(tmp_path, monkeypatch):
    monkeypatch.setattr(lock, "_flock", lambda fd: None)        # a file system without flock
    d = tmp_path / "d"
    d.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    me = lock._me()
    (d / LOCK_NAME).write_text(json.dumps(dict(me, pid=dead.pid)))
    with lock.acquire(d) as got:
        assert got.previous["pid"] == dead.pid
        assert json.loads((d / LOCK_NAME).read_text())["pid"] == os.getpid()
    assert not (d / LOCK_NAME).exists()
    (d / LOCK_NAME).write_text(json.dumps(dict(me, pid=os.getppid())))
    with pytest.raises(lock.LockedError, match=f"PID {os.getppid()}.*remove"):
        lock.acquire(d)
    (d / LOCK_NAME).write_text(json.dumps(dict(me, host="elsewhere", pid=1)))
    with pytest.raises(lock.LockedError, match="on elsewhere"):
        lock.acquire(d)


def test_two_real_runs_in_one_directory(small, tmp_path):
    """The issue's case: a run, and while it runs the same command with --overwrite."""
    out = tmp_path / "same"
    cmd = wrapped(tmp_path, True) + ["run", str(small), "--out", str(out), "--max-iter", "6"]
    first = subprocess.Popen(cmd, env=environment(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for line in first.stdout:
        if line.startswith("it "):
            break
    code, text = cli("run", small, "--out", out, "--max-iter", 6, "--overwrite")
    rest = first.stdout.read()
    first.wait()
    first.stdout.close()
    assert code == 2 and f"PID {first.pid}" in text, text
    assert first.returncode == 0, rest
    s = json.loads((out / "summary.json").read_text())
    rows = (out / "history.csv").read_text().splitlines()
    assert len(rows) == 1 + s["evaluations"]
    assert [r.split(",")[0] for r in rows[1:]] == [str(k) for k in range(1, s["evaluations"] + 1)]


# ------------------------------------------------------------------------------ interruptions
WRAPPER = textwrap.dedent("""
    # contactopt's command line with stub figures (the test's runs are about signals, not plots)
    import sys
    from pathlib import Path
    from contactopt.io import atomic, plots

    def save(fig, path):
        with atomic.atomic_output(path) as tmp:
            tmp.write_bytes({png!r})
        return Path(path)

    plots._save = save
    from contactopt.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def wrapped(tmp_path: Path, quick: bool):
    if not quick:
        return [sys.executable, "-m", "contactopt.cli"]
    script = tmp_path / "quick_cli.py"
    script.write_text(WRAPPER.format(png=PNG))
    return [sys.executable, str(script)]


def interrupt_run(cmd, out, signum, rng, max_iter, env, first=1):
    """Start ``cmd``, send ``signum`` a seeded random delay after a random progress line."""
    when = rng.randint(first, max_iter - 1)          # 0: before the first checkpoint
    delay = round(rng.uniform(0.0, 0.15), 3)
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            bufsize=1)
    seen = []
    try:
        if when == 0:                   # once the run has its directory, in its first evaluations
            while proc.poll() is None and not (out / "history.csv").exists():
                time.sleep(0.005)
            time.sleep(delay)
        else:
            for line in proc.stdout:
                seen.append(line)
                m = re.match(r"^it\s+(\d+)\s", line)
                if m and int(m.group(1)) >= when:
                    break
            time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(signum)
        rest = proc.stdout.read()
        proc.wait(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
    return proc.returncode, "".join(seen) + rest, (when, delay)


def subprocess_reference(small, tmp_path: Path, quick: bool) -> dict:
    """The uninterrupted run in a process of its own, as the interrupted ones run."""
    ref = tmp_path / "ref"
    proc = subprocess.run(wrapped(tmp_path, quick) + ["run", str(small), "--out", str(ref), "--max-iter",
                                                      str(MAX_ITER)], env=environment(), capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return result(ref)


@pytest.fixture(scope="module")
def quick_subprocess_reference(small, tmp_path_factory) -> dict:
    return subprocess_reference(small, tmp_path_factory.mktemp("subref"), True)


def interrupted_then_resumed(small, tmp_path, signum, seed, expected, quick=True, moments=1):
    env = environment()
    base = wrapped(tmp_path, quick)
    rng = random.Random(seed)
    for k in range(moments):
        out = tmp_path / f"run{k}"
        code, text, moment = interrupt_run(base + ["run", str(small), "--out", str(out), "--max-iter", str(MAX_ITER)],
                                           out, signum, rng, MAX_ITER, env, first=0 if moments > 1 else 1)
        name = signal.Signals(signum).name
        if code == 0:                       # it ended before the signal came
            print(f"\n{name} at {moment}: the run had finished")
            continue
        assert code == 128 + signum, text
        assert "Traceback" not in text, text
        if not (out / "summary.json").exists():     # in the set-up, before the directory was claimed
            assert "interrupted" in text and not checkpoint_position(out), text
            print(f"\n{name} at {moment}: in the set-up, nothing written")
            continue
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "interrupted" and summary["signal"] == name, summary
        assert summary["message"] in text
        assert_readable(out)
        position = checkpoint_position(out)
        if position is None:
            assert summary["resume"] is None and "--overwrite" in text
            again = base + ["run", str(small), "--out", str(out), "--max-iter", str(MAX_ITER), "--overwrite"]
        else:
            assert summary["checkpoint"] == {"iteration": position[0], "evaluations": position[1]}
            assert f"continue with: {summary['resume']}" in text
            again = base + shlex.split(summary["resume"])[1:]
        proc = subprocess.run(again, env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert_bit_identical(expected, result(out))
        print(f"\n{name} at {moment}: {summary['message']}; resumed bit for bit")


@pytest.mark.parametrize("signum, seed", [(signal.SIGINT, "sigint"), (signal.SIGTERM, "sigterm")])
def test_interrupted_run_says_so_and_resumes_bit_for_bit(small, quick_subprocess_reference, tmp_path, signum, seed):
    interrupted_then_resumed(small, tmp_path, signum, seed, quick_subprocess_reference)


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_interrupted_runs_at_many_moments_with_their_figures(small, tmp_path, signum):
    interrupted_then_resumed(small, tmp_path, signum, f"many-{signum}", subprocess_reference(small, tmp_path, False),
                             quick=False, moments=6)


def test_the_summary_of_an_interrupted_run_is_not_a_result(small, tmp_path):
    """A sweep never reuses an interrupted run as finished, and gather lists it as interrupted."""
    from contactopt.studies.sweep import _finished_summary
    run = tmp_path / "r"
    run.mkdir()
    (run / "summary.json").write_text(json.dumps({"status": "interrupted", "message": "m"}))
    assert _finished_summary(run) is None
    (run / "summary.json").write_text(json.dumps({"status": 1, "J": 1.0}))
    assert _finished_summary(run) == {"status": 1, "J": 1.0}


# ------------------------------------------------------------------------------ sweeps
SWEEP_SET = "friction.coefficient=0,0.3"
SWEEP = ("--set", SWEEP_SET, "--max-iter", MAX_ITER)
ONE_WORKER = ("--workers", 1, "--threads", 1)          # resources: not part of the resume command


def sweep_rows(out: Path) -> list[dict]:
    with open(out / "sweep.csv", newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def sweep_reference(small, tmp_path_factory):
    pytest.importorskip("distributed")
    out = tmp_path_factory.mktemp("swref") / "sw"
    proc = subprocess.run(contactopt_cmd("sweep", small, *SWEEP, *ONE_WORKER, "--out", out), env=environment(), capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = sweep_rows(out)
    assert any(float(r["J"]) < float(r["J0"]) for r in rows), rows        # a design moved
    return {r["friction.coefficient"]: (r["J"], (out / r["run_dir"] / "alpha.json").read_text()) for r in rows}


def same_sweep_results(out: Path, expected: dict):
    rows = sweep_rows(out)
    assert [r["error"] for r in rows] == ["", ""], rows
    got = {r["friction.coefficient"]: (r["J"], (out / r["run_dir"] / "alpha.json").read_text()) for r in rows}
    assert got == expected
    assert not [p for p in out.rglob(".*") if ".tmp" in p.name or p.name == LOCK_NAME]


@pytest.mark.slow
@pytest.mark.parametrize("signum, seed, after", [(signal.SIGINT, 1, "the cluster started"),
                                                 (signal.SIGTERM, 2, "the first task finished")])
def test_interrupted_sweep_marks_its_tasks_and_resumes_them(small, sweep_reference, tmp_path, signum, seed, after):
    env = environment()
    out = tmp_path / "sw"
    rng = random.Random(seed)
    delay = rng.uniform(0.5, 8.0) if after == "the cluster started" else rng.uniform(0.0, 1.0)
    cmd = contactopt_cmd("sweep", small, *SWEEP, *ONE_WORKER, "--out", out)
    # to the whole process group, as a terminal's Ctrl-C or a batch system's time limit: the
    # local cluster's processes get it too
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    first = proc.stdout.readline()           # "sweep on tcp://…": the cluster is up
    while after == "the first task finished" and not first.splitlines()[-1].startswith("[1/2]"):
        line = proc.stdout.readline()        # "[1/2] friction.coefficient=0.0: J/J0 = …"
        assert line, first
        first += line
    time.sleep(delay)
    os.killpg(proc.pid, signum)
    text = first + proc.communicate(timeout=300)[0]
    print(f"\n{signal.Signals(signum).name} {delay:.2f} s after {after}")
    if proc.returncode == 0:
        pytest.skip("the sweep ended before the signal")
    assert proc.returncode == 128 + signum, text
    assert "Traceback" not in text.split("contactopt: sweep interrupted")[-1], text
    rows = sweep_rows(out)
    assert any(r["error"] == "interrupted" for r in rows), rows
    status = [r["status"] for r in json.loads((out / "sweep.json").read_text())]
    assert set(status) <= {"new", "interrupted"} and "interrupted" in status
    print(f"tasks: {status}; resumed to the uninterrupted sweep's J and α bit for bit")
    again = re.search(r"continue with: (.*)$", text, re.M).group(1)
    assert again.endswith("--resume")
    proc = subprocess.run(contactopt_cmd(*shlex.split(again)[1:], *ONE_WORKER), env=env, capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    same_sweep_results(out, sweep_reference)
    assert not list(out.rglob(LOCK_NAME))


@pytest.mark.slow
@pytest.mark.parametrize("name, nth", [("sweep.csv", 1), ("sweep.json", 2), ("ratio.png", 1), ("lambda.png", 1)])
def test_full_disk_at_a_write_of_a_sweep(small, sweep_reference, tmp_path, monkeypatch, name, nth):
    from contactopt.studies import gather
    out = tmp_path / "sw"
    with monkeypatch.context() as mp:
        enospc(mp, name, nth)
        code, text = cli("sweep", small, *SWEEP, *ONE_WORKER, "--out", out)
    assert code == 74, text
    assert f"cannot write {out / name}: no space left on the device" in text, text
    assert "--resume" in text
    for p in ("sweep.csv", "sweep.json"):
        if (out / p).exists():
            (sweep_rows(out) if p.endswith("csv") else json.loads((out / p).read_text()))
    gather(out, write=False)                 # the run directories are readable as they are
    again = re.search(r"'?(contactopt sweep .*--resume)'?", text).group(1)
    code, text = cli(*shlex.split(again)[1:], *ONE_WORKER)
    assert code == 0, text
    same_sweep_results(out, sweep_reference)
