"""A face body held only by its contacts on the full-space path (docs/guide/assemblies.md): the
examples whose face body floats, on the condensation and the full-space path.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/held_face_fullspace.py \
        [--examples roller_plates dovetail lap_joint roller_bearing]

Per example and path: the seconds of the first evaluation (state and subgradient at α0, the
hierarchy built on the way), the state's Newton steps and Krylov iterations (full space), whether
the first anchored solve needed the stiffer anchor (contactopt.paths.floating), and the relative
differences of Θ, ξ and λ between the paths.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]


class _Count(logging.Handler):
    def __init__(self):
        super().__init__(logging.DEBUG)
        self.stiffer = 0

    def emit(self, record):
        if "a stiffer anchor" in record.getMessage():
            self.stiffer += 1


def run(name: str, path: str) -> dict:
    cfg = load_config(ROOT / "examples" / f"{name}.toml").with_updates(
        {"linear_solver": {"path": path}, "state": {"tol": 1e-12}})
    counter = _Count()
    log = logging.getLogger("contactopt.paths.fullspace")
    log.addHandler(counter)
    old = log.level
    log.setLevel(logging.DEBUG)
    try:
        pb = ShapeProblem(cfg)
        a = pb.model.initial_design()
        t0 = time.perf_counter()
        res = pb.subgradient(a)
        seconds = time.perf_counter() - t0
    finally:
        log.removeHandler(counter)
        log.setLevel(old)
    st = res.state
    return {"seconds": seconds, "value": res.value, "xi": np.asarray(res.gradient), "lam": st.lam,
            "stiffer": counter.stiffer, "dofs": pb.model.assembler.n_free}


def _rel(a, b):
    b = np.asarray(b)
    return float(np.abs(np.asarray(a) - b).max() / max(np.abs(b).max(), 1e-300))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", nargs="+", default=["roller_plates", "dovetail", "lap_joint", "roller_bearing"])
    args = ap.parse_args(argv)
    print("| example | face body DOFs | condensation s | full space s | ratio | stiffer anchor | ΔΘ | Δξ | Δλ |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.examples:
        c = run(name, "condensation")
        f = run(name, "fullspace")
        dxi = float(np.abs(f["xi"] - c["xi"]).max() / max(np.abs(c["xi"]).max(), abs(c["value"]), 1e-300))
        print(f"| {name} | {c['dofs']:,} | {c['seconds']:.1f} | {f['seconds']:.1f} | {f['seconds'] / c['seconds']:.0f} | "
              f"{'yes' if f['stiffer'] else 'no'} | {abs(f['value'] - c['value']) / abs(c['value']):.1e} | {dxi:.1e} | "
              f"{_rel(f['lam'], c['lam']):.1e} |", flush=True)


if __name__ == "__main__":
    main()
