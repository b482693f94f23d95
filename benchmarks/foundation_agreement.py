"""The full-space and condensation paths on every elastic-foundation model that fits both.

For each gallery configuration with a ``[foundation]`` (or one contact pair against a body) and
the test models of the foundation's features (point, averaged and mortar partners, own loads,
prescribed translation, a curved seat), one evaluation Θ(α), ξ and the state λ, w at a perturbed
design on both paths, and their relative differences (max-norm, relative to the condensation's):

    python benchmarks/foundation_agreement.py [--quick] [--petsc]

``--quick`` runs only the small test models (the gallery's take minutes). ``--petsc`` adds the
PETSc path on one process and under ``mpiexec -n 2`` (this script as the ranks' child), its
differences relative to the full-space path's (needs petsc4py, mpi4py and mpiexec)."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.errors import ConfigError
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]
GALLERY = ("block_on_slab", "example1_elastic", "example1_elastic_dissipation", "round_pad_slab",
           "roller_crowning_interference", "block_two_slabs", "hub_edge_relief")
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


def evaluation(cfg, path: str, seed: int = 1, amp: float = 0.003):
    """(Θ, ξ, state, seconds) of one evaluation on ``path`` at the perturbed design."""
    pb = ShapeProblem(cfg.with_updates({"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
    a = pb.model.initial_design()
    d = np.random.default_rng(seed).standard_normal(a.size)
    a = a + amp * (d - d.mean()) * max(1.0, float(np.abs(a).max()))
    if not pb.model.admissible.is_feasible(a):
        a = pb.model.initial_design()
    t = time.perf_counter()
    theta, xi = pb.evaluate(a)
    return theta, xi, pb.solve_state(a), time.perf_counter() - t


def _rel(a, b) -> float:
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(np.asarray(b)).max(), 1e-300))


def compare(name: str, cfg, petsc: bool = False) -> dict:
    out = {path: evaluation(cfg, path) for path in ("condensation", "fullspace")}
    (t0, x0, s0, c0), (t1, x1, s1, c1) = out["condensation"], out["fullspace"]
    row = {"model": name, "Theta": _rel(t1, t0), "xi": _rel(x1, x0), "lambda": _rel(s1.lam, s0.lam),
           "w": _rel(s1.u_c, s0.u_c), "classes": bool(np.array_equal(s0.classes, s1.classes)),
           "slide": int(np.sum(s0.classes == CLASS_CODES["M1"])), "stick": int(np.sum(s0.classes == CLASS_CODES["M3+"])),
           "time_condensation": c0, "time_fullspace": c1}
    if petsc:
        t2, x2, s2, _ = evaluation(cfg, "petsc")
        row["petsc1"] = max(_rel(t2, t1), _rel(x2, x1), _rel(s2.lam, s1.lam))
        with tempfile.TemporaryDirectory() as tmp:
            two = _on_two_ranks(cfg, Path(tmp))
        row["petsc2"] = max(_rel(two["theta"], t1), _rel(two["xi"], x1), _rel(two["lam"], s1.lam))
    return row


def _on_two_ranks(cfg, tmp: Path) -> dict:
    """Θ, ξ, λ of the PETSc path under ``mpiexec -n 2`` (this script as the ranks' child)."""
    import tomli_w
    file, out = tmp / "model.toml", tmp / "out.npz"
    file.write_text(tomli_w.dumps(cfg.data))
    env = dict(os.environ)
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    exe = shutil.which("mpiexec") or sys.exit("mpiexec not found")
    proc = subprocess.run([exe, "-n", "2", sys.executable, __file__, "--child", str(file), str(out)],
                          capture_output=True, text=True, env=env)
    if proc.returncode:
        sys.exit(f"mpiexec -n 2 failed:\n{proc.stderr[-3000:]}")
    with np.load(out) as npz:
        return dict(npz)


def child(file: str, out: str) -> None:
    """On every rank: one evaluation on the PETSc path; rank 0 saves Θ, ξ, λ."""
    from contactopt.ranks import run_on_ranks

    def work():
        theta, xi, st, _ = evaluation(load_config(file), "petsc")
        np.savez(out, theta=theta, xi=xi, lam=st.lam)
        return 0
    run_on_ranks(work)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--petsc", action="store_true")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(*args.child)
        return
    rows = []
    for name, upd in small_models().items():
        rows.append(compare(name, load_config("example1").with_updates(upd), args.petsc))
    if not args.quick:
        for name in GALLERY:
            try:
                rows.append(compare(name, load_config(ROOT / "examples" / f"{name}.toml"), args.petsc))
            except ConfigError as exc:
                rows.append({"model": name, "refused": "; ".join(exc.problems)})
    extra = " PETSc ×1 | PETSc ×2 |" if args.petsc else ""
    print("| model | Θ | ξ | λ | w | same classes | sliding / sticking | s (cond.) | s (full) |" + extra)
    print("|---|---|---|---|---|---|---|---|---|" + ("---|---|" if args.petsc else ""))
    for r in rows:
        if "refused" in r:
            print(f"| {r['model']} | refused: {r['refused']} |")
            continue
        print(f"| {r['model']} | {r['Theta']:.1e} | {r['xi']:.1e} | {r['lambda']:.1e} | {r['w']:.1e} | "
              f"{'yes' if r['classes'] else 'no'} | {r['slide']} / {r['stick']} | {r['time_condensation']:.2f} | "
              f"{r['time_fullspace']:.2f} |" + (f" {r['petsc1']:.1e} | {r['petsc2']:.1e} |" if args.petsc else ""))


if __name__ == "__main__":
    main()
