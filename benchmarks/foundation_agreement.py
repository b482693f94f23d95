"""The full-space and condensation paths on every elastic-foundation model that fits both.

For each gallery configuration with a ``[foundation]`` (or one contact pair against a body) and
the test models of the foundation's features (point, averaged and mortar partners, own loads,
prescribed translation, a curved seat), one evaluation Θ(α), ξ and the state λ, w at a perturbed
design on both paths, and their relative differences (max-norm, relative to the condensation's):

    python benchmarks/foundation_agreement.py [--quick]

``--quick`` runs only the small test models (the gallery's take minutes)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.errors import ConfigError
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]
GALLERY = ("block_on_slab", "example1_elastic", "example1_elastic_dissipation", "round_pad_slab",
           "roller_crowning_interference")
E_BODY = 21.19


def _block(cells=(9, 5, 3), size=(3.0, 2.0, 1.0), origin=(-0.5, -0.5)):
    return {"size": list(size), "cells": list(cells), "origin": list(origin), "element": "hexahedron"}


def small_models() -> dict:
    """Example 1 (coarse) on foundations of each kind (as tests/test_foundation*.py builds them)."""
    base = {"mesh": {"nx": 12, "ny": 6, "nz": 4}}
    soft = {"material": {"E": E_BODY / 10}}
    return {
        "point partners": {**base, "foundation": {"block": _block(), "partner": "point", **soft}},
        "averaged partners, own loads": {**base, "foundation": {
            "block": _block(), "partner": "average", **soft,
            "loads": {"body_force": [0.0, 0.0, -0.02], "pressure": [{"on": "top", "value": 0.005}]}}},
        "mortar partners": {**base, "foundation": {"block": _block(), "partner": "mortar", **soft}},
        "prescribed translation": {**base, "foundation": {
            "block": _block(), "partner": "point", **soft, "control": "displacement", "loaded": "bottom",
            "displacement": [0.002, 0.0, 0.001]}},
        "friction 0.1": {**base, "friction": {"coefficient": 0.1},
                                   "foundation": {"block": _block(), "partner": "point", **soft}},
    }


def compare(name: str, cfg, seed: int = 1, amp: float = 0.003) -> dict:
    out = {}
    for path in ("condensation", "fullspace"):
        c = cfg.with_updates({"linear_solver": {"path": path}, "state": {"tol": 1e-12}})
        pb = ShapeProblem(c)
        a = pb.model.initial_design()
        d = np.random.default_rng(seed).standard_normal(a.size)
        a = a + amp * (d - d.mean()) * max(1.0, float(np.abs(a).max()))
        if not pb.model.admissible.is_feasible(a):
            a = pb.model.initial_design()
        t = time.perf_counter()
        theta, xi = pb.evaluate(a)
        out[path] = (theta, xi, pb.solve_state(a), time.perf_counter() - t)
    (t0, x0, s0, c0), (t1, x1, s1, c1) = out["condensation"], out["fullspace"]
    rel = lambda a, b: float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(np.asarray(b)).max(), 1e-300))
    return {"model": name, "Theta": rel(t1, t0), "xi": rel(x1, x0), "lambda": rel(s1.lam, s0.lam),
            "w": rel(s1.u_c, s0.u_c), "classes": bool(np.array_equal(s0.classes, s1.classes)),
            "slide": int(np.sum(s0.classes == CLASS_CODES["M1"])), "stick": int(np.sum(s0.classes == CLASS_CODES["M3+"])), "time_condensation": c0, "time_fullspace": c1}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    rows = []
    for name, upd in small_models().items():
        rows.append(compare(name, load_config("example1").with_updates(upd)))
    if not args.quick:
        for name in GALLERY:
            try:
                rows.append(compare(name, load_config(ROOT / "examples" / f"{name}.toml")))
            except ConfigError as exc:
                rows.append({"model": name, "refused": "; ".join(exc.problems)})
    print("| model | Θ | ξ | λ | w | same classes | sliding / sticking | s (cond.) | s (full) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "refused" in r:
            print(f"| {r['model']} | refused: {r['refused']} |")
            continue
        print(f"| {r['model']} | {r['Theta']:.1e} | {r['xi']:.1e} | {r['lambda']:.1e} | {r['w']:.1e} | "
              f"{'yes' if r['classes'] else 'no'} | {r['slide']} / {r['stick']} | {r['time_condensation']:.2f} | "
              f"{r['time_fullspace']:.2f} |")


if __name__ == "__main__":
    main()
