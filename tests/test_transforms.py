"""Mechanics as transforms of the contact system (contactopt.paths.transforms): what a model's
mechanics hold, that the frames' rotation is orthogonal, and that no path mixes a mechanic in."""

import numpy as np

import contactopt.paths as paths
from contactopt.config import load_config
from contactopt.paths.base import SolverPath
from contactopt.paths.force import ForceSearch
from contactopt.paths.fullspace import FullSpaceCommon
from contactopt.paths.transforms import Mechanics, Rotate, Shift
from contactopt.paths.zone_paths import ZonePath
from contactopt.problem import ShapeProblem

SPHERE = {"shape": "sphere", "center": [1.0, 1.0, -5.0], "radius": 5.0}


def small_block(obstacle=None, **updates):
    data = {"friction": {"coefficient": 0.3}, "material": {"nu": 0.3}, "state": {"method": "newton", "tol": 1e-12},
            "loads": {"top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
            "design": {"degree": [3, 2], "initial": 0.0, "C2": 0.0}, "geometry": {"a": 2.0, "b": 2.0, "c": 1.0},
            "mesh": {"nx": 4, "ny": 4, "nz": 2}, "body": {"clamped": "top"}, **updates}
    if obstacle is not None:
        data["obstacle"] = obstacle
    return load_config("example1").with_updates(data)


def test_the_papers_examples_have_no_mechanics():
    problem = ShapeProblem(load_config("example1").with_updates({"mesh": {"nx": 6, "ny": 3, "nz": 2}}))
    assert problem.path.mechanics == Mechanics()
    assert problem.model.obstacle is None and problem.model.obstacle_force is None and problem.model.force is None


def test_a_force_controlled_sphere_is_a_rotation_and_a_search():
    forced = {**SPHERE, "control": "force", "force": [0.0, 0.0, 1.2]}
    problem = ShapeProblem(small_block(forced))
    mech, model = problem.path.mechanics, problem.model
    assert isinstance(mech.rotate, Rotate) and isinstance(mech.search, ForceSearch)
    assert mech.shift is None and mech.couple is None and mech.anchor is None
    assert mech.search.force is model.obstacle_force and model.force == 1.2
    assert np.array_equal(mech.frames, model.frames)
    v = np.random.default_rng(0).standard_normal(3 * model.n_contact)
    assert np.allclose(mech.rotate.back(mech.rotate.vector(v)), v, rtol=0, atol=1e-14)
    S = np.diag(np.arange(1.0, v.size + 1))
    assert np.allclose(mech.rotate.matrix(S), mech.rotate.matrix(S).T)


def test_a_tangential_translation_is_a_shift():
    moved = {**SPHERE, "control": "displacement", "displacement": [0.01, 0.0, 0.05]}
    mech = ShapeProblem(small_block(moved)).path.mechanics
    assert isinstance(mech.shift, Shift) and mech.search is None
    assert mech.shift.vector.shape == (3 * mech.shift.slip.shape[0],)
    assert np.all(mech.shift.slip[:, 2] == 0) and np.any(mech.shift.tangential != 0)


def test_no_path_mixes_a_mechanic_in():
    """A path class derives from the interface and what paths of one method share only: the
    mechanics are objects the path holds (its ``mechanics``), not classes it inherits."""
    allowed = {SolverPath, ZonePath, FullSpaceCommon, object}
    for name, cls in paths.PATHS.items():
        assert set(cls.__mro__[1:]) <= allowed, (name, cls.__mro__)
