"""The elastic foundation (issue #22): rigid limit, non-matching meshes, cost.

    python benchmarks/bench_foundation.py [--part limit|meshes|cost|all] [--steps 8]

limit   Example 1 (32×15×9) at α0 on the slab of examples/example1_elastic.toml with
        E_f/E = 1, 10, 100, 1e4, 1e6: max |λ − λ_rigid| / max λ_rigid and the total force.
meshes  The body 12×6×4 of the tests on the slab [−0.5, 2.5]×[−0.5, 1.5]×[−1, 0] (E_f = E/10),
        the slab 0.5, 1, 1.5, 2.7 times as fine as the body, against a slab 4 times as fine, with
        point partners and with averaged ones: max |λ − λ_ref| / max λ_ref, |Σλ − Σλ_ref| / Σλ_ref,
        and the observed order.
cost    Median time of one evaluation (state + subgradient) along a path of small design steps,
        Example 1 rigid, on the slab at E_f/E = 1e6 (the same contact zone: the overhead) and at
        E_f = E/10 (examples/example1_elastic.toml), the problems taking turns at every design.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]
ELASTIC = ROOT / "examples" / "example1_elastic.toml"
E = 21.19


def with_foundation(cfg, **kw):
    f = {**cfg["foundation"], **kw}
    return cfg.with_updates({"foundation": f})


def limit() -> None:
    rigid = ShapeProblem("example1")
    a = rigid.model.initial_design()
    lam0 = rigid.solve_state(a).lam
    el = load_config(ELASTIC)
    print("E_f/E     max|λ−λ_rigid|/max λ_rigid   Σλ/Σλ_rigid − 1   nodes in contact")
    for ratio in (1, 10, 100, 1e4, 1e6):
        st = ShapeProblem(with_foundation(el, material={"E": E * ratio, "nu": 0.277})).solve_state(a)
        print(f"{ratio:7.0e}   {np.abs(st.lam - lam0).max() / lam0.max():.3e}                 "
              f"{st.lam.sum() / lam0.sum() - 1:+.3e}        {int(np.sum(st.lam > 0))} (rigid {int(np.sum(lam0 > 0))})")


def meshes() -> None:
    base = load_config("example1").with_updates({"mesh": {"nx": 12, "ny": 6, "nz": 4}})
    same = np.array([18, 12, 4])                  # the body's h = 1/6, 1/6, 1/4 on the 3×2×1 slab

    def state(f, partner):
        cells = [max(1, int(round(v))) for v in f * same]
        cfg = base.with_updates({"foundation": {"block": {"size": [3.0, 2.0, 1.0], "cells": cells,
                                                          "origin": [-0.5, -0.5]}, "material": {"E": E / 10},
                                                "partner": partner}})
        pb = ShapeProblem(cfg)
        return pb.solve_state(pb.model.initial_design()), cells

    for partner in ("point", "average"):
        ref, cells_ref = state(4.0, partner)
        print(f"partner = {partner!r}; reference: slab {cells_ref} (4× as fine as the body)")
        print("fineness  slab cells     max|λ−λ_ref|/max λ_ref   |Σλ−Σλ_ref|/Σλ_ref   ‖λ−λ_ref‖₂/‖λ_ref‖₂")
        errs, hs = [], []
        for f in (0.5, 1.0, 1.5, 2.7):
            st, cells = state(f, partner)
            e = np.abs(st.lam - ref.lam).max() / ref.lam.max()
            errs.append(e)
            hs.append(1.0 / f)
            print(f"{f:6.1f}×   {str(cells):13s}  {e:.3e}                {abs(st.lam.sum() - ref.lam.sum()) / ref.lam.sum():.3e}"
                  f"            {np.linalg.norm(st.lam - ref.lam) / np.linalg.norm(ref.lam):.3e}")
        print(f"observed order of the max error (fit of log error on log h_f): "
              f"{np.polyfit(np.log(hs), np.log(errs), 1)[0]:.2f}")


BOTH_LEVELS = (6, 12, 24, 48)


def both() -> None:
    """Body and slab refined together (body 6 → 12 → 24 → 48 cells along x1), the slab f times as
    fine as the body (f = 0.5, 1.5, 2.7; 2.7 to 24 only: 1.1M slab cells at 48): the contact force
    on each of the 6×3 cells of the coarsest body's contact face, F_K = Σ_m λ_m |T_m ∩ K| / |T_m|
    (T_m the square of node m's tributary area; nested meshes), against the next refinement —
    Σ_K |F_K,h − F_K,h/2| / Σ_K F_K,h/2 — and the ratio of successive differences (2^order). The
    integral of the pressure over a fixed patch converges where the pressure at a node does not:
    the contact face's edges carry a stress singularity and the zone's edge crosses the nodes.
    Each row runs in a process of its own (the largest slabs peak at 18 GB)."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context
    print(f"contact force on the {BOTH_LEVELS[0]}×{BOTH_LEVELS[0] // 2} cells of the coarsest contact face, body "
          "refined h → h/2 with the slab: Σ|F_h − F_h/2| / ΣF_h/2, and the ratios of successive differences")
    rows = [("rigid", None, None, BOTH_LEVELS)] + [
        (f"{partner}, f = {f}", f, partner, BOTH_LEVELS if f < 2 else BOTH_LEVELS[:3])
        for partner in ("point", "average") for f in (0.5, 1.5, 2.7)]
    for label, f, partner, lv in rows:
        with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as ex:
            diffs, note = ex.submit(_both_row, f, partner, lv).result()
        ratios = [a / b for a, b in zip(diffs[:-1], diffs[1:])]
        print(f"{label:<18}" + "  ".join(f"{d:.3e}" for d in diffs) + "   ratios " +
              "  ".join(f"{r:.2f}" for r in ratios) + note, flush=True)


def _both_row(f, partner, levels):
    coarse = BOTH_LEVELS[0]
    note = ""

    def patch_forces(n):
        nonlocal note
        cfg = load_config("example1").with_updates({"mesh": {"nx": n, "ny": n // 2, "nz": max(2, n // 3)}})
        if f is not None:
            cells = [max(1, int(round(f * v))) for v in (1.5 * n, n, n // 3)]
            cfg = cfg.with_updates({"foundation": {"block": {"size": [3.0, 2.0, 1.0], "cells": cells,
                                                             "origin": [-0.5, -0.5]}, "material": {"E": E / 10},
                                                   "partner": partner},
                                    # body 48 on the slab 108×72×24 peaks at 18 GB (estimated 19):
                                    # past the check's margin of 0.9 × the memory of a 24 GB machine
                                    "linear_solver": {"memory_check": False}})
        pb = ShapeProblem(cfg)
        st = pb.solve_state(pb.model.initial_design())
        if n == levels[-1]:
            note = (f"   (finest: estimated {pb.path.memory_estimate(pb.model).total_gb:.1f} GB, "
                    f"peak RSS {_peak_rss_gb():.1f} GB)")
        xy, h, H = pb.model.mesh.contact_points(), 2.0 / n, 2.0 / coarse
        lo = np.clip(xy - h / 2, 0.0, [2.0, 1.0])
        hi = np.clip(xy + h / 2, 0.0, [2.0, 1.0])
        F = np.zeros((coarse, coarse // 2))
        for i in range(coarse):
            for j in range(coarse // 2):
                ox = np.clip(np.minimum(hi[:, 0], (i + 1) * H) - np.maximum(lo[:, 0], i * H), 0.0, None)
                oy = np.clip(np.minimum(hi[:, 1], (j + 1) * H) - np.maximum(lo[:, 1], j * H), 0.0, None)
                F[i, j] = np.sum(st.lam * ox * oy / np.prod(hi - lo, axis=1))
        return F

    prev, diffs = None, []
    for n in levels:
        F = patch_forces(n)
        if prev is not None:
            diffs.append(float(np.abs(F - prev).sum() / F.sum()))
        prev = F
    return diffs, note


def _peak_rss_gb() -> float:
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


def cost(steps: int) -> None:
    el = load_config(ELASTIC)
    pbs = {"rigid": ShapeProblem("example1"),
           "slab E_f/E = 1e6": ShapeProblem(with_foundation(el, material={"E": E * 1e6, "nu": 0.277})),
           "slab E_f = E/10": ShapeProblem(el)}
    a = pbs["rigid"].model.initial_design()
    rng = np.random.default_rng(0)
    times = {k: [] for k in pbs}
    zones = {}
    for pb in pbs.values():
        pb.evaluate(a)                           # cold
    for _ in range(steps):
        d = rng.standard_normal(a.size)
        a = a + 1e-4 * (d - d.mean())
        for name, pb in pbs.items():
            t = time.perf_counter()
            pb.evaluate(a)
            times[name].append(time.perf_counter() - t)
            zones[name] = pb.solve_state(a).info["zone_nodes"]
    t0 = statistics.median(times["rigid"])
    for name, ts in times.items():
        m = statistics.median(ts)
        print(f"{name:18s} {m:.3f} s per evaluation  ×{m / t0:.2f}   contact zone {zones[name]} nodes")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default="all", choices=("limit", "meshes", "both", "cost", "all"))
    ap.add_argument("--steps", type=int, default=8)
    args = ap.parse_args()
    if args.part in ("limit", "all"):
        limit()
    if args.part in ("meshes", "all"):
        meshes()
    if args.part in ("both", "all"):
        both()
    if args.part in ("cost", "all"):
        cost(args.steps)


if __name__ == "__main__":
    main()
