"""The optimizer under every OpenBLAS kernel: test problems and the paper's examples.

    python benchmarks/bench_kernels.py [--examples] [--cores Prescott Haswell SkylakeX Zen]

Each (problem or example, kernel) runs in its own process with ``OPENBLAS_CORETYPE`` set (numpy's
and scipy's bundled OpenBLAS honour it; the kernel that ran is read back with threadpoolctl).
Test problems: every problem of NONSMOOTH_TESTS.md, GOFFIN-50 and MAXLIN-60 with the default
options and ``eps = 1e-6``; relative error of f and evaluations. With ``--examples``: Examples 1–3
with the built-in defaults (``contactopt run``), J ÷ best known J, evaluations and the stop.
The tables go to docs/stopping.md (between ``<!-- bench_kernels.py:NAME -->`` markers) and the
raw results to ``runs/bench_kernels.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CORES = ["Prescott", "Haswell", "SkylakeX", "Zen"]
BEST_J = {"example1": 8.3545e-8, "example2": 1.3148e-6, "example3": 1.5325e-7}

PROBLEMS_CODE = """
import json
from threadpoolctl import threadpool_info
from contactopt.optimize import minimize_bundle
from contactopt.optimize.gallery import PROBLEMS, goffin_problem, max_linear_problem
probs = dict(PROBLEMS)
probs["GOFFIN-50"] = goffin_problem()
probs["MAXLIN-60"] = max_linear_problem(60)
out = {}
for name, p in probs.items():
    r = minimize_bundle(p, p.x0, eps=1e-6, max_iter=3000, **p.constraints())
    err = abs(r.fun - p.f_star) / (abs(p.f_star) if p.f_star else 1.0)
    out[name] = {"nfev": int(r.nfev), "error": float(err), "status": int(r.status)}
out["_kernel"] = sorted({str(i.get("architecture")) for i in threadpool_info() if i.get("internal_api") == "openblas"})
print(json.dumps(out))
"""

EXAMPLE_CODE = """
import json, sys
from threadpoolctl import threadpool_info
from contactopt.runner import run_optimization
s = run_optimization(sys.argv[1], sys.argv[2]).summary
print(json.dumps({"J": s["J"], "evaluations": s["evaluations"], "status": s["status"],
                  "success": s["success"], "criterion": s["stopping"]["criterion"],
                  "J_tolerance": s["stopping"].get("J_tolerance"), "wall_time_s": s["wall_time_s"],
                  "_kernel": sorted({str(i.get("architecture")) for i in threadpool_info()
                                     if i.get("internal_api") == "openblas"})}))
"""


def run(code: str, core: str, *args) -> dict:
    env = dict(os.environ, OPENBLAS_CORETYPE=core)
    proc = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{core}: {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def problems_table(res: dict) -> str:
    cores = list(res)
    names = [k for k in res[cores[0]] if not k.startswith("_")]
    lines = ["| problem | " + " | ".join(f"{c} ({'/'.join(res[c]['_kernel'])})" for c in cores)
             + " | largest relative error |", "|---|" + "---|" * (len(cores) + 1)]
    for n in names:
        cells = [f"{res[c][n]['nfev']}" + ("" if res[c][n]["status"] == 0 else f" (status {res[c][n]['status']})")
                 for c in cores]
        err = max(res[c][n]["error"] for c in cores)
        lines.append(f"| {n} | " + " | ".join(cells) + f" | {err:.1e} |")
    return "\n".join(lines)


def examples_table(res: dict) -> str:
    cores = list(res)
    names = sorted({k for c in cores for k in res[c]})
    lines = ["| example | " + " | ".join(cores) + " | spread of J |", "|---|" + "---|" * (len(cores) + 1)]
    for n in names:
        J = [res[c][n]["J"] for c in cores]
        cells = [f"{res[c][n]['J'] / BEST_J[n]:.4f}, {res[c][n]['evaluations']} ev."
                 + ("" if res[c][n]["success"] else f" ({res[c][n]['criterion']})") for c in cores]
        lines.append(f"| {n} | " + " | ".join(cells) + f" | {max(J) / min(J) - 1:.2%} |")
    return "\n".join(lines)


def write_block(name: str, body: str) -> None:
    doc = ROOT / "docs" / "stopping.md"
    text = doc.read_text()
    pat = re.compile(rf"(<!-- bench_kernels.py:{name} -->)(.*?)(<!-- /bench_kernels.py:{name} -->)", re.S)
    doc.write_text(pat.sub(lambda m: m.group(1) + "\n" + body + "\n" + m.group(3), text))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cores", nargs="+", default=CORES)
    ap.add_argument("--examples", action="store_true", help="also run Examples 1-3 (about 15 min)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="example runs at a time (their evaluations do not depend on it, their "
                         "wall times do)")
    args = ap.parse_args()
    out_path = ROOT / "runs" / "bench_kernels.json"
    out_path.parent.mkdir(parents=True, exist_ok=True)
    results = json.loads(out_path.read_text()) if out_path.exists() else {}
    probs = {c: run(PROBLEMS_CODE, c) for c in args.cores}
    results["problems"] = probs
    print(problems_table(probs), flush=True)
    write_block("problems", problems_table(probs))
    if args.examples:
        ex = {c: {} for c in args.cores}
        with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(args.jobs) as pool:
            jobs = {(c, n): pool.submit(run, EXAMPLE_CODE, c, n, str(Path(tmp) / f"{c}_{n}"))
                    for c in args.cores for n in BEST_J}
            for (c, n), job in jobs.items():
                ex[c][n] = job.result()
                print(c, n, json.dumps(ex[c][n]), flush=True)
        results["examples"] = ex
        write_block("examples", examples_table(ex))
        print(examples_table(ex))
    out_path.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
