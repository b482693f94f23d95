"""The Delassus path for large meshes (issue #16): the same states and subgradients as the Schur
path (dense S on all contact DOFs), from a sparse Cholesky factorization of A(α) and Delassus
products by solves with it."""

import numpy as np
import pytest
import tomli_w

from contactopt.config import load_config
from contactopt.errors import ConfigError, SolverError
from contactopt.fem.krylov import KrylovNotConverged, gmres
from contactopt.fem.linsolve import pardiso_available
from contactopt.paths import select_path
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization
from contactopt.sensitivity.adjoint import subgradient

pytestmark = pytest.mark.skipif(not pardiso_available(), reason="the Delassus path needs MKL PARDISO")


def pair(name, path="delassus"):
    cfg = load_config(name)
    return (ShapeProblem(cfg.with_updates({"linear_solver": {"path": "condensation", "library": "pardiso"}})),
            ShapeProblem(cfg.with_updates({"linear_solver": {"path": path}})))


def designs(problem, n=3, step=5e-4):
    """α0 and next designs α0 + k·step·d (d volume-preserving, max |d| = 1), as in an optimization."""
    a0 = problem.model.initial_design()
    d = np.random.default_rng(7).standard_normal(a0.size)
    d -= d.mean()
    d /= np.abs(d).max()
    return [a0 + k * step * d for k in range(n)]


@pytest.mark.parametrize("path", ["delassus", "fullspace"])
@pytest.mark.parametrize("name", ["example1", "example2"])
def test_states_and_subgradients_agree_with_the_schur_path(name, path):
    ps, pd = pair(name, path)
    assert (ps.path.name, pd.path.name) == ("condensation", path)
    how = []
    for alpha in designs(ps):
        rs, rd = subgradient(ps, alpha), subgradient(pd, alpha)
        s, d = rs.state, rd.state
        f = np.abs(s.lam).max()
        u = np.abs(s.u_c).max()
        assert np.abs(d.lam - s.lam).max() <= 1e-8 * f
        assert np.abs(d.tau - s.tau).max() <= 1e-8 * f
        assert np.abs(d.u_c - s.u_c).max() <= 1e-8 * u
        assert np.abs(d.u - s.u).max() <= 1e-8 * np.abs(s.u).max()
        assert abs(rd.value - rs.value) <= 1e-10 * abs(rs.value)
        assert np.linalg.norm(rd.gradient - rs.gradient) <= 1e-6 * np.linalg.norm(rs.gradient)
        assert np.array_equal(d.classes, s.classes)
        assert d.info["path"] == path
        how.append(d.info["delassus"])
    if path == "delassus":
        # the first design forms W_Z (the zone's Schur complement), the next ones reuse it
        assert how[0] == "formed" and "reused" in how[1:]
    else:                           # full space: AMG hierarchy and GMRES, nothing factorized
        assert pd.path._hierarchy is not None and d.info["krylov_iterations"] > 0


def test_load_cases_agree_with_the_schur_path():
    small = {"mesh": {"nx": 8, "ny": 4, "nz": 3}}
    cfg = load_config("examples/example1_two_cases.toml").with_updates(small)
    ps = ShapeProblem(cfg.with_updates({"linear_solver": {"path": "condensation", "library": "pardiso"}}))
    pd = ShapeProblem(cfg.with_updates({"linear_solver": {"path": "delassus"}}))
    for alpha in designs(ps, 2):
        rs, rd = subgradient(ps, alpha), subgradient(pd, alpha)
        assert rd.case == rs.case
        assert np.allclose(rd.case_values, rs.case_values, rtol=1e-10, atol=0)
        assert np.linalg.norm(rd.gradient - rs.gradient) <= 1e-6 * np.linalg.norm(rs.gradient)
        for s, d in zip(rs.states, rd.states):
            assert np.abs(d.lam - s.lam).max() <= 1e-8 * np.abs(s.lam).max()


@pytest.mark.integration
def test_gradient_agrees_with_finite_differences():
    from contactopt.sensitivity.check import check_gradient
    _, pd = pair("example2")
    alpha = designs(pd)[1]
    rep = check_gradient(pd, alpha, seed=3, n_directions=4)
    assert rep.passed and rep.rel_errors.max() < 1e-5, rep.rel_errors


def test_auto_takes_the_full_space_path_from_the_crossover(monkeypatch):
    import contactopt.paths as paths
    ex1 = load_config("example1")

    def linear_path(path, n_free, objective, crossover=60_000):
        library = {"pardiso": "pardiso"}.get(path, "auto")
        path = {"pardiso": "condensation"}.get(path, path)
        return select_path(ex1.with_updates({"linear_solver": {"path": path, "library": library,
                                                               "crossover": crossover},
                                             "objective": {"type": objective}}), n_free)
    assert linear_path("auto", 10_000, "target_normal_force", 60_000)[0] == "condensation"
    assert linear_path("auto", 60_000, "target_normal_force", 60_000)[0] == "fullspace"
    monkeypatch.setattr(paths, "_have_pyamg", lambda: False)      # without pyamg: Delassus
    assert linear_path("auto", 60_000, "target_normal_force", 60_000)[0] == "delassus"
    monkeypatch.undo()
    assert linear_path("pardiso", 10**6, "target_normal_force", 60_000) == ("condensation", "pardiso")
    assert linear_path("fullspace", 10, "target_normal_force") == ("fullspace", "pyamg")
    # compliance needs ℓ on every contact DOF: auto stays on the condensation, an explicit choice is refused
    assert linear_path("auto", 10**6, "compliance", 60_000)[0] == "condensation"
    with pytest.raises(ConfigError, match="compliance"):
        linear_path("delassus", 10, "compliance")
    p = ShapeProblem(load_config("example1").with_updates({"linear_solver": {"crossover": 100}}))
    assert p.path.name == "fullspace"


def test_uniqueness_bound_is_not_computed_without_s():
    _, pd = pair("example2")
    assert np.isnan(pd.uniqueness_bound(pd.model.initial_design()))


def test_memory_estimates_of_the_large_mesh_paths():
    from contactopt.fem.memory import condensation_parts, delassus_parts, estimate_counts, fullspace_parts
    n, c, cells, nnz = 866_688, 23_424, 276_480, 70_000_000
    s, d = estimate_counts(n, c, cells, nnz, condensation_parts), estimate_counts(n, c, cells, nnz, delassus_parts)
    kept = estimate_counts(n, c, cells, nnz, delassus_parts, keep_cholesky=True)
    a = estimate_counts(n, c, cells, nnz, fullspace_parts)
    # the Delassus path's peak is its first design (W_Z of a zone that may hold every contact
    # node): the Schur path's, plus the Cholesky where it is kept beside the zone's factor
    assert d.total <= s.total < kept.total
    assert "factor" not in a.parts and a.total < 0.3 * d.total


def test_gmres_converges_and_reports_its_history():
    rng = np.random.default_rng(0)
    n = 120
    Q = 3 * np.eye(n) + rng.standard_normal((n, n)) / np.sqrt(n)
    b = rng.standard_normal(n)
    P = np.linalg.inv(Q + 1e-2 * rng.standard_normal((n, n)) / np.sqrt(n))
    res = gmres(lambda x: Q @ x, b, lambda r: P @ r, rtol=1e-12)
    assert np.linalg.norm(Q @ res.x - b) <= 1e-11 * np.linalg.norm(b)
    assert res.iterations <= 8 and res.history[0] == 1.0
    plain = gmres(lambda x: Q @ x, b, rtol=1e-12)
    assert plain.iterations > res.iterations
    with pytest.raises(KrylovNotConverged) as exc:
        gmres(lambda x: Q @ x, b, rtol=1e-12, max_iter=4)
    assert isinstance(exc.value, SolverError) and len(exc.value.history) >= 4
    assert exc.value.history[-1] > 1e-12 and "did not converge" in str(exc.value)


def test_adjoint_that_does_not_converge_raises_with_its_history():
    from contactopt.sensitivity import adjoint
    _, pd = pair("example2")
    alpha = designs(pd)[1]
    pd.solve_state(alpha)
    keep = adjoint.ADJOINT_RTOL
    adjoint.ADJOINT_RTOL = 1e-30                # unreachable: GMRES must say so, not return
    try:
        with pytest.raises(KrylovNotConverged) as exc:
            subgradient(pd, alpha)
    finally:
        adjoint.ADJOINT_RTOL = keep
    assert len(exc.value.history) > 2 and exc.value.history[-1] < 1e-6


@pytest.mark.integration
@pytest.mark.parametrize("path", ["delassus", "amg"])
def test_run_and_resume_are_exact(tmp_path, path):
    """The Delassus path rebuilds its kept block, the full-space path its AMG hierarchy (seeded,
    one OpenBLAS thread) and takes the last displacement from the checkpoint."""
    cfg = load_config("example2").with_updates({"name": "d2", "linear_solver": {"backend": path}})
    path = tmp_path / "d2.toml"
    path.write_text(tomli_w.dumps(cfg.data))
    ref = run_optimization(str(path), tmp_path / "ref", max_iter=8)

    class Stop(BaseException):
        pass

    def stop_after_3(p):
        if p["iteration"] == 3:
            raise Stop
    with pytest.raises(Stop):
        run_optimization(str(path), tmp_path / "cut", max_iter=8, progress=stop_after_3)
    res = run_optimization(str(path), tmp_path / "cut", resume=True)
    a, b = ref.summary, res.summary
    assert (b["iterations"], b["evaluations"]) == (a["iterations"], a["evaluations"]) and a["iterations"] > 3
    assert np.array_equal(b["alpha"], a["alpha"]) and b["J"] == a["J"]


def test_cholesky_released_for_the_zone_schur_complement_gives_the_same_results():
    """Where both factors do not fit in memory, the Cholesky is released while W_Z is formed and
    the zone's condensation (with S⁻¹ = W_Z) serves the design's remaining solves."""
    from contactopt.fem.linsolve import PardisoCondensation
    ps, pd = pair("example2")
    pd.path._keep_cholesky = False
    for k, alpha in enumerate(designs(ps, 2)):
        rs, rd = subgradient(ps, alpha), subgradient(pd, alpha)
        if k == 0:       # W_Z formed: the Cholesky is gone, the condensation solves without S
            assert pd.path._factor is None and isinstance(pd.path._slot.current, PardisoCondensation)
            assert pd.path._slot.current.S is None and pd.path._slot.current.S_inverse is not None
        assert np.abs(rd.state.lam - rs.state.lam).max() <= 1e-8 * np.abs(rs.state.lam).max()
        assert np.linalg.norm(rd.gradient - rs.gradient) <= 1e-6 * np.linalg.norm(rs.gradient)
    assert pd.path._factor is not None          # the next design factorized anew
