"""Linear design constraints of [design]: symmetry and fixed control points (by reducing the
variables α = P β + α_fixed), grow / shrink, [[design.linear]] rows, and their bad input."""

import json

import numpy as np
import pytest
import tomli_w

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.design.reduction import DesignReduction, reduction_of
from contactopt.errors import ConfigError
from contactopt.io.checkpoint import Checkpoint
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization


def small(**design):
    """Example 1 on an 8 × 4 × 3 mesh (symmetric about x2 = 0.5: clamp at x1 = 0, loads along x1, x3)."""
    return load_config("example1").with_updates({"mesh": {"nx": 8, "ny": 4, "nz": 3}, "name": "small",
                                                 "design": design})


def small_toml(tmp_path, **design):
    """The file of :func:`small` with ``design`` written unvalidated (bad values allowed)."""
    data = small().data
    data["design"].update(design)
    path = tmp_path / "small.toml"
    path.write_text(tomli_w.dumps(data))
    return path


# ---------------------------------------------------------------- the reduction itself
def test_reduction_is_a_copy_of_orbits_and_its_transpose():
    a0 = np.full(8 * 4, 0.01)
    a0[0] = 0.02                      # the fixed point's orbit under x1 and x2: corners (0,0),(7,0),(0,3),(7,3)
    a0[[3, 28, 31]] = 0.02
    red = DesignReduction(7, 3, a0, symmetry=("x1", "x2"), fixed=[(0, 0)])
    assert red.n_alpha == 32 and red.n_beta == 4 * 2 - 1     # 4 × 2 orbits, the corner orbit fixed
    beta = np.random.default_rng(0).uniform(0, 1, red.n_beta)
    a = red.expand(beta).reshape(8, 4)
    assert np.array_equal(a, a[::-1, :]) and np.array_equal(a, a[:, ::-1])      # bit for bit
    assert np.all(a[[0, 0, 7, 7], [0, 3, 0, 3]] == 0.02)
    assert np.array_equal(red.expand(beta), red.P @ beta + red.offset)
    assert np.array_equal(red.restrict(red.expand(beta)), beta)
    xi = np.random.default_rng(1).normal(size=32)
    # ⟨Pᵀ ξ, δβ⟩ = ⟨ξ, P δβ⟩: the chain rule of α(β)
    d = np.random.default_rng(2).normal(size=red.n_beta)
    assert red.pullback(xi) @ d == pytest.approx(xi @ (red.P @ d), rel=1e-14)


def test_reduced_rows_keep_exactly_the_symmetric_part_of_U():
    """U ∩ {α = Pβ}: the reduced set's vertices in α (an LP in both) are the same."""
    from scipy.optimize import linprog
    cfg = small(symmetry=["x2"], fixed=[[2, 1]])
    prob = ShapeProblem(cfg)
    red = reduction_of(prob, prob.model.initial_design())
    U, b = prob.model.admissible, red.bounds
    A_eq = np.vstack([U.A_eq, np.eye(32)[red.orbit < 0]] + [
        (np.eye(32)[k] - np.eye(32)[m])[None] for k in range(32) for m in range(32)
        if k < m and red.orbit[k] == red.orbit[m] >= 0])
    b_eq = np.concatenate([U.b_eq, red.offset[red.orbit < 0], np.zeros(A_eq.shape[0] - U.b_eq.size
                                                                     - int(np.sum(red.orbit < 0)))])
    for seed in range(3):
        c = np.random.default_rng(seed).normal(size=32)
        full = linprog(c, A_ub=U.A_ub, b_ub=U.b_ub, A_eq=A_eq, b_eq=b_eq, bounds=list(zip(U.lb, U.ub)))
        redu = linprog(red.P.T @ c, A_ub=b["A_ub"], b_ub=b["b_ub"], A_eq=b["A_eq"], b_eq=b["b_eq"],
                       bounds=list(zip(b["lb"], b["ub"])))
        assert full.status == 0 and redu.status == 0
        assert redu.fun + c @ red.offset == pytest.approx(full.fun, rel=1e-9, abs=1e-12)
    assert red.n_beta == 8 * 2 - 1


def test_subgradient_in_beta_matches_central_differences():
    cfg = small(symmetry=["x2"], fixed=[[0, 0]]).with_updates(
        {"state": {"method": "newton", "tol": 1e-12}, "friction": {"coefficient": 0.0}})
    prob = ShapeProblem(cfg)
    red = reduction_of(prob, prob.model.initial_design())
    beta = red.beta0 + np.random.default_rng(3).uniform(-0.003, 0.003, red.n_beta)

    def theta(b):
        return prob.evaluate_value(red.expand(b))
    f0, xi = prob.evaluate(red.expand(beta))
    g = red.pullback(xi)
    h = 1e-6
    fd = np.array([(theta(beta + h * e) - theta(beta - h * e)) / (2 * h) for e in np.eye(red.n_beta)])
    assert np.max(np.abs(g - fd)) <= 1e-5 * np.max(np.abs(fd))


# ---------------------------------------------------------------- runs
def _recording(monkeypatch):
    """Every design the runner's oracle asks for."""
    seen = []
    orig = ShapeProblem.subgradient

    def rec(self, alpha, **kw):
        seen.append(np.array(alpha, float))
        return orig(self, alpha, **kw)
    monkeypatch.setattr(ShapeProblem, "subgradient", rec)
    return seen


def test_symmetric_run_is_exactly_symmetric_with_fewer_variables_and_fixed_points_stay(tmp_path, monkeypatch):
    seen = _recording(monkeypatch)
    rr = run_optimization(small(symmetry=["x2"], fixed=[[0, 0], [3, 1]]), tmp_path / "run", max_iter=4)
    a = np.array(json.loads((tmp_path / "run" / "alpha.json").read_text())["alpha"])
    assert np.array_equal(a, a[:, ::-1])
    # 8 × 2 orbits of the mirror, those of (0, 0) and (3, 1) fixed
    assert rr.summary["design_variables"] == {"alpha": 32, "optimized": 14}
    assert rr.summary["J"] <= rr.summary["J0"]
    assert len(seen) > 3
    for x in seen:                  # every iterate: symmetric bit for bit, the fixed points unmoved
        x = x.reshape(8, 4)
        assert np.array_equal(x, x[:, ::-1])
        assert x[0, 0] == x[0, 3] == x[3, 1] == x[3, 2] == 0.01
    assert len({x.tobytes() for x in seen}) > 1
    assert not any("symmetry" in w for w in rr.summary["warnings"])


@pytest.mark.integration
def test_round_pad_symmetric_short_run(tmp_path):
    """examples/round_pad_symmetric.toml (a disc face, tetrahedra, friction): two iterations."""
    from pathlib import Path
    cfg = Path(__file__).resolve().parents[1] / "examples" / "round_pad_symmetric.toml"
    rr = run_optimization(str(cfg), tmp_path / "run", max_iter=2)
    a = np.array(rr.summary["alpha"])
    assert np.array_equal(a, a[:, ::-1])
    assert rr.summary["design_variables"] == {"alpha": 25, "optimized": 15}
    assert rr.summary["J"] <= rr.summary["J0"]
    assert not any("symmetry" in w for w in rr.summary["warnings"])


def test_grow_keeps_every_iterate_above_the_initial_design(tmp_path, monkeypatch):
    seen = _recording(monkeypatch)
    cfg = small(direction="grow", C2=0.012)          # room for 20 % more material
    rr = run_optimization(cfg, tmp_path / "run", max_iter=4)
    assert len(seen) > 3
    assert all(np.all(x >= 0.01) for x in seen)
    x = np.array(rr.summary["alpha"]).ravel()
    assert x.sum() <= 0.012 * 32 * (1 + 1e-9) and np.any(x > 0.01 + 1e-6)
    assert rr.summary["admissible"]


@pytest.mark.integration
def test_linear_row_holds_at_the_optimum(tmp_path):
    c = np.zeros((8, 4))
    c[:4] = 1.0                    # the material of the half x1 < 1 at most its initial share
    rr = run_optimization(small(linear=[{"coefficients": c.tolist(), "upper": 0.16}]), tmp_path / "run",
                          max_iter=3)
    assert np.sum(np.array(rr.summary["alpha"])[:4]) <= 0.16 + 1e-9
    assert rr.summary["admissible"]


def test_no_keys_no_reduction():
    prob = ShapeProblem(small())
    assert reduction_of(prob, prob.model.initial_design()) is None
    U = prob.model.admissible
    assert U.A_eq.shape == (1, 32) and U.volume == "equal" and U.linear_rows.size == 0


# ---------------------------------------------------------------- warnings and bad input
def test_symmetry_warnings_name_what_breaks_it():
    # about x1 = 1: the clamp at x1 = 0 and the traction on the right face break it
    red = reduction_of(p := ShapeProblem(small(symmetry=["x1"])), p.model.initial_design())
    text = "\n".join(red.warnings)
    assert "clamped part 'clamped'" in text and "only the loads break it" in text and "contact face" not in text


def test_a_contact_face_not_symmetric_about_the_line_is_refused():
    # a design rectangle wider than the face: the face is not symmetric about its mid-line x2 = 0.75
    prob = ShapeProblem(small(symmetry=["x2"], domain=[[0.0, 2.0], [0.0, 1.5]]))
    with pytest.raises(ConfigError, match=r"the contact face is not symmetric about x2 = 0.75: node \d+"):
        reduction_of(prob, prob.model.initial_design())


def test_initial_design_must_be_symmetric():
    a0 = np.full((8, 4), 0.01)
    a0[0, 0], a0[0, 1] = 0.008, 0.012
    prob = ShapeProblem(small(symmetry=["x2"], initial=a0.tolist()))
    with pytest.raises(ConfigError, match=r"design.initial is not symmetric .* α\[0,3\] = 0.01 ≠ α\[0,0\]"):
        reduction_of(prob, prob.model.initial_design())


def _all_but(i, j):
    return [[a, b] for a in range(8) for b in range(4) if (a, b) != (i, j)]


@pytest.mark.parametrize("case", ["fixed_outside", "linear_shape", "linear_scalar", "rows_contradict_bounds",
                                  "fixed_and_mean_value", "grow_and_row", "all_fixed", "asymmetric_face"])
def test_bad_design_constraints_exit_2_and_nothing_written(tmp_path, capsys, case):
    one = np.zeros((8, 4))
    one[0, 0] = 1.0
    design, expect = {
        "fixed_outside": ({"fixed": [[0, 0], [8, 1]]}, "design.fixed: control point [8, 1] is outside"),
        "linear_shape": ({"linear": [{"coefficients": [[1.0] * 4] * 7, "upper": 1.0}]},
                         "design.linear[0].coefficients: must be a 8×4"),
        "linear_scalar": ({"linear": [{"coefficients": 1.0, "equal": 1.0}]}, "design.linear[0].coefficients"),
        # Σα ≤ 0.1 against the mean value Σα = 0.32
        "rows_contradict_bounds": ({"linear": [{"coefficients": np.ones((8, 4)).tolist(), "upper": 0.1}]},
                                   "leave no admissible design"),
        # 31 points fixed at 0.01: the mean value needs α[0,0] = 0.01, the row ≤ 0.005
        "fixed_and_mean_value": ({"fixed": _all_but(0, 0), "linear": [{"coefficients": one.tolist(),
                                                                       "upper": 0.005}]},
                                 "design.fixed / design.symmetry leave no admissible design"),
        "all_fixed": ({"fixed": _all_but(0, 0)[:-4] + [[0, 0]], "symmetry": ["x1"]},
                      "nothing is left to optimize"),
        # the design rectangle wider than the face: the face is not symmetric about x2 = 0.75
        "asymmetric_face": ({"symmetry": ["x2"], "domain": [[0.0, 2.0], [0.0, 1.5]]},
                            "the contact face is not symmetric about x2 = 0.75"),
        "grow_and_row": ({"direction": "grow", "C2": 0.012,
                          "linear": [{"coefficients": one.tolist(), "upper": 0.005}]},
                         "leave no admissible design"),
    }[case]
    out = tmp_path / "out"
    code = main(["run", str(small_toml(tmp_path, **design)), "--out", str(out), "--max-iter", "2"])
    err = capsys.readouterr().err
    assert code == 2
    assert expect in err
    assert not out.exists()


@pytest.mark.slow
def test_resumed_symmetric_run_continues_bit_for_bit(tmp_path):
    """The checkpoint holds the bundle in β (and the iterate in α): resuming gives the uninterrupted run."""
    cfg = small(symmetry=["x2"], fixed=[[3, 1]])
    whole = run_optimization(cfg, tmp_path / "whole", max_iter=4)
    run_optimization(cfg, tmp_path / "part", max_iter=2)
    ckpt = Checkpoint.read(tmp_path / "part" / "checkpoint.npz")
    beta, alpha = ckpt.bundle.x, ckpt.alpha
    assert beta.size == 15 and alpha.size == 32 and np.array_equal(alpha.reshape(8, 4), alpha.reshape(8, 4)[:, ::-1])
    resumed = run_optimization(cfg, tmp_path / "part", max_iter=4, resume=True)
    assert resumed.summary["alpha"] == whole.summary["alpha"]
    assert resumed.summary["J"] == whole.summary["J"]
    assert ((tmp_path / "part" / "iterations.csv").read_text() == (tmp_path / "whole" / "iterations.csv").read_text())
