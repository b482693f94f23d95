"""A face body held only by its contacts on the full-space path (contactopt.paths.floating): the
face body's free rigid motions anchored on one of its cells with no contact node, one anchored
solve (a stiffer anchor where the soft one's Newton method makes no progress), then the
unanchored Newton method; against the condensation path, whose anchor is on the contact DOFs
(contactopt.paths.rigid).

The models: the free block of tests/test_rigid.py on the plane and on an elastic slab, and the
shipped assemblies whose face body floats (a roller between two plates, a dovetail in its slot,
a lap joint's upper plate, a roller between two races).
"""

from pathlib import Path

import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.contact.state import CLASS_CODES
from contactopt.paths import fullspace
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from test_rigid import free_block

ROOT = Path(__file__).resolve().parents[1]
SLAB = {"block": {"size": [3.0, 2.0, 1.0], "cells": [3, 2, 1], "origin": [-0.5, -0.5]}}


def _rel(a, b):
    b = np.asarray(b)
    return float(np.abs(np.asarray(a) - b).max() / max(np.abs(b).max(), 1e-300))


def _both(make, design=None):
    """Θ, ξ and the state of one evaluation on the condensation and the full-space path."""
    out = {}
    for path in ("condensation", "fullspace"):
        pb = make(path)
        assert pb.path.name == path and pb.model.body.rigid is not None
        a = pb.model.initial_design() if design is None else design(pb.model)
        theta, xi = pb.evaluate(a)
        out[path] = theta, xi, pb.solve_state(a)
    return out["condensation"], out["fullspace"]


def _agreement(cond, full, xi_scale=None):
    (t0, x0, s0), (t1, x1, s1) = cond, full
    assert np.array_equal(s1.classes, s0.classes)
    assert s1.rigid is not None
    xi = float(np.abs(x1 - x0).max() / (xi_scale or max(np.abs(x0).max(), 1e-300)))
    return {"Theta": abs(t1 - t0) / abs(t0), "xi": xi, "lambda": _rel(s1.lam, s0.lam), "w": _rel(s1.u_c, s0.u_c)}


def _sine(model):
    return 0.002 * np.sin(np.arange(model.n_design)) + 0.001


@pytest.mark.parametrize("where", ["plane", "slab"])
def test_the_free_block_agrees_on_both_paths(where):
    """The block with no clamp pressed onto the plane or onto a slab (one body, or two in one
    Newton system), friction 0.3 and a side load: sticking and sliding nodes (measured 1e-12)."""
    extra = {} if where == "plane" else {"foundation": SLAB}

    def make(path):
        return ShapeProblem(free_block(linear_solver={"path": path}, **extra))
    cond, full = _both(make, _sine)
    d = _agreement(cond, full)
    assert max(d.values()) <= 1e-8, d
    classes = cond[2].classes
    assert np.sum(classes == CLASS_CODES["M1"]) > 0


@pytest.mark.parametrize("name", ["roller_plates", "dovetail"])
def test_the_examples_whose_face_body_floats_agree_on_both_paths(name):
    """A roller held only by its two contacts between two plates, a dovetail's blade in its slot
    (measured 1e-12 to 6e-12). The roller's ξ vanishes by symmetry: measured against Θ."""
    def make(path):
        return ShapeProblem(load_config(ROOT / "examples" / f"{name}.toml").with_updates(
            {"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
    cond, full = _both(make)
    d = _agreement(cond, full, xi_scale=abs(cond[0]) if name == "roller_plates" else None)
    assert max(d.values()) <= 1e-9, d


@pytest.mark.integration
@pytest.mark.parametrize("name", ["lap_joint", "roller_bearing"])
def test_the_lap_joint_and_the_roller_bearing_agree_on_both_paths(name):
    """The lap joint's upper plate (a preload by the bolt head's displacement, then a shear, along
    a load path) and a crowned roller pressed into both races by an overlap: the soft anchor's
    Newton method makes no progress on the preload and the overlap, the stiffer one converges
    (measured 2.6e-13 and 6.6e-13)."""
    def make(path):
        return ShapeProblem(load_config(ROOT / "examples" / f"{name}.toml").with_updates(
            {"linear_solver": {"path": path}, "state": {"tol": 1e-12}}))
    cond, full = _both(make)
    d = _agreement(cond, full)
    assert max(d.values()) <= 1e-9, d


def test_the_anchor_s_iteration_alone_reaches_the_same_state(monkeypatch):
    """Without the unanchored Newton steps, the iteration β ← Nᵀu to its end: the same state."""
    monkeypatch.setattr(fullspace, "FREE_NEWTON_STEPS", 0)

    def make(path):
        return ShapeProblem(free_block(linear_solver={"path": path}))
    cond, full = _both(make, _sine)
    d = _agreement(cond, full)
    assert max(d.values()) <= 1e-8, d
    assert full[2].rigid.iterations > 1


def test_the_subgradient_matches_central_differences_with_a_floating_face_body():
    """ξ·d against central differences on the full space, the block on a slab held only by
    contact, sliding and sticking nodes; h = 1e-2·max|α| as the other full-space checks."""
    pb = ShapeProblem(free_block(linear_solver={"path": "fullspace"}, foundation=SLAB))
    gc = check_gradient(pb, _sine(pb.model), n_directions=3, seed=0, h=1e-2)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0


@pytest.mark.integration
def test_a_resumed_run_of_a_floating_face_body_repeats_the_uninterrupted_one(tmp_path):
    """The dovetail (its blade held only by its flanks) on the full space: a run stopped after 3
    iterations and resumed to 6 ends where the uninterrupted one does, bit for bit (the anchor's
    hierarchy is rebuilt from the checkpoint's design)."""
    import json

    from contactopt.runner import run_optimization
    cfg = load_config(ROOT / "examples" / "dovetail.toml").with_updates(
        {"linear_solver": {"path": "fullspace"}, "optimizer": {"ftol": 0.0, "eps": 1e-12}})
    full = run_optimization(cfg, tmp_path / "full", max_iter=6)
    run_optimization(cfg, tmp_path / "part", max_iter=3)
    resumed = run_optimization(cfg, tmp_path / "part", max_iter=6, resume=True)
    assert full.summary["iterations"] == resumed.summary["iterations"] == 6
    assert resumed.summary["J"] == full.summary["J"] < full.summary["J0"]
    assert (json.loads((tmp_path / "part" / "alpha.json").read_text())
            == json.loads((tmp_path / "full" / "alpha.json").read_text()))
