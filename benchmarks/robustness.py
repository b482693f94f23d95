"""The state solve at random designs of the box [lower, C0] of each configuration: does every one
converge, with how many Newton steps, which fallbacks (contactopt.contact.fallback) and how long
against the solve at α0.

    python benchmarks/robustness.py                        # every shipped configuration, 5 designs
    python benchmarks/robustness.py examples/roller_rigid.toml --designs 50
    python benchmarks/robustness.py examples/roller_rigid.toml --designs 50 --cli   # via `contactopt state --alpha`
    python benchmarks/robustness.py --generated 0 1 2 --designs 3   # generated variants (verification.robustness)

Each design draws every control point uniformly from its box (the slope and volume rows of U are
not imposed: any design of the box gives a valid mesh, and the state must exist there). Prints one
table row per configuration, or per design with --cli; --json writes the rows. Run it under two
BLAS kernels with OPENBLAS_CORETYPE=Haswell / Prescott (docs/robustness.md).
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

from contactopt.verification.robustness import box_designs, generated_variants, random_design_solves

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ["example1", "example2", "example3"] + sorted(str(p.relative_to(ROOT)) for p in (ROOT / "examples").glob("*.toml"))


def run_cli(name: str, n: int, seed: int) -> list[dict]:
    """Each design through ``contactopt state --alpha``; the row from its state.json."""
    from contactopt.problem import ShapeProblem
    model = ShapeProblem(name).model
    designs = [None] + box_designs(model, n, seed)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, alpha in enumerate(designs):
            out = Path(tmp) / f"s{k}"
            cmd = [sys.executable, "-m", "contactopt.cli", "state", name, "--out", str(out)]
            if alpha is not None:
                (Path(tmp) / f"a{k}.json").write_text(json.dumps({"alpha": alpha.tolist()}))
                cmd += ["--alpha", str(Path(tmp) / f"a{k}.json")]
            t0 = time.perf_counter()
            p = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy())
            row = {"design": "alpha0" if alpha is None else k, "exit": p.returncode, "wall_s": time.perf_counter() - t0}
            if p.returncode == 0:
                s = json.loads((out / "state.json").read_text())["summary"]
                row.update(converged=s["converged"], newton_steps=s["iterations"], fallback=s.get("fallback"),
                           solves=s.get("obstacle_solves"), state_s=s["timings_s"]["total"])
            else:
                row["error"] = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ""
            rows.append(row)
            print(json.dumps(row), flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("configs", nargs="*", default=SHIPPED)
    ap.add_argument("--designs", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cli", action="store_true", help="through `contactopt state --alpha`, one row per design")
    ap.add_argument("--json", help="write the rows to this file")
    ap.add_argument("--generated", type=int, nargs="+", metavar="SEED",
                    help="the generated variants of these seeds instead of the configurations")
    args = ap.parse_args(argv)
    rows = []
    if args.generated:
        with tempfile.TemporaryDirectory() as tmp:
            # each variant's designs drawn with its own seed, as the robustness tier does
            return report(args, [(c, name, seed) for seed in args.generated for name, c in generated_variants(seed, tmp)],
                          rows)
    return report(args, [(name, None, args.seed) for name in args.configs], rows)


def report(args, configs, rows) -> int:
    """Solve each configuration (``(config, name, seed)``), print its row, write --json; the exit status."""
    for name, label, seed in configs:
        if args.cli:
            rows += run_cli(name, args.designs, args.seed)
            continue
        row = random_design_solves(name, args.designs, seed, label)
        rows.append(row)
        print(f"{row['config']:40s} {row['converged']:3d}/{row['designs']:<3d} converged, fallbacks {row['fallbacks']} "
              f"{row['fallbacks_used']}, Newton steps <= {row['newton_steps_max']}, "
              f"{row['time_mean_s']:.2f} s per solve (α0 {row['time_alpha0_s']:.2f} s)"
              + (f"; failed: {row['failures']}" if row["failures"] else ""), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    ok = [r["exit"] == 0 and r["converged"] if args.cli else r["alpha0_converged"] and r["converged"] == r["designs"]
          for r in rows]
    return 0 if all(ok) else 1

if __name__ == "__main__":
    sys.exit(main())
