"""Large meshes (issue #16), ≥ 900k DOFs: one evaluation (state + adjoint) at a next design by the
full-space semismooth Newton with AMG-preconditioned GMRES (contactopt.contact.fullspace,
contactopt.sensitivity.adjoint_fullspace), with its parts and peak memory.

    python benchmarks/bench_fullspace.py --sizes 15k 113k
    flock /tmp/contactopt-bench.lock python benchmarks/bench_fullspace.py --sizes 867k

The sizes are bench_scale.py's refinements of Example 1 (imported from it: 867k = 128×60×36,
866 688 DOFs). Every size runs in its own child process (peak RSS of its own, ``ru_maxrss``). The
child builds the model (no memory check: that estimate is today's Schur path's), assembles
A(α0), solves the state cold (r = 0, the AMG hierarchy built there) and its subgradient (the
adjoint (4.15) in full space), then at the next design α1 = α0 + h·d (h = ``--step``, d as in
bench_scale.py: volume-preserving, max |d| = 1) assembles A(α1), solves the state warm — from α0's
forces and displacement, with α0's hierarchy — and the adjoint warm from α0's, with the same
hierarchy, then the design terms of the subgradient. The evaluation at α1 is assembly + state +
objective + adjoint + design terms (the hierarchy is reused, so no AMG setup in it);
``--forces-only`` warm-starts the state from α0's forces alone (u by one Krylov solve first).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scale import SIZES, _peak_rss_gb, _shape, design_direction  # noqa: E402

GOAL_S, GOAL_GB = 120.0, 16.0      # issue #16 at ≥ 900k DOFs: one evaluation, peak memory


def child(shape, step, tol, forces_only):
    from types import SimpleNamespace

    import numpy as np

    from contactopt.config import load_config
    from contactopt.contact.fullspace import solve_fullspace
    from contactopt.fem.model import ElasticModel
    from contactopt.sensitivity.adjoint_fullspace import subgradient_fullspace
    from contactopt.sensitivity.objectives import make_objective

    nx, ny, nz = shape
    cfg = load_config("example1").with_updates({"mesh": {"nx": nx, "ny": ny, "nz": nz},
                                                "linear_solver": {"memory_check": False}})
    t0 = time.perf_counter()
    model = ElasticModel(cfg)
    t_model = time.perf_counter() - t0
    friction = float(cfg["friction"]["coefficient"])
    objective = make_objective(cfg, SimpleNamespace(model=model))
    n, p = model.assembler.n_free, model.n_contact
    rss_model = _peak_rss_gb()
    a0 = model.initial_design()
    d = design_direction(model)
    a1 = a0 + step * d
    if not model.admissible.is_feasible(a1):
        raise SystemExit("the next design is not admissible: lower --step")
    objective.target                                  # noqa: B018 (computed once, outside the timings)

    def solve(asm, **kw):
        return solve_fullspace(asm.A, asm.L, model.contact_dofs, asm.gap, friction, coords=asm.coords,
                               free=model.assembler.free, tol=tol, **kw)

    # α0: cold start, the hierarchy is built here
    t0 = time.perf_counter()
    asm0 = model.assemble(a0)
    t_asm0 = time.perf_counter() - t0
    t0 = time.perf_counter()
    res0 = solve(asm0)
    t_state0 = time.perf_counter() - t0
    t0 = time.perf_counter()
    _, _, _, adj0, _ = subgradient_fullspace(model, objective, a0, asm0, res0, friction)
    t_adj0 = time.perf_counter() - t0
    r0, u0, v0, hier = res0.r, res0.u, adj0.v, res0.hierarchy
    nnz_A = int(asm0.A.nnz)
    del asm0, res0, adj0
    rss_first = _peak_rss_gb()
    # α1: the evaluation
    t0 = time.perf_counter()
    asm1 = model.assemble(a1)
    t_asm = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = solve(asm1, r0=r0, u0=None if forces_only else u0, hierarchy=hier)
    t_state = time.perf_counter() - t0
    value, xi, state, adj, tparts = subgradient_fullspace(model, objective, a1, asm1, res, friction, v0=v0)
    t_eval = t_asm + t_state + sum(tparts.values())
    row = dict(shape=shape, n=n, p=p, nnz_A=nnz_A, step=step, tol=tol, forces_only=forces_only, model_s=t_model,
               levels=hier.sizes(), operator_complexity=hier.operator_complexity, amg_setup=hier.setup_seconds,
               first_assembly=t_asm0, first_state=t_state0, first_subgradient=t_adj0, line_search=res.steps,
               evaluation=t_eval, assembly=t_asm, state=t_state, state_parts=res.timings,
               newton_steps=res.newton_steps, krylov_per_step=res.krylov_iterations, krylov_rtol=res.krylov_rtol,
               error_history=res.history, error=res.error, equilibrium=res.equilibrium,
               classes=res.info["class_counts"], node_classes=state.counts,
               adjoint=tparts["adjoint"], adjoint_krylov=adj.iterations, adjoint_parts=adj.timings,
               objective=tparts["objective"], design_terms=tparts["design_terms"], value=value,
               gradient_norm=float(np.linalg.norm(xi)),
               rss_model_gb=rss_model, rss_first_gb=rss_first, peak_gb=_peak_rss_gb())
    print(json.dumps(row))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", nargs="+", default=["113k"],
                    help=f"keys ({', '.join(f'{k}={v[0]}x{v[1]}x{v[2]}' for k, v in SIZES.items())}) or NXxNYxNZ")
    ap.add_argument("--step", type=float, default=5e-4, help="max |α1 − α0| of the next design")
    ap.add_argument("--tol", type=float, default=1e-10, help="Siconos error and equilibrium of the state")
    ap.add_argument("--forces-only", action="store_true", help="warm start from α0's forces only")
    ap.add_argument("--json", help="also write the rows to this file")
    ap.add_argument("--child", nargs=3, type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(tuple(args.child), args.step, args.tol, args.forces_only)
        return 0
    rows = []
    for key in args.sizes:
        shape = _shape(key)
        label = key if key in SIZES else "x".join(map(str, shape))
        cmd = [sys.executable, __file__, "--step", str(args.step), "--tol", str(args.tol),
               *(["--forces-only"] if args.forces_only else []), "--child", *map(str, shape)]
        t0 = time.perf_counter()
        out = subprocess.run(cmd, capture_output=True, text=True)
        if out.returncode:
            print(f"{label}: failed (exit {out.returncode}): {out.stderr.strip()[-2000:]}", flush=True)
            continue
        row = json.loads(out.stdout.strip().splitlines()[-1])
        row["wall_s"] = time.perf_counter() - t0
        sp_ = row["state_parts"]
        ok = "meets" if row["evaluation"] <= GOAL_S and row["peak_gb"] <= GOAL_GB else "misses"
        print(f"{label}: {row['n']} DOFs, {row['p']} contact nodes, nnz(A) {row['nnz_A']}; model {row['model_s']:.1f} s; "
              f"AMG {len(row['levels'])} levels {row['levels']}, op. complexity {row['operator_complexity']:.2f}, "
              f"setup {row['amg_setup']:.1f} s; first state (cold, α0): assembly {row['first_assembly']:.1f} s, "
              f"state {row['first_state']:.1f} s, adjoint + design terms {row['first_subgradient']:.1f} s", flush=True)
        print(f"  evaluation at α1 = α0 + {row['step']:g}·d (warm from α0's {'forces' if row['forces_only'] else 'forces, u'} "
              f"and hierarchy): {row['evaluation']:.1f} s [{ok} the goal ≤ {GOAL_S:g} s, ≤ {GOAL_GB:g} GB]: "
              f"assembly {row['assembly']:.1f}, state {row['state']:.1f} (start solve {sp_['start']:.1f}, preconditioner "
              f"updates {sp_['preconditioner']:.1f}, Krylov {sp_['krylov']:.1f}, Newton {sp_['newton']:.1f}), "
              f"adjoint {row['adjoint']:.1f} ({row['adjoint_krylov']} GMRES it), design terms {row['design_terms']:.1f} s",
              flush=True)
        print(f"  state: {row['newton_steps']} Newton steps, GMRES iterations per step {row['krylov_per_step']}, "
              f"Siconos error {row['error']:.1e}, equilibrium {row['equilibrium']:.1e}; errors "
              f"{', '.join(f'{e:.1e}' for e in row['error_history'])}; line-search steps {row['line_search']}; "
              f"classes {row['node_classes']}", flush=True)
        print(f"  peak RSS {row['peak_gb']:.2f} GB (model {row['rss_model_gb']:.2f}, after the first state "
              f"{row['rss_first_gb']:.2f}); wall {row['wall_s']:.0f} s", flush=True)
        rows.append(row)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
