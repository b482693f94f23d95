"""Symmetry planes through the contact face, and node classes that round-off does not decide.

A half (quarter) model with u = 0 normal to its symmetry plane(s) must give the full model's state
at a symmetric design: the same u_c, classes, and contact forces — the nodal forces of a node on
a symmetry plane carry half its tributary area in the half model (a quarter on two planes), so
they are half (a quarter) of the full model's there.
"""

import json

import numpy as np
import pytest
import tomli_w
from scipy.spatial import cKDTree

from contactopt._mpi import petsc_missing
from contactopt.cli import main
from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.fem.linsolve import pardiso_available
from contactopt.paths import select_path
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

try:
    import pyamg  # noqa: F401
    HAVE_PYAMG = True
except ImportError:
    HAVE_PYAMG = False

PATHS = ["condensation",
         pytest.param("delassus", marks=pytest.mark.skipif(not pardiso_available(), reason="needs MKL PARDISO")),
         pytest.param("fullspace", marks=pytest.mark.skipif(not HAVE_PYAMG, reason="needs pyamg")),
         pytest.param("petsc", marks=pytest.mark.skipif(petsc_missing() is not None, reason=f"{petsc_missing()}"))]


def example1(**updates):
    return load_config("example1").with_updates({"state": {"method": "newton", "tol": 1e-12}, **updates})


def half_example1(friction, path, nx=8, k=2, nz=3):
    """Example 1 (mesh nx × 2k × nz) and its half x2 ≤ 0.5 with u2 = 0 on x2 = 0.5; the half's
    design domain is the full face, so one α is one ϑ_α on both."""
    common = {"friction": {"coefficient": friction}, "linear_solver": {"path": path}}
    full = example1(**common, mesh={"nx": nx, "ny": 2 * k, "nz": nz})
    half = example1(**common, geometry={"b": 0.5}, mesh={"nx": nx, "ny": k, "nz": nz},
                    design={"domain": [[0.0, 2.0], [0.0, 1.0]]},
                    body={"clamped": ["clamped", {"on": {"x2": 0.5}, "components": [2]}]})
    return ShapeProblem(full), ShapeProblem(half)


def symmetric_design(shape, seed=1, amp=0.004):
    """Control points α_{i,j} = α_{i,d2−j}: ϑ_α symmetric about x2 = 0.5."""
    a = np.random.default_rng(seed).uniform(0.0, amp, shape)
    return (0.5 * (a + a[:, ::-1])).ravel()


def compare(full, part, a_full, a_part, planes):
    """Largest differences (λ, τ, u_c relative to their scales) between the full model's state
    and the part model's, node by node; ``planes`` [(axis, value)] of the part's symmetry planes."""
    sf, sp = full.solve_state(a_full), part.solve_state(a_part)
    xf = full.model.body.reference.points[full.model.contact_nodes]
    xp = part.model.body.reference.points[part.model.contact_nodes]
    d, idx = cKDTree(xf).query(xp)
    assert d.max() < 1e-12
    share = np.ones(xp.shape[0])            # the part's share of a node's tributary area
    for axis, value in planes:
        share[np.abs(xp[:, axis] - value) < 1e-9] *= 0.5
    fscale = sf.lam.max()
    out = {"lam": np.abs(sf.lam[idx] * share - sp.lam).max() / fscale,
           "tau": np.abs(sf.tau[idx] * share[:, None] - sp.tau).max() / fscale,
           "u_c": np.abs(sf.u_c[idx] - sp.u_c).max() / np.abs(sf.u_c).max(),
           "classes": np.array_equal(sf.classes[idx], sp.classes)}
    return out, sf, sp, share


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("friction", [0.3, 0.0])
def test_half_model_of_example1_equals_the_full_model(friction, path):
    full, half = half_example1(friction, path)
    assert half.model.pinned_dofs.size == 8           # u2 on x2 = 0.5 but at the clamped corner x1 = 0
    alpha = symmetric_design((8, 4))
    diff, sf, sh, share = compare(full, half, alpha, alpha, [(1, 0.5)])
    assert diff["classes"], (sf.counts, sh.counts)
    assert diff["lam"] < 1e-8 and diff["tau"] < 1e-8 and diff["u_c"] < 1e-8, diff
    on_plane = share < 1
    assert np.all(sh.tau[on_plane, 1] == 0.0) and np.all(sh.u_c[on_plane, 1] == 0.0)
    # the plane carries contact, and with friction its nodes slide along it (1-D friction)
    assert np.sum(sh.lam[on_plane] > 0) >= 4
    if friction:
        assert sh.counts["M1"] > 0 and sh.counts["M3+"] > 0


def hertz_models(friction, path, n=8, R=5.0, delta=0.04):
    """A paraboloid g = ((x1−1)² + (x2−1)²)/2R − δ pressed δ into the plane by a block 2 × 2 × 1
    clamped at its top (mesh 2n × 2n × 4), and its quarter [0, 1]² with u1 = 0 on x1 = 1 and
    u2 = 0 on x2 = 1; both with the design domain [0, 2]², where ϑ_α is that paraboloid at
    α_ij = (p_i + p_j)/2R − δ, p = (1, −1, 1) the Bernstein coefficients of (2t − 1)²."""
    common = {"friction": {"coefficient": friction}, "linear_solver": {"path": path},
              "material": {"nu": 0.3},
              "loads": {"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]},
              "design": {"degree": [2, 2], "domain": [[0.0, 2.0], [0.0, 2.0]], "initial": 0.0, "C2": 0.0}}
    full = example1(**common, geometry={"a": 2.0, "b": 2.0, "c": 1.0}, mesh={"nx": 2 * n, "ny": 2 * n, "nz": 4},
                    body={"clamped": "top"})
    quarter = example1(**common, geometry={"a": 1.0, "b": 1.0, "c": 1.0}, mesh={"nx": n, "ny": n, "nz": 4},
                       body={"clamped": ["top", {"on": {"x1": 1.0}, "components": [1]},
                                         {"on": {"x2": 1.0}, "components": [2]}]})
    p = np.array([1.0, -1.0, 1.0])
    alpha = ((p[:, None] + p[None, :]) / (2 * R) - delta).ravel()
    return ShapeProblem(full), ShapeProblem(quarter), alpha


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("friction", [0.3, 0.0])
def test_quarter_model_of_a_hertz_contact_equals_the_full_model(friction, path):
    full, quarter, alpha = hertz_models(friction, path)
    diff, sf, sq, share = compare(full, quarter, alpha, alpha, [(0, 1.0), (1, 1.0)])
    assert diff["classes"], (sf.counts, sq.counts)
    assert diff["lam"] < 1e-8 and diff["tau"] < 1e-8 and diff["u_c"] < 1e-8, diff
    centre = np.flatnonzero(share == 0.25)
    assert centre.size == 1 and np.argmax(sq.lam / share) == centre[0]     # the peak at the centre
    assert np.all(sq.u_c[centre[0], :2] == 0.0) and np.all(sq.tau[centre[0]] == 0.0)
    # the centre keeps the normal law alone: M3+ (sticking) with friction, M1 without (F = 0
    # leaves the tangential directions free: sticking and sliding are one class there)
    assert sq.class_names[centre[0]] == ("M3+" if friction else "M1")
    if friction:
        assert sq.counts["M1"] > 0 and sq.counts["M3+"] > 1     # slip at the rim, stick inside


@pytest.mark.parametrize("friction,path", [(0.3, "condensation"), (0.0, "condensation"),
                                           pytest.param(0.3, "fullspace", marks=PATHS[2].marks),
                                           pytest.param(0.3, "petsc", marks=PATHS[3].marks),
                                           pytest.param(0.3, "delassus", marks=[pytest.mark.slow, *PATHS[1].marks])])
def test_half_model_subgradient_matches_central_differences(friction, path):
    _, half = half_example1(friction, path)
    alpha = half.model.initial_design() + 0.005 * np.sin(np.arange(half.model.n_design))
    alpha += 0.01 - alpha.mean()
    rep = check_gradient(half, alpha, seed=1, n_directions=4)
    st = half.solve_state(alpha)
    plane = half.model.contact_pinned[:, 1]
    assert np.sum(st.class_names[plane] == "M1") >= 3          # the plane's nodes slide along it
    assert rep.n_degenerate == 0
    # the full-space paths' states stop at their own tolerance (paths.fullspace.FULLSPACE_TOL)
    assert np.max(rep.rel_errors) <= (1e-6 if path in ("fullspace", "petsc") else 1e-7), rep.rel_errors
    assert rep.taylor_rate >= 1.9


def column(friction, path):
    """A column 1 × 1 × 2 (ν = 0) clamped at its top, under its own weight, standing on the plane:
    its contact face does not move (u_c = 0 up to round-off), the pressure is uniform."""
    return ShapeProblem(example1(
        geometry={"a": 1.0, "b": 1.0, "c": 2.0}, mesh={"nx": 4, "ny": 4, "nz": 6},
        material={"nu": 0.0}, friction={"coefficient": friction}, linear_solver={"path": path},
        body={"clamped": "top"},
        loads={"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0], "body_force": [0.0, 0.0, -1.0]},
        design={"degree": [2, 2], "initial": 0.0, "C2": 0.0}))


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("friction", [0.3, 0.0])
def test_a_column_whose_contact_face_does_not_move_sticks_everywhere(friction, path):
    pr = column(friction, path)
    st = pr.solve_state(pr.model.initial_design())
    assert np.abs(st.u_c).max() < 1e-10 * np.abs(st.u).max()          # u_c is the solver's tolerance
    areas = pr.model.contact_areas()
    assert np.ptp(st.lam / areas) < 1e-10 * np.max(st.lam / areas)     # uniform pressure
    # every node sticks in contact: M3+ with friction; without friction the tangential law is
    # τ = 0 with u_t free, which the classes (and the adjoint) treat as sliding, M1
    assert st.counts["M3+" if friction else "M1"] == pr.model.n_contact, st.counts


def test_a_clamped_normal_component_leaves_the_contact_set_with_a_warning(caplog):
    # one node of the face clamped in u3 only (a point support): no contact node, named
    full, _ = half_example1(0.3, "condensation")
    cfg = example1(mesh={"nx": 8, "ny": 4, "nz": 3},
                   body={"clamped": ["clamped", {"on": {"box": [[1.0, 1.0], [0.5, 0.5], [0.0, 0.0]]},
                                                 "components": [3]}]})
    with caplog.at_level("WARNING"):
        pr = ShapeProblem(cfg)
    node = np.flatnonzero(np.all(np.abs(pr.model.body.reference.points - [1.0, 0.5, 0.0]) < 1e-12, axis=1))[0]
    assert node not in pr.model.contact_nodes
    assert pr.model.n_contact == full.model.n_contact - 1 and pr.model.pinned_dofs.size == 0
    assert any(f"u3 clamped and are no contact nodes: nodes {node}" in r.getMessage() for r in caplog.records)


def test_clamped_normal_component_on_more_than_half_the_face_exits_2_and_writes_nothing(tmp_path, capsys):
    data = example1(mesh={"nx": 8, "ny": 4, "nz": 3}).data
    data["body"]["clamped"] = ["clamped", {"on": {"box": [[0.0, 1.25], [0.0, 1.0], [0.0, 0.0]]}, "components": [3]}]
    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(data))
    out = tmp_path / "out"
    assert main(["state", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "normal component u3 is clamped on 30 of the 45 nodes" in err and "more than half" in err
    assert not out.exists()


def test_partly_clamped_contact_nodes_and_an_elastic_foundation_are_refused():
    cfg = example1(foundation={"block": {"size": [3.0, 2.0, 1.0], "cells": [6, 4, 2], "origin": [-0.5, -0.5]}})
    with pytest.raises(ConfigError, match=r"elastic \[foundation\] does not take"):
        select_path(cfg, 1000, pinned=8)


def test_the_state_command_on_a_half_model(tmp_path):
    # the CLI end to end: a symmetric design of the full model's control points on the half
    _, half = half_example1(0.3, "condensation")
    path = tmp_path / "half.toml"
    path.write_text(tomli_w.dumps(half.config.data))
    alpha = tmp_path / "a.json"
    alpha.write_text(json.dumps({"alpha": np.full((8, 4), 0.01).tolist()}))
    out = tmp_path / "st"
    assert main(["state", str(path), "--alpha", str(alpha), "--out", str(out)]) == 0
    assert (out / "state.json").stat().st_size > 0
