"""One optimization run = one output directory (resolved config, log, history, checkpoint, results).

The story of a run (:func:`run_optimization`): the configuration is resolved and the problem set up;
a resume reads its :class:`~contactopt.io.checkpoint.Checkpoint`, checks it against the
configuration and puts the solver's contexts back, before the directory is touched; the
:class:`~contactopt.io.rundir.RunDirectory` is claimed (lock, run.log, config.toml,
history.csv); the optimizer runs through :func:`contactopt.optimize.minimize` (``method``
"bundle", or "constrained" with [[constraints]]), checkpointing after every iteration; the
result files are written at the optimum (:mod:`contactopt.io.outputs`) from the optimization's
own solves of α0 and of the returned design, which the run keeps (a resumed run repeats them
from the contexts its checkpoint recorded), so that no state is solved after the last evaluation.

Layout of a run directory::

    config.toml        the resolved configuration, with package versions
    run.log            the log of the run
    history.csv        one row per evaluation of Θ
    iterations.csv     one row per bundle-trust iteration: Θ, step kind, t, stationarity measure
    checkpoint.npz     optimizer + oracle state after the last iteration (written atomically;
                       :mod:`contactopt.io.checkpoint`, the one module that reads and writes it)
    summary.json       J0, J, iterations, evaluations, serious/null steps, success, message, alpha, times,
                       admissible (α in U) and constraints_satisfied ([[constraints]]; null without)
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
from .design.reduction import DesignReduction, reduction_of
from .errors import CheckpointError, ConfigError, ContactOptError, Interrupted, SolverError
from .io.atomic import WriteError, atomic_write_json
from .io.checkpoint import Checkpoint, SavedResult, flatten_config
from .io.outputs import write_outputs
from .io.rundir import RunDirectory
from .optimize import BundleResult, minimize
from .optimize._scaling import variable_scaling
from .optimize._trials import FailedTrials
from .optimize.bundle import SUCCESS_STATUS
from .problem import ShapeProblem
from .sensitivity import adjoint
from .sensitivity.objectives import linear_tetrahedra_pressure
from .sensitivity.solution import KeptDesign

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


def package_versions() -> dict:
    out = {}
    for name in ("contactopt", "numpy", "scipy", "daqp", "mkl", "meshio", "matplotlib", "h5py"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


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
    """Θ and a subgradient, with bookkeeping: evaluation count, history rows, timings.

    ``reduction``: the [design] reduction α = P β + α_fixed when the optimizer works on β (its
    checkpoint then also holds α), else None."""

    def __init__(self, problem, run_dir: RunDirectory, reduction=None):
        self.problem = problem
        self.scale = 1.0          # BT sees Θ/scale (scale = Θ(α0)), so its ε is relative
        self.run_dir = run_dir
        self.reduction = reduction
        self.t_start = time.perf_counter()
        self.count = 0
        self.iteration = 0
        self.time = {"state": 0.0, "adjoint": 0.0, "design_terms": 0.0}
        self.trials = FailedTrials(run_dir.path)
        # the solves the outputs read (:class:`~contactopt.sensitivity.solution.KeptDesign`): that of
        # α0 and those of the evaluations since the last iteration, of which the iteration keeps
        # its iterate's; a resumed run has the contexts to repeat them (``start_*``) instead
        self.initial = None
        self.kept: dict[bytes, object] = {}
        self.start_initial = None          # contexts α0 was solved from
        self.start_iterate = None          # (α, contexts) of the iterate's solve

    def __call__(self, x):
        try:
            res = adjoint.subgradient(self.problem, x)
            # [[constraints]]: each response and its subgradient from the same state
            cons = self.problem.constraint_subgradients(x) if self.problem.constraints else []
        except SolverError as exc:
            if self.count == 0:       # the initial design: the current iterate itself
                raise RunAborted(f"state/subgradient failed at evaluation {self.count + 1}: {exc}") from exc
            # a trial design (optimize/_trials.py): a failed trial, the run goes on
            return self.trials.answer(self, x, exc, len(history_fields(self.problem)), len(self.problem.constraints))
        for r in [res] + cons:
            for k in self.time:
                self.time[k] += r.timings.get(k, 0.0)
        kept = self.problem.keep_design()
        self.kept[kept.alpha.tobytes()] = kept
        if self.count == 0:
            self.initial = kept
        self.count += 1
        _log_evaluation(self.count, res)
        self.run_dir.append_history(self._row(res, cons))
        if self.problem.constraints:     # c_i = (value − max)/max ≤ 0 (optimize/constrained.py)
            lim = np.array([c.limit for c in self.problem.constraints])
            c = (np.array([r.value for r in cons]) - lim) / lim
            J = np.array([r.gradient for r in cons]) / lim[:, None]
            return res.value / self.scale, res.gradient / self.scale, c, J
        return res.value / self.scale, res.gradient / self.scale

    def _row(self, res, cons) -> list:
        """The evaluation's row of history.csv (:func:`history_fields`)."""
        st = res.state
        row = [self.count, self.iteration, repr(float(res.value)), f"{np.linalg.norm(res.gradient):.6e}",
               res.n_degenerate, int(np.sum(st.lam > 0)), st.iterations, f"{st.residual:.3e}",
               f"{time.perf_counter() - self.t_start:.3f}"]
        if self.problem.has_load_cases:
            row += [repr(float(v)) for v in res.case_values] + [";".join(res.active_cases)]
        row += [repr(float(v)) for v in res.terms.values()]
        row += [repr(v) for v in self.problem.step_values()]
        return row + [repr(float(c.value)) for c in cons]

    def objective(self):
        """The function the optimizer minimises: of α, or of β with the reduction (Θ(P β +
        α_fixed), Pᵀ ξ and the constraints' rows Pᵀ)."""
        red = self.reduction
        if red is None:
            return self

        def f(beta):
            out = self(red.expand(beta))
            if len(out) == 4:
                return out[0], red.pullback(out[1]), out[2], np.array([red.pullback(row) for row in out[3]])
            return out[0], red.pullback(out[1])
        return f

    def checkpoint(self, state, elapsed: float, result=None, penalty=None) -> Checkpoint:
        """The run's :class:`~contactopt.io.checkpoint.Checkpoint` with the optimizer's ``state``
        (and ``penalty`` state; ``result`` once the optimizer has stopped)."""
        opt = self.problem.config.optimizer
        saved = None
        if result is not None:
            saved = SavedResult(int(result.status), str(result.message), result.criterion,
                                float(result.relative_decrease))
        initial = self.initial.solution.start if self.initial is not None else self.start_initial
        return Checkpoint(bundle=state, evaluations=self.count, elapsed=elapsed, scale=self.scale, eps=opt.eps,
                          max_iter=opt.max_iter, config=flat_config(self.problem.config),
                          contexts=self.problem.export_contexts(),
                          alpha=self.reduction.expand(state.x) if self.reduction is not None else None,
                          penalty=penalty, result=saved, initial=initial, iterate=self.start_iterate)

    def keep_iterate(self, x) -> None:
        """After an iteration: of the kept solves, keep α0's and the iterate's (``x`` the
        optimized variables), and the contexts that repeat the iterate's solve."""
        alpha = self.problem.model.surface.as_vector(x if self.reduction is None else self.reduction.expand(x))
        kept = self.kept.get(alpha.tobytes())
        self.kept = {} if kept is None else {alpha.tobytes(): kept}
        if kept is not None:
            self.start_iterate = (kept.alpha, kept.solution.start)
        elif self.start_iterate is not None and self.start_iterate[0].tobytes() != alpha.tobytes():
            self.start_iterate = None       # an iterate whose solve was not recorded

    def design(self, alpha, which: str):
        """The :class:`~contactopt.sensitivity.solution.KeptDesign` of α for the outputs: the
        run's own solve, else (a resumed run) that solve repeated from its recorded contexts,
        else a solve of its own without warm start (``which`` names it in the log)."""
        alpha = self.problem.model.surface.as_vector(alpha)
        key = alpha.tobytes()
        if self.initial is not None and self.initial.alpha.tobytes() == key:
            return self.initial
        if key in self.kept:
            return self.kept[key]
        start = (self.start_initial if which == "initial" else
                 self.start_iterate[1] if self.start_iterate is not None and
                 self.start_iterate[0].tobytes() == key else None)
        other = self.problem.detached()        # this problem's warm starts stay as they are
        if start is None:
            log.warning("the %s design's solve was not recorded: solved again without warm start", which)
            return KeptDesign(other.solution(alpha, warm_start=False), {})
        # the contexts the solve began from: bit for bit the solve that recorded them
        log.info("the solve of the %s design repeated from the checkpoint", which)
        other.import_contexts(start, f"checkpoint {self.run_dir.checkpoint}")
        return KeptDesign(other.solution(alpha), {})

    def save(self, state, result=None, penalty=None) -> None:
        """Write the checkpoint (atomically, after history.csv is on disk)."""
        self.run_dir.sync_history()
        self.checkpoint(state, time.perf_counter() - self.t_start, result, penalty).write(self.run_dir.checkpoint)


def flat_config(config: Config) -> dict:
    """The configuration a checkpoint is checked against (``max_iter`` aside: a resume may raise it)."""
    return flatten_config(config.with_updates({"optimizer": {"max_iter": 1}}).to_dict())


def _saved_result(ckpt: Checkpoint, max_iter: int, lb=None, ub=None, scale="bounds"):
    """The optimizer's result stored with a finished run's checkpoint (None: the run had not
    stopped, or it is resumed with another ``max_iter`` and so goes on); ``lb``, ``ub`` the box
    of the optimized variables, whose widths scale the state's variables (minimize_bundle's
    option ``scale``)."""
    saved = ckpt.saved_result(max_iter)
    if saved is None:
        return None
    st = ckpt.bundle.copy()
    res = BundleResult(x=st.x.copy(), fun=st.f, jac=st.xi.copy(), nit=st.nit, nfev=st.nfev,
                       n_serious=st.n_serious, n_null=st.n_null, success=saved.status in SUCCESS_STATUS,
                       status=saved.status, message=saved.message, criterion=saved.criterion,
                       stationarity=st.stationarity, relative_decrease=saved.relative_decrease,
                       predicted_decrease=st.predicted, gamma=st.gamma, t=st.t,
                       history=[dict(r) for r in st.history], state=st)
    scaling = variable_scaling(st.x.size, lb, ub, scale)
    return res if scaling is None else scaling.result(res)


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
    not mean several solutions, only that uniqueness is not guaranteed. With a coefficient per
    contact node the largest is compared."""
    F = float(np.max(problem.friction))
    if F <= 0:
        return []
    bound = problem.uniqueness_bound(alpha0)
    if not np.isfinite(bound) or F <= bound:     # not computed (Delassus path)
        return []
    largest = "" if np.ndim(problem.friction) == 0 else "the largest "
    msg = (f"{largest}friction coefficient F = {F:g} exceeds the uniqueness estimate (3.16) "
           f"F0 ≈ {bound:.3g} at the initial design: the state may not be unique (the estimate "
           f"is pessimistic)")
    log.warning(msg)
    return [msg]


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
    def on_disk(cls, path: Path) -> "_Position":
        """Read from the checkpoint itself: a signal may come between its write and any record
        of it kept here, the file (written atomically) is the truth."""
        ckpt = Checkpoint.peek(path)        # none, or not readable: --resume would say so
        return cls() if ckpt is None else cls(ckpt.iteration, ckpt.evaluations, ckpt.finished)

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
                     progress=None, plots=True) -> RunResult:
    """Optimize the contact surface of a configuration; see the module docstring for the outputs.
    ``plots=False`` writes every output but the PNG figures (sweeps, scripted studies).

    One writer per run directory: its lock is taken before anything is written
    (:class:`~contactopt.io.lock.LockedError` if another live process holds it). A failed write
    raises :class:`~contactopt.io.atomic.WriteError`, an interruption (KeyboardInterrupt,
    :class:`Interrupted`) :class:`Interrupted` after summary.json says ``"status": "interrupted"``;
    both say where the run stands and how it continues."""
    run_dir = RunDirectory(outdir if outdir else Path("runs") / load_config(config).name)
    run_dir.refuse_if_held()               # before the set-up, not only once it is done
    ckpt = Checkpoint.peek(run_dir.checkpoint) if resume else None
    if ckpt is not None:      # a resumed run keeps its stopping parameters unless told otherwise
        eps = ckpt.eps if eps is None else eps
        max_iter = ckpt.max_iter if max_iter is None else max_iter
    cfg = resolve_config(config, eps=eps, max_iter=max_iter)
    cfg.assembly.require_design(cfg.source, "an optimization (contactopt run)")
    setup = _set_up(cfg)
    # before the run directory is touched: a kept Delassus block or AMG hierarchy is rebuilt
    ckpt, finished = _restore(run_dir.checkpoint, setup, ckpt) if resume else (None, None)
    run_dir.claim(overwrite=overwrite, resume=resume)
    oracle = None
    try:
        run_dir.start_log()
        _log_setup(setup.problem, setup.seconds)
        run_dir.write_config(cfg.to_toml(), package_versions())
        oracle = _Oracle(setup.problem, run_dir, setup.reduction)
        _start(oracle, setup, ckpt, finished)
        run_warnings = _warnings(setup, resume)
        res = finished if finished is not None else _optimize(oracle, setup, ckpt, progress)
        summary = _finish(run_dir, setup, res, oracle, run_warnings, plots)
    except WriteError as exc:
        position = _Position.on_disk(run_dir.checkpoint)
        exc.args = (f"{exc.args[0]}; {position.describe()}" + position.hint(config, run_dir.path),)
        log.error("run stopped: %s", exc, extra=RAISED)
        raise
    except KeyboardInterrupt as exc:
        position = _Position.on_disk(run_dir.checkpoint)
        raise _interrupted(exc, config, run_dir.path, cfg, position, oracle) from None
    finally:
        run_dir.close()
    return RunResult(run_dir.path, summary)


@dataclass
class _SetUp:
    """What a run is about: the problem, the initial design α0, the [design] reduction
    (None: the optimizer works on α) and the set-up's time."""

    problem: ShapeProblem
    alpha0: np.ndarray
    reduction: DesignReduction | None
    seconds: float

    @property
    def start(self) -> np.ndarray:
        """Where the optimizer starts: α0, or β0 with the reduction."""
        return self.alpha0 if self.reduction is None else self.reduction.beta0

    @property
    def box(self) -> dict:
        """U of the optimized variables (lb, ub, A_ub, b_ub, A_eq, b_eq)."""
        return self.problem.model.admissible.constraints() if self.reduction is None else self.reduction.bounds


def _set_up(cfg: Config) -> _SetUp:
    t = time.perf_counter()
    problem = ShapeProblem(cfg, optimizing=True)
    seconds = time.perf_counter() - t
    alpha0 = problem.model.initial_design()
    red = reduction_of(problem, alpha0)        # [design] symmetry / fixed: α = P β + α_fixed, else None
    problem.model.admissible.require_feasible(alpha0, tol=1e-9)
    problem.model.mesh.coordinates(alpha0)
    return _SetUp(problem, alpha0, red, seconds)


def _restore(path: Path, setup: _SetUp, ckpt: Checkpoint | None):
    """The checkpoint of a resumed run, checked against the configuration and put back into the
    problem, and the optimizer's result when the run had finished (else None)."""
    if not path.exists():
        raise CheckpointError(f"--resume: no checkpoint in {path.parent} (expected {path.name})")
    ckpt = ckpt if ckpt is not None else Checkpoint.read(path)     # raises, saying why
    problem, opt = setup.problem, setup.problem.config.optimizer
    ckpt.require_config(flat_config(problem.config), path)
    ckpt.require_shape([len(row) for row in problem.step_contexts], path)
    problem.import_contexts(ckpt.contexts, f"checkpoint {path}")
    if bool(problem.constraints) != (ckpt.penalty is not None):
        raise CheckpointError(f"checkpoint {path}: {'no' if ckpt.penalty is None else 'a'} penalty state for a "
                              f"configuration {'with' if problem.constraints else 'without'} [[constraints]]")
    if ckpt.penalty is not None:    # a constrained run's end is its penalty state's (minimize_constrained)
        return ckpt, None
    box = setup.box
    return ckpt, _saved_result(ckpt, opt.max_iter, box["lb"], box["ub"], opt.scale)


def _start(oracle: _Oracle, setup: _SetUp, ckpt: Checkpoint | None, finished) -> None:
    """history.csv and the oracle's counts: those of the checkpoint, or new ones with Θ(α0),
    the scale of what the optimizer sees."""
    run_dir, problem = oracle.run_dir, oracle.problem
    if ckpt is not None:
        run_dir.start_history(history_fields(problem), keep_rows=ckpt.evaluations)
        oracle.trials.start(ckpt.evaluations)
        oracle.count, oracle.iteration, oracle.scale = ckpt.evaluations, ckpt.iteration, ckpt.scale
        oracle.start_initial, oracle.start_iterate = ckpt.initial, ckpt.iterate
        oracle.t_start -= ckpt.elapsed
        log.info("resuming %s at iteration %d (%d evaluations)%s", run_dir.path, ckpt.bundle.nit, ckpt.evaluations,
                 "; the optimization had finished, its results are written again" if finished else "")
        return
    run_dir.start_history(history_fields(problem))
    oracle.trials.start()
    log.info("run %s in %s", problem.config.name, run_dir.path)
    theta0 = problem.evaluate_value(setup.alpha0)
    if not np.isfinite(theta0):
        raise SolverError(f"Θ(α0) is not finite ({theta0})")
    oracle.scale = abs(theta0) if theta0 != 0 else 1.0
    log.info("Θ(α0) = %.8e; the bundle method minimises Θ/Θ(α0), so ε is relative", theta0)


def _warnings(setup: _SetUp, resume: bool) -> list[str]:
    """The run's warnings at α0 (a resumed run asks a separate problem: its own must continue
    bit for bit)."""
    problem = setup.problem
    asked = problem.detached() if resume and np.max(problem.friction) > 0 else problem
    out = uniqueness_warnings(asked, setup.alpha0)
    pressure = linear_tetrahedra_pressure(problem.config, problem.model)
    return out + ([pressure] if pressure else []) + (setup.reduction.warnings if setup.reduction is not None else [])


def _optimize(oracle: _Oracle, setup: _SetUp, ckpt: Checkpoint | None, progress):
    """The optimizer's run (:func:`~contactopt.optimize.minimize`), from the start or from the
    checkpoint; its end is checkpointed too."""
    problem, opt = setup.problem, setup.problem.config.optimizer
    method, extra = ("constrained", {"ctol": [c.tol for c in problem.constraints]}) if problem.constraints \
        else ("bundle", {})
    if ckpt is not None:
        extra.update({"state": ckpt.penalty, "bundle_state": ckpt.bundle} if ckpt.penalty is not None
                     else {"state": ckpt.bundle})
    try:
        res = minimize(oracle.objective(), setup.start, method=method, **setup.box, eps=opt.eps,
                       max_iter=opt.max_iter, callback=_callback(oracle, progress), ftol=opt.ftol,
                       ftol_window=opt.ftol_window, metric=opt.metric, metric_memory=opt.metric_memory,
                       scale=opt.scale, **extra)
    except RunAborted as exc:
        path = oracle.run_dir.checkpoint
        exc.checkpoint = path if path.exists() else None
        exc.args = (f"{exc.args[0]}; " + (f"the checkpoint of iteration {oracle.iteration} is kept "
                    f"(continue with --resume)" if exc.checkpoint else
                    "no iteration had finished, so there is no checkpoint"),)
        log.error("run stopped: %s", exc)
        raise
    if res.status is not None and res.success:
        log.info("finished: %s", res.message)
    oracle.keep_iterate(res.x)
    oracle.save(res.state, res, penalty=res.get("penalty"))
    return res


def _callback(oracle: _Oracle, progress):
    """After every iteration: the checkpoint (a few kB, atomic: a killed or aborted run loses at
    most the evaluations of one iteration), then ``progress``."""
    def callback(inter):
        st = inter.state
        pen = inter.get("penalty")       # [[constraints]]: σ and the earlier bundle runs
        nit = st.nit + (pen.nit if pen is not None else 0)
        oracle.iteration = nit
        oracle.keep_iterate(inter.x)
        h = st.history[-1] if st.history else {}
        oracle.save(st, penalty=pen)
        if progress:
            progress(dict(iteration=nit, f=st.f * oracle.scale, step=h.get("step", ""), t=st.t,
                          stationarity=st.stationarity, nfev=oracle.count,
                          elapsed=time.perf_counter() - oracle.t_start))
    return callback


def _finish(run_dir: RunDirectory, setup: _SetUp, res, oracle: _Oracle, run_warnings: list,
            plots: bool = True) -> dict:
    """The result files and summary.json at the optimum (in α)."""
    red = setup.reduction
    if red is not None:
        res.x = red.expand(res.x)
    designs = oracle.design(setup.alpha0, "initial"), oracle.design(res.x, "optimal")
    summary = write_outputs(run_dir.path, setup.problem, setup.alpha0, res, oracle, plots, designs)
    summary["warnings"] = run_warnings
    if oracle.trials.rows():
        summary["failed_trials"] = oracle.trials.summary()
    if red is not None:
        summary["design_variables"] = {"alpha": red.n_alpha, "optimized": red.n_beta}
    run_dir.write_summary(summary)
    return summary


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
                              resume=args.resume, overwrite=args.overwrite, progress=progress,
                              plots=not args.no_plots)
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
