"""A rigid counterpart pressed by a force in a model of several pairs (a pair's ``counterpart`` table
with control = "force"): its translation s along f̂ searched so that its pair's resultant along f̂
balances |f| (paths/force.py, as for the one obstacle), against the analytic pressure of a block
squeezed by a rigid lid, the displacement-controlled model at the found s, the other path and
central differences.

Conventions: per contact node (t1, t2, ν) in the node's frame, ν from the counterpart to the face
body; r the contact force on the face body, λ = r_ν ≥ 0, τ = −r_t; b_m = R_mᵀ f̂ on the pressed
pair's nodes, its resultant along f̂ Σ_m b_m·r_m.
"""

import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.paths.force import excess_of
from contactopt.sensitivity.check import check_gradient
from test_assembly_pairs import DESIGN, TWO_SLABS, _write
from test_assembly_rigid import _on_path, _rigid, _squeezed

PRESSED = {"up": [0.0, 0.0, 0.05], "sideways": [0.015, 0.0, 0.05]}


def _pressed(force, path, tol=1e-12):
    """The block on two slabs, the left slab replaced by the rigid plane pressed by ``force``."""
    return _on_path(_rigid(f'{{ shape = "plane", control = "force", force = {force} }}') + DESIGN, path, tol)


def _design(pb):
    a = pb.model.initial_design()
    return a + 0.003 * np.random.default_rng(1).standard_normal(a.size)


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_a_block_squeezed_by_a_rigid_lid_pressed_by_a_force_carries_its_pressure(friction, tmp_path):
    """The lid of tests/test_assembly_rigid.py pressed down by F = 0.02 onto the unit block held only
    by its contacts: p = F on both faces (unit area) to 1e-10 (measured 1.2e-13), τ = 0, and the lid's
    translation s = F/M with M = E(1 − ν)/((1 + ν)(1 − 2ν)) under the rollers' uniaxial strain."""
    pb = _squeezed(tmp_path, 'control = "force", force = [0.0, 0.0, -0.02]', friction)
    m = pb.model
    lid = m.body.pair_of == 1
    assert np.array_equal(m.obstacle_force.gap_rate > 0, lid) and not np.any(m.obstacle_force.b[~lid])
    st = pb.solve_state(m.initial_design())
    p = st.lam / m.contact_areas()
    for k in range(2):
        mine = m.body.pair_of == k
        assert np.abs(p[mine] / 0.02 - 1).max() <= 1e-10, (k, p[mine])
    assert np.abs(st.tau).max() <= 1e-10 * st.lam.max()
    nu = 0.3
    assert st.obstacle.translation == pytest.approx(0.02 * (1 + nu) * (1 - 2 * nu) / (1 - nu), rel=1e-10)


@pytest.mark.parametrize("path", ["condensation", "fullspace"])
@pytest.mark.parametrize("case", sorted(PRESSED))
def test_a_rigid_plane_pressed_by_a_force_beside_an_elastic_slab(case, path):
    """The plane under the left pair pressed up by f (along e3, or tilted: its translation then drags
    the face): its pair's resultant along f̂ is |f| to 1e-10 (the other pair's nodes carry no part of
    it), and the model with the plane moved by the found translation s f̂ (control = "displacement")
    has the same λ, τ and body displacement to 1e-9 (measured 1e-12 and 5e-11 on the full space);
    on the full space Θ, ξ, λ and s agree with the condensation to 1e-9 (measured 2e-11)."""
    f = PRESSED[case]
    pb = _pressed(f, path)
    assert pb.path.name == path
    m, alpha = pb.model, _design(pb)
    theta, xi = pb.evaluate(alpha)
    st = pb.solve_state(alpha)
    norm = float(np.linalg.norm(f))
    left = m.body.pair_of == 0
    assert not np.any(m.obstacle_force.b[~left]) and not np.any(m.obstacle_force.gap_rate[~left])
    assert abs(excess_of(st, m.obstacle_force.b, norm)) <= 1e-10 * norm
    g = np.c_[-st.tau, st.lam][left].sum(axis=0)           # the plane's frames are the axes
    assert abs(g @ f / norm - norm) <= 1e-10 * norm
    assert st.lam[left].sum() > 0.1 * st.lam.sum() and st.counts["M1"] > 0 and st.counts["L"] > 0
    s = st.obstacle.translation
    d = [float(x) for x in s * np.array(f) / norm]
    moved = _on_path(_rigid(f'{{ shape = "plane", control = "displacement", displacement = {d} }}') + DESIGN, path)
    sd = moved.solve_state(alpha)
    scale = st.lam.max()
    assert np.abs(sd.lam - st.lam).max() <= 1e-9 * scale and np.abs(sd.tau - st.tau).max() <= 1e-9 * scale
    assert np.abs(sd.u - st.u).max() <= 1e-9 * np.abs(st.u).max()
    assert np.array_equal(sd.classes, st.classes)
    if path == "fullspace":
        ref = _pressed(f, "condensation")
        t0, x0 = ref.evaluate(alpha)
        s0 = ref.solve_state(alpha)
        assert abs(theta - t0) <= 1e-9 * abs(t0) and np.abs(xi - x0).max() <= 1e-9 * np.abs(x0).max()
        assert np.abs(st.lam - s0.lam).max() <= 1e-9 * s0.lam.max()
        assert abs(s - s0.obstacle.translation) <= 1e-9 * abs(s0.obstacle.translation)


@pytest.mark.parametrize("path, case", [("condensation", "sideways"), ("fullspace", "up")])
def test_subgradient_with_a_rigid_counterpart_pressed_by_a_force_matches_central_differences(path, case):
    """ξ·d with the translation's dependence on α (paths/force.py's implicit terms through the
    coupling of the pairs) against central differences to 1e-6 (measured 2e-8 and 5e-9)."""
    pb = _pressed(PRESSED[case], path)
    gc = check_gradient(pb, _design(pb), n_directions=2, seed=0, **({} if path == "condensation" else {"h": 1e-2}))
    assert gc.n_degenerate == 0 and gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["L"] > 0


def test_two_counterparts_pressed_by_forces_are_refused_by_name(tmp_path):
    text = _rigid('{ shape = "plane", control = "force", force = [0.0, 0.0, 1.0] }')
    text = text[:text.index("[bodies.right]")] + text[text.index("[[contacts]]"):]
    text = text.replace('counterpart = "right.top"', 'counterpart = { shape = "plane", control = "force", force = [0.0, 0.0, 2.0] }')
    with pytest.raises(ConfigError, match=r"contacts\[0\] and contacts\[1\]: 2 rigid counterparts pressed by "
                                          r"control = 'force'; contactopt searches the translation of one"):
        load_config(_write(tmp_path, text + DESIGN))


def test_a_counterpart_body_pressed_by_a_force_in_several_pairs_is_refused_by_name(tmp_path):
    from contactopt.problem import ShapeProblem
    text = TWO_SLABS.replace('clamped = "bottom"\nmaterial = { E = 6.0',
                             'clamped = "bottom"\ncontrol = "force"\nloaded = "bottom"\nforce = [0.0, 0.0, 1.0]\n'
                             'material = { E = 6.0')
    assert text != TWO_SLABS
    with pytest.raises(ConfigError, match="a counterpart body pressed by control = 'force' takes one pair per model"):
        ShapeProblem(load_config(_write(tmp_path, text + DESIGN)))
