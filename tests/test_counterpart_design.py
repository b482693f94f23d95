"""Designs on counterpart bodies (fem/cpdesigns.py): a [[designs]] entry on a pair's counterpart face.

A block on two slabs (tests/test_assembly_pairs.py) with a design on the block's face and one on
the left slab's top (two designs on two bodies), the block on one slab (one pair), and a floating
roller between two plates. The monolithic model here builds the moved slab and the gaps itself:
the slab's top moves along +x3 by ϑ_β(x1, x2), its weight on a box clamped at its bottom is
(x3 − x3_bottom)/height, and a contact node's gap falls by ϑ_β at its partner below.

Conventions: per contact node (t1, t2, ν), ν from the counterpart to the face body, r the contact
force on the face body, λ = r_ν ≥ 0, τ = −r_t, w = u_face − u_partner.
"""

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.contact.local import solve_local
from contactopt.contact.state import FROM_FCLIB, TO_FCLIB, classify_nodes
from contactopt.errors import ConfigError
from contactopt.fem.elasticity import ElasticityAssembler
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from test_assembly_pairs import DESIGN, TWO_SLABS

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

SLAB_DESIGN = """
[[designs]]
face = "left.top"
degree = [2, 2]
C0 = 0.05
lower = -0.05
C1 = 0.5
C2 = 0.0
nonnegative_gap = false
initial = 0.0
"""

ONE_SLAB = """
name = "block_on_slab_small"
[geometry]
a = 2.0
b = 1.0
c = 1.0
[mesh]
nx = 8
ny = 4
nz = 4
[material]
E = 21.19
nu = 0.277
[loads]
top_traction = [0.0, 0.0, -8.0e-2]
right_traction = [4.0e-2, 0.01, 0.0]
[bodies.block]
clamped = "clamped"
[bodies.slab]
block = { size = [3.0, 2.0, 1.0], cells = [12, 8, 2], origin = [-0.5, -0.5] }
clamped = "bottom"
material = { E = 2.119 }
[[contacts]]
face = "block.contact"
counterpart = "slab.top"
friction = 0.3
[[designs]]
face = "block.contact"
degree = [3, 2]
C0 = 0.2
C1 = 0.5
C2 = 0.01
initial = 0.01
[state]
tol = 1.0e-14
max_iter = 200
"""

TOP_DESIGN = SLAB_DESIGN.replace('"left.top"', '"slab.top"').replace("degree = [2, 2]", "degree = [3, 1]")


def _problem(tmp_path, text, name="model.toml") -> ShapeProblem:
    path = tmp_path / name
    path.write_text(text)
    return ShapeProblem(load_config(path))


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    return _problem(tmp_path_factory.mktemp("two"), TWO_SLABS + DESIGN + SLAB_DESIGN)


def _alpha(pb, seed, face=0.003, slab=0.004, lift=0.008):
    """A design near α0: the slab's top lifted by about ``lift`` towards the block (both pairs carry load)."""
    m = pb.model
    a = m.initial_design()
    n = m.cp_designs.n_face
    rng = np.random.default_rng(seed)
    a[:n] += face * rng.standard_normal(n)
    a[n:] += lift + slab * rng.standard_normal(a.size - n)
    return a


def _monolithic_state(pb, alpha):
    """λ, τ, w and classes of the block on its two slabs in the compliance form W = B K⁻¹ Bᵀ of one
    block matrix of the three bodies (as tests/test_assembly_pairs.py), the left slab's nodes moved
    by its design here: x3 += ϑ_β(x1, x2)·(x3 − x3_bottom)/height, the gaps of its pair's nodes
    lowered by ϑ_β at their partners (the nodes below them)."""
    model = pb.model
    n = model.cp_designs.n_face
    beta = alpha[n:]
    asm_b = model.assemble(alpha)
    gap = model.gap_matrix[:, :n] @ alpha[:n] + model.gap0          # the block's own part of the gaps
    nb = model.body.reference.n_nodes
    blocks, loads, fixed, offset = [], [asm_b.L_full], [model.body.fixed_dofs], 3 * nb
    mat = pb.config.material
    blocks.append(ElasticityAssembler(model.body.reference.cells, nb, np.zeros(0, int), mat.E, mat.nu)
                  .full_stiffness(asm_b.coords))
    partner = np.full(model.n_contact, -1)
    x_b = model.body.reference.points[model.contact_nodes]
    surface = model.surface.surfaces[1]
    for k, spec in enumerate(pb.config.pairs):
        ref = model.foundation.parts[k].mesh.reference
        x = ref.points.copy()
        rows = np.flatnonzero(model.body.pair_of == k)
        if k == 0:                         # the left slab: moved by its design
            lo, hi = x[:, 2].min(), x[:, 2].max()
            theta = surface.basis_matrix(x[:, 0], x[:, 1]) @ beta
            x[:, 2] += theta * (x[:, 2] - lo) / (hi - lo)
        f = spec.foundation
        blocks.append(ElasticityAssembler(ref.cells, ref.n_nodes, np.zeros(0, int), f.material.E, f.material.nu)
                      .full_stiffness(x))
        loads.append(np.zeros(3 * ref.n_nodes))
        bottom = np.flatnonzero(np.isclose(ref.points[:, 2], ref.points[:, 2].min()))
        fixed.append(offset + (3 * bottom[:, None] + np.arange(3)).ravel())
        d = np.linalg.norm(ref.points[None, :, :] - x_b[rows, None, :], axis=2)
        assert np.allclose(d.min(axis=1), 0.0)           # matching meshes: a node under every contact node
        below = np.argmin(d, axis=1)
        if k == 0:
            gap[rows] -= x[below, 2] - ref.points[below, 2]
        partner[rows] = offset // 3 + below
        offset += 3 * ref.n_nodes
    K, L = sp.block_diag(blocks).tocsr(), np.concatenate(loads)
    free = np.setdiff1d(np.arange(K.shape[0]), np.concatenate(fixed))
    index = np.full(K.shape[0], -1)
    index[free] = np.arange(free.size)
    p = model.n_contact
    pb_dofs = (3 * model.contact_nodes[:, None] + np.arange(3)).ravel()
    pf_dofs = (3 * partner[:, None] + np.arange(3)).ravel()
    rows = np.arange(3 * p)
    B = sp.csr_matrix((np.r_[np.ones(3 * p), -np.ones(3 * p)], (np.r_[rows, rows], np.r_[index[pb_dofs],
                                                                                            index[pf_dofs]])),
                      shape=(3 * p, free.size))
    lu = sla.splu(K[free][:, free].tocsc())
    W = B @ lu.solve(B.T.toarray())
    W = 0.5 * (W + W.T)
    w0 = B @ lu.solve(L[free])
    perm = (3 * np.arange(p)[:, None] + TO_FCLIB).ravel()        # (t1, t2, ν) → (ν, t1, t2)
    q = w0[perm]
    q[0::3] += gap
    res = solve_local(W[np.ix_(perm, perm)], q, pb.friction, tol=1e-14, max_iter=200)
    r = res.r.reshape(p, 3)[:, FROM_FCLIB]
    w = (w0 + W @ r.ravel()).reshape(p, 3)
    lam, tau = r[:, 2], -r[:, :2]
    return lam, tau, w, classify_nodes(w, lam, tau, gap, pb.friction)


def test_two_designs_on_two_bodies_concatenate_their_control_points(two):
    """α = (the block's 12, the left slab's 9); U the product of both sets; the slab's design moves
    the gaps of its own pair's nodes alone, by −ϑ_β at their partners (matching meshes)."""
    m = two.model
    assert m.n_design == 21 and m.surface.sizes == (12, 9)
    assert m.admissible.A_eq.shape == (2, 21)
    a0 = m.initial_design()
    beta = np.zeros(21)
    beta[12:] = 0.01 * np.random.default_rng(4).random(9)
    dg = m.assemble(a0 + beta).gap - m.assemble(a0).gap
    left = m.body.pair_of == 0
    assert np.all(dg[~left] == 0.0)
    x = m.body.reference.points[m.contact_nodes[left]]
    theta = m.surface.surfaces[1].basis_matrix(x[:, 0], x[:, 1]) @ beta[12:]
    assert np.abs(dg[left] + theta).max() <= 1e-14


def test_two_designs_on_two_bodies_agree_with_a_monolithic_model(two):
    """λ, τ and w of the block on two slabs, the block's face and the left slab's top designed,
    to 1e-10 of the monolithic model whose slab is moved here; slip, stick and separation present."""
    for seed in (0, 1):
        alpha = _alpha(two, seed)
        st = two.solve_state(alpha)
        lam, tau, w, classes = _monolithic_state(two, alpha)
        scale = lam.max()
        assert np.abs(st.lam - lam).max() <= 1e-10 * scale
        assert np.abs(st.tau - tau).max() <= 1e-10 * scale
        assert np.abs(st.u_c - w).max() <= 1e-10 * np.abs(w).max()
        assert np.array_equal(st.classes, classes)
        pair = two.model.body.pair_of
        assert lam[pair == 0].sum() > 0.05 * lam.sum()          # the designed slab carries load


def test_subgradient_of_two_designs_on_two_bodies_matches_central_differences(two):
    """ξ·d against Richardson central differences to 1e-6 along random directions of both designs and
    along the slab's design alone, with sliding, sticking and free nodes; Taylor order ≈ 2."""
    alpha = _alpha(two, 1)
    gc = check_gradient(two, alpha, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0 and gc.counts["L"] > 0
    assert abs(gc.taylor_rate - 2.0) < 0.3
    value, xi = two.evaluate(alpha)
    h = 1e-5
    for k in (12, 16, 20):                 # the slab's columns, one at a time
        e = np.zeros(alpha.size)
        e[k] = h
        fd = (two.evaluate(alpha + e)[0] - two.evaluate(alpha - e)[0]) / (2 * h)
        assert abs(xi[k] - fd) <= 1e-6 * np.abs(xi).max(), (k, xi[k], fd)
    assert np.abs(xi[12:]).max() > 1e-3 * np.abs(xi).max()       # the slab's design matters


def test_a_counterpart_design_at_zero_gives_the_undesigned_model(tmp_path):
    """The block on one slab with the slab's top designed, at β = 0: Θ, the state and the block's
    part of ξ those of the model without the slab's design (to 1e-12)."""
    plain = _problem(tmp_path, ONE_SLAB, "plain.toml")
    both = _problem(tmp_path, ONE_SLAB + TOP_DESIGN, "both.toml")
    a = plain.model.initial_design() + 0.003 * np.random.default_rng(5).standard_normal(plain.model.n_design)
    ab = np.concatenate([a, np.zeros(both.model.n_design - a.size)])
    v0, xi0 = plain.evaluate(a)
    v1, xi1 = both.evaluate(ab)
    assert abs(v1 - v0) <= 1e-12 * abs(v0)
    assert np.abs(xi1[:a.size] - xi0).max() <= 1e-10 * np.abs(xi0).max()
    s0, s1 = plain.solve_state(a), both.solve_state(ab)
    assert np.abs(s1.lam - s0.lam).max() <= 1e-12 * s0.lam.max()
    assert np.array_equal(s1.classes, s0.classes)
    assert np.abs(xi1[a.size:]).max() > 0


def test_subgradient_of_a_designed_slab_under_one_block_matches_central_differences(tmp_path):
    """One pair (the block on its slab, fem.foundation.Foundation designed): ξ·d to 1e-6."""
    pb = _problem(tmp_path, ONE_SLAB + TOP_DESIGN)
    gc = check_gradient(pb, _alpha(pb, 2), n_directions=3, seed=1)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors


ROLLER_DESIGNS = """
[[designs]]
face = "roller.lower"
chart = "cylinder"
degree = [2, 0]
C0 = 0.02
lower = -0.02
C1 = 0.5
C2 = 0.0
nonnegative_gap = false
initial = 0.0

[[designs]]
face = "lower.top"
degree = [2, 0]
C0 = 0.02
lower = -0.02
C1 = 0.5
C2 = 0.0
nonnegative_gap = false
initial = 0.0
"""


def test_subgradient_with_a_floating_roller_and_a_designed_plate_matches_central_differences(tmp_path):
    """The roller held only by its two contacts (examples/roller_plates.toml) with a design on its
    lower face and one on the lower plate's top: ξ·d to 1e-6 of central differences."""
    text = (EXAMPLES / "roller_plates.toml").read_text().replace('"roller_plates/', f'"{EXAMPLES}/roller_plates/')
    pb = _problem(tmp_path, text + ROLLER_DESIGNS)
    assert pb.model.body.rigid is not None
    m = pb.model
    a = m.initial_design()
    a[m.cp_designs.n_face:] += 1e-3 * np.random.default_rng(6).standard_normal(a.size - m.cp_designs.n_face)
    gc = check_gradient(pb, a, n_directions=3, seed=2)
    assert gc.n_degenerate == 0
    assert gc.passed, gc.rel_errors


@pytest.mark.parametrize("face, words", [
    ('"ground.top"', "no body is named 'ground'"),
    ('"left.bottom"', "or after it a counterpart body's part that is a pair's counterpart face (here: left.top, "
                      "right.top)"),
])
def test_a_design_on_no_counterpart_face_is_refused(face, words, tmp_path):
    """A design on a part of no body, or on a counterpart body's part no pair meets: ConfigError."""
    path = tmp_path / "bad.toml"
    path.write_text(TWO_SLABS + DESIGN + SLAB_DESIGN.replace('"left.top"', face))
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert words in str(exc.value)


def test_a_counterpart_design_before_the_face_bodys_is_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(TWO_SLABS + SLAB_DESIGN + DESIGN)
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert "comes after the designs of the face body 'block'" in str(exc.value)


def test_the_paths_that_do_not_form_it_refuse_a_counterpart_design(tmp_path):
    """The full-space path keeps the counterparts assembled: a design of one is refused by name."""
    text = TWO_SLABS.replace("[state]", '[linear_solver]\npath = "fullspace"\n[state]') + DESIGN + SLAB_DESIGN
    with pytest.raises(ConfigError) as exc:
        _problem(tmp_path, text)
    assert ("designs[1].face = 'left.top': a designed counterpart is condensed per design on the condensation "
            "path so far; use linear_solver.path = 'condensation'") in str(exc.value)


@pytest.mark.parametrize("objective", ["max_pressure", "peak_stress"])
def test_pressure_and_stress_objectives_of_a_designed_slab_match_central_differences(objective, tmp_path):
    """The peak pressure (KS) and the peak von Mises stress of the block (∂J/∂u on every DOF) with the
    slab's top designed: ξ·d along the slab's design alone against Richardson central differences."""
    pb = _problem(tmp_path, ONE_SLAB + TOP_DESIGN + f'[objective]\ntype = "{objective}"\nscale = 1.0e4\n')
    alpha = _alpha(pb, 3)
    value, xi = pb.evaluate(alpha)
    d = np.random.default_rng(0).standard_normal(alpha.size)
    d[:pb.model.cp_designs.n_face] = 0.0
    h = 1e-6
    f1 = (pb.evaluate_value(alpha + h * d) - pb.evaluate_value(alpha - h * d)) / (2 * h)
    f2 = (pb.evaluate_value(alpha + 2 * h * d) - pb.evaluate_value(alpha - 2 * h * d)) / (4 * h)
    fd = (4 * f1 - f2) / 3
    assert abs(xi @ d - fd) <= 1e-6 * abs(fd), (xi @ d, fd)


def test_subgradient_along_a_load_path_with_a_designed_slab_matches_central_differences():
    """Pressed, then sheared (the slip of the first step the second's reference): ξ·d of the pressure
    uniformity with the block's face and the left slab's top designed, to 1e-6."""
    import tomllib
    text = TWO_SLABS + DESIGN + SLAB_DESIGN + (
        '[[load_steps]]\nname = "press"\ntop_traction = [0.0, 0.0, -8.0e-2]\n'
        '[[load_steps]]\nname = "shear"\ntop_traction = [0.0, 0.0, -8.0e-2]\nright_traction = [4.0e-2, 0.01, 0.0]\n'
        '[objective]\ntype = "pressure_uniformity"\n')
    data = tomllib.loads(text)
    data["loads"] = {}
    pb = ShapeProblem(load_config(data))
    gc = check_gradient(pb, _alpha(pb, 0), n_directions=2, seed=0)
    assert gc.n_degenerate == 0 and gc.passed, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["M3+"] > 0


@pytest.mark.parametrize("objective", ["compliance", "frictional_dissipation"])
def test_objectives_through_the_counterparts_compliance_are_refused(objective, tmp_path):
    with pytest.raises(ConfigError) as exc:
        _problem(tmp_path, ONE_SLAB + TOP_DESIGN + f'[objective]\ntype = "{objective}"\n')
    assert f"objective {objective!r} with a design on a counterpart body (slab.top)" in str(exc.value)


def test_check_gradient_of_two_designs_on_two_bodies_from_the_command_line(tmp_path, capsys):
    """``contactopt check-gradient`` on the block on its slab with both designed: passes, Taylor order 2."""
    path = tmp_path / "both.toml"
    path.write_text(ONE_SLAB + TOP_DESIGN)
    assert main(["check-gradient", str(path), "--directions", "2"]) == 0
    out = capsys.readouterr().out
    assert "PASSED" in out and "observed order 2.0" in out
