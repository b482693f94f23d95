"""Load cases: one factorization per design, per-case states, the max and sum objectives."""

import json

import numpy as np
import pytest
import tomli_w

from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.io.checkpoint import Checkpoint
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization
from contactopt.sensitivity.adjoint import subgradient
from contactopt.sensitivity.check import check_gradient

SMALL = {"mesh": {"nx": 8, "ny": 4, "nz": 3}}
PULL = [5e-2, 0.0, 0.0]
PUSH = [-5e-2, 0.0, 0.0]


def two_cases(**objective):
    """Example 1 on a small mesh: the paper's loads ("pull") and the side traction reversed ("push")."""
    cfg = load_config("examples/example1_two_cases.toml").with_updates(SMALL)
    return cfg.with_updates({"objective": objective}) if objective else cfg


def single(right_traction):
    return load_config("example1").with_updates({**SMALL, "loads": {"right_traction": right_traction}})


def wavy(problem, amp=0.005, phase=0.0):
    a = problem.model.initial_design() + amp * np.sin(np.arange(problem.model.n_design) + phase)
    return a + 0.01 - a.mean()


def config_problems(raw) -> list[str]:
    with pytest.raises(ConfigError) as exc:
        load_config(raw)
    return exc.value.problems


# ---------------------------------------------------------------- configuration
def test_load_cases_are_what_the_user_wrote_plus_explicit_loads():
    cfg = two_cases()
    # with cases the block's default side traction is off: [loads] holds only what the file writes
    assert cfg["loads"]["right_traction"] == [0.0, 0.0, 0.0]
    pr = ShapeProblem(cfg)
    assert pr.case_names == ("pull", "push")
    for case, t in zip(pr.cases, (PULL, PUSH)):
        loads = {name: list(v) for name, _, v in case.loads.tractions if np.any(v)}
        assert loads == {"top": [0.0, 0.0, -8e-2], "right": t}


def test_bad_load_cases_are_all_reported_at_once():
    base = load_config("example1").with_updates(SMALL).data
    cases = [{"name": "a", "right_traction": PULL}, {"name": "a", "top_traction": [1, 2], "spin": 1}]
    problems = config_problems({**base, "load_cases": cases,
                                "objective": {**base["objective"], "weights": [1.0, 2.0, 3.0]}})
    text = "\n".join(problems)
    assert "load_cases[1].name = 'a': another case has this name" in text
    assert "load_cases[1].top_traction" in text and "load_cases[1].spin: unknown key" in text
    assert "objective.weights: has 3 number(s) for 2 load cases" in text
    problems = config_problems({**base, "load_cases": [{"name": "a"}, {"name": "b"}],
                                "objective": {**base["objective"], "weights": {"a": 1.0, "c": 2.0}}})
    assert any("objective.weights.c: no load case has this name (cases: a, b)" in p for p in problems)
    problems = config_problems({**base, "objective": {**base["objective"], "combine": "sum", "weights": [1.0]}})
    assert any("objective.combine = 'sum': combines load cases, but the configuration has no [[load_cases]]"
               in p for p in problems)
    assert any("objective.weights: weighs load cases" in p for p in problems)
    problems = config_problems({**base, "load_cases": [{"name": "a", "target": {"kind": "constant", "value": "x"}}],
                                "objective": {**base["objective"], "type": "compliance"}})
    assert any("load_cases[0].target.value: must be a finite number" in p for p in problems)
    assert any("a case's target is the target of objective.type = 'target_normal_force'" in p for p in problems)
    assert any("load_cases: must be a non-empty array" in p for p in config_problems({**base, "load_cases": []}))


def test_resolved_configuration_round_trips(tmp_path):
    cfg = two_cases(combine="sum", weights={"push": 2.0})
    path = tmp_path / "c.toml"
    path.write_text(cfg.to_toml())
    again = load_config(str(path))
    assert again.data == cfg.data
    assert ShapeProblem(again).combination.weights.tolist() == [1.0, 2.0]


# ---------------------------------------------------------------- one code path
def test_one_case_is_the_configuration_without_cases():
    """[[load_cases]] with one case holding Example 1's loads = Example 1, to the last bit."""
    ref = ShapeProblem(load_config("example1").with_updates(SMALL))
    raw = load_config("example1").with_updates(SMALL).data
    loads = raw.pop("loads")
    one = ShapeProblem(load_config({**raw, "load_cases": [{"name": "paper", **loads}]}))
    assert len(ref.cases) == 1 and ref.cases[0].loads is None and not ref.has_load_cases
    for phase in (0.0, 1.0):
        alpha = wavy(ref, phase=phase)
        a, b = subgradient(ref, alpha), subgradient(one, alpha)
        assert a.value == b.value and np.array_equal(a.gradient, b.gradient)
        assert a.active_cases == (ref.config.name,) and b.active_cases == ("paper",)


def test_each_case_is_the_single_case_problem_of_its_loads():
    """One factorization for all cases: Θ_k and λ_k as if each case were a problem of its own."""
    pr = ShapeProblem(two_cases())
    alpha = wavy(pr)
    res = subgradient(pr, alpha)
    assert pr.n_state_solves == 1                               # one condensation for both cases
    for k, t in enumerate((PULL, PUSH)):
        alone = ShapeProblem(single(t))
        st = alone.solve_state(alpha)
        assert res.case_values[k] == pytest.approx(alone.evaluate_value(alpha), rel=1e-9)
        assert np.allclose(res.states[k].lam, st.lam, rtol=0, atol=1e-11 * st.lam.max())
    # the max objective's subgradient is that of the worst case alone
    k = int(np.argmax(res.case_values))
    alone = ShapeProblem(single((PULL, PUSH)[k]))
    assert res.case == pr.case_names[k] and res.value == res.case_values[k]
    assert np.allclose(res.gradient, alone.evaluate(alpha)[1], rtol=0, atol=1e-9 * np.abs(res.gradient).max())


# ---------------------------------------------------------------- subgradients vs central differences
@pytest.mark.parametrize("objective,active", [({"combine": "max"}, "pull"),
                                              ({"combine": "max", "weights": [1.0, 3.0]}, "push"),
                                              ({"combine": "sum", "weights": [0.7, 1.3]}, None)])
@pytest.mark.integration
def test_combined_subgradient_matches_central_differences(objective, active):
    pr = ShapeProblem(two_cases(**objective))
    alpha = wavy(pr)
    res = subgradient(pr, alpha)
    assert [st.n_degenerate for st in res.states] == [0, 0]
    w = pr.combination.weights * res.case_values
    if active:                                  # one case clearly active: the max is smooth here
        assert res.active_cases == (active,) and res.case == active and res.exact
        assert w.max() > 1.3 * w.min()
    else:
        assert res.value == pytest.approx(w.sum(), rel=1e-14) and res.exact
    rep = check_gradient(pr, alpha, seed=3, n_directions=6)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


def test_compliance_of_each_case_takes_the_derivative_of_its_own_loads():
    """Σ_k L_kᵀu_k: each case's ∂J/∂α at fixed u holds ∂L_k/∂α of the case's loads (its side
    traction on a face whose area moves with α), not of [loads]; the sum against central
    differences to 1e-6 (with the derivative of [loads] in its place, 1.6e-2 relative)."""
    pr = ShapeProblem(two_cases(type="compliance", combine="sum"))
    alpha = wavy(pr)
    res = subgradient(pr, alpha)
    assert [st.n_degenerate for st in res.states] == [0, 0]
    # h = 1e-7: the differences' error falls as h² here (1.7e-5 at h = 1e-5, 1.7e-7 at 1e-6, 2e-9 at 1e-7)
    h, rng = 1e-7, np.random.default_rng(8)
    directions = [rng.standard_normal(alpha.size) for _ in range(3)]
    fd = np.array([(pr.evaluate_value(alpha + h * d) - pr.evaluate_value(alpha - h * d)) / (2 * h)
                   for d in directions])
    g = np.array([res.gradient @ d for d in directions])
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(fd).max()


def test_tied_cases_are_reported_active():
    pr = ShapeProblem(two_cases())
    alpha = wavy(pr)
    v = subgradient(pr, alpha).case_values
    tied = ShapeProblem(two_cases(weights=[1.0, v[0] / v[1]], active_tol=1e-6))
    res = subgradient(tied, alpha)
    assert res.active_cases == ("pull", "push") and res.n_active == 2 and not res.exact
    loose = ShapeProblem(two_cases(active_tol=0.0))
    assert subgradient(loose, alpha).active_cases == ("pull",)


# ---------------------------------------------------------------- runs, outputs, resume
class _Stop(BaseException):
    pass


@pytest.mark.integration
def test_run_outputs_every_case_and_resume_is_exact(tmp_path):
    cfg_path = tmp_path / "two.toml"
    cfg_path.write_text(tomli_w.dumps(two_cases().with_updates({"name": "two"}).data))
    ref = run_optimization(str(cfg_path), tmp_path / "ref", max_iter=10)
    s = ref.summary
    lc = s["load_cases"]
    assert lc["names"] == ["pull", "push"] and lc["combine"] == "max"
    assert s["J0"] == max(lc["J0"].values()) and s["J"] == pytest.approx(max(lc["J"].values()), rel=1e-12)
    assert set(lc["active"]) <= {"pull", "push"} and lc["active"]
    assert (ref.outdir / "cases.png").stat().st_size > 0
    rows = (ref.outdir / "history.csv").read_text().strip().splitlines()
    header = rows[0].split(",")
    assert header[-3:] == ["f_pull", "f_push", "active_cases"] and len(rows) == 1 + s["evaluations"]
    for r in rows[1:]:
        f, fk = float(r.split(",")[2]), [float(x) for x in r.split(",")[-3:-1]]
        assert f == max(fk) and r.split(",")[-1] in ("pull", "push", "pull;push")
    z = Checkpoint.read(ref.outdir / "checkpoint.npz").contexts
    assert z[1][0]["warm"].shape == z[0][0]["warm"].shape and z[1][0]["zone"].size

    def stop_after_3(p):
        if p["iteration"] == 3:
            raise _Stop
    out = tmp_path / "killed"
    with pytest.raises(_Stop):
        run_optimization(str(cfg_path), out, max_iter=10, progress=stop_after_3)
    res = run_optimization(str(cfg_path), out, resume=True)
    a, b = ref.summary, res.summary
    assert a["iterations"] > 3
    assert (b["iterations"], b["evaluations"]) == (a["iterations"], a["evaluations"])
    assert np.array_equal(b["alpha"], a["alpha"]) and b["load_cases"]["J"] == a["load_cases"]["J"]
    ha, hb = ((d / "history.csv").read_text().splitlines() for d in (ref.outdir, out))
    cut = [0, 1, 2, 3, 4, 5, 6, 7, 9, 10, 11]          # every column but the wall time
    assert [[r.split(",")[i] for i in cut] for r in ha] == [[r.split(",")[i] for i in cut] for r in hb]
    assert json.loads((out / "summary.json").read_text())["load_cases"]["J"] == a["load_cases"]["J"]


def test_cases_share_the_factor_of_s_to_the_last_bit():
    from contactopt.contact.zone import ZoneProblem
    from contactopt.paths.condensation import on_factor as _on_factor
    pr = ShapeProblem(two_cases())
    alpha = wavy(pr)
    pr.solve_state(alpha)
    conds = [pr.cached_system(alpha, k) for k in range(2)]
    zp0 = ZoneProblem(conds[0].S, conds[0].ell, np.arange(10), ordered=False)
    zone = np.arange(3, 17)
    fresh = ZoneProblem(conds[1].S, conds[1].ell, zone, ordered=False)
    shared = _on_factor(zp0, conds[1].ell, zone)
    r = np.linspace(0.1, 1.0, 3 * zone.size)
    assert np.array_equal(shared.q0, fresh.q0) and np.array_equal(shared.product(r), fresh.product(r))
    assert np.array_equal(shared.displacements(r), fresh.displacements(r)) and np.array_equal(shared.W, fresh.W)


def test_block_loads_in_a_case_on_a_body_from_a_file_are_refused():
    from pathlib import Path
    mesh = str(Path(__file__).parent / "data" / "two_groups.msh")
    problems = config_problems({"body": {"mesh": mesh},
                                "load_cases": [{"name": "a", "traction": [{"on": "top", "value": [0, 0, -1.0]}]},
                                               {"name": "b", "right_traction": PULL}]})
    assert [p for p in problems if "load_cases" in p] == [
        "<dict>: load_cases[1].right_traction: is a load on a part of the built-in block; on a body from a "
        "file use traction = [{ on = \"<part>\", value = [...] }]"]
