"""Several designed faces in one model (``[[designs]]`` with more than one entry): a block on two
slabs with a design on each of its two contact faces (fem/designs.py, mesh/morph.SeveralMorphs).

α = (α_0, α_1) concatenates the faces' control points; each face's harmonic weight is 1 on it and 0
on the other; gaps per contact node (t1, t2, ν) as in tests/test_assembly_pairs.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.errors import ConfigError
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.check import check_gradient
from test_assembly_pairs import TWO_SLABS

LEFT = '{ body = "block", x3 = 0.0, box = [[0.0, 1.1], [0.0, 1.0], [-1.0, 1.0]] }'
RIGHT = '{ body = "block", x3 = 0.0, box = [[1.1, 2.0], [0.0, 1.0], [-1.0, 1.0]] }'

FIRST = f"""
[[designs]]
face = {LEFT}
degree = [3, 2]
C0 = 0.2
C1 = 0.5
C2 = 0.01
initial = 0.01
"""
SECOND = f"""
[[designs]]
face = {RIGHT}
degree = [2, 2]
C0 = 0.2
C1 = 0.5
C2 = 0.02
initial = 0.02
"""


def _problem(tmp_path, text, name="model.toml") -> ShapeProblem:
    path = tmp_path / name
    path.write_text(text)
    return ShapeProblem(load_config(path))


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    return _problem(tmp_path_factory.mktemp("two"), TWO_SLABS + FIRST + SECOND)


def test_two_designs_concatenate_their_control_points_and_sets(two):
    """α has 12 + 9 entries; U is the product: each design's volume row on its own block; the
    initial design is each design's initial value."""
    m = two.model
    assert m.n_design == 21
    a0 = m.initial_design()
    assert np.all(a0[:12] == 0.01) and np.all(a0[12:] == 0.02)
    U = m.admissible
    assert U.A_eq.shape == (2, 21)
    assert np.array_equal(U.A_eq[0] != 0, np.arange(21) < 12)
    assert np.isclose(U.b_eq[0], 0.01 * 12) and np.isclose(U.b_eq[1], 0.02 * 9)
    bad = a0.copy()
    bad[15] = 0.5                                 # above designs[1]'s C0
    assert any(v.startswith("designs[1]: bound") for v in U.violations(bad))


def test_a_design_moves_its_face_alone(two):
    """A change of α_0 changes the gaps of the left pair's nodes and leaves those of the right
    pair (and every node of the right face) exactly as they were, and the other way round."""
    m = two.model
    pair = m.body.pair_of
    a0 = m.initial_design()
    ref = m.assemble(a0)
    for block, moved in ((slice(0, 12), 0), (slice(12, 21), 1)):
        a = a0.copy()
        a[block] += 0.01 * np.random.default_rng(3).random(a[block].size)
        asm = m.assemble(a)
        still = pair != moved
        assert np.array_equal(asm.gap[still], ref.gap[still])
        assert np.abs(asm.gap[~still] - ref.gap[~still]).min() > 1e-4
        other = m.body.designs[1 - moved].face.nodes
        assert np.array_equal(asm.coords[other], ref.coords[other])


def test_one_of_two_designs_at_rest_is_the_model_of_the_other_alone(tmp_path):
    """With α_1 = 0 the model of two designs is the model of the left design alone (the right
    pair's face held fixed in shape, and the block's top alone among its named parts: the
    automatic choice keeps the parts that touch no designed face), the same weight on the left
    face, Θ and ξ_0 to 1e-12."""
    top = TWO_SLABS.replace('clamped = "clamped"\n', 'clamped = "clamped"\nfixed_shape = ["top"]\n', 1)
    assert top != TWO_SLABS
    one = _problem(tmp_path, top + FIRST, "one.toml")
    two = _problem(tmp_path, top + FIRST + SECOND, "two.toml")
    rng = np.random.default_rng(5)
    a = one.model.initial_design() + 0.003 * rng.standard_normal(12)
    both = np.concatenate([a, np.zeros(9)])
    assert np.array_equal(two.model.weight[0], one.model.weight)
    t1, x1 = one.evaluate(a)
    t2, x2 = two.evaluate(both)
    assert abs(t2 - t1) <= 1e-12 * abs(t1)
    assert np.abs(x2[:12] - x1).max() <= 1e-12 * np.abs(x1).max()


def test_subgradient_of_two_designs_matches_central_differences(two):
    """ξ·d of both designs together against Richardson central differences to 1e-6, with sliding,
    sticking and free nodes."""
    a = two.model.initial_design()
    alpha = a + 0.003 * np.random.default_rng(1).standard_normal(a.size)
    gc = check_gradient(two, alpha, n_directions=3, seed=0)
    assert gc.n_degenerate == 0
    assert gc.passed and max(gc.rel_errors) <= 1e-6, gc.rel_errors
    assert gc.counts["M1"] > 0 and gc.counts["L"] > 0


@pytest.mark.parametrize("face, words", [
    ('"slab.top"', ["designs[1].face", "no body is named 'slab'"]),
    ('"block.nowhere"', ["designs[1].face", "nowhere"]),
    ('{ body = "block", x3 = 0.0, box = [[0.9, 2.0], [0.0, 1.0], [-1.0, 1.0]] }',
     ["designs[1].face and designs[0].face", "share", "node"]),
])
def test_bad_designs_are_refused_by_name_and_nothing_is_written(face, words, tmp_path, capsys):
    """A design on a part of no body, on no part of the face body, or sharing nodes with another
    design: ConfigError naming it, exit 2 from the CLI, no output directory."""
    text = TWO_SLABS + FIRST + SECOND.replace(RIGHT, face)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as exc:
        ShapeProblem(load_config(path))
    for w in words:
        assert w in str(exc.value), str(exc.value)
    out = tmp_path / "out"
    assert main(["state", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert words[0] in err
    assert not out.exists()


def test_state_files_keep_alpha_per_design(two, tmp_path, capsys):
    """state.json holds α as one control-point matrix per design, which --alpha reads back."""
    path = tmp_path / "model.toml"
    path.write_text(TWO_SLABS + FIRST + SECOND)
    out = tmp_path / "st"
    assert main(["state", str(path), "--out", str(out)]) == 0
    alpha = json.loads((out / "state.json").read_text())["alpha"]
    assert [np.shape(a) for a in alpha] == [(4, 3), (3, 3)]
    assert np.all(np.array(alpha[1]) == 0.02)
    assert main(["state", str(path), "--alpha", str(out / "state.json"), "--out", str(tmp_path / "again")]) == 0
    capsys.readouterr()
