"""Two bodies and more, and rigid obstacles, on the PETSc path: the elastic counterparts' DOFs in
the Newton system of all bodies (paths/coupled.py's change of unknowns, each body's rows spread over the ranks by
fem/distributed.py's DistributedBodies) against the pyamg full-space path — the same method, a
different linear algebra and numbering — on one process and under ``mpiexec -n 2``: Θ, the state
(u, λ, τ), ξ and v_λ at two designs (tests/mpi/compare_paths.py), within 1e-9 relative (measured
≤ 5e-13). Then ξ against central differences on two ranks (friction with sliding nodes, mortar
partners), an objective of the whole displacement along a load path (the product A(α) x through
T⁻¹), a resumed two-body run on two ranks bit for bit, and what the path does not take, refused
by name. A counterpart or a face body held only by its contacts is anchored as on the full space
(paths/floating.py). A rigid obstacle other than the plane is the same change of unknowns with no counterpart
DOFs (T the nodes' frames, paths/transforms.py FrameChange); a force-controlled one runs the
translation's search around the PETSc solve.

Conventions: per contact node (t1, t2, ν), r the contact force on the body, λ = r_ν ≥ 0, w =
u_body − u_partner the state's u_c. Skipped without petsc4py/mpi4py; ``.ci/run`` runs this file
with them installed.
"""

import json
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from contactopt._mpi import petsc_missing
from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "mpi"))
from compare_paths import evaluations  # noqa: E402

from test_foundation_fullspace import FOUNDATIONS, _block, _config  # noqa: E402
from test_petsc import assert_kills_resume_bit_for_bit, compare_on_two_ranks, mpiexec, run_here  # noqa: E402

MISSING = petsc_missing()
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"PETSc path: {MISSING}")

TOL = 1e-9


def _two_slabs(path):
    from test_assembly_pairs import DESIGN, TWO_SLABS
    return load_config(tomllib.loads(TWO_SLABS + DESIGN)).with_updates(
        {"linear_solver": {"path": path}, "state": {"tol": 1e-12}})


MODELS = {**{kind: (lambda path, kind=kind: _config(FOUNDATIONS[kind], path)) for kind in FOUNDATIONS},
          "two slabs (two pairs)": _two_slabs,
          "example1_elastic": lambda path: load_config(ROOT / "examples" / "example1_elastic.toml").with_updates(
              {"mesh": {"nx": 12, "ny": 6, "nz": 4}, "foundation": {"block": {"size": [3.0, 2.0, 1.0], "cells": [9, 6, 3], "origin": [-0.5, -0.5]}},
               "linear_solver": {"path": path}})}
def _pressed(sideways, path):
    """The slab pressed up by f = (f1, 0, 3) on its bottom face (tests/test_foundation_fullspace.py)."""
    return _config({"block": _block(), "material": {"E": 2.0}, "control": "force", "force": [sideways, 0.0, 3.0]},
                   path)


MODELS["pressed sideways by a force"] = lambda path: _pressed(0.5, path)


def _rigid_pairs(make):
    """A model of tests/test_assembly_rigid.py: the block on a rigid counterpart beside the slab, or
    on rigid counterparts only (no counterpart body: T the nodes' frames, q their translations)."""
    def config(path):
        from test_assembly_pairs import DESIGN
        return load_config(tomllib.loads(make() + DESIGN)).with_updates(
            {"linear_solver": {"path": path}, "state": {"tol": 1e-12}})
    return config


def _sphere_beside_slab():
    from test_assembly_rigid import FULL_SPACE_CASES, _rigid
    return _rigid(FULL_SPACE_CASES["sphere moved"])


def _spheres_only():
    from test_assembly_rigid import ONE_PAIR_CASES, _all_rigid
    return _all_rigid(ONE_PAIR_CASES["sphere moved"])


def _floating_slab():
    """The right slab held only by its contacts (clamped along x3 only: friction holds it)."""
    from test_assembly_pairs import TWO_SLABS
    return TWO_SLABS.replace('clamped = "bottom"\nmaterial = { E = 6.0',
                             'clamped = { on = "bottom", components = [3] }\nmaterial = { E = 6.0')


def _plane_pressed():
    """The block on two slabs, the left one replaced by the rigid plane pressed by a tilted force."""
    from test_assembly_rigid import _rigid
    return _rigid('{ shape = "plane", control = "force", force = [0.015, 0.0, 0.05] }')


def _slab_pressed():
    """The right slab pressed by a tilted force on its bottom, beside the clamped left one."""
    from test_assembly_pairs import TWO_SLABS
    return TWO_SLABS.replace('clamped = "bottom"\nmaterial = { E = 6.0',
                             'control = "force"\nloaded = "bottom"\nforce = [0.01, -0.005, 0.045]\nmaterial = { E = 6.0')


MODELS["a slab held only by its contacts"] = _rigid_pairs(_floating_slab)
MODELS["two pairs, the rigid plane pressed by a force"] = _rigid_pairs(_plane_pressed)
MODELS["two pairs, a slab pressed by a force"] = _rigid_pairs(_slab_pressed)
MODELS["a moved rigid sphere beside the slab"] = _rigid_pairs(_sphere_beside_slab)
MODELS["rigid spheres only (two pairs)"] = _rigid_pairs(_spheres_only)




def _obstacle(name):
    """A block on a rigid obstacle of tests/test_obstacles.py (its nodes' frames: T = diag(R_m) at
    the contact DOFs, no counterpart DOFs)."""
    def config(path):
        from test_obstacles import CYLINDER, FORCED, SPHERE, block
        return block({"sphere": {**SPHERE, "displacement": [0.003, 0.0, 0.05]}, "cylinder": CYLINDER,
                      "forced sphere": FORCED["sphere"],
                      "plane moved": {"shape": "plane", "control": "displacement",
                                      "displacement": [0.003, 0.001, 0.02]}}[name], path=path)
    return config


for _name in ("sphere", "cylinder", "forced sphere"):
    MODELS[f"obstacle: {_name}"] = _obstacle(_name)


def _free_block(where):
    """The block with no clamp of tests/test_rigid.py, held only by its contact on the plane or
    on a slab (the face body anchored on one cell, paths/floating.py)."""
    from test_fullspace_held_face import SLAB
    from test_rigid import free_block
    extra = {} if where == "plane" else {"foundation": SLAB}
    return lambda path: free_block(linear_solver={"path": path}, **extra)


MODELS["the face body held only by contact on the plane"] = _free_block("plane")
MODELS["the face body held only by contact on a slab"] = _free_block("slab")
_reference = {}


def reference(name):
    """The pyamg full-space path's evaluations of a model (computed once per session)."""
    if name not in _reference:
        _reference[name] = evaluations(MODELS[name]("fullspace"), "fullspace")
    return _reference[name]


def assert_agree(ref, got, what):
    """Every array within TOL; on an obstacle (one body, tests/test_petsc.py's bounds) the states
    within 1e-8 and Θ, ξ, v_λ within 2e-10: there both backends' Newton stops at 1e-10, and τ of a
    node sliding at a hundredth of the others' slip follows its direction (measured 1.3e-9)."""
    obstacle = what.startswith("obstacle")
    assert set(ref) == set(got)
    for key in sorted(ref):
        x, y = np.atleast_1d(ref[key]), np.atleast_1d(got[key])
        assert x.shape == y.shape, f"{what}: {key} has shape {y.shape}, expected {x.shape}"
        err = float(np.abs(x - y).max()) / max(float(np.abs(x).max()), 1e-300)
        tol = TOL if not obstacle else 2e-10 if key.startswith(("value", "xi", "v_lam")) else 1e-8
        assert err <= tol, f"{what}: {key} differs from the full-space path by {err:.2e} (relative) > {tol:g}"


def write(tmp_path, cfg, name="bodies"):
    file = tmp_path / f"{name}.toml"
    file.write_text(tomli_w.dumps(cfg.data))
    return file


@pytest.mark.parametrize("name", sorted(MODELS))
def test_one_rank_equals_the_full_space(name):
    got = evaluations(MODELS[name]("petsc"), "petsc")
    assert_agree(reference(name), got, f"{name}, PETSc path on 1 rank")


@pytest.mark.parametrize("name", ["mortar partners", "prescribed translation", "two slabs (two pairs)",
                                  "pressed sideways by a force", "obstacle: cylinder", "obstacle: forced sphere",
                                  "a slab held only by its contacts", "the face body held only by contact on the plane",
                                  "the face body held only by contact on a slab"])
def test_two_ranks_equal_the_full_space(name, tmp_path):
    got = compare_on_two_ranks(tmp_path, write(tmp_path, MODELS[name]("petsc")))
    assert int(got.pop("ranks")) == 2
    assert_agree(reference(name), got, f"{name}, PETSc path on 2 ranks")


def test_subgradient_matches_central_differences_on_two_ranks(tmp_path):
    """Mortar partners, friction 0.3 with sliding and sticking nodes: ξ·d against central
    differences of Θ (step 1e-6 of α, the states solved to 1e-10) on two ranks."""
    got = compare_on_two_ranks(tmp_path, write(tmp_path, MODELS["mortar partners"]("petsc")), "--differences")
    fd, xi, sliding = got["fd"], got["fd_xi"], int(got["fd_M1"])
    assert sliding > 0
    err = np.abs(fd - xi) / np.abs(fd).max()
    assert err.max() <= 1e-6, (fd, xi)


def test_an_objective_of_the_whole_displacement_along_a_load_path_agrees():
    """Press, then shear, objective the friction work (A(α) ũ multiplied on the ranks through
    T⁻¹) and then the peak stress (∂J/∂u on every DOF, into u_loc by Tᵀ): Θ and ξ as the full
    space's."""
    steps = [{"name": "press", "top_traction": [0.0, 0.0, -8.0e-2]},
             {"name": "shear", "top_traction": [0.0, 0.0, -8.0e-2], "right_traction": [4.0e-2, 0.01, 0.0]}]
    for objective in ({"type": "frictional_dissipation"}, {"type": "peak_stress"}):
        out = {}
        for path in ("fullspace", "petsc"):
            pb = ShapeProblem(_config(FOUNDATIONS["point partners"], path, load_steps=steps, objective=objective))
            a = pb.model.initial_design()
            a = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
            out[path] = pb.evaluate(a), pb.solve_state(a)
        ((t0, x0), s0), ((t1, x1), s1) = out["fullspace"], out["petsc"]
        assert np.array_equal(s1.classes, s0.classes), objective
        assert abs(t1 - t0) <= TOL * abs(t0) and t0 > 0, objective
        assert np.abs(x1 - x0).max() <= TOL * np.abs(x0).max(), objective
        assert np.sum(s0.classes == CLASS_CODES["M1"]) > 0


def test_a_resumed_two_body_run_repeats_the_uninterrupted_one_on_two_ranks(tmp_path):
    """Stopped after 2 iterations and resumed to 5 on two ranks: the history of the uninterrupted
    run bit for bit (the checkpoint holds both bodies' displacement in u_loc)."""
    cfg = write(tmp_path, MODELS["point partners"]("petsc"))
    for out, iters, extra in (("whole", "5", ()), ("part", "2", ()), ("part", "5", ("--resume",))):
        proc = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(tmp_path / out), "--max-iter",
                       iters, *extra)
        assert proc.returncode == 0, proc.stderr[-3000:]

    def values(d):
        return [",".join(r.split(",")[:4]) for r in (tmp_path / d / "history.csv").read_text().splitlines()]
    assert len(values("whole")) > 3
    assert values("part") == values("whole")


def test_a_two_body_load_path_run_killed_at_random_moments_resumes_bit_for_bit_on_two_ranks(tmp_path):
    """The slab on its elastic foundation (point partners) pressed, then sheared, the target of the
    last step: kill -9 of the whole mpiexec group at seeded random moments of the run on two ranks,
    then ``--resume`` on two ranks: J, α and history.csv (every column but the times; the steps'
    own columns included) bit for bit the uninterrupted run's, which takes serious steps (the
    design moves) after null ones."""
    steps = [{"name": "press", "top_traction": [0.0, 0.0, -8.0e-2]},
             {"name": "shear", "top_traction": [0.0, 0.0, -8.0e-2], "right_traction": [4.0e-2, 0.01, 0.0]}]
    cfg = _config(FOUNDATIONS["point partners"], "petsc", name="bodies", load_steps=steps,
                  loads={"top_traction": [0.0] * 3, "right_traction": [0.0] * 3}, objective={"steps": "last"},
                  optimizer={"ftol": 0.0, "eps": 1e-8})
    assert_kills_resume_bit_for_bit(tmp_path, write(tmp_path, cfg), 6, "kill -9 slab on its foundation")
    assert "f_step_shear" in (tmp_path / "whole" / "history.csv").read_text().splitlines()[0]
    assert json.loads((tmp_path / "whole" / "summary.json").read_text())["serious_steps"] > 0


def test_a_two_body_checkpoint_resumes_on_another_number_of_ranks(tmp_path):
    """Two iterations on two ranks, continued to four on one process: J as the uninterrupted
    run's on one process (the checkpoint holds all bodies' displacement in u_loc, in the model's
    order, not PETSc's)."""
    file = write(tmp_path, MODELS["point partners"]("petsc"))
    code, out = run_here("run", file, "--out", tmp_path / "whole", "--max-iter", 4)
    assert code == 0, out
    proc = mpiexec(2, "-m", "contactopt.cli", "run", str(file), "--out", str(tmp_path / "a"), "--max-iter", "2")
    assert proc.returncode == 0, proc.stderr[-3000:]
    code, out = run_here("run", file, "--out", tmp_path / "a", "--max-iter", 4, "--resume")
    assert code == 0, out
    J, got = (json.loads((tmp_path / d / "summary.json").read_text()) for d in ("whole", "a"))
    assert got["iterations"] == J["iterations"] == 4
    assert abs(got["J"] - J["J"]) <= 1e-6 * abs(J["J"])


@pytest.mark.parametrize("sideways", [0.0, 0.5])
def test_a_counterpart_pressed_by_a_force_agrees_and_its_subgradient_matches(sideways):
    """The translation's search around the PETSc solve (its gaps and shift sent to the ranks with
    each solve), F's adjoint and design term on the ranks: Θ, ξ, λ and the translation as the
    full space's; ξ·d against central differences (measured 3e-8 and 1e-10 … 3e-8)."""
    out = {}
    for path in ("fullspace", "petsc"):
        pb = ShapeProblem(_pressed(sideways, path))
        a = pb.model.initial_design()
        a = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
        theta, xi = pb.evaluate(a)
        out[path] = theta, xi, pb.solve_state(a)
    (t0, x0, s0), (t1, x1, s1) = out["fullspace"], out["petsc"]
    assert abs(t1 - t0) <= TOL * abs(t0) and np.abs(x1 - x0).max() <= TOL * np.abs(x0).max()
    assert np.abs(s1.lam - s0.lam).max() <= TOL * np.abs(s0.lam).max()
    assert abs(s1.obstacle.translation - s0.obstacle.translation) <= TOL * abs(s0.obstacle.translation)
    assert np.abs(s1.foundation.displacement - s0.foundation.displacement).max() <= \
        1e-8 * np.abs(s0.foundation.displacement).max()
    gc = check_gradient(pb, a, n_directions=2, seed=0, h=1e-2)
    assert gc.n_degenerate == 0 and max(gc.rel_errors) <= 1e-6, gc.rel_errors


def test_a_sphere_pressed_by_a_force_on_tetrahedra_matches_central_differences(tmp_path):
    """The force search on the PETSc path with the products of A(α) on the ranks (the adjoint of F,
    ∂F/∂α of z = w̃ + ẽ sent to the ranks): ξ·d against central differences, the translation as the
    full space's."""
    from test_obstacles import FORCED, tet_block
    out = {}
    for path in ("fullspace", "petsc"):
        pb = ShapeProblem(tet_block(tmp_path, FORCED["sphere"]).with_updates({"linear_solver": {"path": path}}))
        a = 0.002 * np.sin(np.arange(pb.model.n_design)) + 0.001
        out[path] = pb.solve_state(a)
    s0, s1 = out["fullspace"], out["petsc"]
    assert np.array_equal(s0.classes, s1.classes) and s1.counts["M1"] > 0 and s1.counts["M3+"] > 0
    assert abs(s1.info["obstacle_translation"] - s0.info["obstacle_translation"]) <= \
        TOL * abs(s0.info["obstacle_translation"])
    rep = check_gradient(pb, a, seed=2, n_directions=3)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_the_plane_moved_tangentially_equals_the_full_space_and_matches_central_differences():
    """The plane's translation (no frames: the one body's numbering, the shift as the slip's
    reference): the state as the full space's to 1e-10, ξ·d against central differences."""
    states = {}
    for path in ("fullspace", "petsc"):
        pb = ShapeProblem(_obstacle("plane moved")(path))
        a = np.full(pb.model.n_design, 0.001)
        states[path] = pb.solve_state(a)
    s0, s1 = states["fullspace"], states["petsc"]
    assert np.array_equal(s1.classes, s0.classes) and s0.counts["M1"] > 0 and s0.counts["M3+"] > 0
    assert np.abs(s1.lam - s0.lam).max() <= 1e-10 * s0.lam.max()
    assert np.abs(s1.u - s0.u).max() <= 1e-10 * np.abs(s0.u).max()
    # (the Newton stops at 1e-10: h = 1e-2·max|α| as the full-space path's checks; 2e-6 at the default)
    rep = check_gradient(pb, a, seed=1, n_directions=3, h=1e-2)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


def test_a_counterpart_held_only_by_its_contacts_matches_central_differences():
    """The anchored first solve on the ranks (γ N Nᵀ added to the owned rows and taken out again),
    the free Newton method after it, the adjoint on the unanchored matrix: ξ·d against central
    differences, the anchor carrying no force at the state."""
    pb = ShapeProblem(MODELS["a slab held only by its contacts"]("petsc"))
    a = pb.model.initial_design()
    a = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    st = pb.solve_state(a)
    assert st.rigid is not None and st.rigid.residual <= 1e-10
    assert st.counts["M1"] > 0 and st.counts["M3+"] > 0
    gc = check_gradient(pb, a, n_directions=3, seed=0, h=1e-2)
    assert gc.n_degenerate == 0 and max(gc.rel_errors) <= 1e-6, gc.rel_errors


def test_a_dovetail_s_blade_held_only_by_its_flanks_agrees_with_the_full_space():
    """The dovetail example (two flank pairs against one slot, friction 0.3, two designs): its
    blade floats in the slot; Θ, ξ, λ and τ at a design off the initial one (measured 1e-12)."""
    out = {}
    for path in ("fullspace", "petsc"):
        pb = ShapeProblem(load_config(ROOT / "examples" / "dovetail.toml").with_updates(
            {"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
        d = np.sin(np.arange(pb.model.n_design) + 1.0).reshape(2, -1)     # each design's volume kept
        a = pb.model.initial_design() + 1e-3 * (d - d.mean(axis=1, keepdims=True)).ravel()
        assert pb.model.admissible.is_feasible(a)
        res = pb.subgradient(a)
        out[path] = res.value, res.gradient, res.state
    (t0, x0, s0), (t1, x1, s1) = out["fullspace"], out["petsc"]
    assert s1.rigid is not None and np.array_equal(s0.classes, s1.classes)
    for got, ref in ((t1, t0), (x1, x0), (s1.lam, s0.lam), (s1.tau, s0.tau)):
        ref = np.atleast_1d(ref)
        assert np.abs(np.atleast_1d(got) - ref).max() <= TOL * np.abs(ref).max()


def test_a_face_body_held_only_by_contact_matches_central_differences():
    """The face body's anchor on one of its cells with no contact node (γ N Nᵀ in the owned rows,
    taken out for the free Newton method and the adjoint): ξ·d against central differences, the
    block on a slab, sliding and sticking nodes."""
    pb = ShapeProblem(MODELS["the face body held only by contact on a slab"]("petsc"))
    a = 0.002 * np.sin(np.arange(pb.model.n_design)) + 0.001
    st = pb.solve_state(a)
    assert st.rigid is not None and st.rigid.residual <= 1e-10
    assert st.counts["M1"] > 0
    gc = check_gradient(pb, a, n_directions=3, seed=0, h=1e-2)
    assert gc.n_degenerate == 0 and max(gc.rel_errors) <= 1e-6, gc.rel_errors


