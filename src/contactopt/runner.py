"""One optimization run = one output directory (resolved config, log, history, checkpoint, results).

Layout of a run directory::

    config.toml        the resolved configuration, with package versions
    run.log            the log of the run
    history.csv        one row per evaluation of Θ
    iterations.csv     one row per bundle-trust iteration: Θ, step kind, t, stationarity measure
    checkpoint.npz     optimizer + oracle state after the last iteration (written atomically)
    summary.json       J0, J, iterations, evaluations, serious/null steps, success, message, alpha, times
    alpha.json         optimal control points;  surface.csv  ϑ_α on a grid
    stress.png, pressure.png, surface.png, history.png, classes.png, contact.png (pressure, ‖τ‖,
                       slip, stick/slip), von_mises.png (the largest von Mises stresses)
    initial.vtu, optimal.vtu, bodies.pvd
    optimal_body.msh (the input's format) + optimal_body.toml, optimal_body.stl,
    contact_surface.step, contact_surface.iges   the optimal design for CAD and other FE tools
                                                 (:mod:`contactopt.io.export`; summary.json "export")

    .contactopt.lock   the lock of the process writing the directory, while it runs
                       (:mod:`contactopt.io.lock`: one writer per directory)

A state solve that fails during the run (e.g. Newton does not converge) stops it with
:class:`RunAborted`; the checkpoint of the last finished iteration stays and ``--resume``
continues from it. So does a write that fails (:class:`~contactopt.io.atomic.WriteError`: a full
disk, a read-only file system) and an interruption (:class:`Interrupted`, SIGINT or SIGTERM),
after which summary.json says ``"status": "interrupted"`` and the command that continues the run;
both messages say where the run stands, read from the checkpoint itself. A checkpoint written
once the optimization has stopped carries its result, and resuming from it writes the outputs
again without another iteration. Resuming (``resume=True``) restores the optimizer state and the warm start
of the state solver saved with the last checkpoint, truncates history.csv to the evaluations before it, and goes on:
the iterates that follow are those of an uninterrupted run.
"""

from __future__ import annotations

import csv
import hashlib
import logging
import os
import shlex
import signal
import time
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from .config import Config, load_config
from .errors import CheckpointError, ConfigError, ContactOptError, SolverError
from .io.atomic import WriteError, atomic_savez, atomic_write_json, atomic_write_text, write_error
from .io.lock import LockedError, describe, held_by
from .io.rundir import claim_output_dir

log = logging.getLogger(__name__)

HISTORY_FIELDS = ["evaluation", "iteration", "f", "subgradient_norm", "degenerate_nodes", "contact_nodes",
                  "state_iterations", "state_residual", "time_s"]


def history_fields(problem) -> list[str]:
    """The columns of history.csv: with load cases also Θ_k per case (``f_<name>``, unweighted)
    and the names of the active cases (separated by ';')."""
    terms = [f"term_{name}" for name in problem.term_names()]     # [[objective.terms]], unweighted
    steps = [f"f_step_{name}" for name in problem.step_columns()]     # load paths: J at each step's end
    steps += [f"constraint_{c.name}" for c in problem.constraints]    # each constraint's response
    if not problem.has_load_cases:
        return HISTORY_FIELDS + terms + steps
    return HISTORY_FIELDS + [f"f_{name}" for name in problem.case_names] + ["active_cases"] + terms + steps


class RunAborted(ContactOptError):
    """The run stopped early because a state solve failed; the last checkpoint is kept.

    ``checkpoint`` is its path (None when no iteration had finished)."""

    checkpoint = None


class Interrupted(KeyboardInterrupt):
    """The process was asked to stop (SIGINT, SIGTERM): the evaluation in progress is abandoned.

    ``signum`` is the signal; a run's summary.json then says ``"status": "interrupted"``, and
    ``message``/``resume`` say where the run stands and the command that continues it."""

    def __init__(self, signum=signal.SIGINT, message: str = "", resume: str | None = None):
        self.signum = int(signum)
        self.message = message
        self.resume = resume
        super().__init__(message)


def package_versions() -> dict:
    out = {}
    for name in ("contactopt", "numpy", "scipy", "daqp", "mkl", "meshio", "matplotlib", "h5py"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


def config_fingerprint(config: Config) -> str:
    return hashlib.sha256(config.to_toml().encode()).hexdigest()[:16]


@dataclass
class RunResult:
    outdir: Path
    summary: dict


# a log record whose text the exception raised next carries too: the command line prints that
# one and leaves the record to run.log
RAISED = {"raised": True}

LONG_EVALUATION = 5.0    # seconds: evaluations longer than this are logged at INFO (else DEBUG)


def _peak_rss_gb() -> float:
    try:
        import resource
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    except Exception:      # pragma: no cover - not POSIX
        return float("nan")


def _log_setup(problem, seconds: float) -> None:
    """The run log's record of the model: sizes, linear-solver path, memory estimate, set-up time."""
    model = problem.model
    est = problem.path.memory_estimate(model)
    log.info("model: %d free DOFs, %d elements, %d contact nodes; linear solver: %s path (%s); "
             "estimated peak of an evaluation %s; set-up %.1f s, peak RSS %.2f GB",
             model.assembler.n_free, len(model.body.reference.cells), model.n_contact, problem.path.name,
             problem.path.library, est.describe(), seconds, _peak_rss_gb())
    if model.foundation is not None:
        log.info("elastic foundation: %s", ", ".join(f"{k} {v}" for k, v in model.foundation.summary().items()))


def _log_evaluation(count: int, res) -> None:
    """Time per phase and peak memory of one evaluation (INFO when it was long)."""
    st = res.state
    total = sum(res.timings.values())
    level = logging.INFO if total >= LONG_EVALUATION else logging.DEBUG
    if not log.isEnabledFor(level):
        return
    phases = ", ".join(f"{k} {v:.2f}" for k, v in st.timings.items() if k != "total")
    log.log(level, "evaluation %d: %.2f s — state %.2f s (%s; zone %s nodes, Delassus block %s, %s "
            "Newton steps%s), adjoint %.2f s, design terms %.2f s; peak RSS %.2f GB", count, total,
            res.timings.get("state", 0.0), phases, st.stats.zone_nodes, st.stats.delassus,
            st.iterations, f", {st.stats.sparse_solves} sparse solves" if st.stats.sparse_solves is not None else "",
            res.timings.get("adjoint", 0.0), res.timings.get("design_terms", 0.0), _peak_rss_gb())


class _Oracle:
    """Θ and a subgradient, with bookkeeping: evaluation count, history rows, timings."""

    def __init__(self, problem, history_path: Path, t_start: float):
        self.problem = problem
        self.scale = 1.0          # BT sees Θ/scale (scale = Θ(α0)), so its ε is relative
        self.history_path = history_path
        self.t_start = t_start
        self.count = 0
        self.iteration = 0
        self.last_good = None
        self.reduction = None     # [design] symmetry / fixed: the bundle works on β (design.reduction)
        self.time = {"state": 0.0, "adjoint": 0.0, "design_terms": 0.0}

    def __call__(self, x):
        from .sensitivity.adjoint import subgradient
        try:
            res = subgradient(self.problem, x)
            # [[constraints]]: each response and its subgradient from the same state
            cons = self.problem.constraint_subgradients(x) if self.problem.constraints else []
        except SolverError as exc:
            raise RunAborted(f"state/subgradient failed at evaluation {self.count + 1}: {exc}") from exc
        for r in [res] + cons:
            for k in self.time:
                self.time[k] += r.timings.get(k, 0.0)
        self.count += 1
        st = res.state
        _log_evaluation(self.count, res)
        row = [self.count, self.iteration, repr(float(res.value)), f"{np.linalg.norm(res.gradient):.6e}",
               res.n_degenerate, int(np.sum(st.lam > 0)), st.iterations, f"{st.residual:.3e}",
               f"{time.perf_counter() - self.t_start:.3f}"]
        if self.problem.has_load_cases:
            row += [repr(float(v)) for v in res.case_values] + [";".join(res.active_cases)]
        row += [repr(float(v)) for v in res.terms.values()]
        row += [repr(v) for v in self.problem.step_values()]
        row += [repr(float(c.value)) for c in cons]
        try:     # appended: rows after the checkpoint's evaluations are dropped on --resume
            with open(self.history_path, "a", newline="") as fh:
                csv.writer(fh).writerow(row)
        except OSError as exc:
            raise write_error(self.history_path, exc) from exc
        if self.problem.constraints:     # c_i = (value − max)/max ≤ 0 (optimize/constrained.py)
            lim = np.array([c.limit for c in self.problem.constraints])
            c = (np.array([r.value for r in cons]) - lim) / lim
            J = np.array([r.gradient for r in cons]) / lim[:, None]
            return res.value / self.scale, res.gradient / self.scale, c, J
        return res.value / self.scale, res.gradient / self.scale


def _reduced(oracle, red):
    """The oracle of β: Θ(P β + α_fixed) and its subgradient Pᵀ ξ (and the constraints' rows Pᵀ)."""
    def f(beta):
        out = oracle(red.expand(beta))
        if len(out) == 4:
            return out[0], red.pullback(out[1]), out[2], np.array([red.pullback(row) for row in out[3]])
        return out[0], red.pullback(out[1])
    return f


def _saved_stopping(path: Path) -> dict:
    try:
        with np.load(path, allow_pickle=False) as z:
            return {"eps": float(z["meta_eps"]), "max_iter": int(z["meta_max_iter"])}
    except Exception:
        return {}       # a missing or corrupt checkpoint is reported by _read_checkpoint


def _write_checkpoint(path: Path, bstate, oracle: _Oracle, fingerprint: str, elapsed: float, result=None,
                      penalty=None):
    """The optimizer's and the oracle's state (atomically, after history.csv is on disk).

    ``result``: the optimizer's result once it has stopped, so that a resumed finished run
    writes its outputs again without another iteration; ``penalty``: the
    :class:`~contactopt.optimize.constrained.PenaltyState` of a run with [[constraints]] (σ, the
    outer iteration, the finished bundle runs), saved as ``penalty_*``."""
    try:
        with open(oracle.history_path, "rb+") as fh:
            os.fsync(fh.fileno())
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise write_error(oracle.history_path, exc) from exc
    d = bstate.to_dict()
    opt = oracle.problem.config.optimizer
    arrays = {f"bundle_{k}": np.asarray(v) for k, v in d.items()}
    arrays.update(meta_fingerprint=np.array(fingerprint), meta_evaluations=np.array(oracle.count),
                  meta_elapsed=np.array(elapsed), meta_scale=np.array(oracle.scale), meta_eps=np.array(opt.eps),
                  meta_max_iter=np.array(opt.max_iter))
    if oracle.reduction is not None:     # the bundle works on β: the design in α
        arrays["meta_alpha"] = oracle.reduction.expand(d["x"])
    if result is not None:
        arrays.update(meta_result_status=np.array(int(result.status)), meta_result_message=np.array(result.message),
                      meta_result_criterion=np.array(result.criterion or ""),
                      meta_result_relative_decrease=np.array(float(result.relative_decrease)))
    if penalty is not None:
        arrays.update({f"penalty_{k}": np.asarray(v) for k, v in penalty.to_dict().items()})
    arrays.update(oracle.problem.export_contexts())   # what each load case carries, per its path
    atomic_savez(path, **arrays)


def _saved_result(path: Path, bstate, max_iter: int, lb=None, ub=None, scale="bounds"):
    """The optimizer's result stored with a finished run's checkpoint (None: the run had not
    stopped, or it is resumed with another ``max_iter`` and so goes on); ``lb``, ``ub`` the box
    of the optimized variables, whose widths scale the state's variables (minimize_bundle's
    option ``scale``)."""
    from .optimize import BundleResult
    from .optimize._scaling import variable_scaling
    from .optimize.bundle import SUCCESS_STATUS
    with np.load(path, allow_pickle=False) as z:
        if "meta_result_status" not in z.files or int(z["meta_max_iter"]) != max_iter:
            return None
        status, message = int(z["meta_result_status"]), str(z["meta_result_message"])
        criterion, rel = str(z["meta_result_criterion"]) or None, float(z["meta_result_relative_decrease"])
    st = bstate.copy()
    res = BundleResult(x=st.x.copy(), fun=st.f, jac=st.xi.copy(), nit=st.nit, nfev=st.nfev,
                       n_serious=st.n_serious, n_null=st.n_null, success=status in SUCCESS_STATUS, status=status,
                       message=message, criterion=criterion, stationarity=st.stationarity,
                       relative_decrease=rel, predicted_decrease=st.predicted, gamma=st.gamma, t=st.t,
                       history=[dict(r) for r in st.history], state=st)
    scaling = variable_scaling(st.x.size, lb, ub, scale)
    return res if scaling is None else scaling.result(res)


def _read_checkpoint(path: Path, fingerprint: str):
    from .optimize import BundleState
    if not path.exists():
        raise CheckpointError(f"--resume: no checkpoint in {path.parent} (expected {path.name})")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as exc:  # zip/npz corruption surfaces as many exception types
        raise CheckpointError(f"checkpoint {path} is corrupt or unreadable: {exc}") from None
    if "meta_fingerprint" not in data:
        raise CheckpointError(f"checkpoint {path} is not a contactopt checkpoint")
    if str(data["meta_fingerprint"]) != fingerprint:
        raise CheckpointError(f"checkpoint {path} belongs to a run with another configuration")
    bundle = {k[len("bundle_"):]: v for k, v in data.items() if k.startswith("bundle_")}
    try:
        bstate = BundleState.from_dict(bundle)
    except ContactOptError as exc:
        raise CheckpointError(f"checkpoint {path}: {exc}") from None
    contexts = {k: v for k, v in data.items() if not k.startswith(("bundle_", "meta_", "penalty_"))}
    return (bstate, int(data["meta_evaluations"]), float(data["meta_elapsed"]), float(data["meta_scale"]),
            contexts)


def _read_penalty(path: Path):
    """The :class:`~contactopt.optimize.constrained.PenaltyState` of a checkpoint (None: a run
    without [[constraints]])."""
    from .optimize.constrained import PenaltyState
    with np.load(path, allow_pickle=False) as z:
        d = {k[len("penalty_"):]: z[k] for k in z.files if k.startswith("penalty_")}
    if not d:
        return None
    try:
        return PenaltyState.from_dict(d)
    except ContactOptError as exc:
        raise CheckpointError(f"checkpoint {path}: {exc}") from None


def _truncate_history(path: Path, n_rows: int, fields=HISTORY_FIELDS):
    rows = []
    if path.exists():     # the rows after the checkpoint may be cut short (a full disk): harmless
        text = path.read_bytes().decode("utf-8", errors="replace").replace("\0", "")
        rows = list(csv.reader(text.splitlines()))
    body = rows[1:1 + n_rows] if rows else []
    atomic_write_text(path, ",".join(fields) + "\n" + "".join(",".join(r) + "\n" for r in body))


def resolve_config(config, *, eps=None, max_iter=None) -> Config:
    cfg = load_config(config)
    upd = {}
    if eps is not None:
        upd["eps"] = eps
    if max_iter is not None:
        upd["max_iter"] = max_iter
    return cfg.with_updates({"optimizer": upd}) if upd else cfg


def uniqueness_warnings(problem, alpha0) -> list[str]:
    """Warnings of a run at its initial design: F above the uniqueness estimate (3.16).

    ``problem`` should hold the state at α0 already (the bound then costs two extreme eigenvalues
    of the condensed stiffness, no new solve). The estimate is pessimistic: exceeding it does
    not mean several solutions, only that uniqueness is not guaranteed."""
    if problem.friction <= 0:
        return []
    bound = problem.uniqueness_bound(alpha0)
    if not np.isfinite(bound) or problem.friction <= bound:     # not computed (Delassus path)
        return []
    msg = (f"friction coefficient F = {problem.friction:g} exceeds the uniqueness estimate (3.16) "
           f"F0 ≈ {bound:.3g} at the initial design: the state may not be unique (the estimate "
           f"is pessimistic)")
    log.warning(msg)
    return [msg]


class _RunLog(logging.FileHandler):
    """run.log; a write that fails (a full disk) silences it instead of printing a traceback:
    the write of a file that matters fails soon after and says why."""

    def handleError(self, record):
        self.setLevel(logging.CRITICAL + 1)


def _config_arg(config, out: Path) -> str:
    """The configuration as the user gave it, else the run's resolved config.toml."""
    return shlex.quote(str(config) if isinstance(config, (str, os.PathLike)) else str(out / "config.toml"))


def resume_command(config, out: Path) -> str:
    """The command that continues the run in ``out``."""
    return f"contactopt run {_config_arg(config, out)} --out {shlex.quote(str(out))} --resume"


class _Position:
    """Where the run stands on disk: the iteration and evaluations of its last checkpoint, and
    whether that checkpoint is of the finished optimization (only the outputs were missing)."""

    def __init__(self, iteration=None, evaluations=None, finished=False):
        self.iteration, self.evaluations, self.finished = iteration, evaluations, finished

    @classmethod
    def on_disk(cls, ckpt: Path) -> "_Position":
        """Read from the checkpoint itself: a signal may come between its write and any record
        of it kept here, the file (written atomically) is the truth."""
        try:
            with np.load(ckpt, allow_pickle=False) as z:
                before = int(z["penalty_counts"][1]) if "penalty_counts" in z.files else 0   # earlier σ
                return cls(before + int(z["bundle_nit"]), int(z["meta_evaluations"]), "meta_result_status" in z.files)
        except Exception:         # none, or not readable: --resume would say so
            return cls()

    def describe(self) -> str:
        if self.iteration is None:
            return "no iteration had finished, so there is no checkpoint"
        if self.finished:
            return (f"the checkpoint of the finished optimization (iteration {self.iteration}, "
                    f"{self.evaluations} evaluations) stands")
        return f"the checkpoint of iteration {self.iteration} ({self.evaluations} evaluations) stands"

    def hint(self, config, out: Path) -> str:
        if self.iteration is None:
            return (f"; start it again with: contactopt run {_config_arg(config, out)} "
                    f"--out {shlex.quote(str(out))} --overwrite")
        return f"; continue with: {resume_command(config, out)}"


def run_optimization(config, outdir=None, *, eps=None, max_iter=None, resume=False, overwrite=False,
                     progress=None) -> RunResult:
    """Optimize the contact surface of a configuration; see the module docstring for the outputs.

    One writer per run directory: its lock is taken before anything is written
    (:class:`~contactopt.io.lock.LockedError` if another live process holds it). A failed write
    raises :class:`~contactopt.io.atomic.WriteError`, an interruption (KeyboardInterrupt,
    :class:`Interrupted`) :class:`Interrupted` after summary.json says ``"status": "interrupted"``;
    both say where the run stands and how it continues."""
    from .optimize import minimize_bundle
    from .problem import ShapeProblem
    out = Path(outdir) if outdir else Path("runs") / load_config(config).name
    if out.is_dir():
        holder = held_by(out)          # refused before the set-up, not only once it is done
        if holder is not None:
            raise LockedError(out, holder, "run directory")
    if resume and (eps is None or max_iter is None):
        # a resumed run keeps the stopping parameters it was started with unless told otherwise
        saved = _saved_stopping(out / "checkpoint.npz")
        eps = saved.get("eps") if eps is None else eps
        max_iter = saved.get("max_iter") if max_iter is None else max_iter
    cfg = resolve_config(config, eps=eps, max_iter=max_iter)
    t_setup = time.perf_counter()
    problem = ShapeProblem(cfg)
    t_setup = time.perf_counter() - t_setup
    model = problem.model
    alpha0 = model.initial_design()
    from .design.reduction import reduction_of
    red = reduction_of(problem, alpha0)        # [design] symmetry / fixed: α = P β + α_fixed, else None
    model.admissible.require_feasible(alpha0, tol=1e-9)
    model.mesh.coordinates(alpha0)
    fingerprint = config_fingerprint(cfg.with_updates({"optimizer": {"max_iter": 1}}))
    out = Path(outdir or Path("runs") / cfg.name)
    ckpt = out / "checkpoint.npz"
    finished = None
    if resume:
        bstate, n_eval, elapsed0, scale, contexts = _read_checkpoint(ckpt, fingerprint)
        n_cases = 1 + sum(1 for k in contexts if k.startswith("case") and k.endswith("_warm"))
        if n_cases != len(problem.cases):
            raise CheckpointError(f"checkpoint {ckpt}: holds the warm starts of {n_cases} load "
                                  f"case(s), the configuration has {len(problem.cases)}")
        # before the run directory is touched: a kept Delassus block or AMG hierarchy is rebuilt
        problem.import_contexts(contexts, f"checkpoint {ckpt}")
        pstate = _read_penalty(ckpt)
        if bool(problem.constraints) != (pstate is not None):
            raise CheckpointError(f"checkpoint {ckpt}: {'no' if pstate is None else 'a'} penalty state for a "
                                  f"configuration {'with' if problem.constraints else 'without'} [[constraints]]")
        # a constrained run's end is its penalty state's: minimize_constrained returns it without evaluating
        box = red.bounds if red is not None else model.admissible.constraints()
        finished = None if pstate is not None else _saved_result(ckpt, bstate, cfg.optimizer.max_iter,
                                                                 box["lb"], box["ub"],
                                                                 cfg.optimizer.scale)
    lock = claim_output_dir(out, overwrite=overwrite, resume=resume)
    root = logging.getLogger("contactopt")
    old_level = root.level
    handler = None
    oracle = None
    try:
        try:
            handler = _RunLog(out / "run.log")
        except OSError as exc:
            raise write_error(out / "run.log", exc) from exc
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
        root.addHandler(handler)
        handler.setLevel(logging.INFO)
        if root.getEffectiveLevel() > logging.INFO:
            root.setLevel(logging.INFO)
        if lock.previous:
            log.warning("took over the lock of %s from a writer that no longer runs (%s)", out,
                        describe(lock.previous))
        _log_setup(problem, t_setup)
        vers = package_versions()
        atomic_write_text(out / "config.toml", "# resolved configuration of this run\n# versions: "
                          + ", ".join(f"{k} {v}" for k, v in vers.items()) + "\n" + cfg.to_toml())
        t_start = time.perf_counter()
        hist = out / "history.csv"
        oracle = _Oracle(problem, hist, t_start)
        oracle.reduction = red
        state_kw = {}
        if resume:
            _truncate_history(hist, n_eval, history_fields(problem))
            oracle.count = n_eval
            oracle.iteration = bstate.nit + (pstate.nit if pstate is not None else 0)   # rows before a callback
            oracle.t_start -= elapsed0
            oracle.scale = scale
            state_kw["state"] = bstate
            if pstate is not None:
                state_kw = {"state": pstate, "bundle_state": bstate}
            log.info("resuming %s at iteration %d (%d evaluations)%s", out, bstate.nit, n_eval,
                     "; the optimization had finished, its results are written again" if finished else "")
        else:
            atomic_write_text(hist, ",".join(history_fields(problem)) + "\n")
            log.info("run %s in %s", cfg.name, out)
            theta0 = problem.evaluate_value(alpha0)
            if not np.isfinite(theta0):
                raise SolverError(f"Θ(α0) is not finite ({theta0})")
            oracle.scale = abs(theta0) if theta0 != 0 else 1.0
            log.info("Θ(α0) = %.8e; the bundle method minimises Θ/Θ(α0), so ε is relative", theta0)
        # at α0 (a resumed run asks a separate problem: its own must continue bit for bit)
        run_warnings = uniqueness_warnings(ShapeProblem(cfg) if resume and problem.friction > 0 else problem,
                                           alpha0)
        if red is not None:
            run_warnings += red.warnings

        def callback(inter):
            st = inter.state
            pen = inter.get("penalty")       # [[constraints]]: σ and the earlier bundle runs
            nit = st.nit + (pen.nit if pen is not None else 0)
            oracle.iteration = nit
            h = st.history[-1] if st.history else {}
            # after every iteration (a few kB, atomic): a killed or aborted run loses at most
            # the evaluations of one iteration
            _write_checkpoint(ckpt, st, oracle, fingerprint, time.perf_counter() - oracle.t_start, penalty=pen)
            if progress:
                progress(dict(iteration=nit, f=st.f * oracle.scale, step=h.get("step", ""), t=st.t,
                              stationarity=st.stationarity, nfev=oracle.count,
                              elapsed=time.perf_counter() - oracle.t_start))

        opt = cfg.optimizer
        if finished is not None:
            res = finished
        else:
            try:
                f, x0, cons = oracle, alpha0, model.admissible.constraints()
                if red is not None:       # the optimizer works on β; Pᵀ ξ its subgradient
                    f, x0, cons = _reduced(oracle, red), red.beta0, red.bounds
                minimize = minimize_bundle
                if problem.constraints:        # the exact penalty with an adapted weight
                    from functools import partial

                    from .optimize.constrained import minimize_constrained
                    minimize = partial(minimize_constrained, ctol=[c.tol for c in problem.constraints])
                res = minimize(f, x0, **cons, eps=opt.eps, max_iter=opt.max_iter, callback=callback,
                               ftol=opt.ftol, ftol_window=opt.ftol_window, metric=opt.metric,
                               metric_memory=opt.metric_memory, scale=opt.scale, **state_kw)
            except RunAborted as exc:
                exc.checkpoint = ckpt if ckpt.exists() else None
                exc.args = (f"{exc.args[0]}; " + (f"the checkpoint of iteration {oracle.iteration} is kept "
                            f"(continue with --resume)" if exc.checkpoint else
                            "no iteration had finished, so there is no checkpoint"),)
                log.error("run stopped: %s", exc)
                raise
            if res.status is not None and res.success:
                log.info("finished: %s", res.message)
            _write_checkpoint(ckpt, res.state, oracle, fingerprint, time.perf_counter() - oracle.t_start, res,
                              penalty=res.get("penalty"))
        if red is not None:
            res.x = red.expand(res.x)
        summary = _finish(out, problem, alpha0, res, oracle, t_start)
        summary["warnings"] = run_warnings
        if red is not None:
            summary["design_variables"] = {"alpha": red.n_alpha, "optimized": red.n_beta}
        atomic_write_json(out / "summary.json", summary)
    except WriteError as exc:
        position = _Position.on_disk(ckpt)
        exc.args = (f"{exc.args[0]}; {position.describe()}" + position.hint(config, out),)
        log.error("run stopped: %s", exc, extra=RAISED)
        raise
    except KeyboardInterrupt as exc:
        raise _interrupted(exc, config, out, cfg, _Position.on_disk(ckpt), oracle) from None
    finally:
        if handler is not None:
            root.removeHandler(handler)
            handler.close()
        root.setLevel(old_level)
        lock.release()
    return RunResult(out, summary)


def _interrupted(exc, config, out: Path, cfg, position: _Position, oracle) -> Interrupted:
    """summary.json of an interrupted run (where it stands, how to continue) and the exception
    that carries the same to the caller."""
    signum = getattr(exc, "signum", signal.SIGINT)
    name = signal.Signals(signum).name
    doing = ("while writing the results" if position.finished else
             f"during iteration {(position.iteration or 0) + 1}" if oracle is not None else "during the set-up")
    message = f"interrupted by {name} {doing}; {position.describe()}"
    resume = resume_command(config, out) if position.iteration is not None else None
    summary = {"name": cfg.name, "status": "interrupted", "signal": name, "message": message,
               "checkpoint": ({"iteration": position.iteration, "evaluations": position.evaluations}
                              if position.iteration is not None else None),
               "resume": resume,
               "evaluations": int(oracle.count) if oracle is not None else 0}
    try:
        atomic_write_json(out / "summary.json", summary)
    except (WriteError, KeyboardInterrupt) as err:     # a full disk or a second signal: said, not fatal
        log.error("summary.json of the interrupted run not written: %s", err)
    log.error("run %s", message, extra=RAISED)
    return Interrupted(signum, message + position.hint(config, out), resume)


def _stopping(res, opt) -> dict:
    """Both stopping tests of the run at its end, and which one fired (summary.json); ``opt`` the
    run's ``[optimizer]``.

    ``criterion``: "stationarity" (certified, status 0), "predicted_decrease" or "f_change"
    (status 4), "roundoff" (5), "max_iter" (1), "callback" (2) or "stalled" (3); the measures are
    those of Θ/Θ(α0).
    ``J_tolerance``: the relative decrease of J that the bundle model still predicts at the last
    iterate, from a step of the size of the last serious step — at a practical stop at most
    ``ftol`` (docs/stopping.md); ``relative_decrease`` the realised one over the last
    ``ftol_window`` serious steps, for comparison."""
    rel = float(res.relative_decrease)
    pred = float(res.predicted_decrease)
    return {"criterion": res.criterion,
            "stationarity": float(res.stationarity), "eps": float(opt.eps),
            "J_tolerance": pred if np.isfinite(pred) else None,
            "relative_decrease": rel if np.isfinite(rel) else None,
            "ftol": float(opt.ftol), "ftol_window": int(opt.ftol_window)}


def _finish(out: Path, problem, alpha0, res, oracle, t_start) -> dict:
    from .io.plots import plot_history, plot_node_classes, plot_stress_comparison, plot_surface
    from .io.vtk import write_body_vtu, write_foundation_vtu, write_pvd
    model = problem.model
    x = np.asarray(res.x)
    t0 = time.perf_counter()
    c0 = problem.evaluate_cases(alpha0, warm_start=False)      # Θ of the combined load cases
    states0, J0, steps0 = problem.solve_states(alpha0), c0.value, _step_outputs(out, problem, "initial")
    c1 = problem.evaluate_cases(x, warm_start=False)
    states1, J, steps1 = problem.solve_states(x), c1.value, _step_outputs(out, problem, "optimal")
    s0, s1 = states0[c1.case], states1[c1.case]      # the load case active at the optimum
    target = problem.cases[c1.case].objective.target
    write_body_vtu(out / "initial.vtu", model, s0)
    write_body_vtu(out / "optimal.vtu", model, s1)
    pvd = [(0, "initial.vtu"), (1, "optimal.vtu")]
    if model.foundation is not None:          # the elastic foundation: part 1 of each time step
        write_foundation_vtu(out / "initial_foundation.vtu", model.foundation, s0)
        write_foundation_vtu(out / "optimal_foundation.vtu", model.foundation, s1)
        pvd += [(0, "initial_foundation.vtu", 1), (1, "optimal_foundation.vtu", 1)]
    write_pvd(out / "bodies.pvd", pvd)
    plot_stress_comparison(out / "stress.png", model, target if target is not None else np.zeros_like(s0.lam),
                           s0.lam, s1.lam)
    from .io.pressure import contact_pressure
    p0, p1 = contact_pressure(model, s0.lam, s0.coords), contact_pressure(model, s1.lam, s1.coords)
    # the target in the same units: λ̄ over the optimal design's areas, as the optimal λ
    p_target = (contact_pressure(model, target, s1.coords) if target is not None else np.zeros_like(p0))
    plot_stress_comparison(out / "pressure.png", model, p_target, p0, p1, zlabel="contact pressure $p = \\lambda/a$")
    plot_surface(out / "surface.png", model, x)
    plot_node_classes(out / "classes.png", model, s1.classes)
    from .io.plots import plot_contact_response, plot_peak_stress
    plot_contact_response(out / "contact.png", model, p1, s1.tau, s1.u_c[:, :2], s1.classes,
                          title="optimal design")
    plot_peak_stress(out / "von_mises.png", model, s1.coords, s1.u, title="optimal design")
    plot_history(out / "history.png", [{**r, "kind": r.get("step")} for r in res.history])
    atomic_write_text(out / "iterations.csv", "iteration,J,step,t,stationarity,evaluations\n" + "".join(
        f"{r['iteration']},{r['f'] * oracle.scale!r},{r['step']},{r['t']:.6e},{r['stationarity']:.6e},"
        f"{r['nfev']}\n" for r in res.history))
    amat = model.surface.as_matrix(x)
    atomic_write_json(out / "alpha.json", {"alpha": amat.tolist(), "shape": list(amat.shape)})
    sf = model.surface
    g1, g2 = np.meshgrid(np.linspace(sf.x1lo, sf.x1lo + sf.a, 41), np.linspace(sf.x2lo, sf.x2lo + sf.b, 21))
    h = model.surface.evaluate(x, g1.ravel(), g2.ravel())
    atomic_write_text(out / "surface.csv", "x1,x2,theta\n" + "".join(
        f"{a:.6g},{b:.6g},{c:.10g}\n" for a, b, c in zip(g1.ravel(), g2.ravel(), h)))
    wall = time.perf_counter() - oracle.t_start
    summary = {
        "name": problem.config.name, "J0": J0, "J": J, "ratio": J / J0 if J0 else None,
        "iterations": int(res.nit), "evaluations": int(oracle.count), "serious_steps": int(res.n_serious),
        "null_steps": int(res.n_null), "success": bool(res.success), "message": str(res.message),
        "status": int(res.status), "stopping": _stopping(res, problem.config.optimizer),
        "alpha": amat.tolist(), "feasible": bool(model.admissible.is_feasible(x, tol=1e-8)),
        "wall_time_s": wall,
        "time_breakdown_s": {**oracle.time, "outputs": time.perf_counter() - t0},
        "final_state": s1.summary(),
    }
    if model.foundation is not None:
        summary["foundation"] = model.foundation.summary()
    if problem.term_names():            # each term's value at α0 and at the optimum
        summary["objective"] = {"J0": problem.objective_report(alpha0, warm_start=False),
                                "J": problem.objective_report(x, warm_start=False)}
    if problem.constraints:             # each response at the optimum: value, limit, margin (≥ 0: met)
        summary["constraints"] = _constraint_outputs(problem, alpha0, x, res)
    if problem.has_load_cases:
        summary["load_cases"] = _load_case_outputs(out, problem, (c0, states0), (c1, states1))
    if steps1:
        summary["load_steps"] = {"names": list(steps1), "J0": steps0, "J": steps1, "objective_steps":
                                 problem.config.objective.steps}
    summary["export"] = _export(out, model, x)
    summary["time_breakdown_s"]["outputs"] = time.perf_counter() - t0
    atomic_write_json(out / "summary.json", summary)
    return summary


def _constraint_outputs(problem, alpha0, x, res) -> dict:
    """summary.json's ``constraints``: per constraint its value, limit, margin (limit − value),
    relative violation tolerance and whether it holds, at the optimum and at α0, and the penalty
    weight σ the run ended with (optimize/constrained.py)."""
    out = {}
    initial = problem.constraint_report(alpha0, warm_start=False)
    for con, (name, rep) in zip(problem.constraints, problem.constraint_report(x, warm_start=False).items()):
        out[name] = {**rep, "tol": con.tol, "satisfied": bool(rep["value"] <= con.limit * (1 + con.tol)),
                     "initial": {k: initial[name][k] for k in ("value", "margin")}}
    return {"responses": out, "sigma": float(res.get("sigma", float("nan"))), "sigma_raised": int(res.get("outer", 0))}


def _step_outputs(out: Path, problem, which: str) -> dict:
    """Load paths: J at each step's end at the design just evaluated, and (at the optimum) a
    stick/slip map per step, classes-<step>.png."""
    if not problem.has_load_steps:
        return {}
    if which == "optimal":
        from .io.plots import plot_node_classes
        for k in range(len(problem.cases)):
            pre = f"{problem.cases[k].name}." if problem.has_load_cases else ""
            for name, sub, state in problem.step_results(k) or []:
                if sub == max(s.substep for s in problem.steps[k] if s.name == name):
                    plot_node_classes(out / f"classes-{pre}{name}.png", problem.model, state.classes)
    return dict(zip(problem.step_columns(), problem.step_values()))


def _export(out: Path, model, x) -> dict:
    """The optimal design for CAD and other FE tools (contactopt.io.export); a failure is recorded
    in the summary, never lost results: the run's other files are written already."""
    from .io.export import export_design
    try:
        return export_design(model, x, out, strict=False)
    except WriteError:          # a full disk is not an export problem: the run stops and says so
        raise
    except ContactOptError as exc:
        log.warning("export of the optimal design failed: %s", exc)
        return {"files": {}, "error": str(exc)}


def _load_case_outputs(out: Path, problem, initial, optimal) -> dict:
    """Per-case λ maps (cases.png) and the summary's ``load_cases``: Θ_k at α0 and at the
    optimum, the active cases there and the case whose state the other plots show."""
    from .io.plots import plot_load_cases
    names = problem.case_names
    (c0, states0), (c1, states1) = initial, optimal
    plot_load_cases(out / "cases.png", problem.model, names, [s.lam for s in states0], [s.lam for s in states1],
                    c0.values, c1.values)
    return {"combine": problem.combination.kind, "names": list(names),
            "weights": dict(zip(names, problem.combination.weights.tolist())),
            "J0": dict(zip(names, c0.values.tolist())), "J": dict(zip(names, c1.values.tolist())),
            "active_at_J0": [names[i] for i in c0.active], "active": [names[i] for i in c1.active],
            "shown": names[c1.case], "active_tol": problem.combination.active_tol}


def run_from_cli(args) -> int:
    """``contactopt run``: prints one progress line per iteration."""
    def progress(p):
        print(f"it {p['iteration']:4d}  Θ {p['f']:.8e}  {p['step']:>7}  t {p['t']:.2e}  "
              f"stat {p['stationarity']:.2e}  evals {p['nfev']:4d}  {p['elapsed']:7.1f}s", flush=True)
    if args.max_iter is not None and args.max_iter < 1:
        raise ConfigError([f"--max-iter {args.max_iter}: must be an integer ≥ 1"])
    if args.eps is not None and not (0 < args.eps < 1):
        raise ConfigError([f"--eps {args.eps}: must be in (0, 1)"])
    try:
        rr = run_optimization(args.config, args.out, eps=args.eps, max_iter=args.max_iter,
                              resume=args.resume, overwrite=args.overwrite, progress=progress)
    except RunAborted as exc:
        print(f"contactopt: run stopped: {exc}", flush=True)
        raise
    s = rr.summary
    print(f"{s['message']}")
    print(f"J0 = {s['J0']:.8e}  J = {s['J']:.8e}  J/J0 = {s['ratio']:.4g}  iterations {s['iterations']} "
          f"(serious {s['serious_steps']}, null {s['null_steps']}), evaluations {s['evaluations']}, "
          f"{s['wall_time_s']:.1f}s")
    for name, c in s.get("constraints", {}).get("responses", {}).items():
        print(f"constraint {name}: {c['initial']['value']:.6e} → {c['value']:.6e} (max {c['limit']:.6e}, "
              f"margin {c['margin']:.3e}{'' if c['satisfied'] else ', violated'})")
    if "load_cases" in s:
        lc = s["load_cases"]
        print(f"load cases ({lc['combine']}), active at the optimum: {', '.join(lc['active'])}")
        for name in lc["names"]:
            print(f"  {name}: Θ0 = {lc['J0'][name]:.8e}  Θ = {lc['J'][name]:.8e}")
    print(f"results in {rr.outdir}/")
    return 0
