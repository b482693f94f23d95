"""The assembly spelling of a model, ``[bodies.<name>]``, ``[[contacts]]`` and ``[[designs]]``: the
one- and two-body models written in it resolve to the configurations of ``[body]``, ``[foundation]``,
``[obstacle]`` and ``[design]`` and give the same Θ and ξ to the bit; bad input is refused with
every problem named at once and nothing written."""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from contactopt import ShapeProblem
from contactopt.cli import main
from contactopt.config import load_config
from contactopt.errors import ConfigError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

SMALL = {"nx": 8, "ny": 4, "nz": 3}

HEADER = """
name = "slab"
[mesh]
nx = 8
ny = 4
nz = 3
[loads]
top_traction = [0.0, 0.0, -8.0e-2]
right_traction = [5.0e-2, 0.0, 0.0]
"""
OBJECTIVE = """[objective]
type = "target_normal_force"
target = { kind = "step", per_area = true, default = 0.0, regions = [ { x1 = [0.6875, 2.0], value = 0.0676 } ] }
"""

BLOCK_ON_SLAB = HEADER + """[bodies.block]
[bodies.slab]
block = { size = [3.0, 2.0, 1.0], cells = [6, 4, 2], origin = [-0.5, -0.5] }
clamped = "bottom"
material = { E = 2.119 }
[[contacts]]
face = "block.contact"
counterpart = "slab.top"
friction = 0.3
[[designs]]
face = "block.contact"
initial = 0.01
""" + OBJECTIVE

BLOCK_ON_SLAB_OLD = HEADER + """[friction]
coefficient = 0.3
[design]
initial = 0.01
[foundation]
block = { size = [3.0, 2.0, 1.0], cells = [6, 4, 2], origin = [-0.5, -0.5] }
clamped = "bottom"
material = { E = 2.119 }
""" + OBJECTIVE


def _write(tmp_path, text: str, name: str = "model.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _same_evaluation(a, b) -> None:
    """Θ and ξ of two configurations at their initial design and at a perturbed one, to the bit."""
    pa, pb = ShapeProblem(a), ShapeProblem(b)
    alpha = pa.model.initial_design()
    assert np.array_equal(alpha, pb.model.initial_design())
    rng = np.random.default_rng(3)
    for x in (alpha, alpha + 0.002 * rng.random(alpha.size)):
        fa, ga = pa.evaluate(x)
        fb, gb = pb.evaluate(x)
        assert fa == fb and np.array_equal(ga, gb)


def _sections(cfg) -> dict:
    data = cfg.to_dict()
    for key in ("assembly", "name", "description"):
        data.pop(key, None)
    return data


def test_a_body_on_an_elastic_body_is_the_foundation_model_bit_for_bit(tmp_path):
    new = load_config(_write(tmp_path, BLOCK_ON_SLAB))
    old = load_config(_write(tmp_path, BLOCK_ON_SLAB_OLD, "old.toml"))
    assert _sections(new) == _sections(old)
    assert new.assembly.bodies == ("block", "slab")
    assert [(p.face, p.counterpart) for p in new.assembly.contacts] == [("block.contact", "slab.top")]
    assert new.assembly.designs == ("block.contact",)
    assert old.assembly.bodies == ("body", "foundation")
    _same_evaluation(new, old)


def test_the_resolved_assembly_reads_back_to_itself(tmp_path):
    cfg = load_config(_write(tmp_path, BLOCK_ON_SLAB))
    again = load_config(_write(tmp_path, tomli_w.dumps(cfg.to_dict()), "resolved.toml"))
    assert again.to_dict() == cfg.to_dict()
    assert again.assembly == cfg.assembly


def test_a_body_against_a_rigid_counterpart_is_the_obstacle_model_bit_for_bit(tmp_path):
    """The roller pressed by a force-controlled plane (examples/roller_rigid.toml) in the assembly
    spelling: the rigid counterpart is a table with the keys of [obstacle]."""
    shutil.copytree(EXAMPLES / "roller_rigid", tmp_path / "roller_rigid")
    old_path = shutil.copy(EXAMPLES / "roller_rigid.toml", tmp_path / "old.toml")
    raw = tomllib.loads(Path(old_path).read_text())
    body, obstacle, design = raw.pop("body"), raw.pop("obstacle"), raw.pop("design")
    friction = raw.pop("friction")["coefficient"]
    raw["bodies"] = {"roller": {k: body[k] for k in ("mesh", "clamped")}}
    raw["contacts"] = [{"face": f"roller.{body['contact']}", "counterpart": obstacle, "friction": friction,
                        "initial_gap": body["initial_gap"]}]
    raw["designs"] = [{"face": f"roller.{body['contact']}", **design}]
    new = load_config(_write(tmp_path, tomli_w.dumps(raw)))
    old = load_config(old_path)
    assert _sections(new) == _sections(old)
    assert new.assembly.contacts[0].counterpart == "rigid plane"
    _same_evaluation(new, old)


def test_the_fixed_plane_as_a_counterpart_is_the_model_without_an_obstacle(tmp_path):
    text = BLOCK_ON_SLAB.replace('counterpart = "slab.top"', 'counterpart = { shape = "plane" }')
    text = text.replace('[bodies.slab]\nblock = { size = [3.0, 2.0, 1.0], cells = [6, 4, 2], origin = [-0.5, -0.5] }'
                        '\nclamped = "bottom"\nmaterial = { E = 2.119 }\n', "")
    new = load_config(_write(tmp_path, text))
    old = load_config("example1").with_updates({"mesh": SMALL, "name": "slab", "design": {"initial": 0.01}})
    assert new.obstacle is None and new.foundation is None
    assert new.friction == old.friction and new.design == old.design and new.body == old.body


def test_a_model_without_designs_solves_states_and_run_refuses_it(tmp_path, capsys):
    text = BLOCK_ON_SLAB.replace('[[designs]]\nface = "block.contact"\ninitial = 0.01\n', "")
    path = _write(tmp_path, text)
    cfg = load_config(path)
    assert cfg.assembly.designs == ()
    out = tmp_path / "state"
    assert main(["state", str(path), "--out", str(out)]) == 0
    capsys.readouterr()
    assert (out / "state.json").exists()
    # the state of the reference shape: the same as the design-carrying model at ϑ = 0
    with_design = load_config(_write(tmp_path, BLOCK_ON_SLAB, "designed.toml"))
    lam = ShapeProblem(cfg).solve_state(np.zeros(1)).lam
    ref = ShapeProblem(with_design)
    assert np.allclose(ref.solve_state(np.zeros(ref.model.n_design)).lam, lam, rtol=0, atol=1e-12)
    run_out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(run_out), "--max-iter", "1"]) == 2
    err = capsys.readouterr().err
    assert "[[designs]]" in err and "contactopt state" in err
    assert not run_out.exists()
    assert main(["check-gradient", str(path)]) == 2
    assert "[[designs]]" in capsys.readouterr().err


BAD = """
name = "bad"
[bodies.block]
[bodies.slab]
block = { size = [3.0, 2.0, 1.0], cells = [6, 4, 2], origin = [-0.5, -0.5] }
[[contacts]]
face = "blok.contact"
counterpart = "slab.top"
[[designs]]
face = "nobody.contact"
[[loads.traction]]
on = "ghost.right"
value = [1.0, 0.0, 0.0]
"""


def test_bad_names_are_all_listed_at_once_and_nothing_is_written(tmp_path, capsys):
    path = _write(tmp_path, BAD)
    out = tmp_path / "out"
    assert main(["state", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    for needle in ("contacts[0].face = 'blok.contact': no body is named 'blok'",
                   "designs[0].face = 'nobody.contact': no body is named 'nobody'"):
        assert needle in err, err
    assert not out.exists()


@pytest.mark.parametrize("change, needle", [
    (('counterpart = "slab.top"', 'counterpart = "block.contact"'),
     "contacts[0]: face and counterpart are the same part 'block.contact'"),
    (('counterpart = "slab.top"', 'counterpart = "block.top"'), "not self-contact"),
    (('face = "block.contact"\ncounterpart', 'face = "block"\ncounterpart'),
     "contacts[0].face = 'block': must be \"<body>.<part>\""),
    (('[[designs]]\nface = "block.contact"', '[[designs]]\nface = "slab.top"'),
     "designs[0].face = 'slab.top': contactopt designs the face of the contact pair (block.contact)"),
    (('right_traction = [5.0e-2, 0.0, 0.0]', 'right_traction = [5.0e-2, 0.0, 0.0]\n[[loads.traction]]\n'
      'on = "ghost.right"\nvalue = [1.0, 0.0, 0.0]'), "loads.traction[0].on = 'ghost.right': no body is named"),
    (('friction = 0.3', 'friction = 0.3\nfrixion = 0.2'), "contacts[0].frixion: unknown key"),
    (('clamped = "bottom"', 'clamped = 5'), "bodies.slab.clamped = 5: must be"),
    (('face = "block.contact"\ninitial = 0.01', 'face = "block.contact"\ninitial = 0.01\nC1 = -1'),
     "designs[0].C1 = -1: must be"),
    (('[bodies.block]', '[body]\nmesh = ""\n[bodies.block]'), "[body]: is the one-body spelling"),
    (('[[designs]]', '[bodies.extra]\nmesh = ""\n[[designs]]'), "bodies.extra: takes part in no contact pair"),
])
def test_each_bad_assembly_is_refused_by_name(tmp_path, state_refused, change, needle):
    text = BLOCK_ON_SLAB.replace(*change)
    assert text != BLOCK_ON_SLAB
    state_refused(_write(tmp_path, text), needle)


def test_two_bodies_of_one_name_are_refused_by_the_toml_reader(tmp_path, state_refused):
    text = BLOCK_ON_SLAB.replace('[bodies.slab]', '[bodies.block]\n[bodies.slab]', 1)
    text = text.replace('[bodies.block]\n[bodies.block]', '[bodies.block]\nmesh = ""\n[bodies.block]')
    state_refused(_write(tmp_path, text), "not valid TOML", "block")


def test_what_the_mechanics_do_not_take_yet_is_refused_by_name(tmp_path):
    """Several pairs or designs: refused with the sentence that says what is solved so far."""
    text = BLOCK_ON_SLAB + ('[[contacts]]\nface = "slab.bottom"\ncounterpart = { shape = "plane", control = "force", '
                            'force = [0.0, 0.0, 1.0] }\n')
    with pytest.raises(ConfigError) as exc:
        load_config(_write(tmp_path, text))
    assert "contacts[1].face = 'slab.bottom': with several pairs contactopt takes the faces of every pair on one " \
           "body so far ('block'" in str(exc.value)
    assert "control = 'force'" not in str(exc.value)       # a rigid counterpart pressed by a force is taken
    text = BLOCK_ON_SLAB + '[[designs]]\nface = "block.contact"\n'
    with pytest.raises(ConfigError, match="2 designed faces"):
        load_config(_write(tmp_path, text))


def test_mesh_paths_of_bodies_and_rigid_counterparts_are_relative_to_the_file(tmp_path):
    sub = tmp_path / "sub"
    sub.mkdir()
    shutil.copytree(EXAMPLES / "roller_rigid", sub / "roller_rigid")
    text = ('name = "r"\n[bodies.roller]\nmesh = "roller_rigid/roller.msh"\nclamped = [ { on = "top", components = '
            '[3] }, { on = "mid", components = [1] }, { on = "sym", components = [2] } ]\n[[contacts]]\n'
            'face = "roller.contact"\ncounterpart = { shape = "surface", mesh = "plate.stl" }\n')
    cfg_path = _write(sub, text)
    with pytest.raises(ConfigError) as exc:
        load_config(cfg_path)
    # the body's mesh was found; the counterpart's file is looked for beside the configuration
    assert "bodies.roller.mesh" not in str(exc.value)
    assert f"contacts[0].counterpart.mesh = '{sub / 'plate.stl'}': no such file" in str(exc.value)


def test_the_json_schema_takes_the_assembly_spelling_and_its_resolved_record(tmp_path):
    jsonschema = pytest.importorskip("jsonschema")
    from contactopt.config import json_schema
    validator = jsonschema.Draft202012Validator(json_schema())
    raw = tomllib.loads(BLOCK_ON_SLAB)
    assert list(validator.iter_errors(raw)) == []
    assert list(validator.iter_errors(load_config(_write(tmp_path, BLOCK_ON_SLAB)).to_dict())) == []
    raw["contacts"][0]["frixion"] = 0.2
    assert [e.message for e in validator.iter_errors(raw)] == ["Additional properties are not allowed ('frixion' was "
                                                                "unexpected)"]


def test_the_shipped_assembly_example_is_example1_elastic():
    new, old = load_config(EXAMPLES / "block_on_slab.toml"), load_config(EXAMPLES / "example1_elastic.toml")
    assert _sections(new) == _sections(old)
    assert new.assembly.bodies == ("block", "slab")


def test_the_state_files_name_each_pair_and_each_contact_node_s_pair_and_place(tmp_path, capsys):
    path = _write(tmp_path, BLOCK_ON_SLAB)
    out = tmp_path / "state"
    assert main(["state", str(path), "--out", str(out)]) == 0
    capsys.readouterr()
    doc = json.loads((out / "state.json").read_text())
    with np.load(out / "state.npz") as z:
        lam, pressure, classes = z["lam"], z["pressure"], z["classes"]
        coords, pair, nodes = z["contact_coords"], z["contact_pair"], z["contact_nodes"]
    cfg = load_config(path)
    ref = ShapeProblem(cfg).model.body.reference.points
    assert np.array_equal(coords, ref[nodes]) and np.all(coords[:, 2] == 0.0)
    assert pair.dtype.kind == "i" and np.all(pair == 0) and pair.size == lam.size
    [report] = doc["contacts"]
    assert (report["name"], report["face"], report["counterpart"]) == ("block-slab", "block.contact", "slab.top")
    assert report["total_normal_force"] == pytest.approx(lam.sum(), rel=1e-15)
    assert report["total_normal_force"] == pytest.approx(doc["summary"]["total_normal_force"], rel=1e-15)
    assert report["peak_pressure"] == pressure.max() > 0
    assert sum(report["node_classes"].values()) == report["nodes"] == lam.size
    assert report["node_classes"]["L"] == int(np.sum(classes == 0))


def test_a_run_reports_each_pair_at_the_initial_and_the_optimal_design(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(_write(tmp_path, BLOCK_ON_SLAB)), "--out", str(out), "--max-iter", "2", "--no-plots"]) == 0
    capsys.readouterr()
    summary = json.loads((out / "summary.json").read_text())
    for at, state in (("optimal", summary["final_state"]),):
        [report] = summary["contacts"][at]
        assert report["name"] == "block-slab"
        assert report["total_normal_force"] == pytest.approx(state["total_normal_force"], rel=1e-15)
    assert [r["name"] for r in summary["contacts"]["initial"]] == ["block-slab"]


def test_the_examples_copy_takes_the_mesh_folders_of_every_body_and_rigid_counterpart():
    from contactopt.io.examples import _mesh_paths
    data = {"bodies": {"roller": {"mesh": "roller/roller.msh"}, "race": {"mesh": "races/outer.msh"}},
            "contacts": [{"face": "roller.top", "counterpart": "race.inner"},
                         {"face": "roller.bottom", "counterpart": {"shape": "surface", "mesh": "inner/race.stl"}}]}
    assert sorted(_mesh_paths(data)) == ["inner/race.stl", "races/outer.msh", "roller/roller.msh"]
    old = {"body": {"mesh": "pad/pad.msh"}, "foundation": {"mesh": "slab/slab.msh"}}
    assert sorted(_mesh_paths(old)) == ["pad/pad.msh", "slab/slab.msh"]


def test_a_counterpart_body_left_free_is_refused_in_the_keys_written_naming_its_free_motions(tmp_path, state_refused):
    """A problem found while the meshes are read names the assembly's keys, not the one-body sections
    the assembly is read as; the one-body spelling keeps its own."""
    free = 'clamped = [{ on = "bottom", components = [3] }]'
    motions = "the translation along x1, the translation along x2, the rotation about x3"
    state_refused(_write(tmp_path, BLOCK_ON_SLAB.replace('clamped = "bottom"', free), "a.toml"),
                  "bodies.slab.clamped leaves 3 rigid-body motion(s) free, " + motions, "its own clamps")
    state_refused(_write(tmp_path, BLOCK_ON_SLAB_OLD.replace('clamped = "bottom"', free), "b.toml"),
                  "foundation.clamped leaves 3 rigid-body motion(s) free, " + motions)
    # a part the mesh does not have, found when the body is built
    state_refused(_write(tmp_path, BLOCK_ON_SLAB.replace('counterpart = "slab.top"', 'counterpart = "slab.tpo"'),
                         "c.toml"), "contacts[0].counterpart")
