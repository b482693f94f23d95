"""A design study: one optimization run per combination of settings, on dask.distributed.

Layout of a sweep directory::

    sweep.toml         the base configuration (resolved) and the settings of the sweep
    sweep.csv          one row per finished task: one column per swept key (named as the key),
                       then J0, J, ratio (J/J0), evaluations, success, wall_time_s, error, run_dir
    sweep.json         the same rows with more fields (status, warnings, message, worker)
    runs/<name>/       one run directory per task (:mod:`contactopt.runner`), <name> from the
                       settings, e.g. ``friction.coefficient=0.1``
    ratio.png, surfaces.png, lambda.png   comparison plots (:mod:`contactopt.studies.plots`)

Each task is a pure function of its settings: its dask key is derived from the task's resolved
configuration, the stopping parameters and its run directory, and all it does is write that run
directory and return a row. Nothing is lost:

- a task that fails (no convergence, an inverted mesh) returns a row with ``error`` set, and the
  others go on;
- a worker that dies mid-task has its task run again elsewhere by the scheduler (up to its
  ``allowed-failures``); the task finds the run directory of its first attempt and continues it
  from the checkpoint (``run_optimization(resume=True)``). A directory without a checkpoint (the
  worker died before the first iteration ended) is started afresh; one with ``summary.json`` of
  the same configuration is the finished result and is reused as it is;
- ``sweep.csv``/``sweep.json`` are rewritten atomically after each finished task, and
  :func:`gather` rebuilds them from the run directories alone;
- ``resume=True`` (CLI ``--resume``) runs the sweep again in its directory: finished runs are
  reused, unfinished ones resumed.

One sweep per directory: the driver holds the sweep directory's lock (:mod:`contactopt.io.lock`)
and every task its run directory's. Interrupted (SIGINT, SIGTERM), the driver marks the tasks
that had not finished ``interrupted`` in sweep.csv (``error``) and sweep.json (``status``) and
stops its local cluster; their runs keep their checkpoints and ``--resume`` continues them.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import os
import shlex
import signal
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..config import load_config, validate
from ..errors import ConfigError
from ..io.atomic import WriteError, atomic_write_json, atomic_write_text, write_error
from ..io.lock import DirLock, LockedError, describe, held_by
from ..io.rundir import RunDirectory, claim_output_dir
from .settings import SweepTask, build_tasks, format_value

log = logging.getLogger(__name__)

__all__ = ["SweepResult", "run_sweep", "run_task", "gather", "RESULT_COLUMNS"]

RESULT_COLUMNS = ["J0", "J", "ratio", "evaluations", "success", "wall_time_s", "error", "run_dir"]
RUNS = "runs"


@dataclass
class SweepResult:
    """Rows in task order (dicts with the settings' keys and RESULT_COLUMNS, and more)."""

    outdir: Path
    keys: list
    rows: list
    wall_time_s: float = 0.0
    dashboard: str | None = None
    plots: list = field(default_factory=list)

    @property
    def n_failed(self) -> int:
        return sum(1 for r in self.rows if r.get("error"))


# ---------------------------------------------------------------------------------------- task
@dataclass(frozen=True)
class TaskSpec:
    """What a worker needs for one task (pickled to it)."""

    task: SweepTask
    run_dir: str
    sweep_dir: str
    max_iter: int | None
    eps: float | None
    threads: dict            # {host: threads per task}; see contactopt.studies.cluster
    plots: bool = True       # each run's PNG figures


def _same_config(run_dir: Path, cfg) -> bool:
    try:
        text = (run_dir / "config.toml").read_text()
        return validate(tomllib.loads(text)).to_dict() == cfg.to_dict()
    except (OSError, tomllib.TOMLDecodeError, ConfigError):
        return False


def _row(task: SweepTask, run_dir: str, **values) -> dict:
    row = {k: v for k, v in task.settings}
    row.update({c: None for c in RESULT_COLUMNS})
    row.update(run_dir=run_dir, error="", task=task.index)
    row.update(values)
    return row


def _summary_row(task: SweepTask, rel: str, summary: dict, status: str) -> dict:
    return _row(task, rel, J0=summary.get("J0"), J=summary.get("J"), ratio=summary.get("ratio"),
                evaluations=summary.get("evaluations"), success=summary.get("success"),
                wall_time_s=summary.get("wall_time_s"), status=status,
                iterations=summary.get("iterations"), message=summary.get("message", ""),
                warnings=summary.get("warnings", []))


def _worker_threads(threads: dict) -> tuple[int, str]:
    """This worker's thread budget and address (outside dask: 1 and 'local')."""
    try:
        from distributed import get_worker

        from .cluster import host_of
        addr = get_worker().address
        return int(threads.get(host_of(addr), 1)), addr
    except (ImportError, ValueError):
        return int(threads.get("local", 1)), "local"


def run_task(spec: TaskSpec) -> dict:
    """Run (or reuse, or continue) one task's optimization; always returns a row, never raises
    for a failed run (its error is in the row)."""
    from ..runner import resolve_config, run_optimization
    from .cluster import limit_threads
    task = spec.task
    out = Path(spec.run_dir)
    rel = os.path.relpath(out, spec.sweep_dir)
    n_threads, worker = _worker_threads(spec.threads)
    if os.environ.get("CONTACTOPT_SWEEP_THREADS") != str(n_threads):
        limit_threads(n_threads)
        os.environ["CONTACTOPT_SWEEP_THREADS"] = str(n_threads)
    t0 = time.perf_counter()
    status = "new"
    try:
        cfg = resolve_config(task.config, eps=spec.eps, max_iter=spec.max_iter)
        summary = _finished_summary(out) if _same_config(out, cfg) else None
        if summary is not None:
            log.info("task %s: reusing the finished run in %s", task.label, out)
            return dict(_summary_row(task, rel, summary, "reused"), worker=worker)
        resume = overwrite = False
        if RunDirectory(out).checkpoint.exists():
            resume, status = True, "resumed"
        elif out.exists() and any(out.iterdir()):
            overwrite, status = True, "restarted"     # died before its first checkpoint
        log.info("task %s: %s run in %s (%d threads, worker %s)", task.label, status, out, n_threads, worker)
        rr = run_optimization(cfg, out, eps=spec.eps, max_iter=spec.max_iter, resume=resume,
                              overwrite=overwrite, plots=spec.plots)
        return dict(_summary_row(task, rel, rr.summary, status), worker=worker)
    except Exception as exc:     # a failed task is a result too; the sweep goes on
        log.warning("task %s failed: %s", task.label, exc)
        return _row(task, rel, error=f"{type(exc).__name__}: {exc}", status="failed", worker=worker,
                    wall_time_s=time.perf_counter() - t0, success=False)


def _finished_summary(run_dir: Path) -> dict | None:
    """summary.json of a finished run (None: absent, unreadable, or of an interrupted run)."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return None if summary.get("status") == "interrupted" else summary


def task_key(spec: TaskSpec) -> str:
    """A deterministic dask key: the same task (configuration, stopping, directory) -> the same key."""
    text = "\n".join([spec.task.config.to_toml(), repr((spec.max_iter, spec.eps)),
                      os.path.abspath(spec.run_dir)])
    return f"contactopt-run-{spec.task.name[:60]}-{hashlib.sha256(text.encode()).hexdigest()[:16]}"


# ---------------------------------------------------------------------------------------- tables
def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return format_value(value) if not isinstance(value, str) else value


def write_tables(outdir: Path, keys: list, rows: list) -> None:
    """sweep.csv and sweep.json from rows (finished tasks, in task order), each atomically."""
    rows = sorted(rows, key=lambda r: r["task"])
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(keys) + RESULT_COLUMNS)
    for r in rows:
        w.writerow([_cell(r.get(k)) for k in list(keys) + RESULT_COLUMNS])
    atomic_write_text(outdir / "sweep.csv", buf.getvalue())
    atomic_write_json(outdir / "sweep.json", rows)


def _write_definition(outdir: Path, base, settings, max_iter, eps) -> None:
    import tomli_w
    sweep = {"settings": {k: v for k, v in settings}, "base": base.source}
    if max_iter is not None:
        sweep["max_iter"] = max_iter
    if eps is not None:
        sweep["eps"] = eps
    atomic_write_text(outdir / "sweep.toml", "# a contactopt sweep: [sweep] settings over the base "
                      "configuration [config]\n" + tomli_w.dumps({"sweep": sweep, "config": base.to_dict()}))


def read_definition(outdir) -> tuple:
    """(base Config, settings [(key, values)], max_iter, eps) of a sweep directory."""
    path = Path(outdir) / "sweep.toml"
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError([f"{path}: not a sweep definition ({exc})"]) from None
    sw = data["sweep"]
    return (validate(data["config"], str(path)), list(sw["settings"].items()), sw.get("max_iter"),
            sw.get("eps"))


def gather(outdir, *, write: bool = True) -> SweepResult:
    """Rebuild the rows of a sweep from its run directories (summary.json of finished runs; an
    unfinished run is a row with error 'unfinished'); rewrite sweep.csv/json when ``write``."""
    outdir = Path(outdir)
    base, settings, max_iter, eps = read_definition(outdir)
    tasks = build_tasks(base, settings)
    keys = [k for k, _ in settings]
    rows = []
    for task in tasks:
        run_dir = outdir / RUNS / task.name
        rel = os.path.relpath(run_dir, outdir)
        summary = _finished_summary(run_dir)
        if summary is not None:
            rows.append(_summary_row(task, rel, summary, "finished"))
        elif (run_dir / "summary.json").exists():     # an interrupted run: its summary says so
            rows.append(_row(task, rel, error="interrupted", status="interrupted", success=False))
        elif run_dir.exists():
            rows.append(_row(task, rel, error="unfinished", status="unfinished", success=False))
    if write:
        write_tables(outdir, keys, rows)
    return SweepResult(outdir, keys, rows)


# ---------------------------------------------------------------------------------------- driver
def _prepare(outdir: Path, *, resume: bool, overwrite: bool, settings, base, max_iter, eps) -> DirLock:
    if resume and (outdir / "sweep.toml").exists():
        old_base, old_settings, _, _ = read_definition(outdir)
        if old_base.to_dict() != base.to_dict():
            raise ConfigError([f"--resume: {outdir} holds a sweep of another base configuration"])
    lock = claim_output_dir(outdir, overwrite=overwrite, resume=resume, what="sweep")
    try:
        if lock.previous:
            log.warning("took over the lock of %s from a sweep that no longer runs (%s)", outdir,
                        describe(lock.previous))
        try:
            (outdir / RUNS).mkdir(exist_ok=True)
        except OSError as exc:
            raise write_error(outdir / RUNS, exc) from exc
        _write_definition(outdir, base, settings, max_iter, eps)
    except BaseException:
        lock.release()
        raise
    return lock


def resume_command(config, settings, outdir, max_iter=None, eps=None) -> str:
    """The command that continues the sweep in ``outdir``."""
    cfg = str(config) if isinstance(config, (str, os.PathLike)) else str(getattr(config, "source", ""))
    cfg = cfg if cfg and not cfg.startswith("<") else "CONFIG"      # a configuration built in Python
    parts = ["contactopt", "sweep", cfg]
    for key, values in settings:
        parts += ["--set", f"{key}=" + ",".join(format_value(v) for v in values)]
    if max_iter is not None:
        parts += ["--max-iter", str(max_iter)]
    if eps is not None:
        parts += ["--eps", repr(eps)]
    return " ".join(shlex.quote(p) for p in parts + ["--out", str(outdir), "--resume"])


def run_sweep(config, settings, outdir, *, workers: int | None = None, scheduler: str | None = None,
              threads: int | None = None, max_iter: int | None = None, eps: float | None = None,
              resume: bool = False, overwrite: bool = False, progress=None, plots: bool = True,
              dashboard_address: str = ":8787", on_client=None) -> SweepResult:
    """Run every combination of ``settings`` [(key, [values])] over ``config`` on dask.distributed.

    ``scheduler``: address of a running scheduler (``tcp://host:8786``); else a LocalCluster of
    ``workers`` processes (default: one per core). ``threads``: MKL/BLAS threads per task (default
    cores per host // tasks running at once on it). ``progress(row, done, total)`` is called as
    each task finishes; ``on_client(client, dashboard)`` once connected. Invalid settings raise
    ConfigError before anything is written.
    """
    from .cluster import connect, dashboard_link, thread_budget
    if max_iter is not None and (not isinstance(max_iter, int) or max_iter < 1):
        raise ConfigError([f"max_iter {max_iter!r}: must be an integer ≥ 1"])
    if eps is not None and not (0 < eps < 1):
        raise ConfigError([f"eps {eps!r}: must be in (0, 1)"])
    if workers is not None and workers < 1:
        raise ConfigError([f"workers {workers}: must be ≥ 1"])
    if threads is not None and threads < 1:
        raise ConfigError([f"threads {threads}: must be ≥ 1"])
    base = load_config(config)
    tasks = build_tasks(base, settings)          # every problem listed before anything is written
    keys = [k for k, _ in settings]
    outdir = Path(outdir)
    if outdir.is_dir() and held_by(outdir) is not None:     # before a cluster is started for nothing
        raise LockedError(outdir, held_by(outdir) or {}, "sweep directory")
    again = resume_command(config, settings, outdir, max_iter, eps)
    t0 = time.perf_counter()
    lock = None
    try:
        with connect(workers=workers, scheduler=scheduler, threads=threads,
                     dashboard_address=dashboard_address) as client:
            lock = _prepare(outdir, resume=resume, overwrite=overwrite, settings=settings, base=base,
                            max_iter=max_iter, eps=eps)
            out = outdir
            dash = dashboard_link(client)
            log.info("sweep of %d tasks in %s on %s; dashboard %s", len(tasks), out,
                     client.scheduler.address, dash or "unavailable (install bokeh)")
            if on_client:
                on_client(client, dash)
            budget = thread_budget(client, threads)
            log.info("threads per task by host: %s", budget)
            rows = _run_tasks(client, tasks, out, keys, budget, max_iter, eps, progress, again, plots)
        result = SweepResult(out, keys, rows, time.perf_counter() - t0, dash)
        if plots:
            from .plots import plot_sweep
            try:
                result.plots = plot_sweep(out, keys, rows)
            except WriteError as exc:   # a full disk is said, not hidden among the warnings
                exc.args = (f"{exc.args[0]}; sweep.csv and sweep.json are complete, and '{again}' "
                            f"writes the figures again (every run is reused)",)
                raise
            except Exception as exc:   # a figure is never worth losing the results for
                log.warning("comparison plots failed: %s", exc)
    finally:
        if lock is not None:
            lock.release()
    return result


def _run_tasks(client, tasks, out: Path, keys, budget, max_iter, eps, progress, again: str,
               plots: bool = True) -> list:
    specs = [TaskSpec(t, str((out / RUNS / t.name).resolve()), str(out.resolve()), max_iter, eps, budget, plots)
             for t in tasks]
    rows = []
    try:
        return _collect(client, specs, out, keys, rows, progress)
    except WriteError as exc:
        exc.args = (f"{exc.args[0]}; {len(rows)} of {len(specs)} tasks had finished; continue with: {again}",)
        raise
    except KeyboardInterrupt as exc:
        from ..runner import RAISED, Interrupted
        finished = {r["task"] for r in rows}
        for spec in specs:
            if spec.task.index not in finished:
                rows.append(_row(spec.task, os.path.relpath(spec.run_dir, spec.sweep_dir), error="interrupted",
                                 status="interrupted", success=False))
        signum = getattr(exc, "signum", signal.SIGINT)
        message = (f"sweep interrupted by {signal.Signals(signum).name}: {len(finished)} of {len(specs)} tasks "
                   f"had finished, the others are marked interrupted in sweep.csv")
        try:
            write_tables(out, keys, rows)
        except (WriteError, KeyboardInterrupt) as err:
            log.error("the tables of the interrupted sweep were not written: %s", err)
        log.error("%s", message, extra=RAISED)
        raise Interrupted(signum, f"{message}; continue with: {again}", again) from None


def _collect(client, specs, out: Path, keys, rows: list, progress) -> list:
    """Gather the tasks' rows as they finish into ``rows``, rewriting the tables each time."""
    from distributed import as_completed
    futures = {client.submit(run_task, s, key=task_key(s), retries=1): s for s in specs}
    done = 0
    for fut in as_completed(futures):
        spec = futures[fut]
        try:
            row = fut.result()
        except Exception as exc:     # KilledWorker after the allowed failures, a lost scheduler
            rel = os.path.relpath(spec.run_dir, spec.sweep_dir)
            row = _row(spec.task, rel, error=f"{type(exc).__name__}: {exc}", status="lost", success=False)
        rows.append(row)
        done += 1
        write_tables(out, keys, rows)
        if row["error"]:
            log.info("[%d/%d] %s: failed: %s", done, len(specs), spec.task.label, row["error"])
        else:
            log.info("[%d/%d] %s: J/J0 = %s (%s evaluations, %.1f s, %s)", done, len(specs),
                     spec.task.label, row["ratio"], row["evaluations"], row["wall_time_s"] or 0.0,
                     row["status"])
        if progress:
            progress(row, done, len(specs))
        fut.release()
    return sorted(rows, key=lambda r: r["task"])
