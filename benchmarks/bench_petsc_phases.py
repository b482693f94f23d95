"""Memory per rank of the PETSc path, phase by phase: Example 1 on its elastic slab (two bodies,
the sizes of bench_two_bodies_scale.py) built, then evaluated at α0 and α1 = α0 + h·d as
bench_petsc.py does; every rank's resident memory at the boundaries of its phases (the problem's
set-up, the distributed rows, the PETSc matrices, the GAMG set-up, each Krylov solve of the Newton
method and of the adjoint, the design terms) and its peak between two of them (sampled every 20 ms).

    python benchmarks/bench_petsc_phases.py --size 200k --ranks 2
    python benchmarks/bench_petsc_phases.py --size 200k --ranks 2 --trim   # freed heap returned first

``--trim`` returns the freed heap to the system (glibc's malloc_trim) before each reading, so that
a reading is what the rank holds, not what its allocator kept of earlier peaks. Needs
petsc4py/mpi4py and mpiexec (README 'One optimization on many cores'). GB are 2^30 bytes, as
bench_petsc.py's ru_maxrss.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import MappingProxyType

sys.path.insert(0, str(Path(__file__).resolve().parent))

GB = 2**30


def _rss() -> tuple[float, float]:
    """(VmRSS, VmHWM) of this process in GB."""
    with open("/proc/self/status") as f:
        d = dict(line.split(":", 1) for line in f)
    return tuple(int(d[k].split()[0]) * 1024 / GB for k in ("VmRSS", "VmHWM"))


class Meter:
    """RSS at named marks and the peak since the previous mark (a sampling thread)."""

    def __init__(self, trim: bool):
        self.trim = ctypes.CDLL("libc.so.6").malloc_trim if trim else None
        self.peak, self.rows, self.t0 = 0.0, [], time.perf_counter()
        threading.Thread(target=self._sample, daemon=True).start()

    def _sample(self):
        while True:
            self.peak = max(self.peak, _rss()[0])
            time.sleep(0.02)

    def mark(self, label: str) -> None:
        if self.trim is not None:
            self.trim(0)
        now = _rss()[0]
        self.rows.append((time.perf_counter() - self.t0, label, now, max(self.peak, now)))
        self.peak = now


def _instrument(meter: Meter) -> None:
    """Marks before and after the path's commands and the phases inside them."""
    from contactopt.contact.fullspace import petsc as fp
    from contactopt.fem import distributed as fd
    from contactopt.paths import petsc as pp

    def wrap(name, f):
        def g(*a, **k):
            meter.mark(f"{name} …")
            out = f(*a, **k)
            meter.mark(f"{name} done")
            return out
        return g
    pp.PetscPath.handlers = MappingProxyType({c: wrap(c.name.lower(), f) for c, f in pp.PetscPath.handlers.items()})
    for cls, names in ((pp.PetscPath, ("__init__", "_hierarchy")),
                       (fd.DistributedBodies, ("__init__", "owned_stiffness")),
                       (fp.PetscNewton, ("solve", "adjoint")), (fp.PetscHierarchy, ("coarse",))):
        for n in names:
            setattr(cls, n, wrap(f"{cls.__name__}.{n}", getattr(cls, n)))


def child(size: str, step: float, trim: bool, out: str) -> None:
    meter = Meter(trim)
    _instrument(meter)
    from bench_petsc import design_direction
    from bench_two_bodies_scale import two_bodies
    from contactopt.problem import ShapeProblem
    from contactopt.ranks import run_on_ranks

    def work():
        meter.mark("start")
        problem = ShapeProblem(two_bodies(size, "petsc"))
        meter.mark("problem built")
        a0 = problem.model.initial_design()
        d = design_direction(problem.model)
        for k in range(2):
            meter.mark(f"evaluation at α{k}")
            problem.subgradient(a0 + k * step * d)
        meter.mark("end")
    run_on_ranks(work)
    meter.mark("end")
    rank = int(os.environ.get("OMPI_COMM_WORLD_RANK", "0"))
    Path(f"{out}.{rank}.json").write_text(json.dumps({"rows": meter.rows, "peak": _rss()[1]}))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="200k", help="a size of bench_two_bodies_scale.py (15k, 200k, 367k, 1m)")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--step", type=float, default=2e-4, help="h of the second design α0 + h·d")
    ap.add_argument("--trim", action="store_true", help="return the freed heap to the system before each reading")
    ap.add_argument("--all", action="store_true", help="every mark (default: the phases, not each Krylov solve)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return child(args.size, args.step, args.trim, args.child)
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "rss")
        cmd = [sys.executable, __file__, "--size", args.size, "--step", str(args.step), "--child", out]
        cmd += ["--trim"] if args.trim else []
        env = dict(os.environ)
        if args.ranks > 1:
            cmd = [shutil.which("mpiexec") or sys.exit("mpiexec not found"), "-n", str(args.ranks), *cmd]
            if os.geteuid() == 0:
                env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            sys.exit(proc.stderr[-3000:])
        ranks = [json.loads((Path(tmp) / f"rss.{r}.json").read_text()) for r in range(args.ranks)]
    print(f"{'mark (rank 0)':<42} " + " ".join(f"{f'rank {r}: now, peak GB':>22}" for r in range(args.ranks)))
    for i, row in enumerate(ranks[0]["rows"]):
        if not args.all and "coarse" in row[1]:
            continue
        cells = []
        for r in ranks:       # the other ranks have no "start"/"problem built"/evaluation marks: match by name
            same = [x for x in r["rows"] if x[1] == row[1]]
            k = sum(1 for x in ranks[0]["rows"][:i] if x[1] == row[1])
            cells.append(f"{same[k][2]:10.2f} {same[k][3]:10.2f}" if k < len(same) else f"{'':>21}")
        print(f"{row[1]:<42} " + " ".join(f"{c:>22}" for c in cells))
    print("peak (VmHWM) per rank: " + ", ".join(f"{r['peak']:.2f} GB" for r in ranks))


if __name__ == "__main__":
    sys.exit(main())
