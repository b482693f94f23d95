"""Configuration loading and validation."""

import pytest

from contactopt.config import EXAMPLES, load_config, validate
from contactopt.errors import ConfigError


@pytest.mark.parametrize("name", EXAMPLES)
def test_examples_load_with_paper_constants(name):
    cfg = load_config(name)
    assert cfg["design"]["degree"] == [7, 3]
    assert (cfg["design"]["C0"], cfg["design"]["C1"], cfg["design"]["C2"]) == (0.75, 0.5, 0.01)
    assert cfg["material"] == {"E": 21.19, "nu": 0.277}
    assert cfg["friction"]["coefficient"] == 0.3
    mesh = (cfg["mesh"]["nx"], cfg["mesh"]["ny"], cfg["mesh"]["nz"])
    assert mesh == ((32, 15, 9) if name == "example1" else (24, 11, 11))


def test_every_problem_is_listed_at_once():
    with pytest.raises(ConfigError) as info:
        validate({"mesh": {"nx": 0, "nz": 2.5, "colour": 1}, "material": {"nu": 0.5},
                  "loads": {"top_traction": [0, 1]}, "design": {"C0": 1.5}, "extra": {}})
    probs = info.value.problems
    text = "\n".join(probs)
    for needle in ("extra: unknown section", "mesh.colour: unknown key", "mesh.nx = 0", "mesh.nz = 2.5",
                   "material.nu = 0.5", "loads.top_traction", "design.C0 = 1.5"):
        assert needle in text, needle
    assert len(probs) == 7


def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        load_config(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[mesh\nnx = 3")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad)


def test_target_tables_are_checked():
    with pytest.raises(ConfigError, match="objective.target.kind"):
        validate({"objective": {"target": {"kind": "wave"}}})
    with pytest.raises(ConfigError, match=r"regions\[0\].x1"):
        validate({"objective": {"target": {"kind": "step", "regions": [{"x1": [1.0, 0.0], "value": 1.0}]}}})


def test_the_deprecated_backend_key_is_read_and_a_wrong_value_named():
    """[linear_solver] backend still selects the path (with a warning naming path and library);
    a value it never had is refused with the values it had and the keys to write instead."""
    ls = load_config("example1").with_updates({"linear_solver": {"backend": "amg"}})["linear_solver"]
    assert (ls["path"], "backend" in ls) == ("fullspace", False)
    with pytest.raises(ConfigError, match=r"linear_solver.backend = 'foo': must be one of .*'amg'.*linear_solver.path"):
        load_config("example1").with_updates({"linear_solver": {"backend": "foo"}})
