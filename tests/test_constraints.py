"""Nonlinear constraints c(x) ≤ 0 in the bundle method (optimize/constrained.py) and the
[[constraints]] of a configuration: the constrained test problems reach their known optima
(under every BLAS kernel in the slow tier), σ grows from a small start and a resumed run repeats
an uninterrupted one; each constraint's subgradient matches central differences; bad input
exits 2 and writes nothing; state.json and summary.json report value, limit and margin."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.optimize.constrained import PenaltyState, minimize_constrained
from contactopt.optimize.gallery import CONSTRAINED
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

ROOT = Path(__file__).resolve().parents[1]
REL = 1e-6          # f within 1e-6 (relative, of max(1, |f*|)) of the known optimum
CTOL = 1e-8


def solve(prob, **kw):
    return minimize_constrained(prob, prob.x0, ctol=CTOL, eps=1e-7, max_iter=3000, **prob.constraints(), **kw)


# ------------------------------------------------------------------ test problems with known optima
@pytest.mark.parametrize("name", list(CONSTRAINED))
def test_constrained_problems_reach_their_optimum(name):
    prob = CONSTRAINED[name]
    res = solve(prob)
    assert np.max(res.constraints) <= CTOL, res.constraints
    assert abs(res.objective - prob.f_star) <= REL * max(1.0, abs(prob.f_star)), (res.objective, prob.f_star)
    # the returned design is feasible for U as well (the linear rows)
    if prob.A_ub is not None:
        assert np.max(prob.A_ub @ res.x - prob.b_ub) <= 1e-9


def test_the_optimum_is_where_the_docstring_says():
    """x* of the constructed problems, and the oracle's answers there (f* and c = 0 active)."""
    f, _, c, _ = CONSTRAINED["C-L1-halfspace"](np.array([0.0, 0.0, 1.0 / 3.0]))
    assert f == pytest.approx(1 / 3, abs=1e-15) and c[0] == pytest.approx(0.0, abs=1e-15)
    f, _, c, _ = CONSTRAINED["C-Linf-L1ball"](np.full(10, 1.9))
    assert f == 1.9 and abs(c[0]) <= 1e-14
    f, _, c, _ = CONSTRAINED["C-Rosen-Suzuki"](np.array([0.0, 1.0, 2.0, -1.0]))
    assert f == -44.0 and c[0] == 0.0


def test_a_small_first_weight_is_raised_until_the_result_is_feasible():
    prob = CONSTRAINED["C-Rosen-Suzuki"]
    res = solve(prob, sigma0=0.01)
    assert res.outer >= 2 and res.sigma == pytest.approx(0.01 * 10 ** res.outer)
    assert np.max(res.constraints) <= CTOL
    assert abs(res.objective - prob.f_star) <= REL * abs(prob.f_star)
    # the counts and the history run over every bundle run
    assert res.nit == len(res.history) and res.history[-1]["iteration"] == res.nit
    assert [r["iteration"] for r in res.history] == list(range(1, res.nit + 1))


def test_the_multiplier_estimate_is_above_the_multiplier():
    """Rosen–Suzuki at x*: ∇f + μ1∇g1 + μ3∇g3 = 0 with μ = (1, 2) (∇f = (−5, −3, −13, 5),
    ∇g1 = (1, 1, 5, −3), ∇g3 = (2, 1, 4, −1)); the ℓ∞
    penalty is exact for σ > μ1 + μ3 = 3, and the estimate from the oracle at x* is twice that."""
    from contactopt.optimize.constrained import multiplier_estimate
    prob = CONSTRAINED["C-Rosen-Suzuki"]
    x = np.array([0.0, 1.0, 2.0, -1.0])
    _, g, _, _ = prob(x)
    from contactopt.optimize.gallery import _rosen_suzuki_pieces
    z = x[None, :] + 1j * 1e-30 * np.eye(4)
    P = np.asarray(_rosen_suzuki_pieces(z)).imag.T / 1e-30          # ∇f, ∇f + 10∇g_i
    J = (P[1:] - P[0]) / 10
    assert multiplier_estimate(g, J) == pytest.approx(6.0, rel=1e-12)


def test_an_infeasible_limit_is_reported_not_hidden():
    """c(x) = 1 + ‖x‖² ≤ 0 has no solution: the run stops after max_outer raises, not successful."""
    def oracle(x):
        return float(x @ x), 2 * x, np.array([1.0 + x @ x]), (2 * x)[None, :]
    res = minimize_constrained(oracle, np.ones(2), ctol=1e-8, max_outer=3, max_iter=500)
    assert not res.success and res.status == 6 and res.outer == 3
    assert "infeasible" in res.message


def test_resuming_from_any_iteration_repeats_the_run_bit_for_bit():
    """The penalty state and the bundle state of a callback, across a raise of σ, give the rest of
    the uninterrupted run exactly (what the runner's checkpoint holds)."""
    prob = CONSTRAINED["C-Mifflin1"]
    snaps = []

    def keep(inter):
        snaps.append((inter.penalty.copy(), inter.state.copy()))
    whole = minimize_constrained(prob, prob.x0, ctol=CTOL, sigma0=0.01, max_iter=300, callback=keep)
    assert whole.outer >= 2
    raised = [k for k in range(1, len(snaps)) if snaps[k][0].sigma != snaps[k - 1][0].sigma]
    picks = sorted({1, len(snaps) // 2, raised[0] - 1, raised[0], len(snaps) - 2})
    for k in picks:
        pen, st = snaps[k]
        pen = PenaltyState.from_dict({key: np.asarray(v) for key, v in pen.to_dict().items()})    # via arrays
        again = minimize_constrained(prob, None, ctol=CTOL, max_iter=300, state=pen, bundle_state=st)
        assert np.array_equal(again.x, whole.x), k
        assert again.nit == whole.nit and again.nfev == whole.nfev and again.sigma == whole.sigma
        assert again.history == whole.history


def test_a_run_stopped_by_max_iter_goes_on_when_resumed_with_more():
    """The state of a run's end (what the runner's last checkpoint holds) resumes with a larger
    max_iter, across a raise of σ, to the uninterrupted run's end."""
    prob = CONSTRAINED["C-Rosen-Suzuki"]
    whole = minimize_constrained(prob, prob.x0, ctol=CTOL, sigma0=0.01, max_iter=400)
    assert whole.outer >= 2
    for stop in (5, whole.nit - 3):
        part = minimize_constrained(prob, prob.x0, ctol=CTOL, sigma0=0.01, max_iter=stop)
        assert part.status == 1 and part.nit == stop and "max_iter reached" in part.message
        again = minimize_constrained(prob, None, ctol=CTOL, max_iter=400, state=part.penalty, bundle_state=part.state)
        assert np.array_equal(again.x, whole.x) and again.history == whole.history and again.nfev == whole.nfev


# ------------------------------------------------------------------ [[constraints]] of a configuration
def hex_problem(constraints, path="condensation", objective=None):
    upd = {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "state": {"method": "newton", "tol": 1e-12},
           "linear_solver": {"path": path}, "constraints": constraints}
    if objective:
        upd["objective"] = objective
    return ShapeProblem(load_config("example1").with_updates(upd))


def wavy(problem, amp=0.005, mean=0.01):
    a = amp * np.sin(np.arange(problem.model.n_design))
    return a + mean - a.mean()


CONSTRAINTS = [{"type": "peak_stress", "max": 1.0, "region": {"box": [[0, 1], [0, 1], [0, 0.2]]}},
               {"type": "max_pressure", "max": 1.0},
               {"type": "compliance", "max": 1.0},
               {"type": "frictional_dissipation", "max": 1.0},
               {"type": "peak_stress", "max": 1.0, "aggregate": "ks", "rho": 20.0}]


def _gradient_cases():
    for body in ("hex", "tet"):
        for path in ("condensation", "delassus", "fullspace"):
            fast = (body, path) == ("hex", "condensation")
            yield pytest.param(body, path, marks=() if fast else (pytest.mark.slow,), id=f"{body}-{path}")


@pytest.mark.parametrize("body,path", list(_gradient_cases()))
def test_each_constraint_subgradient_matches_central_differences(body, path, tet_box_config):
    """At designs with a unique max and no degenerate node (compliance: condensation only)."""
    if path == "delassus":
        from contactopt.fem.linsolve import pardiso_available
        if not pardiso_available():
            pytest.skip("the Delassus path needs MKL PARDISO")
    tables = [t for t in CONSTRAINTS if path == "condensation" or t["type"] != "compliance"]
    problem = hex_problem(tables, path) if body == "hex" else ShapeProblem(tet_box_config(path, constraints=tables))
    alpha = wavy(problem) if body == "hex" else wavy(problem, 0.001, 0.002)
    worst = {}
    for j, con in enumerate(problem.constraints):
        with problem._as_objective(j):
            rep = check_gradient(problem, alpha, seed=j, n_directions=1 if path == "condensation" else 2)
        assert rep.n_degenerate == 0
        worst[con.name] = float(np.max(rep.rel_errors))
    assert max(worst.values()) <= 1e-6, worst
    assert list(worst) == [n for n in ["peak_stress", "max_pressure", "compliance", "frictional_dissipation",
                                       "peak_stress_2"] if n in {c.name for c in problem.constraints}]


def test_a_constraint_is_the_objective_of_its_type_with_a_limit():
    """One path, not two: the constraint's value and subgradient are those of the objective of the
    same type and keys, and the oracle's Θ is untouched by the constraints beside it."""
    table = CONSTRAINTS[0]
    problem = hex_problem([table])
    alpha = wavy(problem)
    res = problem.constraint_subgradients(alpha)[0]
    theta = problem.subgradient(alpha)
    alone = hex_problem([], objective={k: v for k, v in table.items() if k != "max"})
    ref = alone.subgradient(alpha)
    assert res.value == ref.value and np.array_equal(res.gradient, ref.gradient)
    plain = hex_problem([]).subgradient(alpha)
    assert theta.value == plain.value and np.array_equal(theta.gradient, plain.gradient)
    rep = problem.constraint_report(alpha)["peak_stress"]
    assert rep == {"type": "peak_stress", "value": ref.value, "limit": 1.0, "margin": 1.0 - ref.value}


def test_with_load_cases_a_constraint_holds_in_the_worst_case():
    """The response of a constraint is the largest of the cases' (each with its own loads)."""
    upd = {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "constraints": [{"type": "max_pressure", "max": 1.0}]}
    cfg = load_config(ROOT / "examples" / "example1_two_cases.toml").with_updates(upd)
    problem = ShapeProblem(cfg)
    alpha = wavy(problem)
    value = problem.constraint_values(alpha)[0]
    per_case = ShapeProblem(cfg.with_updates({"objective": {"type": "max_pressure"}, "constraints": []}))
    comb = per_case.evaluate_cases(alpha)
    assert len(comb.values) == 2 and comb.values[0] != comb.values[1]
    assert value == max(comb.values)
    res = problem.constraint_subgradients(alpha)[0]
    ref = per_case.subgradient(alpha)
    assert res.value == ref.value and np.array_equal(res.gradient, ref.gradient)


def test_a_symmetric_design_takes_constraints_on_its_reduced_variables(tmp_path):
    """[design] symmetry: the bundle works on β, the constraints' subgradients pulled back too."""
    from contactopt.runner import run_optimization
    cfg = load_config("example1").with_updates({
        "mesh": {"nx": 8, "ny": 4, "nz": 3}, "design": {"symmetry": ["x2"]}, "name": "sym",
        "constraints": [{"type": "max_pressure", "max": 0.02}]})
    s = run_optimization(cfg, tmp_path / "run", max_iter=4).summary
    assert s["design_variables"]["optimized"] < s["design_variables"]["alpha"]
    alpha = np.asarray(s["alpha"])
    assert np.array_equal(alpha, alpha[:, ::-1])
    resp = s["constraints"]["responses"]["max_pressure"]
    assert resp["limit"] == 0.02 and resp["margin"] == pytest.approx(0.02 - resp["value"], abs=1e-15)
    rows = (tmp_path / "run" / "history.csv").read_text().splitlines()
    assert rows[0].split(",")[-1] == "constraint_max_pressure" and len(rows) == s["evaluations"] + 1


@pytest.mark.parametrize("case,text,message", [
    ("type", '[[constraints]]\ntype = "volume"\nmax = 1.0\n', "constraints[0].type = 'volume'"),
    ("rho", '[[constraints]]\ntype = "peak_stress"\naggregate = "ks"\nrho = 0.0\nmax = 1.0\n', "constraints[0].rho"),
    ("p", '[[constraints]]\ntype = "max_pressure"\naggregate = "pnorm"\np = -1.0\nmax = 1.0\n', "constraints[0].p"),
    ("missing_max", '[[constraints]]\ntype = "compliance"\n', "constraints[0].max: missing"),
    ("key_of_another_type", '[[constraints]]\ntype = "compliance"\nregion = "top"\nmax = 1.0\n',
     "constraints[0].region: unknown key for type 'compliance'"),
    ("region", '[[constraints]]\ntype = "peak_stress"\nregion = "foot"\nmax = 1.0\n', "constraints[0].region"),
    ("no_admissible_design", '[[constraints]]\ntype = "max_pressure"\nmax = 0.0\n',
     "constraints[0].max = 0.0: must be a number > 0"),
    ("tol", '[[constraints]]\ntype = "compliance"\nmax = 1.0\ntol = 2.0\n', "constraints[0].tol"),
    # Σα ≤ 0.1 against the mean value Σα = 0.32: the linear rows beside a constraint
    ("rows_contradict_bounds", '[[constraints]]\ntype = "compliance"\nmax = 1.0\n', "leave no admissible design"),
])
def test_bad_constraints_exit_2_and_write_nothing(small_toml, refused_by_state_and_run, case, text, message):
    design = {"linear": [{"coefficients": np.ones((8, 4)).tolist(), "upper": 0.1}]} \
        if case == "rows_contradict_bounds" else {}
    refused_by_state_and_run(small_toml(text, design=design), message)


def test_state_json_reports_value_limit_and_margin(tmp_path, capsys, small_toml):
    cfg = small_toml('[[constraints]]\ntype = "max_pressure"\nmax = 0.5\n'
                     '[[constraints]]\ntype = "compliance"\nmax = 1e-9\n')
    out = tmp_path / "st"
    assert main(["state", str(cfg), "--out", str(out)]) == 0
    doc = json.loads((out / "state.json").read_text())["constraints"]
    assert list(doc) == ["max_pressure", "compliance"]
    problem = ShapeProblem(load_config(cfg))
    values = problem.constraint_values(problem.model.initial_design())
    for (_, c), v, lim in zip(doc.items(), values, (0.5, 1e-9)):
        assert c["value"] == pytest.approx(v, rel=1e-10) and c["limit"] == lim
        assert c["margin"] == pytest.approx(lim - v, rel=1e-10, abs=1e-18)
    assert doc["compliance"]["margin"] < 0 < doc["max_pressure"]["margin"]
    printed = capsys.readouterr().out
    assert "constraint compliance" in printed and "(violated)" in printed


# ------------------------------------------------------------------ runs (slow tier)
@pytest.mark.slow
def test_the_bracket_meets_the_stress_limit_that_the_unconstrained_optimum_breaks(tmp_path):
    from contactopt.runner import run_optimization
    free = run_optimization(ROOT / "examples" / "bracket_uniform.toml", tmp_path / "free").summary
    con = run_optimization(ROOT / "examples" / "bracket_stress.toml", tmp_path / "con").summary
    limit = load_config(ROOT / "examples" / "bracket_stress.toml")["constraints"][0]["max"]
    problem = ShapeProblem(load_config(ROOT / "examples" / "bracket_stress.toml"))
    peak_free = problem.constraint_values(np.asarray(free["alpha"]).ravel())[0]
    resp = con["constraints"]["responses"]["peak_stress"]
    assert peak_free > 1.1 * limit                      # the unconstrained optimum violates the limit
    assert resp["initial"]["value"] > limit             # so does the initial design
    assert resp["satisfied"] and abs(resp["margin"]) <= 1e-4 * limit        # met, and active
    assert free["J"] < con["J"] < con["J0"]
    rows = (tmp_path / "con" / "history.csv").read_text().splitlines()
    assert rows[0].endswith(",constraint_peak_stress") and len(rows) == con["evaluations"] + 1


@pytest.mark.slow
def test_check_gradient_passes_on_the_bracket_as_shipped(capsys):
    """At α0 the side load puts the peak stress at one point: Θ's and the constraint's subgradients
    agree with central differences (at the symmetric bracket's α0 the peak sat at two mirror
    points and the constraint's check failed). Taylor remainders of order 2: Θ's over the four
    steps, the constraint's over the two larger (on the two smaller they reach the states'
    round-off, 4e-14 … 6e-14 of a peak stress of 0.051, and the fit over all four prints 1.5)."""
    assert main(["check-gradient", str(ROOT / "examples" / "bracket_stress.toml"), "--directions", "3"]) == 0
    out = capsys.readouterr().out
    orders = [float(line.split()[2]) for line in out.splitlines() if line.strip().startswith("observed order")]
    rows = [[float(v) for v in line.split()[2::2]] for line in out.splitlines() if line.strip().startswith("h =")]
    assert len(orders) == 2 and len(rows) == 8 and orders[0] >= 1.9, out
    (h0, r0), (h1, r1) = rows[4], rows[5]                 # the constraint's two larger steps
    assert np.log(r0 / r1) / np.log(h0 / h1) >= 1.9, out


@pytest.mark.slow
@pytest.mark.parametrize("iteration", [60, 125])
def test_a_killed_constrained_run_resumes_bit_for_bit(tmp_path, iteration):
    """Killed (SIGKILL) after ``iteration`` — before and after σ is raised — and resumed with
    --resume: J, α, iterations.csv and history.csv (but its times) are those of the uninterrupted
    run. The bracket without its side load under the limit 0.019 (σ raised at iteration 107)."""
    import signal
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    data = load_config(ROOT / "examples" / "bracket_stress.toml").data
    data["loads"].pop("traction")
    data["constraints"][0]["max"] = 0.019
    cfg = tmp_path / "bracket_symmetric.toml"
    cfg.write_text(load_config(data).to_toml())

    def cmd(out, *extra):
        return [sys.executable, "-m", "contactopt.cli", "run", str(cfg), "--out", str(out), *extra]
    ref, part = tmp_path / "ref", tmp_path / "part"
    subprocess.run(cmd(ref), env=env, check=True, capture_output=True, timeout=1200)
    proc = subprocess.Popen(cmd(part), env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    for line in proc.stdout:
        if line.startswith("it ") and int(line.split()[1]) >= iteration:
            break
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stdout.close()
    subprocess.run(cmd(part, "--resume"), env=env, check=True, capture_output=True, timeout=1200)
    a, b = (json.loads((d / "summary.json").read_text()) for d in (ref, part))
    assert a["J"] == b["J"] and a["alpha"] == b["alpha"] and a["constraints"] == b["constraints"]
    assert (ref / "iterations.csv").read_text() == (part / "iterations.csv").read_text()

    def rows(d):
        lines = (d / "history.csv").read_text().splitlines()
        col = lines[0].split(",").index("time_s")
        return [[v for k, v in enumerate(r.split(",")) if k != col] for r in lines]
    assert rows(ref) == rows(part)


KERNEL_PROBE = """
import json, numpy as np
from contactopt.optimize.constrained import minimize_constrained
from contactopt.optimize.gallery import CONSTRAINED
out = {}
for name, p in CONSTRAINED.items():
    r = minimize_constrained(p, p.x0, ctol=1e-8, eps=1e-7, max_iter=3000, **p.constraints())
    out[name] = [r.objective, float(np.max(r.constraints)), int(r.nfev)]
print(json.dumps(out))
"""


@pytest.mark.slow
@pytest.mark.parametrize("kernel", ["Prescott", "Haswell", "SkylakeX", "Zen"])
def test_constrained_problems_reach_their_optimum_under_every_blas_kernel(kernel, kernel_probe):
    """In a subprocess with OPENBLAS_CORETYPE = kernel and one thread (a kernel whose
    instructions this CPU lacks would die of an illegal instruction: skipped)."""
    out = kernel_probe(kernel, KERNEL_PROBE)
    for name, (f, c, _) in out.items():
        f_star = CONSTRAINED[name].f_star
        assert c <= CTOL and abs(f - f_star) <= REL * max(1.0, abs(f_star)), (kernel, name, f, c)
