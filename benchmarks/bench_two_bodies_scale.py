"""Two bodies at scale: Example 1 on its elastic slab (examples/example1_elastic.toml), body and
slab refined together, one evaluation (state + subgradient) on a path, as a ratio to one clean
PARDISO Cholesky of a matrix of the same size.

    python benchmarks/bench_two_bodies_scale.py                      # 200k, 367k, fullspace
    python benchmarks/bench_two_bodies_scale.py --sizes 367k --paths condensation fullspace
    python benchmarks/bench_two_bodies_scale.py --sizes 1m
    python benchmarks/bench_two_bodies_scale.py --paths fullspace petsc     # PETSc on one process

Each (size, path) runs in its own child process (its peak RSS its own). The child builds the
problem, evaluates at α0, α1 = α0 + h·d and α2 = α0 + 2h·d (an optimization's steps, as
benchmarks/bench_scale.py does) and reports the time at α2 with its Newton steps and Krylov
iterations (state and adjoint), the set-up time and the peak RSS; the ratio of the CPU times
(the evaluation's and the reference's process time) beside the ratio of wall times, the steadier
of the two on a machine shared with other jobs. It saves diag(A(α2), K_f) —
both bodies' stiffness, the size of the two-body system — and, once the child has exited, the
parent times contactopt's PARDISO Cholesky (``linsolve.factorize``, analysis included) of that
matrix in a clean process: the reference of the ratio. Timings with one BLAS thread.
``--brick`` adds a second yardstick, the issue's wording of it: the same clean-process Cholesky of
one brick of about as many DOFs (Example 1's body refined alone, each side by the cube root of the
two bodies' DOFs over the body's) — one connected body, whose factor fills more than the two
bodies' block-diagonal matrix does.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_scale import _peak_rss_gb, clean_spd_factorization, design_direction

ROOT = Path(__file__).resolve().parents[1]
ELASTIC = ROOT / "examples" / "example1_elastic.toml"
# (body nx, ny, nz), (slab cells): the slab 3 × 2 × 1 under the body 2 × 1 × 1, refined with it
SIZES = {"15k": ((32, 15, 9), (24, 16, 8)), "200k": ((64, 30, 18), (48, 32, 16)),
         "367k": ((80, 37, 22), (60, 40, 20)), "1m": ((112, 52, 31), (84, 56, 28))}


def two_bodies(key, path):
    """The configuration of size ``key`` (``SIZES``) on ``path``, no memory check."""
    from contactopt.config import load_config
    (nx, ny, nz), cells = SIZES[key]
    base = load_config(ELASTIC)
    return base.with_updates({"mesh": {"nx": nx, "ny": ny, "nz": nz},
                              "foundation": {**base.to_dict()["foundation"],
                                             "block": {**base.to_dict()["foundation"]["block"], "cells": list(cells)}},
                              "linear_solver": {"path": path, "memory_check": False}})


def child(key, path, step, out_dir):
    import scipy.sparse as sp

    from contactopt._threads import sequential_openblas
    from contactopt.problem import ShapeProblem
    from contactopt.sensitivity.adjoint import subgradient

    cfg = two_bodies(key, path)
    t0 = time.perf_counter()
    problem = ShapeProblem(cfg)
    t_setup = time.perf_counter() - t0
    model = problem.model
    fnd = model.foundation
    a0 = model.initial_design()
    d = design_direction(model)
    a1, a2 = a0 + step * d, a0 + 2 * step * d
    with sequential_openblas():
        t0 = time.perf_counter()
        subgradient(problem, a0)
        t_first = time.perf_counter() - t0
        t0 = time.perf_counter()
        subgradient(problem, a1)
        t_second = time.perf_counter() - t0
        t0, c0 = time.perf_counter(), time.process_time()
        res = subgradient(problem, a2)
        t_eval, cpu_eval = time.perf_counter() - t0, time.process_time() - c0
    st = res.state
    A = problem.cached_system(a2).assembled.A
    if A is None:                      # the PETSc path forms A(α) on its ranks only
        A = model.assemble(a2).A
    K = fnd.K if fnd.K is not None else fnd.assembler.stiffness(fnd.mesh.reference.points)
    both = sp.block_diag([A, K], format="csr")
    a_file = Path(out_dir) / f"A_{key}_{path}.npz"
    sp.save_npz(a_file, both, compressed=False)
    row = dict(size=key, path=problem.path.name, n_body=int(model.assembler.n_free), n_slab=int(fnd.assembler.n_free),
               p=int(model.n_contact), setup=t_setup, first=t_first, second=t_second, evaluation=t_eval, evaluation_cpu=cpu_eval,
               newton=int(st.iterations), krylov=st.info.get("krylov_iterations"),
               adjoint_krylov=st.info.get("adjoint_krylov"), zone=st.info.get("zone_nodes"),
               peak_gb=_peak_rss_gb(), A_file=str(a_file), theta=float(res.value))
    print(json.dumps(row), flush=True)


def brick_matrix(key, n_target, out_dir):
    """The stiffness of Example 1's body alone with about ``n_target`` free DOFs, saved (its file)."""
    import scipy.sparse as sp

    from contactopt.config import load_config
    from contactopt.fem.model import ElasticModel
    (nx, ny, nz), _ = SIZES[key]
    body = ElasticModel(load_config("example1").with_updates({"mesh": {"nx": nx, "ny": ny, "nz": nz},
                                                              "linear_solver": {"memory_check": False}}))
    f = (n_target / body.assembler.n_free) ** (1.0 / 3.0)
    model = ElasticModel(load_config("example1").with_updates(
        {"mesh": {"nx": round(nx * f), "ny": round(ny * f), "nz": round(nz * f)}, "linear_solver": {"memory_check": False}}))
    A = model.assemble(model.initial_design()).A
    a_file = Path(out_dir) / f"brick_{key}.npz"
    sp.save_npz(a_file, sp.csr_matrix(A), compressed=False)
    return a_file, A.shape[0]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["200k", "367k"], choices=list(SIZES))
    ap.add_argument("--paths", nargs="+", default=["fullspace"], choices=("condensation", "fullspace", "petsc", "auto"))
    ap.add_argument("--step", type=float, default=2e-3)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--brick", action="store_true", help="also time the Cholesky of one brick of as many DOFs")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args.child[0], args.child[1], args.step, args.child[2])
        return
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    print("| DOFs (body + slab) | path | evaluation s | reference s | ratio | ratio of CPU times | peak GB | Newton | "
          "Krylov (state) | Krylov (adjoint) | set-up s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for key in args.sizes:
            for path in args.paths:
                out = subprocess.run([sys.executable, __file__, "--child", key, path, tmp, "--step", str(args.step)],
                                     capture_output=True, text=True, env=env, cwd=Path(__file__).parent)
                if out.returncode:
                    print(f"| {key} | {path} | failed: {out.stderr.strip().splitlines()[-1][:200]} |", flush=True)
                    continue
                row = json.loads(out.stdout.strip().splitlines()[-1])
                ref = clean_spd_factorization(row["A_file"], args.repeat)
                print(f"| {row['n_body']:,} + {row['n_slab']:,} | {row['path']} | {row['evaluation']:.2f} | "
                      f"{ref['seconds']:.2f} | {row['evaluation'] / ref['seconds']:.2f} | "
                      f"{row['evaluation_cpu'] / ref['cpu_seconds']:.2f} | {row['peak_gb']:.2f} | "
                      f"{row['newton']} | {row['krylov']} | {row['adjoint_krylov']} | {row['setup']:.1f} |", flush=True)
                Path(row["A_file"]).unlink()
                if args.brick:
                    b_file, n_brick = brick_matrix(key, row["n_body"] + row["n_slab"], tmp)
                    brick = clean_spd_factorization(b_file, args.repeat)
                    print(f"|   one brick of {n_brick:,} DOFs: Cholesky {brick['seconds']:.2f} s "
                          f"({brick['cpu_seconds']:.2f} s CPU): ratio {row['evaluation'] / brick['seconds']:.2f}, "
                          f"of CPU times {row['evaluation_cpu'] / brick['cpu_seconds']:.2f} |", flush=True)
                    Path(b_file).unlink()


if __name__ == "__main__":
    main()
