"""A wedge in a rigid V-groove (contactopt.verification.vgroove): both flanks carry the load
against statics, frictionless and sliding in with friction; the half model (a symmetry plane
through the wedge's middle) designed along its inclined flank's normal; examples/vgroove.toml.
"""

from pathlib import Path

import numpy as np
import pytest

from contactopt.config import validate
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization
from contactopt.sensitivity.check import check_gradient
from contactopt.verification import vgroove as vg

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def wedge(tmp_path, half=False, friction=0.0, **kw):
    mesh = vg.wedge_mesh(tmp_path / f"wedge{int(half)}.msh", 3, 6, 1, half=half)
    groove = vg.groove_stl(tmp_path / "groove.stl")
    return ShapeProblem(validate(vg.config(mesh, groove, half=half, friction=friction, **kw), "vgroove"))


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_both_flanks_carry_the_normal_force_of_statics(tmp_path, friction):
    # the wedge held by the groove alone: 2N(sin β + F cos β) = q·(top's area), every node sliding in
    pr = wedge(tmp_path, friction=friction)
    st = pr.solve_state(pr.model.initial_design())
    forces = vg.flank_forces(pr, st)
    n = vg.flank_force(friction)
    for side in ("left", "right"):
        f = forces[side]
        assert f["normal"] == pytest.approx(n, rel=1e-6), side
        assert f["vertical"] == pytest.approx(vg.load() / 2, rel=1e-9), side
        assert f["up"] == pytest.approx(friction * n, rel=1e-6, abs=1e-8 * n), side
        if friction:
            assert f["slide"] == 1.0
    assert forces["left"]["normal"] == pytest.approx(forces["right"]["normal"], rel=1e-9)


def test_the_half_model_with_its_symmetry_plane_equals_the_whole_wedge(tmp_path):
    full, half = wedge(tmp_path, friction=0.3), wedge(tmp_path, half=True, friction=0.3)
    assert half.model.body.chart.kind == "plane"
    sf, sh = full.solve_state(full.model.initial_design()), half.solve_state(half.model.initial_design())
    xf = full.model.body.reference.points[full.model.contact_nodes]
    xh = half.model.body.reference.points[half.model.contact_nodes]
    right = np.flatnonzero(xf[:, 0] > 0)
    order = [right[np.argmin(np.linalg.norm(xf[right] - x, axis=1))] for x in xh]
    assert np.abs(xf[order] - xh).max() <= 1e-12
    assert np.abs(sf.lam[order] - sh.lam).max() <= 1e-9 * sh.lam.max()


def test_the_design_along_the_flanks_normal_and_its_subgradient(tmp_path):
    # ϑ > 0 removes material along the flank's inward normal: a uniform offset lowers the wedge into
    # the groove by ϑ / sin β and leaves its forces; a design's subgradient against central differences
    pr = wedge(tmp_path, half=True, friction=0.3, objective={"type": "pressure_uniformity"},
               design={"C2": 1.0, "nonnegative_gap": False, "lower": -0.02})
    model = pr.model
    n = model.n_design
    x0 = model.mesh.coordinates(np.zeros(n)).reshape(-1, 3)
    x1 = model.mesh.coordinates(np.full(n, 1e-3)).reshape(-1, 3)
    d = (x1 - x0)[model.contact_nodes]
    inward = np.array([-np.cos(vg.BETA), 0.0, np.sin(vg.BETA)])
    assert np.abs(d - 1e-3 * inward).max() <= 1e-12
    s0, s1 = pr.solve_state(np.zeros(n)), pr.solve_state(np.full(n, 1e-3))
    assert np.abs(s1.lam - s0.lam).max() <= 1e-8 * s0.lam.max()
    alpha = 2e-3 * np.sin(1.0 + np.arange(n))
    rep = check_gradient(pr, alpha, seed=2, n_directions=2)
    assert rep.n_degenerate == 0 and np.max(rep.rel_errors) <= 1e-6, rep.rel_errors


@pytest.mark.slow
def test_the_vgroove_example_lowers_the_tip_peak_by_removing_material_there(tmp_path):
    # max_pressure along the slope: the tip's corner peak (2.5 × the mean) falls near the mean pressure
    summary = run_optimization(EXAMPLES / "vgroove.toml", tmp_path / "run", plots=False).summary
    assert summary["ratio"] <= 0.45
    alpha = np.ravel(summary["alpha"])
    assert alpha[0] > 0.005 > alpha[-1]      # ϑ at the tip (ξ1 lowest) above the mean offset, at the top below it
