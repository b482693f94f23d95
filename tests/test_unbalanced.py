"""A load with a component along a rigid motion that nothing holds is refused by name, never solved
into a "converged" state: a block 2 × 1 × 1 clamped in u1 on its face x1 = 0 and in u2 on its
face x2 = 0 (the symmetry planes of a quarter model) but not along x3, pressed by a force-controlled
plane (the roller's set-up without its axial clamp). Nothing but the contact holds it along x3, and
the plane pushes it by |f| with no load to push back: no contact force balances that.

Convention: the plane's force f on the body, along its normal e3; λ ≥ 0 the normal contact force."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.problem import ShapeProblem

MESSAGE = "the load has a component along a rigid motion that nothing holds: the translation along x3"


def quarter_block(top=0.0, force=0.1, friction=0.0):
    return load_config("example1").with_updates({
        "friction": {"coefficient": friction}, "geometry": {"a": 2.0, "b": 1.0, "c": 1.0},
        "mesh": {"nx": 6, "ny": 3, "nz": 3}, "design": {"degree": [3, 2], "initial": 0.0, "C2": 0.0},
        "loads": {"top_traction": [0.0, 0.0, top], "right_traction": [0.0, 0.0, 0.0]},
        "body": {"clamped": [{"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]},
        "obstacle": {"shape": "plane", "control": "force", "force": [0.0, 0.0, force]}})


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_a_force_controlled_plane_under_a_body_nothing_holds_along_x3_is_refused_by_name(friction):
    with pytest.raises(ConfigError, match=MESSAGE) as err:
        ShapeProblem(quarter_block(friction=friction))
    assert "pushes the body by 0.1 along x3" in str(err.value) and "clamp the body along x3" in str(err.value)


def test_the_same_body_loaded_against_the_planes_force_is_held_and_solved():
    # a top traction whose resultant (−0.05 × area 2) balances the plane's 0.1
    problem = ShapeProblem(quarter_block(top=-0.05))
    assert problem.model.body.rigid.count == 1
    st = problem.solve_state(problem.model.initial_design(), warm_start=False)
    assert st.converged and st.lam.sum() == pytest.approx(0.1, rel=1e-9)
    assert np.all(np.isfinite(st.u)) and np.abs(st.lam).max() < 0.1


def test_the_cli_refuses_it_with_exit_2_and_writes_nothing(tmp_path):
    cfg = tmp_path / "quarter.toml"
    cfg.write_text(quarter_block().to_toml())
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "contactopt.cli", "state", str(cfg), "--out", str(out)],
                       capture_output=True, text=True)
    assert p.returncode == 2, p.stderr
    assert MESSAGE in p.stderr and not out.exists()
