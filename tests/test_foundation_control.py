"""An elastic foundation moved by a prescribed translation of its loaded part, or pressed by a
force on it (``[foundation] control``, ``loaded``, ``displacement``, ``force``): the state against
the force balance and against the displacement-controlled state at the same translation, the
subgradient against central differences, bad input refused with exit 2 and nothing written."""

from pathlib import Path

import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient

COARSE = {"mesh": {"nx": 12, "ny": 6, "nz": 4}}
BLOCK = {"size": [3.0, 2.0, 1.0], "cells": [9, 5, 3], "origin": [-0.5, -0.5], "element": "hexahedron"}
FORCE = 3.0


def _problem(**foundation):
    f = {"block": BLOCK, "material": {"E": 2.0}, **foundation}
    return ShapeProblem(load_config("example1").with_updates({**COARSE, "foundation": f}))


def _design(model, seed=1, amp=0.003):
    a = model.initial_design()
    d = np.random.default_rng(seed).standard_normal(a.size)
    return a + amp * (d - d.mean())


def test_the_contact_forces_balance_the_force_on_the_loaded_part():
    """Example 1's body on a foundation block pressed up by f = (0, 0, 3) on its bottom face: the
    contact resultant along f equals |f| (the foundation's equilibrium: no other support carries
    load along f), the bottom face and every node of the foundation move by the search's s f̂
    beyond their elastic displacement, and prescribing that translation gives the same state."""
    pb = _problem(control="force", force=[0.0, 0.0, FORCE])
    alpha = _design(pb.model)
    st = pb.solve_state(alpha)
    assert st.converged
    assert abs(st.lam.sum() - FORCE) <= 1e-8 * FORCE
    s = st.obstacle.translation
    assert s > 0 and abs(st.obstacle.resultant - FORCE) <= 1e-8 * FORCE
    fnd = pb.model.foundation
    bottom = fnd.mesh.loaded
    u = np.asarray(st.foundation.displacement).reshape(-1, 3)
    assert np.allclose(u[bottom], [0.0, 0.0, s], rtol=0, atol=1e-14)
    # the same translation prescribed: the same state
    pd = _problem(control="displacement", displacement=[0.0, 0.0, s])
    sd = pd.solve_state(alpha)
    assert np.abs(sd.lam - st.lam).max() <= 1e-9 * st.lam.max()
    assert np.array_equal(sd.classes, st.classes)
    assert np.allclose(np.asarray(sd.foundation.displacement), np.asarray(st.foundation.displacement),
                       rtol=0, atol=1e-10 * abs(s))


def test_the_fixed_foundation_is_todays():
    pb = _problem()
    assert pb.model.foundation.translation is None and pb.model.foundation.motion is None
    assert pb.model.obstacle_force is None


@pytest.mark.parametrize("control", ["force", "displacement"])
def test_subgradient_matches_central_differences(control):
    """ξ·d against central differences to 1e-6 with friction (sliding and sticking nodes): the
    force's translation through the implicit function theorem, the prescribed one as a load."""
    extra = {"force": [0.0, 0.0, FORCE]} if control == "force" else {"displacement": [0.0, 0.0, 0.8]}
    pb = _problem(control=control, **extra)
    gc = check_gradient(pb, _design(pb.model), n_directions=3, seed=0 if control == "force" else 3)
    assert gc.n_degenerate == 0
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0
    assert np.max(gc.rel_errors) <= 1e-6, gc.rel_errors


def test_the_roller_example_is_pressed_by_its_force():
    problem = ShapeProblem(str(Path(__file__).parents[1] / "examples" / "roller_crowning.toml"))
    st = problem.solve_state(problem.model.initial_design())
    force = problem.model.config.foundation.force[2]
    # the race's push along e3 is carried by the contact forces (the face a graph over x3 = 0: the
    # nodes' frames are the axes)
    assert problem.model.frames is None
    assert abs(st.lam.sum() - force) <= 1e-8 * force and st.obstacle.translation > 0


def _toml(tmp_path, foundation: str, extra: str = "") -> Path:
    p = tmp_path / "bad.toml"
    p.write_text('name = "bad"\n[mesh]\nnx = 8\nny = 4\nnz = 3\n' + extra + '[foundation]\n'
                 'block = { size = [3.0, 2.0, 1.0], cells = [6, 4, 2], origin = [-0.5, -0.5] }\n' + foundation)
    return p


BAD = {
    "force with displacement control": ('control = "displacement"\ndisplacement = [0.0, 0.0, 0.1]\n'
                                        'force = [0.0, 0.0, 1.0]\n',
                                        "foundation.force = [0.0, 0.0, 1.0]: given with foundation.control = "
                                        "'displacement'"),
    "force control without force": ('control = "force"\n', "foundation.force: required with foundation.control"),
    "zero force": ('control = "force"\nforce = [0.0, 0.0, 0.0]\n', "foundation.force = [0, 0, 0]"),
    "displacement control without displacement": ('control = "displacement"\n',
                                                  "foundation.displacement: required"),
    "a loaded part without control": ('loaded = "left"\n', "foundation.loaded: given with foundation.control = "
                                      "'fixed'"),
    "missing loaded part": ('control = "force"\nforce = [0.0, 0.0, 1.0]\nloaded = "base"\n',
                            "no part named 'base'"),
    "clamped along the force": ('control = "force"\nforce = [0.0, 0.0, 1.0]\nclamped = ["left"]\n',
                                "clamped component(s) of nodes outside foundation.loaded lie along the force"),
    "another path": ('control = "force"\nforce = [0.0, 0.0, 1.0]\n', "foundation.control = 'force'",
                     '[linear_solver]\npath = "delassus"\n'),
    "load steps": ('control = "force"\nforce = [0.0, 0.0, 1.0]\n', "[[load_steps]] with foundation.control = "
                   "'force'", '[[load_steps]]\nname = "half"\nbody_force = [0.0, 0.0, -0.1]\n'
                   '[[load_steps]]\nname = "all"\nbody_force = [0.0, 0.0, -0.2]\n'),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_foundation_control_exits_2_and_writes_nothing(case, tmp_path, capsys):
    body, message, *extra = BAD[case]
    out = tmp_path / "out"
    assert main(["state", str(_toml(tmp_path, body, *extra)), "--out", str(out)]) == 2
    assert not out.exists()
    assert message in capsys.readouterr().err


def test_a_foundation_loaded_and_pulled_away_is_refused():
    with pytest.raises(ConfigError, match="pull it away from the body"):
        _problem(control="force", force=[0.0, 0.0, 0.1], loads={"body_force": [0.0, 0.0, -1.0]})


def test_a_curved_seat_pressed_by_a_force_balances_it_and_its_subgradient_matches(tmp_path):
    """The spherical pad on the elastic seat (contactopt.verification.two_spheres, the contact
    nodes' frames from the pad's chart), the seat pressed by a force on its bottom face instead of
    its clamps: the contact forces, rotated to the axes, sum to the force; ξ·d against central
    differences to 1e-6."""
    from contactopt.config import validate
    from contactopt.verification import two_spheres
    cfg = two_spheres.two_spheres_config(tmp_path, 0.5)
    sym = [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]
    cfg["foundation"].update(control="force", force=[0.0, 0.0, 0.0036], clamped=sym, loaded="bottom")
    cfg["objective"] = {"type": "pressure_uniformity"}
    pb = ShapeProblem(validate(cfg, "hertz"))
    m = pb.model
    assert m.frames is not None
    st = pb.solve_state(m.initial_design())
    resultant = np.einsum("mij,mj->i", m.frames, np.c_[-np.reshape(st.tau, (-1, 2)), st.lam])
    assert np.allclose(resultant, [0.0, 0.0, 0.0036], rtol=0, atol=1e-8 * 0.0036)
    alpha = m.initial_design() + 1e-3 * np.random.default_rng(0).standard_normal(m.n_design)
    gc = check_gradient(pb, alpha, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert np.max(gc.rel_errors) <= 1e-6, gc.rel_errors
