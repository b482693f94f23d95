"""The cost of a run's figures against one state solve, measured in one process.

``MKL_NUM_THREADS=1 PYTHONPATH=src python benchmarks/bench_outputs.py [--repeat 3]`` solves
Example 1's state at α0 and at a nearby design (cold starts, as the run's outputs do), then draws
the seven figures of a run (contactopt.runner's figures: stress, pressure, surface, classes,
contact, von Mises, history of 120 iterations) into a temporary directory. It prints, per figure
and in total, the wall and CPU seconds and the total as a multiple of one state solve (in wall
and in CPU time: on a busy machine the CPU ratio is the one to read), the median over
``--repeat`` rounds. Ratios, not seconds, are what carry over between machines.

``--run [--max-iter N]`` instead runs ``contactopt run example1`` in this process (into a
temporary directory, figures included) and prints the run's wall time, the time after its last
evaluation (``runner._finish``: the result files, figures and summary) in wall and CPU seconds,
one evaluation's median wall and CPU time (state solve, adjoint and subgradient, timed around
each call of the run's oracle), and their ratio: what the outputs cost in evaluations of the same
run; the CPU time counts the process that draws figures beside the run's own (io/forked.py).
The script reads nothing but ``runner._finish`` and ``runner._Oracle``, so that it measures an
older checkout as well (``PYTHONPATH=<checkout>/src``).
"""

from __future__ import annotations

import argparse
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.io import plots
from contactopt.io.pressure import contact_pressure
from contactopt.problem import ShapeProblem


def run_phases(max_iter: int | None) -> None:
    """A whole run of Example 1 with its phase after the last evaluation timed (module docstring)."""
    from contactopt import runner

    evals, finish = [], {}
    real_call, real_finish = runner._Oracle.__call__, runner._finish

    def call(self, x):
        t, c = time.perf_counter(), time.process_time()
        try:
            return real_call(self, x)
        finally:
            evals.append((time.perf_counter() - t, time.process_time() - c))

    def children() -> float:
        use = resource.getrusage(resource.RUSAGE_CHILDREN)
        return use.ru_utime + use.ru_stime

    def timed_finish(*args, **kwargs):
        t, c, k = time.perf_counter(), time.process_time(), children()
        try:
            return real_finish(*args, **kwargs)
        finally:
            finish["wall"], finish["cpu"] = time.perf_counter() - t, time.process_time() - c
            finish["children"] = children() - k

    runner._Oracle.__call__, runner._finish = call, timed_finish
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        s = runner.run_optimization("example1", Path(tmp) / "run", max_iter=max_iter).summary
        total = time.perf_counter() - t
    ev_wall = statistics.median(e[0] for e in evals)
    ev_cpu = statistics.median(e[1] for e in evals)
    print(f"contactopt run example1{f' --max-iter {max_iter}' if max_iter else ''}: {s['evaluations']} "
          f"evaluations, J = {s['J']!r}")
    print(f"total wall {total:.2f} s; one evaluation (median of {len(evals)}): {ev_wall:.3f} s wall, "
          f"{ev_cpu:.3f} s cpu")
    cpu = finish["cpu"] + finish["children"]
    print(f"after the last evaluation: {finish['wall']:.2f} s wall = {finish['wall'] / ev_wall:.2f} evaluations, "
          f"{cpu:.2f} s cpu = {cpu / ev_cpu:.2f} evaluations (of which {finish['children']:.2f} s in a "
          "child process)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--run", action="store_true", help="time a whole run's phase after its last evaluation")
    ap.add_argument("--max-iter", type=int, default=None)
    args = ap.parse_args()
    if args.run:
        run_phases(args.max_iter)
        return
    pb = ShapeProblem(load_config("example1"))
    m = pb.model
    a0 = m.initial_design()
    a1 = a0 + 0.002 * np.linspace(-1.0, 1.0, a0.size)
    pb.solve_state(a0)                       # the first solve sets up the mesh and the factorization
    solves, solves_cpu = [], []
    for _ in range(args.repeat):
        t, c = time.perf_counter(), time.process_time()
        s0 = pb.solve_state(a0, warm_start=False)
        s1 = pb.solve_state(a1, warm_start=False)
        solves.append((time.perf_counter() - t) / 2)
        solves_cpu.append((time.process_time() - c) / 2)
    solve, solve_cpu = statistics.median(solves), statistics.median(solves_cpu)
    p0, p1 = contact_pressure(m, s0.lam, s0.coords), contact_pressure(m, s1.lam, s1.coords)
    hist = [{"iteration": i, "f": 1.0 / (i + 1), "kind": "serious" if i % 2 else "null",
             "stationarity": 0.1 / (i + 1)} for i in range(120)]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        figures = {
            "stress": lambda: plots.plot_stress_comparison(out / "stress.png", m, np.zeros_like(s0.lam), s0.lam, s1.lam),
            "pressure": lambda: plots.plot_stress_comparison(out / "pressure.png", m, p1, p0, p1),
            "surface": lambda: plots.plot_surface(out / "surface.png", m, a1),
            "classes": lambda: plots.plot_node_classes(out / "classes.png", m, s1.classes),
            "contact": lambda: plots.plot_contact_response(out / "contact.png", m, p1, s1.tau, s1.u_c[:, :2],
                                                           s1.classes, title="optimal design"),
            "von_mises": lambda: plots.plot_peak_stress(out / "von_mises.png", m, s1.coords, s1.u, title="optimal design"),
            "history": lambda: plots.plot_history(out / "history.png", hist),
        }
        plots.plot_history(out / "warm-up.png", hist)       # fonts and mathtext loaded once per process
        wall = {k: [] for k in figures}
        cpu = {k: [] for k in figures}
        for _ in range(args.repeat):
            for name, draw in figures.items():
                t, c = time.perf_counter(), time.process_time()
                draw()
                wall[name].append(time.perf_counter() - t)
                cpu[name].append(time.process_time() - c)
    print(f"one state solve (cold start, median of {2 * args.repeat}): {solve:.3f} s wall, {solve_cpu:.3f} s cpu")
    print(f"{'figure':10s} {'wall s':>8s} {'cpu s':>8s}")
    for name in figures:
        print(f"{name:10s} {statistics.median(wall[name]):8.3f} {statistics.median(cpu[name]):8.3f}")
    total = sum(statistics.median(v) for v in wall.values())
    total_cpu = sum(statistics.median(v) for v in cpu.values())
    print(f"{'all':10s} {total:8.3f} {total_cpu:8.3f}   = {total / solve:.2f} state solves (wall), "
          f"{total_cpu / solve_cpu:.2f} (cpu)")


if __name__ == "__main__":
    main()
