"""Large meshes (issue #16): cost and peak memory of one evaluation (state + subgradient) at a
next design on refinements of Example 1, as ratios to one clean-process PARDISO factorization.

    python benchmarks/bench_scale.py            # 113k, 210k, 371k, 867k DOFs, path 'auto'
    python benchmarks/bench_scale.py --sizes 113k 210k --paths condensation delassus   # paths side by side
    python benchmarks/bench_scale.py --sizes 48x22x13          # any NXxNYxNZ refinement

Every (size, path) runs in its own child process, so that its peak RSS (``ru_maxrss``, which
includes MKL PARDISO's memory) is its own. The child builds ``ShapeProblem`` on example1 with the
refined ``[mesh]``, evaluates ``contactopt.sensitivity.adjoint.subgradient`` once at α0 (the
first design: ordering, analysis, contact zone, Delassus block or AMG hierarchy), then at
α1 = α0 + h·d and α2 = α0 + 2h·d (h = ``--step``, d a volume-preserving direction with
max|d| = 1, as optimization steps), and reports the time at α2 — an evaluation as in the course
of an optimization — with its parts (``result.timings``, ``state.timings``), sparse solves or
Krylov iterations, and the time at α1 (the second design, which pays for the first design's
Delassus block where the Cholesky had to be released: a fresh ordering), the size of the
sparse factor, the peak RSS and the up-front memory estimate of :mod:`contactopt.fem.memory`. It
saves A(α2); after the child has exited, the parent times one factorization of that same matrix
with pypardiso's defaults in a clean process (``benchmarks/_reference.py``), the reference of
every ratio, and contactopt's own PARDISO Cholesky of it in another clean process (a stricter
yardstick: pypardiso's default is an LU). A reference that does not fit the memory (a Cholesky
of 867k DOFs) is reported as such.

Paths: ``auto`` is ``[linear_solver] path = "auto"`` (the path it picks by size and memory:
``delassus`` from 60k DOFs, ``amg`` where the Delassus path's estimate exceeds the memory);
``condensation`` the condensation onto all contact DOFs (PARDISO Schur mode, dense S); ``delassus`` a
sparse Cholesky of A(α) and Delassus products by solves; ``amg`` the full-space Newton with AMG.
A (size, path) whose estimated peak exceeds ``--max-gb`` (default 16 GB) is skipped and reported.

``--candidates SIZE`` instead measures, in one process on A(α) of that size, the pieces of a path
without S on all contact DOFs (docs/large_meshes.md): a Cholesky factorization, the Schur
condensation on all contact DOFs and on a zone, solves with a kept factorization, PCG with the
factorization of A(α0) as preconditioner at designs α0 + h·d, and pyamg SA + PCG.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SIZES = {"15k": (32, 15, 9), "113k": (64, 30, 18), "210k": (80, 37, 22), "371k": (96, 45, 27),
         "867k": (128, 60, 36), "1m": (136, 64, 38)}
PATHS = ("auto", "condensation", "delassus", "fullspace")   # [linear_solver] path
GOALS = {"113k": 1.5, "210k": 1.5, "371k": 1.0}    # evaluation / reference factorization


def _shape(key):
    if key in SIZES:
        return SIZES[key]
    try:
        nx, ny, nz = (int(v) for v in key.lower().split("x"))
    except ValueError:
        raise SystemExit(f"size {key!r}: one of {', '.join(SIZES)} or NXxNYxNZ") from None
    return nx, ny, nz


def design_direction(model):
    """d: a volume-preserving direction of the control points with max |d| = 1 (seeded), the
    shape of an optimization step α → α + h·d."""
    import numpy as np
    d = np.random.default_rng(1).standard_normal(model.n_design)
    d -= d.mean()
    return d / np.abs(d).max()


def _peak_rss_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20     # KiB on Linux


def child(shape, path, step, out_dir):
    """One size and path in this (fresh) process; prints one JSON line."""
    import scipy.sparse as sp

    from contactopt._threads import sequential_openblas
    from contactopt.config import load_config
    from contactopt.problem import ShapeProblem
    from contactopt.sensitivity.adjoint import subgradient

    nx, ny, nz = shape
    cfg = load_config("example1").with_updates({"mesh": {"nx": nx, "ny": ny, "nz": nz},
                                                "linear_solver": {"path": path,
                                                                  "memory_check": path != "condensation"}})
    t0 = time.perf_counter()
    problem = ShapeProblem(cfg)
    t_setup = time.perf_counter() - t0
    model = problem.model
    n, p = model.assembler.n_free, model.n_contact
    est = problem.path.memory_estimate(model).total_gb
    rss_model = _peak_rss_gb()
    a0 = model.initial_design()
    d = design_direction(model)
    a1 = a0 + step * d
    a2 = a0 + 2 * step * d
    if not model.admissible.is_feasible(a2):
        raise SystemExit("the next designs are not admissible: lower --step")
    with sequential_openblas():
        t0 = time.perf_counter()
        subgradient(problem, a0)
        t_first = time.perf_counter() - t0
        t0 = time.perf_counter()
        res1 = subgradient(problem, a1)
        t_second = time.perf_counter() - t0
        t0 = time.perf_counter()
        res = subgradient(problem, a2)
        t_eval = time.perf_counter() - t0
    st = res.state
    path = problem.path          # the factorization it keeps, for PARDISO's memory report (none in full space)
    fac = getattr(path, "_factor", None) or (path._slot.current if getattr(path, "_slot", None) else None)
    A = problem.cached_system(a2).assembled.A
    if fac is not None:
        ip = fac._ps.iparm    # PARDISO's own memory report (KiB): analysis peak, permanent, factor
        pardiso_gb = max(int(ip[14]), int(ip[15]) + int(ip[16])) / 2**20
    else:
        pardiso_gb = 0.0
    a_file = Path(out_dir) / f"A_{nx}x{ny}x{nz}.npz"
    sp.save_npz(a_file, A, compressed=False)
    row = dict(shape=shape, path=problem.path.name, n=n, p=p, nnz_A=int(A.nnz),
               nnz_factor=int(fac.stats["nnz_factor"]) if fac is not None else 0, pardiso_gb=pardiso_gb,
               setup=t_setup, first=t_first, second=t_second, evaluation=t_eval,
               second_delassus=res1.state.info["delassus"],
               parts={**{k: v for k, v in st.timings.items() if k != "total"},
                      "adjoint": res.timings["adjoint"], "design_terms": res.timings["design_terms"]},
               zone=st.info["zone_nodes"], newton_it=int(st.iterations), delassus=st.info["delassus"],
               solves=st.info.get("sparse_solves"), adjoint_krylov=st.info.get("adjoint_krylov"),
               krylov=st.info.get("krylov_iterations"),
               rss_model_gb=rss_model, peak_gb=_peak_rss_gb(), estimate_gb=est, A_file=str(a_file))
    print(json.dumps(row))


def _estimate_only(shape, path="condensation"):
    """Estimated peak (GB) of a size and path without running it: a child builds the body only."""
    code = ("import sys, json; from contactopt.config import load_config; "
            "from contactopt.mesh.body import build_body; from contactopt.fem.memory import free_dofs; "
            "from contactopt.paths import PATHS, select_path; "
            "nx, ny, nz = map(int, sys.argv[1:4]); "
            "cfg = load_config('example1').with_updates({'mesh': {'nx': nx, 'ny': ny, 'nz': nz}}); "
            "b = build_body(cfg); "
            "path = select_path(cfg, free_dofs(b))[0] if sys.argv[4] == 'auto' else sys.argv[4]; "
            "print(json.dumps(PATHS[path].memory_estimate(b).total_gb))")
    out = subprocess.run([sys.executable, "-c", code, *map(str, shape), path], capture_output=True, text=True)
    if out.returncode:
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


_SPD_SCRIPT = r"""
import json, sys, time, resource
import scipy.sparse as sp
from contactopt.fem.linsolve import factorize
A = sp.load_npz(sys.argv[1]).tocsr()
times, cpu = [], []
for _ in range(int(sys.argv[2])):
    t0, c0 = time.perf_counter(), time.process_time()
    f = factorize(A, "pardiso"); times.append(time.perf_counter() - t0); cpu.append(time.process_time() - c0); f.close()
print(json.dumps({"seconds": sorted(times)[len(times) // 2], "cpu_seconds": sorted(cpu)[len(cpu) // 2],
                  "peak_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}))
"""


def clean_spd_factorization(a_file, repeat):
    """A second, steadier yardstick: contactopt's own PARDISO Cholesky (``linsolve.factorize``,
    analysis included) of the same matrix in a clean process, with that process's peak RSS."""
    out = subprocess.run([sys.executable, "-c", _SPD_SCRIPT, str(a_file), str(repeat)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


PARDISO_OPTIONS = {"classic (iparm[23] = 0)": {23: 0},
                   "parallel nested dissection (iparm[1] = 3)": {1: 3},
                   "VBSR storage (iparm[36] = -80)": {36: -80}}


def _pardiso_options(A, b, rel, timed):
    """Cholesky factorizations of A with PARDISO options other than contactopt's (two-level
    parallel factorization, METIS ordering, CSR): analysis + factorization, numerical
    refactorization, one solve and its residual."""
    import numpy as np
    import scipy.sparse as sp

    from contactopt.fem import _pardiso
    upper = sp.triu(A, format="csr")
    for name, opts in PARDISO_OPTIONS.items():
        ps = _pardiso.PardisoSPD(upper)
        for k, v in opts.items():
            ps.iparm[k] = v
        try:
            t_an, _ = timed(ps.analyze)
            t_f, _ = timed(ps.factor)
            t_num, _ = timed(lambda: ps.factor(upper))
            t_s, x = timed(lambda: ps.solve(b))
            res = np.linalg.norm(A @ x - b) / np.linalg.norm(b)
            print(f"  PARDISO {name}: analysis + factorization {t_an + t_f:.2f} s{rel(t_an + t_f)}, numerical "
                  f"refactorization {t_num:.2f} s{rel(t_num)}, solve {t_s:.3f} s, residual {res:.1e}, "
                  f"nnz(L) {ps.nnz_factor}", flush=True)
        except Exception as exc:        # an option this MKL refuses: say so, go on
            print(f"  PARDISO {name}: {exc}", flush=True)
        finally:
            ps.close()


CANDIDATES = ("factor", "options", "schur", "zone", "block", "steps", "amg")


def candidates(shape, steps, block, rtol, skip=(), zone_fraction=0.55):
    """The candidates of a path without S on all contact DOFs, in isolation on A(α) of one size
    (in this process): a fresh factorization, the Schur condensation of today's path and one on
    a zone only, solves with a kept factorization (single and block right-hand sides), PCG with
    the factorization of A(α0) as preconditioner for A(α0 + h·d), pyamg SA + PCG. ``skip`` names
    parts not to run (a large size: "schur"). Prints one line per measurement."""
    import numpy as np

    from _iterative import Cholesky, DelassusOperator, amg_preconditioner, pcg
    from contactopt._threads import sequential_openblas
    from contactopt.config import load_config
    from contactopt.fem.amg import rigid_body_modes
    from contactopt.fem.linsolve import condense, factorize
    from contactopt.fem.model import ElasticModel

    nx, ny, nz = shape
    model = ElasticModel(load_config("example1").with_updates({"mesh": {"nx": nx, "ny": ny, "nz": nz},
                                                               "linear_solver": {"memory_check": False}}))
    a0 = model.initial_design()
    d = design_direction(model)
    asm0 = model.assemble(a0)
    A0, L0 = asm0.A, asm0.L
    c = model.contact_dofs
    n = A0.shape[0]
    print(f"candidates on {nx}x{ny}x{nz}: {n} DOFs, {len(c)} contact DOFs, nnz(A) {A0.nnz}", flush=True)

    def timed(fn):
        t0 = time.perf_counter()
        out = fn()
        return time.perf_counter() - t0, out

    t_fact, F0 = None, None
    rel = lambda t: f" = {t / t_fact:.2f} × factorization" if t_fact else ""   # noqa: E731
    with sequential_openblas():
        if "factor" not in skip:
            if n <= 250_000:
                factorize(A0, "pardiso").close()                   # library load, thread start
            t_fact, F0 = timed(lambda: factorize(A0, "pardiso"))
            print(f"  factorization of A(α0), contactopt Cholesky: {t_fact:.2f} s "
                  f"(analysis {F0.timings['analyze']:.2f}, numeric {F0.timings['factor']:.2f}); "
                  f"nnz(L) {F0.stats['nnz_factor']}; peak RSS so far {_peak_rss_gb():.2f} GB", flush=True)
            F0.close()
            F0 = Cholesky(A0, "pardiso")          # the same factorization, able to refactor
            A1 = model.assemble(a0 + steps[0] * d).A
            t_num, _ = timed(lambda: F0.refactor(A1))
            F0.refactor(A0)
            dofs = c[: 3 * (len(c) // 6)]           # a zone of half the contact nodes
            W = DelassusOperator(F0.solve, n, dofs)
            r = np.random.default_rng(2).standard_normal(dofs.size)
            t_prod = min(timed(lambda: W @ r)[0] for _ in range(3))
            print(f"  numerical refactorization at α0 + {steps[0]:g}·d (analysis kept): {t_num:.2f} s{rel(t_num)}; "
                  f"a Delassus product W_Z r on {dofs.size // 3} contact nodes: {t_prod:.3f} s{rel(t_prod)}",
                  flush=True)
        if "options" not in skip:
            _pardiso_options(A0, L0, rel, timed)
        if "schur" not in skip:
            t_schur, cond = timed(lambda: condense(A0, c, "pardiso"))
            t_refac, _ = timed(lambda: cond.refactor(A0, trusted=True))
            print(f"  today's Schur condensation (dense S on all contact DOFs): {t_schur:.2f} s{rel(t_schur)}; "
                  f"refactor (analysis reused) {t_refac:.2f} s{rel(t_refac)}", flush=True)
            cond.close()
            del cond
        if "zone" not in skip:
            # a Schur complement on the contact zone only (a stand-in zone: the contact nodes of
            # largest x1, zone_fraction of them; Example 1's zone at 113k: 1091 of 1984 nodes)
            x1 = asm0.coords[model.contact_nodes, 0]
            z = np.sort(np.argsort(-x1, kind="stable")[:int(round(zone_fraction * len(x1)))])
            cz = c.reshape(-1, 3)[z].ravel()
            t_zone, cond = timed(lambda: condense(A0, cz, "pardiso"))
            t_zrefac, _ = timed(lambda: cond.refactor(A0, trusted=True))
            print(f"  Schur on a zone of {len(z)} of {len(x1)} contact nodes: {t_zone:.2f} s{rel(t_zone)}, "
                  f"refactor {t_zrefac:.2f} s{rel(t_zrefac)}; its dense (3z)² is {(len(cz) / len(c)) ** 2:.2f} "
                  f"and (3z)³ {(len(cz) / len(c)) ** 3:.2f} of those on all contact DOFs", flush=True)
            cond.close()
            del cond
        if F0 is not None and "block" not in skip:
            t1 = min(timed(lambda: F0.solve(L0))[0] for _ in range(3))
            Bk = np.zeros((n, block))
            Bk[c[:block], np.arange(block)] = 1.0                    # Bᵀ e_j: contact DOF columns
            tk, Xk = timed(lambda: F0.solve(Bk))
            print(f"  solve with the factorization: 1 rhs {t1:.3f} s{rel(t1)}; "
                  f"block of {block} contact columns {tk:.2f} s = {tk / block:.3f} s per column "
                  f"-> all {len(c)} columns (W = B A⁻¹ Bᵀ) ≈ {tk / block * len(c):.0f} s, "
                  f"{n * len(c) * 8 / 2**30:.1f} GB", flush=True)
            del Xk, Bk
        if F0 is not None and "steps" not in skip:
            rng = np.random.default_rng(0)
            two_factors = n <= 250_000      # the reference of the error: a second factorization
            for h in steps:
                asm = model.assemble(a0 + h * d)
                A, L = asm.A, asm.L
                if two_factors:
                    tf, F = timed(lambda: factorize(A, "pardiso"))
                    x_ref = F.solve(L)
                    F.close()
                tp, res = timed(lambda: pcg(A, L, F0.solve, rtol=rtol, max_iter=200))
                if not two_factors:     # a second factor does not fit: A(α0)'s time, residual only
                    tf, x_ref = t_fact, res.x
                err = (f"error vs direct {np.linalg.norm(res.x - x_ref) / np.linalg.norm(x_ref):.1e}"
                       if two_factors else f"residual {res.history[-1]:.1e} (no second factorization)")
                Y = rng.standard_normal((n, block))
                tb, resb = timed(lambda: pcg(A, Y, F0.solve, rtol=rtol, max_iter=200))
                print(f"  step h = {h:g}: PCG(M = A(α0)⁻¹) to {rtol:g}: {res.iterations} it, {tp:.2f} s = "
                      f"{tp / tf:.2f} × a fresh factorization ({tf:.2f} s), {err}; "
                      f"block of {block}: {resb.iterations} it, {tb / block:.3f} s per column", flush=True)
        if F0 is not None:
            F0.close()
        if "amg" not in skip:
            B = rigid_body_modes(asm0.coords, model.assembler.free)
            ts, (M, ml) = timed(lambda: amg_preconditioner(A0, B))
            tp, res = timed(lambda: pcg(A0, L0, M, rtol=rtol, max_iter=500))
            print(f"  pyamg SA (rigid-body modes, {len(ml.levels)} levels, operator complexity "
                  f"{ml.operator_complexity():.2f}): setup {ts:.2f} s{rel(ts)}; PCG to {rtol:g}: "
                  f"{res.iterations} it, {tp:.2f} s{rel(tp)}, {tp / res.iterations:.3f} s per iteration", flush=True)
    print(f"  peak RSS of this process {_peak_rss_gb():.2f} GB")


def _meminfo():
    info = {}
    with open("/proc/meminfo") as f:
        for line in f:
            k, v = line.split(":", 1)
            info[k] = int(v.split()[0]) / 2**20
    return info


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", nargs="+", default=["113k", "210k", "371k", "867k"],
                    help=f"keys ({', '.join(f'{k}={v[0]}x{v[1]}x{v[2]}' for k, v in SIZES.items())}) or NXxNYxNZ")
    ap.add_argument("--paths", nargs="+", choices=PATHS, default=["auto"],
                    help="auto: [linear_solver] path = 'auto' (the path it picks by size and memory)")
    ap.add_argument("--step", type=float, default=5e-4, help="max |α1 − α0| of the next design")
    ap.add_argument("--max-gb", type=float, default=16.0, help="skip sizes estimated above this peak")
    ap.add_argument("--repeat", type=int, default=3, help="clean-process reference factorizations (median)")
    ap.add_argument("--json", help="also write the rows to this file")
    ap.add_argument("--candidates", metavar="SIZE",
                    help="instead: measure the candidate solvers in isolation on this size (e.g. 113k)")
    ap.add_argument("--block", type=int, default=64, help="columns of the block solves (--candidates)")
    ap.add_argument("--steps", type=float, nargs="+", default=[1e-4, 3e-4, 1e-3, 3e-3],
                    help="design steps h of the reused-factorization PCG (--candidates)")
    ap.add_argument("--skip", nargs="+", choices=CANDIDATES, default=[],
                    help="parts of --candidates not to run (e.g. schur on a large size)")
    ap.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        nx, ny, nz, path, out_dir = args.child
        child((int(nx), int(ny), int(nz)), path, args.step, out_dir)
        return 0
    if args.candidates:
        candidates(_shape(args.candidates), args.steps, args.block, 1e-10, set(args.skip))
        return 0

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import scipy.sparse as sp

    from _reference import clean_factorization

    with open("/proc/loadavg") as f:
        load = f.read().split()[:3]
    mi = _meminfo()
    print(f"machine: load average {' '.join(load)}, MemAvailable {mi['MemAvailable']:.1f} of "
          f"{mi['MemTotal']:.1f} GB")
    head = (f"{'size':<10} {'path':<8} {'DOFs':>8} {'p':>5} {'eval[s]':>8} {'ref[s]':>7} {'ratio':>6} "
            f"{'goal':>5} {'peak GB':>7} {'est GB':>6}  parts [s]")
    print(head)
    print("-" * len(head))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for key in args.sizes:
            shape = _shape(key)
            label = key if key in SIZES else "x".join(map(str, shape))
            for path in args.paths:
                est = _estimate_only(shape, path)
                if est is not None and est > args.max_gb:
                    print(f"{label:<10} {path:<8} skipped: estimated peak {est:.1f} GB > --max-gb {args.max_gb:g}",
                          flush=True)
                    rows.append(dict(shape=shape, path=path, skipped=True, estimate_gb=est))
                    continue
                cmd = [sys.executable, __file__, "--step", str(args.step), "--child", *map(str, shape), path, tmp]
                out = subprocess.run(cmd, capture_output=True, text=True)
                if out.returncode:
                    print(f"{label:<10} {path:<8} failed (exit {out.returncode}): "
                          f"{out.stderr.strip().splitlines()[-1] if out.stderr.strip() else ''}", flush=True)
                    continue
                row = json.loads(out.stdout.strip().splitlines()[-1])
                # the references need memory of their own: a Cholesky factor of the estimated size
                # (PARDISO_BYTES per entry), pypardiso's LU about twice that
                from contactopt.fem import memory
                chol_gb = (memory.PARDISO_BYTES * memory.CHOLESKY_FILL * memory.fill_factor(row["n"])
                           * row["nnz_A"] / 2**30)
                avail = _meminfo()["MemAvailable"]
                if 2 * chol_gb < 0.8 * avail:
                    A = sp.load_npz(row["A_file"])
                    ref = clean_factorization(A, repeat=args.repeat)
                    del A
                else:
                    ref = {"seconds": float("nan"), "what": f"skipped: pypardiso's LU needs about {2 * chol_gb:.0f} GB"}
                if chol_gb < 0.8 * avail:
                    spd = clean_spd_factorization(row["A_file"], args.repeat)
                else:
                    spd = {"seconds": float("nan"), "peak_gb": float("nan")}
                row["spd_factorization"], row["spd_peak_gb"] = spd["seconds"], spd["peak_gb"]
                Path(row["A_file"]).unlink()
                row["reference"], row["reference_what"] = ref["seconds"], ref["what"]
                row["ratio"] = row["evaluation"] / ref["seconds"]
                if ref["what"].startswith("skipped"):
                    print(f"{label:<10} reference {ref['what']}", flush=True)
                goal = GOALS.get(key)
                parts = ", ".join(f"{k} {v:.2f}" for k, v in row["parts"].items())
                est_s = f"{row['estimate_gb']:6.2f}" if row["estimate_gb"] is not None else f"{'-':>6}"
                print(f"{label:<10} {row['path']:<8} {row['n']:>8} {row['p']:>5} {row['evaluation']:8.2f} "
                      f"{ref['seconds']:7.2f} {row['ratio']:6.2f} {goal if goal else '-':>5} "
                      f"{row['peak_gb']:7.2f} {est_s}  {parts}; zone {row['zone']}, "
                      f"[first design {row['first']:.2f} s, second {row['second']:.2f} s (W_Z {row['second_delassus']})], "
                      f"Newton {row['newton_it']} it, W_Z {row['delassus']}, sparse solves {row['solves']}, "
                      f"GMRES {row['krylov']} (state) / {row['adjoint_krylov']} (adjoint), nnz(L)/nnz(A) "
                      f"{row['nnz_factor'] / row['nnz_A']:.1f}, PARDISO {row['pardiso_gb']:.2f} GB; "
                      f"eval/Cholesky {row['evaluation'] / spd['seconds']:.2f} (Cholesky {spd['seconds']:.2f} s, "
                      f"{spd['peak_gb']:.2f} GB)", flush=True)
                rows.append(row)
    with open("/proc/loadavg") as f:
        print(f"machine after: load average {' '.join(f.read().split()[:3])}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
