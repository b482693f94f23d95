"""Hashes of the oracle's output, to show that a change of the evaluation code keeps it bit for bit.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/hash_evaluation.py [--only NAME ...] [--per-node-friction]

For Examples 1–3 on the condensation, Delassus and full-space paths, and for a few mechanics on a
small mesh of Example 1 (a 3-step load path with the friction work among the objective's terms,
two load cases, [[constraints]], a force-controlled obstacle along a load path), one problem
evaluates Θ and ξ at α0 and then at α0 + δ (δ = 10⁻³ cos k, so that the second evaluation starts
from the first's warm start and contact zone, as in a run). Each line prints the sha256 of the
float64 bytes of Θ and of ξ (and of each constraint's value and subgradient), first 16 hex digits.
Run it before and after a change, with the same BLAS kernel and threads: the lines must be equal.
``--per-node-friction``: each model's ``contact_friction`` the array of ``[friction] coefficient``
at every contact node; the lines must equal those of the scalar.
"""

from __future__ import annotations

import argparse
import hashlib

import numpy as np

from contactopt import load_config
from contactopt.fem.linsolve import pardiso_available
from contactopt.problem import ShapeProblem

SMALL = {"mesh": {"nx": 8, "ny": 4, "nz": 3}}
TOP, SIDE = [0.0, 0.0, -8e-2], [5e-2, 0.0, 0.0]
STEPS = [{"name": "press", "top_traction": TOP},
         {"name": "shear", "top_traction": TOP, "right_traction": SIDE},
         {"name": "back", "top_traction": TOP, "right_traction": [2e-2, 0.0, 0.0], "substeps": 2}]
TERMS = [{"type": "target_normal_force", "weight": 1.0,
          "target": {"kind": "constant", "value": 0.001}},
         {"type": "frictional_dissipation", "weight": 10.0}]


def _small(**sections):
    base = load_config("example1").with_updates(SMALL).data
    data = dict(base)
    for sec, values in sections.items():
        data[sec] = values if isinstance(values, list) else {**data.get(sec, {}), **values}
    return load_config(data)


def _load_path():
    return _small(loads={"top_traction": [0.0] * 3, "right_traction": [0.0] * 3}, load_steps=STEPS,
                  objective={"type": "sum", "terms": TERMS, "steps": "max"})


def _cases():
    return _small(load_cases=[{"name": "pull", "right_traction": SIDE},
                              {"name": "push", "right_traction": [-5e-2, 0.0, 0.0]}],
                  loads={"right_traction": [0.0] * 3}, objective={"combine": "sum"})


def _constraints():
    return _small(constraints=[{"type": "compliance", "max": 1.0}, {"type": "max_pressure", "max": 1.0},
                               {"type": "peak_stress", "max": 1.0}])


def _forced():
    obstacle = {"shape": "sphere", "center": [1.0, 1.0, -5.0], "radius": 5.0, "control": "force",
                "force": [0.0, 0.0, 1.2]}
    steps = [{"name": "a", "obstacle_force": [0.0, 0.0, 0.6]}, {"name": "b", "obstacle_force": [0.0, 0.0, 1.2],
                                                                "substeps": 2}]
    return load_config("example1").with_updates({
        "friction": {"coefficient": 0.3}, "material": {"nu": 0.3}, "state": {"method": "newton", "tol": 1e-12},
        "loads": {"top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
        "design": {"degree": [3, 2], "initial": 0.0, "C2": 0.0}, "geometry": {"a": 2.0, "b": 2.0, "c": 1.0},
        "mesh": {"nx": 8, "ny": 8, "nz": 3}, "body": {"clamped": "top"}, "obstacle": obstacle,
        "load_steps": steps})


def cases() -> dict:
    out = {}
    for ex in ("example1", "example2", "example3"):
        for path in ("condensation", "delassus", "fullspace"):
            out[f"{ex}-{path}"] = (lambda ex=ex, path=path:
                                   load_config(ex).with_updates({"linear_solver": {"path": path}}))
    out["load-path"] = _load_path
    out["load-cases"] = _cases
    out["constraints"] = _constraints
    out["forced-path"] = _forced
    return out


def digest(x) -> str:
    return hashlib.sha256(np.ascontiguousarray(np.asarray(x, dtype=np.float64)).tobytes()).hexdigest()[:16]


def hashes(config, per_node_friction: bool = False) -> list[str]:
    problem = ShapeProblem(config)
    if per_node_friction:
        problem.model.contact_friction = np.full(problem.model.n_contact, float(config.friction.coefficient))
    alpha0 = problem.model.initial_design()
    out = []
    for tag, alpha in (("a0", alpha0), ("a0+d", alpha0 + 1e-3 * np.cos(np.arange(alpha0.size)))):
        value, xi = problem.evaluate(alpha)
        out.append(f"{tag} Θ {digest(value)} ξ {digest(xi)}")
        for con, res in zip(problem.constraints, problem.constraint_subgradients(alpha)):
            out.append(f"{tag} {con.name} {digest(res.value)} ξ {digest(res.gradient)}")
    return out


def main(argv=None) -> int:
    table = cases()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", choices=sorted(table), help="these configurations only")
    ap.add_argument("--per-node-friction", action="store_true",
                    help="the coefficient as an array, one per contact node (the same value)")
    args = ap.parse_args(argv)
    for name, make in table.items():
        if args.only and name not in args.only:
            continue
        if "delassus" in name and not pardiso_available():
            print(f"{name}: skipped (the Delassus path needs MKL PARDISO)")
            continue
        for line in hashes(make(), args.per_node_friction):
            print(f"{name:24s} {line}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
