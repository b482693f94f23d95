"""The state solve at random designs of the box [lower, C0]: every design of the box gives a valid
mesh, and its state must converge, on every shipped configuration (curved faces, force control,
symmetry planes, load steps, elastic foundations among them) and under two BLAS kernels.

The tier ``robustness`` runs them in a subprocess per kernel
(``OPENBLAS_CORETYPE``, contactopt.verification.robustness); the roller's random designs (a frictionless body on two symmetry planes
under force control, whose contact node on both planes has u_T = 0) also run in the default tier."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from contactopt.problem import ShapeProblem
from contactopt.verification.robustness import GENERATED, box_designs, solve_at

ROOT = Path(__file__).resolve().parents[1]
# the 32x15x9 Example 1 on a fine mesh takes a minute per state: its coarse relatives stand for it
TIER = ["example1", "example2", "example3"] + sorted(
    str(p.relative_to(ROOT)) for p in (ROOT / "examples").glob("*.toml") if p.name != "example1_fine.toml")
SCRIPT = ("import json, sys; from contactopt.verification.robustness import random_design_solves; "
          "json.dump([random_design_solves(c, 3) for c in sys.argv[2:]], open(sys.argv[1], 'w'))")
PAPER = ("example1", "example2", "example3")


def test_the_roller_solves_at_random_designs_of_its_box():
    problem = ShapeProblem(str(ROOT / "examples" / "roller_rigid.toml"))
    for alpha in box_designs(problem.model, 2, seed=1):
        row = solve_at(problem, alpha)
        assert row["converged"], row.get("error")


@pytest.mark.robustness
@pytest.mark.parametrize("kernel", ["Haswell", "Prescott"])
def test_every_shipped_configuration_solves_at_random_designs_under_two_kernels(kernel, tmp_path):
    out = tmp_path / "rows.json"
    env = dict(os.environ, OPENBLAS_CORETYPE=kernel, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    p = subprocess.run([sys.executable, "-c", SCRIPT, str(out), *TIER], cwd=ROOT, env=env,
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr[-3000:]
    rows = json.loads(out.read_text())
    assert [r["config"] for r in rows] == TIER
    for r in rows:
        assert r["alpha0_converged"] and r["converged"] == r["designs"], r
        if r["config"] in PAPER:
            assert r["fallbacks"] == 0, r
    assert np.isfinite([r["time_mean_s"] for r in rows]).all()


GENERATED_SEEDS = (0, 1, 2)
GENERATED_SCRIPT = ("import json, sys; from contactopt.verification.robustness import generated_variants, random_design_solves; "
                    "json.dump([random_design_solves(c, 3, seed, name) for seed in map(int, sys.argv[3:]) "
                    "for name, c in generated_variants(seed, sys.argv[2])], open(sys.argv[1], 'w'))")


@pytest.mark.robustness
@pytest.mark.parametrize("kernel", ["Haswell", "Prescott"])
def test_generated_variants_solve_at_random_designs_under_two_kernels(kernel, tmp_path):
    """Generated configurations (a random crown and tilt of the face, force control, a symmetry
    plane, load steps, an elastic foundation, the full-space path; random friction, loads and forces, seeded), each
    at α0 and three random designs of its box: every state converges. The fallbacks used per
    configuration are in the rows (benchmarks/robustness.py --generated prints them)."""
    out = tmp_path / "rows.json"
    env = dict(os.environ, OPENBLAS_CORETYPE=kernel, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    p = subprocess.run([sys.executable, "-c", GENERATED_SCRIPT, str(out), str(tmp_path), *map(str, GENERATED_SEEDS)],
                       cwd=ROOT, env=env, capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr[-3000:]
    rows = json.loads(out.read_text())
    assert len(rows) == len(GENERATED_SEEDS) * len(GENERATED)
    for r in rows:
        assert r["alpha0_converged"] and r["converged"] == r["designs"], r
