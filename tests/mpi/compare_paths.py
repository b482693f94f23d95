"""Run under mpiexec (or alone): Θ, the state and the subgradient of a configuration on the PETSc
path at two designs (the second warm-started from the first), written by rank 0 to an .npz file.

    mpiexec -n 2 python tests/mpi/compare_paths.py CONFIG OUT.npz [key=value ...]

key=value: mesh.nx=8 style overrides of the configuration (numbers or strings)."""

import sys

import numpy as np

from contactopt.config import load_config
from contactopt.ranks import run_on_ranks


def overrides(items):
    out = {}
    for item in items:
        key, value = item.split("=", 1)
        sec, name = key.split(".")
        try:
            value = int(value)
        except ValueError:
            try:
                value = float(value)
            except ValueError:
                pass
        out.setdefault(sec, {})[name] = value
    return out


def evaluations(config, path):
    """(Θ, ξ, λ, τ, u) at α0 and at a second design, on ``path``."""
    from contactopt.problem import ShapeProblem
    cfg = config.with_updates({"linear_solver": {"path": path}})
    problem = ShapeProblem(cfg)
    a0 = problem.model.initial_design()
    rng = np.random.default_rng(7)
    a1 = np.clip(a0 + 0.1 * problem.model.admissible.C0 * rng.uniform(-1, 1, a0.size), 0.0,
                 problem.model.admissible.C0)
    out = {}
    for tag, a in (("0", a0), ("1", a1)):
        res = problem.subgradient(a)
        st = res.state
        out.update({f"value{tag}": res.value, f"xi{tag}": res.gradient, f"lam{tag}": st.lam,
                    f"tau{tag}": st.tau, f"u{tag}": st.u, f"v_lam{tag}": res.v_lam})
    return out


def main(argv):
    config = load_config(argv[0]).with_updates(overrides(argv[2:]))
    from contactopt._mpi import world_size
    out = evaluations(config, "petsc")
    np.savez(argv[1], ranks=world_size(), **out)
    return 0


if __name__ == "__main__":
    sys.exit(run_on_ranks(main, sys.argv[1:]))
