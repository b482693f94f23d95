"""Run under mpiexec (or alone): Θ, the state and the subgradient of a configuration on the PETSc
path at two designs (the second warm-started from the first), written by rank 0 to an .npz file;
on a load path also every step's state and central differences of Θ (:func:`evaluations`).

    mpiexec -n 2 python tests/mpi/compare_paths.py CONFIG OUT.npz [--differences] [key=value ...]

key=value: mesh.nx=8 style overrides of the configuration (numbers or strings); ``--differences``:
the central differences without a load path too."""

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


def evaluations(config, path, differences=False, h=1e-6):
    """(Θ, ξ, λ, τ, u) at α0 and at a second design, on ``path``; on a load path also every
    solve's state (``u1_step2`` ...) and, with ``differences``, central differences of Θ at the
    second design (``fd``, step ``h``) with ξ along the same directions (``fd_xi``) and the node
    classes' counts (``fd_M1``: sliding nodes over the steps, ``fd_degenerate``)."""
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
        for j, (_, _, sj) in enumerate(problem.step_results() or []):
            out.update({f"lam{tag}_step{j}": sj.lam, f"tau{tag}_step{j}": sj.tau, f"u{tag}_step{j}": sj.u})
    if differences:
        res = problem.subgradient(a1)
        out["fd_M1"] = sum(sj.counts["M1"] for _, _, sj in problem.step_results() or [("", "", res.state)])
        out["fd_degenerate"] = res.n_degenerate
        dirs = [np.eye(a1.size)[i] for i in range(0, a1.size, 3)] + [np.random.default_rng(3).standard_normal(a1.size)]
        out["fd"] = np.array([(problem.evaluate_value(a1 + h * d) - problem.evaluate_value(a1 - h * d)) / (2 * h)
                              for d in dirs])
        out["fd_xi"] = np.array([res.gradient @ d for d in dirs])
    return out


def main(argv):
    flags = [a for a in argv[2:] if a.startswith("--")]
    config = load_config(argv[0]).with_updates(overrides([a for a in argv[2:] if a not in flags]))
    from contactopt._mpi import world_size
    out = evaluations(config, "petsc", differences=bool(config.load_steps) or "--differences" in flags)
    np.savez(argv[1], ranks=world_size(), **out)
    return 0


if __name__ == "__main__":
    sys.exit(run_on_ranks(main, sys.argv[1:]))
