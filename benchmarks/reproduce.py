"""Reproduction of the paper's Examples 1–3 and of the manufactured-target case (REPRODUCTION.md).

    python benchmarks/reproduce.py [--cases example1 example2 example3 manufactured] [--out runs/reproduce]

Each case is one ``contactopt run`` under ``/usr/bin/time -v`` (wall time and peak memory of the
whole command, outputs included), in its own run directory. From the run directory the script
reads summary.json and iterations.csv and reports, beside the paper's figures:
J0, Jopt, Jopt/J0, iterations and evaluations, the stopping test that ended the run (summary.json
``status`` and ``stopping``), the iterations after which the certified test would have held for
ε = 1e-3 and 1e-4 (the test is made at the start of every iteration on the same deterministic
sequence, so a run with the larger ε stops exactly there), the (evaluation, iteration) at which
J/J0 first reached the paper's Jopt/J0, wall time, peak memory and max |α − α_paper|. The
manufactured case reports max |α − α*| instead.
Results go to ``<out>/reproduction.json`` and the figures to ``docs/figures/``; the tables of
REPRODUCTION.md and the run figures quoted in the README (between ``<!-- reproduce.py:NAME -->``
markers) are rewritten from reproduction.json at the end (``--docs-only`` rewrites them alone).
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from calibrate_examples import PAPER

ROOT = Path(__file__).resolve().parents[1]
CASES = {"example1": "example1", "example2": "example2", "example3": "example3",
         "manufactured": str(ROOT / "examples" / "manufactured.toml")}
PAPER_ITERATIONS = {"example1": (307, 12), "example2": (233, 20), "example3": (286, 24)}   # ε = 1e-4, 1e-3


def timed_run(config: str, out: Path) -> dict:
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "contactopt.cli", "run", config, "--out", str(out),
           "--overwrite"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", proc.stderr).group(1)
    parts = [float(x) for x in wall.split(":")]
    seconds = sum(v * 60 ** i for i, v in enumerate(reversed(parts)))
    rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr).group(1))
    return {"wall_time_command_s": seconds, "peak_memory_MB": rss_kb / 1024}


def first_below(rows, eps):
    """Iteration count at which BT's test max(‖p‖, α_p + σ) ≤ ε first holds (None: never)."""
    for r in rows:
        if float(r["stationarity"]) <= eps:
            return int(r["iteration"]) - 1, float(r["J"])
    return None


def first_reaching(out: Path, J0: float, ratio: float):
    """(evaluation, iteration) at which J/J0 ≤ ratio first holds at an evaluated design (None: never)."""
    with open(out / "history.csv") as fh:
        for r in csv.DictReader(fh):
            if float(r["f"]) <= ratio * J0:
                return int(r["evaluation"]), int(r["iteration"])
    return None


def case_result(name: str, out: Path, timing: dict) -> dict:
    s = json.loads((out / "summary.json").read_text())
    with open(out / "iterations.csv") as fh:
        rows = list(csv.DictReader(fh))
    alpha = np.asarray(s["alpha"])
    res = {"case": name, "J0": s["J0"], "J": s["J"], "ratio": s["ratio"], "iterations": s["iterations"],
           "evaluations": s["evaluations"], "serious": s["serious_steps"], "null": s["null_steps"],
           "success": s["success"], "status": s.get("status"), "stopping": s.get("stopping"),
           "message": s["message"], "admissible": s["admissible"],
           "wall_time_run_s": s["wall_time_s"], **timing}
    for eps in (1e-3, 1e-4):
        hit = first_below(rows, eps)
        res[f"iterations_eps_{eps:.0e}"] = None if hit is None else hit[0]
        res[f"ratio_eps_{eps:.0e}"] = None if hit is None else hit[1] / s["J0"]
    if name in PAPER:
        ref = PAPER[name]
        res.update(paper_J0=ref["J0"], paper_Jopt=ref["Jopt"], paper_ratio=ref["Jopt"] / ref["J0"],
                   paper_iterations=PAPER_ITERATIONS[name],
                   max_abs_alpha_minus_paper=float(np.abs(alpha - np.asarray(ref["alpha"])).max()),
                   evaluations_to_paper_ratio=first_reaching(out, s["J0"], ref["Jopt"] / ref["J0"]))
    else:
        from contactopt.config import load_config
        star = np.asarray(load_config(CASES[name])["objective"]["target"]["alpha"], float)
        res["max_abs_alpha_minus_star"] = float(np.abs(alpha - star).max())
        res["ratio_target"] = 1e-6
    return res


def reference_factorization(repeat: int = 5) -> float:
    """Median time of one factorization (analysis included) of Example 1's A(α0): the machine's
    speed at the time of a run, measured before and after it (a shared machine drifts)."""
    code = ("import statistics, time; from contactopt import ShapeProblem, load_config; "
            "from contactopt.fem.linsolve import factorize; "
            "pr = ShapeProblem(load_config('example1')); A = pr.model.assemble(pr.model.initial_design()).A; "
            "factorize(A).close(); ts = []\n"
            f"for _ in range({repeat}):\n"
            "    t0 = time.perf_counter(); factorize(A).close(); ts.append(time.perf_counter() - t0)\n"
            "print(statistics.median(ts))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


BEST_J = {"example1": 8.3545e-8, "example2": 1.3148e-6, "example3": 1.5325e-7}   # long runs, REPRODUCTION.md


def _stop(r) -> str:
    st = r.get("stopping") or {}
    crit = st.get("criterion")
    if crit == "predicted_decrease":
        text = f"predicted decrease {st['J_tolerance']:.1e} < ftol {st['ftol']:.0e}"
    elif crit == "stationarity":
        text = f"stationarity {st['stationarity']:.1e} ≤ ε = {st['eps']:.0e}"
    else:
        text = str(crit)
    return text + (", `success: true`" if r["success"] else ", `success: false`")


def render_results(results: dict) -> dict:
    """The generated blocks of REPRODUCTION.md and README.md from reproduction.json."""
    ex = [n for n in ("example1", "example2", "example3") if n in results]
    head = "| | " + " | ".join(f"Ex. {n[-1]} paper | Ex. {n[-1]} ours" for n in ex) + " |"
    sep = "|---|" + "---|---|" * len(ex)

    def row(label, paper, ours):
        return f"| {label} | " + " | ".join(f"{paper(results[n])} | {ours(results[n])}" for n in ex) + " |"

    dash = lambda r: "–"                                            # noqa: E731
    lines = [head, sep,
             row("J0", lambda r: f"{r['paper_J0']:.4e}", lambda r: f"{r['J0']:.4e}"),
             row("Jopt (÷ best known)", lambda r: f"{r['paper_Jopt']:.4e}",
                 lambda r: f"{r['J']:.4e} ({r['J'] / BEST_J[r['case']]:.4f})"),
             row("**Jopt/J0**", lambda r: f"{r['paper_ratio']:.3g}", lambda r: f"**{r['ratio']:.3g}**"),
             row("stopped by", lambda r: f"ε = 1e-4, {r['paper_iterations'][0]} iterations", _stop),
             row("evaluations", dash, lambda r: f"**{r['evaluations']}**"),
             row("iterations; serious / null steps", dash,
                 lambda r: f"{r['iterations']}; {r['serious']} / {r['null']}"),
             row("evaluations to the paper's Jopt/J0", dash,
                 lambda r: str((r.get("evaluations_to_paper_ratio") or ["–"])[0])),
             row("wall time (whole command)", dash, lambda r: f"{r['wall_time_command_s']:.0f} s"),
             row("reference factorization around it", dash, lambda r: f"{r['reference_factorization_s']:.2f} s"),
             row("peak memory", dash, lambda r: f"{r['peak_memory_MB']:.0f} MB"),
             row("max \\|α − α_paper\\|", dash, lambda r: f"{r['max_abs_alpha_minus_paper']:.4f}")]
    blocks = {"results": "\n".join(lines)}
    if "manufactured" in results:
        m = results["manufactured"]
        blocks["manufactured"] = "\n".join([
            "| J0 | J | J/J0 (goal ≤ 1e-6) | max \\|α − α*\\| (goal ≤ 1e-3) | stopped by | evaluations | wall time, peak memory |",
            "|---|---|---|---|---|---|---|",
            f"| {m['J0']:.4e} | {m['J']:.3g} | **{m['ratio']:.2g}** | **{m['max_abs_alpha_minus_star']:.2g}** | "
            f"{_stop(m)} | **{m['evaluations']}** | {m['wall_time_command_s']:.0f} s, {m['peak_memory_MB']:.0f} MB |"])
    if "example1" in results:
        r = results["example1"]
        blocks["example1"] = (f"{r['evaluations']} evaluations, {r['wall_time_command_s']:.0f} s on a 2-core "
                              f"machine in the REPRODUCTION.md run")
    return blocks


def update_docs(results: dict) -> None:
    """Rewrite every ``<!-- reproduce.py:NAME -->…<!-- /reproduce.py:NAME -->`` block."""
    blocks = render_results(results)
    for doc in (ROOT / "REPRODUCTION.md", ROOT / "README.md"):
        text = doc.read_text()
        for name, body in blocks.items():
            pat = re.compile(rf"(<!-- reproduce.py:{name} -->)(.*?)(<!-- /reproduce.py:{name} -->)", re.S)
            sep = "\n" if name in ("results", "manufactured") else ""
            text = pat.sub(lambda m: m.group(1) + sep + body + sep + m.group(3), text)
        doc.write_text(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--out", default=str(ROOT / "runs" / "reproduce"))
    ap.add_argument("--docs-only", action="store_true", help="rewrite the documents from reproduction.json")
    args = ap.parse_args()
    if args.docs_only:
        update_docs(json.loads((Path(args.out) / "reproduction.json").read_text()))
        return
    base = Path(args.out)
    base.mkdir(parents=True, exist_ok=True)
    figures = ROOT / "docs" / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    results_path = base / "reproduction.json"
    results = json.loads(results_path.read_text()) if results_path.exists() else {}
    for name in args.cases:
        out = base / name
        print(f"== {name}: contactopt run {CASES[name]} --out {out}", flush=True)
        t_ref = reference_factorization()
        timing = timed_run(CASES[name], out)
        timing["reference_factorization_s"] = 0.5 * (t_ref + reference_factorization())
        r = case_result(name, out, timing)
        results[name] = r
        results_path.write_text(json.dumps(results, indent=1))
        for png in ("stress.png", "surface.png", "history.png", "classes.png"):
            shutil.copy(out / png, figures / f"{name}_{png}")
        print(json.dumps(r, indent=1), flush=True)
    update_docs(results)


if __name__ == "__main__":
    main()
