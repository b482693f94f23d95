"""A counterpart pressed by a force in a model of several pairs (a pair's rigid ``counterpart`` table
with control = "force", or a counterpart body's ``bodies.<name>.control = "force"``): its translation
s along f̂ searched so that its pairs' resultant along f̂ balances |f| (paths/force.py, as for the one
obstacle and the one foundation), against the analytic pressure of a block squeezed by a rigid lid,
the displacement-controlled model at the found s, the other path and central differences.

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


# the right slab of the block on two slabs pressed up by a force on its bottom (its loaded part, which
# translates by s f̂ and the slab with it) instead of clamped there; f up, or tilted (its translation
# then drags the face)
BODY_PRESSED = {"up": [0.0, 0.0, 0.045], "tilted": [0.01, -0.005, 0.045]}


def _body_force(force, control="force"):
    key = "force" if control == "force" else "displacement"
    text = TWO_SLABS.replace('clamped = "bottom"\nmaterial = { E = 6.0',
                             f'control = "{control}"\nloaded = "bottom"\n{key} = {list(map(float, force))}\n'
                             'material = { E = 6.0')
    assert text != TWO_SLABS
    return text + DESIGN


@pytest.mark.parametrize("path", ["condensation", "fullspace"])
@pytest.mark.parametrize("case", sorted(BODY_PRESSED))
def test_a_counterpart_body_pressed_by_a_force_beside_a_clamped_one(case, path):
    """The right slab pressed by f: the right pair's resultant along f̂ is |f| to 1e-8 (measured
    1e-15 and 1e-12 on the full space; the slab has no loads of its own, the left pair carries the
    rest of the block's load), the slab's bottom and the partners move by s f̂ beyond their elastic
    displacement, and the model with the bottom moved by the found s f̂ (control = "displacement")
    has the same λ, τ, body and slab displacements to 1e-10 (measured 9e-15); on the full space to
    1e-9, the floor of its Newton method's tolerance (measured 2e-11 up, 3e-10 tilted); there Θ, ξ,
    λ and s agree with the condensation to 1e-9 (measured 7e-11 at most)."""
    f = BODY_PRESSED[case]
    pb = _on_path(_body_force(f), path, 1e-13)
    assert pb.path.name == path
    m, alpha = pb.model, _design(pb)
    st = pb.solve_state(alpha)
    norm = float(np.linalg.norm(f))
    right = m.body.pair_of == 1
    assert not np.any(m.obstacle_force.b[~right]) and not np.any(m.obstacle_force.motion[~right])
    g = np.c_[-st.tau, st.lam][right].sum(axis=0)           # the slabs' frames are the axes
    assert abs(g @ f / norm - norm) <= 1e-8 * norm
    assert abs(st.obstacle.resultant - norm) <= 1e-8 * norm
    assert st.lam[~right].sum() > 0.1 * st.lam.sum() and st.counts["M1"] > 0 and st.counts["L"] > 0
    s = st.obstacle.translation
    assert abs(s) > 1e-3
    slab = m.foundation.parts[1]
    u = np.asarray(st.foundation.displacement)[3 * m.foundation.parts[0].n_nodes:].reshape(-1, 3)
    assert np.abs(u[slab.mesh.loaded] - s * np.array(f) / norm).max() <= 1e-14
    d = s * np.array(f) / norm
    moved = _on_path(_body_force(d, "displacement"), path, 1e-13)
    assert moved.model.obstacle_force is None
    sd = moved.solve_state(alpha)
    scale, same = st.lam.max(), 1e-10 if path == "condensation" else 1e-9
    assert np.abs(sd.lam - st.lam).max() <= same * scale and np.abs(sd.tau - st.tau).max() <= same * scale
    assert np.abs(sd.u - st.u).max() <= same * np.abs(st.u).max()
    assert np.abs(np.asarray(sd.foundation.displacement) - np.asarray(st.foundation.displacement)).max() \
        <= same * abs(s)
    assert np.abs(sd.foundation.u_partner - st.foundation.u_partner).max() <= same * abs(s)
    assert np.array_equal(sd.classes, st.classes)
    if path == "fullspace":
        ref = _on_path(_body_force(f), "condensation", 1e-13)
        theta, xi = pb.evaluate(alpha)
        t0, x0 = ref.evaluate(alpha)
        s0 = ref.solve_state(alpha)
        assert abs(theta - t0) <= 1e-9 * abs(t0) and np.abs(xi - x0).max() <= 1e-9 * np.abs(x0).max()
        assert np.abs(st.lam - s0.lam).max() <= 1e-9 * s0.lam.max()
        assert abs(s - s0.obstacle.translation) <= 1e-9 * abs(s0.obstacle.translation)


@pytest.mark.parametrize("path, case", [("condensation", "tilted"), ("fullspace", "up")])
def test_subgradient_with_a_counterpart_body_pressed_by_a_force_matches_central_differences(path, case):
    """ξ·d with the slab's translation depending on α through the coupling of both slabs (paths/force.py
    on the condensed S_eff; on the full space paths/coupled.py in every body's unknowns) against
    central differences to 1e-6 (measured 3e-10 and 6e-11)."""
    pb = _on_path(_body_force(BODY_PRESSED[case]), path)
    gc = check_gradient(pb, _design(pb), n_directions=2, seed=0, **({} if path == "condensation" else {"h": 1e-2}))
    assert gc.n_degenerate == 0 and gc.passed, gc.rel_errors
    assert max(gc.rel_errors) <= 1e-6
    assert gc.counts["M1"] > 0 and gc.counts["L"] > 0


def test_two_pressed_counterparts_one_of_them_a_body_are_refused_by_name(tmp_path):
    """One counterpart pressed per model: the right slab and a rigid plane under the left pair both
    pressed are refused, the body named with its pair."""
    text = _body_force(BODY_PRESSED["up"])
    text = text[:text.index("[bodies.left]")] + text[text.index("[bodies.right]"):]
    text = text.replace('counterpart = "left.top"', 'counterpart = { shape = "plane", control = "force", '
                                                    'force = [0.0, 0.0, 1.0] }')
    with pytest.raises(ConfigError, match=r"contacts\[0\] and bodies\.right \(contacts\[1\]\): 2 counterparts "
                                          r"pressed by control = 'force'; contactopt searches the translation of one"):
        load_config(_write(tmp_path, text))
