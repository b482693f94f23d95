"""Command-line interface: ``contactopt run | sweep | state | export | check-gradient | solve-fclib``.

Only this module prints. Exit codes: 0 done; 1 a check failed or a sweep task failed; 2 an
error of the library (``ContactOptError``: bad input, a directory in use by another process, a
failed solve), said in one paragraph on stderr, nothing written for input that is rejected;
74 a file could not be written (no space, read-only, permission denied; the message names the
file and how the run continues); 128 + the signal's number when interrupted (130 SIGINT,
143 SIGTERM), after the run's summary.json or the sweep's tables say so.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import re
import signal
import sys
import threading
import time
from importlib import import_module
from pathlib import Path

import numpy as np

from ._mpi import world_size
from ._progress import LiveLine
from .config import json_schema, load_config
from .errors import ConfigError, ContactOptError, Interrupted, MeshError
from .io.atomic import WriteError, atomic_write_json, atomic_write_text, write_error
from .io.examples import copy_examples, list_examples
from .io.lock import acquire

log = logging.getLogger("contactopt")

EXIT_WRITE = 74        # sysexits.h EX_IOERR: a file could not be written


def _deferred(module: str, name: str):
    """``name`` of the package's ``module``, imported when first called."""
    def call(*args, **kw):
        return getattr(import_module(module, __package__), name)(*args, **kw)
    call.__name__ = call.__qualname__ = name
    return call


# The commands' own modules load with the command that calls them: the solver (scipy, the FEM
# model), the figures (matplotlib) and the file formats (h5py, meshio) take about a second to
# import, and `contactopt --help`, `contactopt schema` and a rejected configuration need none of them.
ElasticModel = _deferred(".fem.model", "ElasticModel")
export_design = _deferred(".io.export", "export_design")
normalize_formats = _deferred(".io.export", "normalize_formats")
solve_fclib = _deferred(".io.fclib", "solve_fclib")
prepare_output_dir = _deferred(".io.rundir", "prepare_output_dir")
state_files = _deferred(".io.statefiles", "state_files")
write_state = _deferred(".io.statefiles", "write_state")
write_steps = _deferred(".io.statefiles", "write_steps")
run_from_cli = _deferred(".runner", "run_from_cli")
check_gradient = _deferred(".sensitivity.check", "check_gradient")
parse_settings = _deferred(".studies", "parse_settings")
run_sweep = _deferred(".studies", "run_sweep")
_shape_problem = _deferred(".problem", "ShapeProblem")
flat_design = _deferred(".design.several", "flat_design")
surfaces_of = _deferred(".design.several", "surfaces_of")


def ShapeProblem(config, **kw):
    """:class:`contactopt.problem.ShapeProblem` of ``config``, loaded and validated before the
    solver's modules are imported: a rejected configuration is said at once."""
    return _shape_problem(load_config(config), **kw)


def _read_alpha(path: str, model) -> np.ndarray:
    p = Path(path)
    if not p.exists():
        raise ConfigError([f"--alpha {path}: no such file"])
    try:
        if p.suffix == ".npy":
            arr = np.load(p)
        elif p.suffix == ".npz":
            with np.load(p) as z:
                arr = z["alpha"]
        elif p.suffix == ".json":
            obj = json.loads(p.read_text())
            arr = flat_design(model.surface, obj["alpha"] if isinstance(obj, dict) else obj)
        else:
            arr = np.loadtxt(p, ndmin=1)
    except (ValueError, KeyError, OSError) as exc:
        raise ConfigError([f"--alpha {path}: cannot read a design from it ({exc})"]) from None
    arr = np.asarray(arr, float)
    if arr.size != model.n_design:
        shapes = " + ".join(f"{s.shape[0]}×{s.shape[1]}" for s in surfaces_of(model.surface))
        raise ConfigError([f"--alpha {path}: has {arr.size} numbers, the design has {model.n_design} "
                           f"control points ({shapes})"])
    return arr.reshape(-1)


def _cmd_state(args) -> int:
    problem = ShapeProblem(args.config, method=args.method)
    model = problem.model
    alpha = _read_alpha(args.alpha, model) if args.alpha else model.initial_design()
    what = f"--alpha {args.alpha}" if args.alpha else "the initial design (design.initial)"
    try:
        model.mesh.coordinates(alpha)                   # mesh validity before any output
    except MeshError as exc:
        raise MeshError(f"{what}: {exc}; a state is solved for any design outside the admissible set "
                        "U, but not for one that inverts or distorts the mesh") from None
    warnings = _design_warnings(model, alpha, what)
    out_path = Path(args.out or f"state-{problem.config.name}")
    created = not out_path.exists()
    out = prepare_output_dir(out_path, overwrite=args.overwrite)
    t0 = time.perf_counter()
    try:
        states = problem.solve_states(alpha)           # every load case (one assembly)
        bound, reason = problem.uniqueness_estimate(alpha)
        reports = [problem.objective_report(alpha, k if problem.has_load_cases else None)
                   for k in range(len(states))]
        cons = problem.constraint_report(alpha) if problem.constraints else None    # the worst load case
    except Exception:
        if created and not any(out.iterdir()):
            out.rmdir()                  # a failed solve leaves no empty directory behind
        raise
    for state in states:
        state.uniqueness_bound = bound           # JSON has no NaN: absent, with the reason
        state.uniqueness_reason = reason or None
    print(f"state of {problem.config.name} ({problem.config.source}) — method {states[0].method}, "
          f"backend {states[0].summary().get('backend')}")
    if problem.has_load_steps:
        return _write_step_states(out, problem, alpha, states, warnings, bound, reason, t0)
    if not problem.has_load_cases:
        write_state(out, model, states[0], config=problem.config, warnings=warnings, objective=reports[0],
                    constraints=cons)
        _print_state(states[0], bound, reason, reports[0], cons)
        print(f"  wrote {out}/ ({', '.join(state_files(model))}) in {time.perf_counter() - t0:.1f}s")
        return 0
    # load cases: one directory per case, and cases.json listing them
    names = problem.case_names
    dirs = [_case_dir(name, k) for k, name in enumerate(names)]
    if len(set(dirs)) < len(dirs):       # names that differ only in unsafe characters
        dirs = [f"case-{k}-{d[5:]}" for k, d in enumerate(dirs)]
    for name, d, state, report in zip(names, dirs, states, reports):
        write_state(out / d, model, state, config=problem.config, warnings=warnings, objective=report,
                    constraints=cons)
        print(f"load case {name!r} → {out / d}/")
        _print_state(state, bound, reason, report, cons)
    atomic_write_json(out / "cases.json", {
        "name": problem.config.name, "combine": problem.combination.kind, "names": list(names), "warnings": warnings,
        "cases": [{"name": n, "directory": d, "summary": st.summary()} for n, d, st in zip(names, dirs, states)]})
    print(f"  wrote {out}/cases.json and {len(names)} case directories ({', '.join(state_files(model))}) "
          f"in {time.perf_counter() - t0:.1f}s")
    return 0


def _design_warnings(model, alpha, what: str) -> list[str]:
    """The constraints of the admissible set U that α breaks (bounds, slopes, the mean value,
    ϑ_α ≥ 0 on the contact face), as warnings: a single state solve needs none of them."""
    broken = model.admissible.violations(alpha, tol=1e-8)
    if not broken:
        return []
    head = (f"{what} lies outside the admissible set U ({len(broken)} constraint(s) broken); "
            "the state is solved all the same")
    for line in [head, *broken]:
        print(f"contactopt: warning: {line}", file=sys.stderr)
    return [head, *broken]


def _write_step_states(out, problem, alpha, states, warnings, bound, reason, t0) -> int:
    """`contactopt state` on load paths: step-<name>/ per step (case-<case>/step-<name>/ with
    load cases), each with the objective and the constraints at the step's end; steps.json with
    Θ and the constraints over the steps; body.pvd."""
    for k, name in enumerate(problem.case_names):
        where = out / _case_dir(name, k) if problem.has_load_cases else out
        ends = [(step, state) for step, _, state in problem.step_results(k) or []
                if state.substep == _substeps(problem, k, step)]
        reports = problem.step_reports(alpha, k)
        if not ends:                     # a case without steps: its one state as step "static"
            ends = [("static", states[k])]
            reports = [("static", problem.objective_report(alpha, k), problem.constraint_report(alpha, k))]
        case = k if problem.has_load_cases else None
        combined = {**problem.objective_report(alpha, case), "steps": problem.step_choice.spec}
        limits = {n: {**c, "steps": con.steps.spec} for (n, c), con in
                  zip(problem.constraint_report(alpha, case).items(), problem.constraints)}
        write_steps(where, problem.model, ends, config=problem.config, warnings=warnings,
                    reports=[r[1:] for r in reports], combined=(combined, limits))
        for (step, state), (_, objective, cons) in zip(ends, reports):
            print(f"{'load case ' + repr(name) + ', ' if problem.has_load_cases else ''}step {step!r} → "
                  f"{where}/step-{step}/")
            _print_state(state, bound, reason, objective, cons)
    print(f"  wrote {out}/ in {time.perf_counter() - t0:.1f}s")
    return 0


def _substeps(problem, k: int, name: str) -> int:
    return max(s.substep for s in problem.steps[k] if s.name == name)


def _case_dir(name: str, k: int) -> str:
    """Directory of load case ``name`` (k-th): its name where that is a safe file name."""
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", str(name)).strip(".")
    return f"case-{safe}" if safe else f"case-{k}"


def _print_state(state, bound, reason, objective=None, constraints=None) -> None:
    s = state.summary()
    if objective is not None:
        terms = ", ".join(f"{k} {v['value']:.6e}" for k, v in objective["terms"].items())
        print(f"  objective {objective['type']} = {objective['value']:.8e}" + (f" ({terms})" if terms else ""))
    for name, c in (constraints or {}).items():
        print(f"  constraint {name} = {c['value']:.6e} ≤ {c['limit']:.6e}: margin {c['margin']:.3e}"
              + ("" if c["margin"] >= 0 else " (violated)"))
    print(f"  iterations {state.iterations}, residual {state.residual:.2e}, contact conditions {state.complementarity:.2e}")
    print("  nodes: " + ", ".join(f"{k} {v}" for k, v in s['node_classes'].items()))
    print(f"  total normal force {s['total_normal_force']:.6g}, max {s['max_normal_force']:.4g}")
    if bound is not None:
        F = (state.friction if np.ndim(state.friction) == 0
             else f"{np.min(state.friction):g} to {np.max(state.friction):g} per contact node")
        print(f"  uniqueness bound (3.16) F0 ≈ {bound:.3g} (F = {F}; pessimistic)")
    else:
        print(f"  uniqueness bound (3.16) not computed: {reason}")
    print("  time: " + ", ".join(f"{k} {v:.3f}s" for k, v in state.timings.items()))


def _cmd_export(args) -> int:
    run = Path(args.run_dir)
    if not (run / "config.toml").is_file():
        raise ConfigError([f"{run}: not a run directory (no config.toml; 'contactopt run' writes one)"])
    formats = normalize_formats([f for item in args.format for f in item.split(",") if f]
                                if args.format else None)
    if not args.alpha and not (run / "alpha.json").is_file():
        raise ConfigError([f"{run}: has no alpha.json (the run has not finished); pass --alpha FILE"])
    model = ElasticModel(load_config(run / "config.toml"))
    alpha = _read_alpha(args.alpha or str(run / "alpha.json"), model)
    out = Path(args.out) if args.out else run
    res = _export_locked(model, alpha, out, formats, args)
    print(f"exported the design of {run / 'alpha.json' if not args.alpha else args.alpha} into {out}/:")
    for fmt, names in res["files"].items():
        print(f"  {fmt:5s} " + ", ".join(names))
    for fmt, why in res["skipped"].items():
        print(f"  {fmt:5s} skipped: {why}")
    if res.get("cad_unit"):
        print(f"  STEP/IGES in millimetres (model coordinates in {res['unit']}); mesh and STL in the model's units"
              + (", surface trimmed to the contact face" if res.get("surface_trimmed") else ""))
    return 0


def _export_locked(model, alpha, out: Path, formats, args) -> dict:
    """export_design into ``out`` as its only writer (refused while a run or export holds it)."""
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        lock = acquire(out, what="output directory")
    except OSError as exc:
        raise write_error(out, exc) from exc
    try:
        return export_design(model, alpha, out, formats, unit=args.unit, strict=args.format is not None)
    except BaseException:
        lock.release()
        if created and not any(out.iterdir()):
            out.rmdir()                    # a failed export leaves no empty directory behind
        raise
    finally:
        lock.release()


def _cmd_check_gradient(args) -> int:
    config = load_config(args.config)
    config.assembly.require_design(config.source, "a gradient check (contactopt check-gradient)")
    problem = ShapeProblem(config)
    model = problem.model
    alpha = _read_alpha(args.alpha, model) if args.alpha else model.initial_design()
    model.admissible.require_feasible(alpha, tol=1e-8)
    passed = True
    states = {} if args.state_method is None else {"state_method": args.state_method,
                                                   "state_tol": 1e-13 if args.state_method == "newton" else 1e-14}
    for j in [None] + list(range(len(problem.constraints))):     # Θ, then each constraint's response
        if j is None:
            rep = check_gradient(problem, alpha, seed=args.seed, n_directions=args.directions, h=args.h, **states)
            print(f"gradient check of {problem.config.name}: Θ = {rep.value:.8e}, degenerate nodes "
                  f"{rep.n_degenerate} {rep.counts}")
        else:
            con = problem.constraints[j]
            rep = check_gradient(problem.for_constraint(j), alpha, seed=args.seed, n_directions=args.directions,
                                 h=args.h, **states)
            print(f"\nconstraint {con.name} (max {con.limit:g}): value = {rep.value:.8e}")
        passed = _print_check(rep) and passed
    return 0 if passed else 1


def _print_check(rep) -> bool:
    print(f"{'dir':>4} {'finite difference':>18} {'predicted':>18} {'rel. diff':>10}")
    for k, (fd, pr, rel) in enumerate(zip(rep.fd, rep.predicted, rep.rel_errors)):
        print(f"{k:4d} {fd:18.10e} {pr:18.10e} {rel:10.2e}")
    print("Taylor remainder |Θ(α+hd) − Θ(α) − h ξᵀd| (direction 0):")
    for h, r in zip(rep.taylor_h, rep.taylor_remainder):
        print(f"  h = {h:9.2e}   remainder {r:10.3e}")
    print(f"  observed order {rep.taylor_rate:.2f} (2 expected where Θ is smooth)")
    print(("PASSED" if rep.passed else "FAILED") + f": max relative difference {max(rep.rel_errors):.2e} "
          f"(tolerance {rep.tol:.0e})")
    return rep.passed


def _cmd_solve_fclib(args) -> int:
    t0 = time.perf_counter()
    res = solve_fclib(args.file, method=args.method, tol=args.tol)
    dt = time.perf_counter() - t0
    print(f"{args.file}: method {res.method}, error {res.error:.3e}, iterations {res.iterations}, "
          f"converged {res.converged}, time {dt:.3f}s")
    return 0 if res.converged else 1


def _cmd_run(args) -> int:
    _refuse_invalid(args.config)
    return run_from_cli(args)


def _refuse_invalid(config) -> None:
    """The ConfigError of a configuration that ``run`` would reject, raised before the optimizer's
    modules are imported. A configuration that loads is loaded again by the run, which logs its
    warnings; here they are logged only ahead of the error, as the run would."""
    logger, held = logging.getLogger("contactopt.config"), []

    def hold(record):
        held.append(record)
        return False

    logger.addFilter(hold)
    try:
        load_config(config)
    except ConfigError:
        logger.removeFilter(hold)
        for record in held:
            logger.handle(record)
        raise
    finally:
        logger.removeFilter(hold)


def _cmd_sweep(args) -> int:
    settings = parse_settings(args.set or [])
    if args.max_iter is not None and args.max_iter < 1:
        raise ConfigError([f"--max-iter {args.max_iter}: must be an integer ≥ 1"])
    if args.workers is not None and args.scheduler:
        raise ConfigError(["--workers and --scheduler exclude each other (the workers of a "
                           "cluster are started with 'dask worker')"])
    out = Path(args.out or "sweep")

    def connected(client, dashboard):
        print(f"sweep on {client.scheduler.address}, dashboard: {dashboard or 'unavailable (install bokeh)'}",
              flush=True)

    def progress(row, done, total):
        what = ", ".join(f"{k}={row[k]}" for k, _ in settings)
        if row["error"]:
            print(f"[{done}/{total}] {what}: FAILED {row['error']}", flush=True)
        else:
            print(f"[{done}/{total}] {what}: J/J0 = {row['ratio']:.4g}  evaluations {row['evaluations']}  "
                  f"{row['wall_time_s']:.1f}s  {row['status']}", flush=True)

    res = run_sweep(args.config, settings, out, workers=args.workers, scheduler=args.scheduler,
                    threads=args.threads, max_iter=args.max_iter, eps=args.eps, resume=args.resume,
                    overwrite=args.overwrite, progress=progress, on_client=connected, plots=not args.no_plots)
    print(f"{len(res.rows) - res.n_failed} of {len(res.rows)} tasks finished, {res.n_failed} failed, "
          f"{res.wall_time_s:.1f}s; results in {res.outdir}/ (sweep.csv, sweep.json"
          + "".join(f", {p.name}" for p in res.plots) + ")")
    return 1 if res.n_failed else 0


def _cmd_examples(args) -> int:
    """Copy the shipped example configurations (and their meshes) into a directory, or list them."""
    if args.list:
        for ex in list_examples():
            text = " ".join(ex.description.split())
            print(f"{ex.name:28s} {text if len(text) <= 90 else text[:89] + '…'}")
        return 0
    written = copy_examples(args.dir, overwrite=args.overwrite)
    tomls = sorted(p.name for p in written if p.suffix == ".toml")
    print(f"{len(tomls)} configurations and {len(written) - len(tomls)} mesh and geometry files in {args.dir}/; "
          f"run one with: contactopt run {Path(args.dir) / 'bracket.toml'}")
    return 0


def _cmd_schema(args) -> int:
    """The JSON Schema of a configuration file, for TOML editors (docs/configuration.md)."""
    text = json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
    if args.out:
        atomic_write_text(Path(args.out), text)
        print(f"wrote {args.out}")
    else:
        print(text, end="")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="contactopt", description=(
        "Shape optimization of 3D elastic bodies in unilateral contact with Coulomb friction "
        "(Beremlijski, Haslinger, Kočvara, Kučera, Outrata, SIAM J. Optim. 2009)."))
    ap.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    sub = ap.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="optimize the contact surface of a configuration")
    r.add_argument("config", help="TOML file or built-in example (example1, example2, example3)")
    r.add_argument("--out", help="output directory (default runs/<name>)")
    r.add_argument("--max-iter", type=int, help="maximum bundle-trust iterations")
    r.add_argument("--eps", type=float, help="BT stopping parameter ε")
    r.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    r.add_argument("--overwrite", action="store_true", help="replace the contents of a non-empty --out")
    r.add_argument("--no-plots", action="store_true",
                   help="write every output but the PNG figures (the summary, history, VTU and exports)")
    r.set_defaults(func=_cmd_run)

    s = sub.add_parser("state", help="solve the contact problem for one design")
    s.add_argument("config")
    s.add_argument("--alpha", help="design file (.json, .npy, .npz with 'alpha', or text); default α0")
    s.add_argument("--out", help="output directory (default state-<name>)")
    s.add_argument("--method", choices=["newton", "fixed-point"], help="contact solver")
    s.add_argument("--overwrite", action="store_true")
    s.set_defaults(func=_cmd_state)

    e = sub.add_parser("export", help="the optimal design of a run for CAD and other FE tools")
    e.add_argument("run_dir", help="run directory of 'contactopt run' (config.toml, alpha.json)")
    e.add_argument("--format", action="append", metavar="FMT",
                   help="mesh (alias msh: the body in the input's mesh format), stl, step, iges; repeat or "
                        "separate by commas (default: all; STEP/IGES need contactopt[cad])")
    e.add_argument("--out", help="output directory (default RUN_DIR)")
    e.add_argument("--alpha", help="design file instead of RUN_DIR/alpha.json")
    e.add_argument("--unit", default="mm", choices=["mm", "cm", "m", "in", "um"],
                   help="length unit of the model's coordinates; STEP/IGES are written in mm (default mm)")
    e.set_defaults(func=_cmd_export)

    g = sub.add_parser("check-gradient", help="subgradient vs finite differences")
    g.add_argument("config")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--directions", type=int, default=10)
    g.add_argument("--h", type=float, default=1e-3, help="finite-difference step (relative to |α|)")
    g.add_argument("--alpha", help="design file; default α0")
    g.add_argument("--state-method", choices=["fixed-point", "newton"],
                   help="the states' method: the successive approximations to 1e-14 (default; Newton to 1e-13 "
                        "where a body held only by contact keeps them from settling) or Newton to 1e-13 (faster "
                        "where the successive approximations contract slowly)")
    g.set_defaults(func=_cmd_check_gradient)

    w = sub.add_parser("sweep", help="one optimization per combination of settings, on dask.distributed")
    w.add_argument("config", help="TOML file or built-in example: the base configuration")
    w.add_argument("--set", action="append", metavar="KEY=V1,V2,...",
                   help="a dotted config key and its values (TOML scalars); repeat for a product")
    w.add_argument("--workers", type=int, help="worker processes of a local cluster (default: cores)")
    w.add_argument("--scheduler", help="address of a running dask scheduler, e.g. tcp://host:8786")
    w.add_argument("--threads", type=int, help="MKL/BLAS threads per task (default: cores per host "
                   "// tasks running on it)")
    w.add_argument("--out", help="sweep directory (default sweep)")
    w.add_argument("--max-iter", type=int, help="maximum bundle-trust iterations of every run")
    w.add_argument("--eps", type=float, help="BT stopping parameter ε of every run")
    w.add_argument("--resume", action="store_true",
                   help="reuse finished runs in --out and continue unfinished ones")
    w.add_argument("--overwrite", action="store_true", help="replace the contents of a non-empty --out")
    w.add_argument("--no-plots", action="store_true",
                   help="no PNG figures: neither each run's nor the sweep's comparison plots")
    w.set_defaults(func=_cmd_sweep)

    f = sub.add_parser("solve-fclib", help="solve an FCLIB local frictional-contact problem")
    f.add_argument("file")
    f.add_argument("--method", default="newton", choices=["newton", "fixed-point"])
    f.add_argument("--tol", type=float, default=1e-8)
    f.set_defaults(func=_cmd_solve_fclib)

    x = sub.add_parser("examples", help="copy the example configurations and their meshes into a directory")
    x.add_argument("dir", nargs="?", default="contactopt-examples",
                   help="directory to copy them into (default contactopt-examples)")
    x.add_argument("--list", action="store_true", help="list the examples with their descriptions, copy nothing")
    x.add_argument("--overwrite", action="store_true", help="replace files of the same name in DIR")
    x.set_defaults(func=_cmd_examples)

    j = sub.add_parser("schema", help="the JSON Schema of a configuration file (for TOML editors)")
    j.add_argument("-o", "--out", help="write it to this file (default: print it)")
    j.set_defaults(func=_cmd_schema)
    return ap


def main(argv=None) -> int:
    """The command line; under ``mpiexec`` rank 0 runs it and the other ranks serve its PETSc path
    (:mod:`contactopt.ranks`), so only rank 0 prints, logs and writes."""
    if world_size() <= 1:         # not under mpiexec: the ranks' machinery (the solver) is not needed
        return _main(argv)
    from .ranks import run_on_ranks
    return run_on_ranks(_main, argv)


def _main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    # the console shows warnings (more with -v); a run's log file records INFO and up
    console = logging.StreamHandler(sys.stderr)
    # progress of long solves (contactopt.progress, INFO on large meshes) shows at every verbosity
    console.setLevel(min(level, logging.INFO))
    # (a record the raised exception repeats is printed once, as the error)
    console.addFilter(lambda r: (r.levelno >= level or r.name == "contactopt.progress")
                      and not getattr(r, "raised", False))
    console.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    logging.getLogger().addHandler(console)
    logging.getLogger("contactopt").setLevel(min(level, logging.INFO))
    # on a terminal, a long set-up (a factorization, a foundation's compliance) shows one line
    # that counts its seconds; piped or redirected, nothing of it
    live = LiveLine(sys.stderr) if _interactive(sys.stderr) else None
    progress_logger = logging.getLogger("contactopt.progress")
    old_progress_level = progress_logger.level
    if live is not None:
        progress_logger.addHandler(live)
        progress_logger.setLevel(logging.DEBUG)
    try:
        with _signals_interrupt():
            return args.func(args)
    except WriteError as exc:
        print(f"contactopt: error: {exc}", file=sys.stderr)
        return EXIT_WRITE
    except ContactOptError as exc:
        print(f"contactopt: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"contactopt: {getattr(exc, 'message', '') or 'interrupted'}", file=sys.stderr)
        return 128 + getattr(exc, "signum", signal.SIGINT)
    finally:      # the next command in this process (tests, a notebook) has its own
        logging.getLogger().removeHandler(console)
        if live is not None:
            progress_logger.removeHandler(live)
            progress_logger.setLevel(old_progress_level)
            live.close()


def _interactive(stream) -> bool:
    """Whether ``stream`` is a terminal a person watches (not a pipe, a file or a CI log)."""
    try:
        return stream.isatty() and os.environ.get("TERM", "") != "dumb"
    except (AttributeError, ValueError):
        return False


@contextlib.contextmanager
def _signals_interrupt():
    """SIGINT and SIGTERM (a cluster's time limit) raise :class:`contactopt.runner.Interrupted`
    in the main thread, so that a run stops as after Ctrl-C: the evaluation in progress is
    abandoned, the last checkpoint stands and summary.json says how to continue."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise Interrupted(signum)

    saved = {sig: signal.signal(sig, interrupt) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


if __name__ == "__main__":
    sys.exit(main())
