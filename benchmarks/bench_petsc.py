"""One optimization on many cores (issue #23): one evaluation (state + adjoint + design terms) of
Example 1 refined, on the pyamg full-space path and on the PETSc path with 1 and 2 MPI ranks;
evaluation time and peak memory per rank, and the ratios the issue asks for.

    python benchmarks/bench_petsc.py --sizes 113k            # pyamg, PETSc ×1, PETSc ×2
    flock /tmp/contactopt-bench.lock python benchmarks/bench_petsc.py --sizes 113k 371k 867k
    python benchmarks/bench_petsc.py --bodies --sizes 200k 367k   # Example 1 on its elastic slab

Goals: PETSc on 2 ranks ≥ 1.7× faster than on 1 rank; PETSc on 1 rank ≤ 1.2× the pyamg path.
Sizes are bench_scale.py's refinements of Example 1 (113k = 64×30×18, 371k = 96×45×27, 867k =
128×60×36). Every run is a child process of its own (``mpiexec -n 2`` for two ranks), which
builds the problem (no memory check), evaluates at α0 — the cold start, where either path builds
its multigrid hierarchy — then times the evaluation at the next design α1 = α0 + h·d (d as in
bench_scale.py), warm-started from α0 with α0's hierarchy, as an optimization step is, and at
α0 + k·h·d for k = 2..``--repeat`` (the fastest of these is reported: the machine may be shared;
the parts, counts and J are α1's). Peak RSS
(``ru_maxrss``) is reported per rank. Needs petsc4py/mpi4py and mpiexec (README 'One
optimization on many cores'); as root, OpenMPI's OMPI_ALLOW_RUN_AS_ROOT(_CONFIRM) are set.

``--bodies``: two bodies, Example 1 on its elastic slab refined together (the sizes of
bench_two_bodies_scale.py: 200k, 367k, 1m); the rows add the relative differences of ξ and λ
from the pyamg path's, and the parts of the time that the 16-rank estimate of docs/scaling.md
reads (the Krylov solves, the work every rank repeats).

``--setup``: the problem built only (no evaluation), on the PETSc path on 1 and 2 ranks: the
set-up's time and peak RSS per rank (with ``--bodies``, the owned rows of the two bodies' system
formed once, the PETSc matrices made).

    python benchmarks/bench_petsc.py --bodies --setup --sizes 200k
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scale import SIZES, _peak_rss_gb, _shape, design_direction  # noqa: E402
from bench_two_bodies_scale import SIZES as BODIES  # noqa: E402
from bench_two_bodies_scale import two_bodies  # noqa: E402

GOAL_SPEEDUP, GOAL_SLOWDOWN = 1.7, 1.2


def child(shape, path, step, repeat, arrays=None, setup=False):
    """One evaluation on ``path`` in this process (and its MPI ranks); rank 0 prints one JSON line
    (and saves ξ and λ of α1 to ``arrays``). ``shape``: Example 1's mesh, or a key of ``BODIES``;
    ``setup``: the problem built only."""
    import numpy as np

    from contactopt.config import load_config
    from contactopt.problem import ShapeProblem
    from contactopt.ranks import run_on_ranks

    nx, ny, nz = shape if not isinstance(shape, str) else (0, 0, 0)

    def work():
        if isinstance(shape, str):
            cfg = two_bodies(shape, path)
        else:
            cfg = load_config("example1").with_updates({"mesh": {"nx": nx, "ny": ny, "nz": nz},
                                                        "linear_solver": {"path": path, "memory_check": False}})
        t0 = time.perf_counter()
        problem = ShapeProblem(cfg)
        t_setup = time.perf_counter() - t0
        if setup:
            return {"dofs": int(problem.path.n_unknowns), "setup_s": t_setup}
        a0 = problem.model.initial_design()
        d = design_direction(problem.model)
        a1 = a0 + step * d
        if not problem.model.admissible.is_feasible(a0 + repeat * step * d):
            raise SystemExit("the next design is not admissible: lower --step")
        t0 = time.perf_counter()
        problem.subgradient(a0)
        t_cold = time.perf_counter() - t0
        times = []
        for k in range(1, repeat + 1):        # successive designs α0 + k·h·d, each warm from the last
            t0 = time.perf_counter()
            res = problem.subgradient(a0 + k * step * d) if k > 1 else problem.subgradient(a1)
            times.append(time.perf_counter() - t0)
            if k == 1:
                first = res
        t_eval = min(times)
        res = first
        st = res.state
        if arrays:
            np.savez(arrays, xi=res.gradient, lam=st.lam)
        t = st.timings
        return {"dofs": int(problem.path.n_unknowns) if isinstance(shape, str) else int(problem.model.assembler.n_free),
                "krylov_s": t.get("fullspace_krylov", 0.0), "newton_s": t.get("fullspace_newton", 0.0), "setup_s": t_setup, "cold_s": t_cold,
                "eval_s": t_eval, "state_s": res.timings["state"], "adjoint_s": res.timings["adjoint"],
                "design_s": res.timings["design_terms"], "newton": int(st.iterations),
                "krylov": int(st.info.get("krylov_iterations", 0)), "adjoint_krylov": int(st.info.get("adjoint_krylov", 0)),
                "J": float(res.value), "xi_norm": float(np.linalg.norm(res.gradient)),
                "eval_all_s": times}

    out = run_on_ranks(work)
    rss = [_peak_rss_gb()]
    if os.environ.get("OMPI_COMM_WORLD_SIZE", "1") != "1":
        from mpi4py import MPI
        rss = MPI.COMM_WORLD.gather(rss[0], root=0)
        if MPI.COMM_WORLD.Get_rank() > 0:
            return
    print(json.dumps({**out, "path": path, "ranks": len(rss), "rss_gb": rss}), flush=True)


def run(size, path, ranks, step, repeat, bodies=False, arrays=None, setup=False):
    cmd = [sys.executable, __file__, "--child", size, path, str(step), str(repeat)]
    if bodies:
        cmd += ["--bodies", "--arrays", str(arrays)]
    if setup:
        cmd += ["--setup"]
    env = dict(os.environ)
    if ranks > 1:
        exe = shutil.which("mpiexec") or sys.exit("mpiexec not found")
        cmd = [exe, "-n", str(ranks), *cmd]
        if os.geteuid() == 0:
            env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        sys.exit(f"{size} {path} ×{ranks} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _differences(files) -> str:
    """The largest relative differences of ξ and λ of the runs saved in ``files`` (the first the reference)."""
    import numpy as np
    ref = np.load(files[0])
    out = []
    for f in files[1:]:
        got = np.load(f)
        out.append(max(float(np.abs(got[k] - ref[k]).max() / np.abs(ref[k]).max()) for k in ("xi", "lam")))
    return ", ".join(f"{d:.1e}" for d in out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs="+", default=["113k"], help=f"{', '.join(SIZES)} or NXxNYxNZ; with --bodies "
                    f"{', '.join(BODIES)}")
    ap.add_argument("--bodies", action="store_true", help="Example 1 on its elastic slab (two bodies)")
    ap.add_argument("--arrays", help=argparse.SUPPRESS)
    ap.add_argument("--step", type=float, default=2e-4, help="h of the next design α0 + h·d")
    ap.add_argument("--repeat", type=int, default=3, help="evaluations timed at successive designs; "
                    "the fastest is reported (the machine may be shared)")
    ap.add_argument("--setup", action="store_true", help="the problem built only: set-up time and peak memory "
                    "per rank on the PETSc path, 1 and 2 ranks")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        size, path, step, repeat = args.child
        return child(size if args.bodies else _shape(size), path, float(step), int(repeat), args.arrays, args.setup)
    if args.setup:
        print(f"{'size':>6} {'DOFs':>8} {'ranks':>5} {'set-up s':>8} {'peak GB per rank':>18}")
        for size in args.sizes:
            for ranks in (1, 2):
                r = run(size, "petsc", ranks, args.step, args.repeat, args.bodies, None, setup=True)
                print(f"{size:>6} {r['dofs']:>8} {ranks:>5} {r['setup_s']:8.2f} "
                      f"{' '.join(f'{g:.2f}' for g in r['rss_gb']):>18}", flush=True)
        return 0
    print(f"{'size':>6} {'DOFs':>8} {'path':>9} {'ranks':>5} {'eval s':>7} {'state':>6} {'adjoint':>7} "
          f"{'design':>6} {'Newton':>6} {'GMRES':>5} {'krylov s':>8} {'peak GB per rank':>18}")
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes:
            rows, files = {}, []
            for path, ranks in (("fullspace", 1), ("petsc", 1), ("petsc", 2)):
                files.append(Path(tmp) / f"{size}_{path}_{ranks}.npz")
                r = rows[path, ranks] = run(size, path, ranks, args.step, args.repeat, args.bodies, files[-1])
                print(f"{size:>6} {r['dofs']:>8} {path:>9} {ranks:>5} {r['eval_s']:7.2f} {r['state_s']:6.2f} "
                      f"{r['adjoint_s']:7.2f} {r['design_s']:6.2f} {r['newton']:>6} {r['krylov']:>5} "
                      f"{r['krylov_s']:8.2f} {' '.join(f'{g:.2f}' for g in r['rss_gb']):>18}", flush=True)
            ref, one, two = rows["fullspace", 1], rows["petsc", 1], rows["petsc", 2]
            speedup, slowdown = one["eval_s"] / two["eval_s"], one["eval_s"] / ref["eval_s"]
            dj = max(abs(r["J"] - ref["J"]) / abs(ref["J"]) for r in (one, two))
            print(f"{size:>6}: 2 ranks {speedup:.2f}× faster than 1 (goal ≥ {GOAL_SPEEDUP}), PETSc on 1 rank "
                  f"{slowdown:.2f}× the pyamg path (goal ≤ {GOAL_SLOWDOWN}); J agrees to {dj:.1e}"
                  + (f"; ξ, λ of PETSc ×1, ×2 against pyamg: {_differences(files)}" if args.bodies else ""), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
