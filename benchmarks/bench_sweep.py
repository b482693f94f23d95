"""Speed-up of a sweep with 2 worker processes over 1 (LocalCluster, 1 MKL/BLAS thread per task).

The sweep is 4 friction coefficients (0, 0.1, 0.2, 0.3) of Example 1 on a coarse mesh with a
fixed number of bundle iterations (ε tiny, so every task runs all of them and the tasks take
about the same time). Per configuration it reports the task phase (connected to the cluster ->
last task finished) and the whole call (cluster start and stop included); rounds alternate
1 and 2 workers so that a drift of the machine's speed hits both alike. The ratio is computed
within each round.

    python benchmarks/bench_sweep.py [--rounds 2] [--nx 16 --ny 8 --nz 5] [--max-iter 40]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from contactopt.config import load_config
from contactopt.studies import run_sweep

FRICTIONS = [0.0, 0.1, 0.2, 0.3]


def one_sweep(cfg, workers: int, max_iter: int) -> tuple[float, float, float]:
    marks = {}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = run_sweep(cfg, [("friction.coefficient", FRICTIONS)], Path(tmp) / "sw", workers=workers,
                        threads=1, max_iter=max_iter, eps=1e-12, plots=False, dashboard_address=":0",
                        on_client=lambda c, d: marks.setdefault("start", time.perf_counter()),
                        progress=lambda row, done, total: marks.__setitem__("end", time.perf_counter()))
        total = time.perf_counter() - t0
    if res.n_failed:
        raise SystemExit(f"{res.n_failed} task(s) failed: {[r['error'] for r in res.rows if r['error']]}")
    # the tasks' own wall times: their sum over the task phase is the parallelism achieved
    return marks["end"] - marks["start"], total, sum(r["wall_time_s"] for r in res.rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--nx", type=int, default=16)
    ap.add_argument("--ny", type=int, default=8)
    ap.add_argument("--nz", type=int, default=5)
    ap.add_argument("--max-iter", type=int, default=40)
    args = ap.parse_args()
    cfg = load_config("example1").with_updates({"mesh": {"nx": args.nx, "ny": args.ny, "nz": args.nz}})
    print(f"sweep of 4 friction coefficients, mesh {args.nx}x{args.ny}x{args.nz}, {args.max_iter} BT "
          f"iterations per task, {os.cpu_count()} cores; load average before: {os.getloadavg()}")
    ratios = []
    for r in range(args.rounds):
        t1, w1, s1 = one_sweep(cfg, 1, args.max_iter)
        t2, w2, s2 = one_sweep(cfg, 2, args.max_iter)
        ratios.append((t1 / t2, w1 / w2))
        print(f"round {r + 1}: 1 worker tasks {t1:6.1f}s (call {w1:6.1f}s) | 2 workers tasks {t2:6.1f}s "
              f"(call {w2:6.1f}s) | speed-up tasks {t1 / t2:.2f}, whole call {w1 / w2:.2f} | one task "
              f"{s2 / s1:.2f}x slower with 2 workers (shared cores), load {os.getloadavg()[0]:.2f}", flush=True)
    print(f"load average after: {os.getloadavg()}")
    best = max(ratios)
    print(f"speed-up 2 workers / 1 worker: task phase {', '.join(f'{a:.2f}' for a, _ in ratios)}; "
          f"whole call {', '.join(f'{b:.2f}' for _, b in ratios)} (best round {best[0]:.2f})")


if __name__ == "__main__":
    main()
