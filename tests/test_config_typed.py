"""The typed configuration: sections as frozen dataclasses read from the one schema, and the
JSON Schema of ``contactopt schema`` checked against every example with a standard validator."""

import dataclasses
import json
import tomllib
from importlib import resources
from pathlib import Path

import pytest

from contactopt.cli import main
from contactopt.config import (
    EXAMPLES,
    FOUNDATION,
    OBSTACLE,
    SCHEMA,
    TOP_LEVEL,
    Config,
    json_schema,
    load_config,
    validate,
)
from contactopt.config import sections as S
from contactopt.errors import ConfigError

jsonschema = pytest.importorskip("jsonschema")

ROOT = Path(__file__).parent.parent
FILES = sorted((ROOT / "examples").glob("*.toml"))
SECTION_TYPES = {"body": S.Body, "geometry": S.Geometry, "mesh": S.Mesh, "material": S.Material,
                 "friction": S.Friction, "loads": S.Loads, "design": S.Design, "objective": S.Objective,
                 "state": S.State, "linear_solver": S.LinearSolver, "optimizer": S.Optimizer}


def _raw(name):
    if name in EXAMPLES:
        return tomllib.loads(resources.files("contactopt").joinpath("examples", f"{name}.toml").read_text())
    return tomllib.loads(Path(name).read_text())


@pytest.fixture(scope="module")
def validator():
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.mark.parametrize("sec", list(SECTION_TYPES))
def test_every_key_of_the_schema_is_a_field_without_a_default(sec):
    """One default per option: the schema's; a section's dataclass declares its keys and types only."""
    fields = dataclasses.fields(SECTION_TYPES[sec])
    assert [f.name for f in fields] == list(SCHEMA[sec])
    assert all(f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING for f in fields)


def test_optional_sections_have_every_key_of_the_schema():
    assert [f.name for f in dataclasses.fields(S.Foundation)] == list(FOUNDATION)
    assert [f.name for f in dataclasses.fields(S.Obstacle)] == list(OBSTACLE)
    assert set(TOP_LEVEL) <= {f.name for f in dataclasses.fields(Config)}


@pytest.mark.parametrize("name", EXAMPLES)
def test_typed_sections_hold_the_resolved_values(name):
    cfg = load_config(name)
    for sec in ("body", "geometry", "mesh", "friction", "state", "linear_solver", "optimizer"):
        typed = dataclasses.asdict(getattr(cfg, sec))
        assert typed == {k: cfg[sec].get(k) for k in SCHEMA[sec]} | ({"clamped": typed["clamped"]} if sec == "body"
                                                                     else {})
    assert cfg.body.clamped == (S.Clamp(cfg["body"]["clamped"], [1, 2, 3]),)
    assert cfg.design.degree == cfg["design"]["degree"] and cfg.state.tol == cfg["state"]["tol"]
    assert cfg.loads.top_traction == cfg["loads"]["top_traction"]
    assert cfg.objective.target.kind == cfg["objective"]["target"]["kind"]
    assert cfg.foundation is None and cfg.obstacle is None and cfg.load_cases == () and cfg.load_steps == ()
    assert cfg.material.formulation == "auto" and "formulation" not in cfg["material"]


def test_a_config_is_frozen_and_writes_back_what_it_read(tmp_path):
    cfg = load_config("example1")
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.state = None
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.state.tol = 1.0
    again = validate(tomllib.loads(cfg.to_toml()), cfg.source)
    assert again == cfg and again.state == cfg.state
    copy = cfg.to_dict()
    copy["state"]["tol"] = 0.5
    assert cfg.state.tol == 1e-12 and cfg["state"]["tol"] == 1e-12


def test_clamps_read_as_records():
    assert S.Clamp.all_of([{"on": {"x1": 0.0}, "components": [1]}, "bottom"]) == (
        S.Clamp({"x1": 0.0}, [1]), S.Clamp("bottom", [1, 2, 3]))


def test_records_of_arrays_of_tables(tmp_path):
    """Load cases, steps, objective terms and linear design rows read as typed records."""
    cfg = load_config(ROOT / "examples" / "example1_two_cases.toml")
    assert [c.name for c in cfg.load_cases] == [c["name"] for c in cfg["load_cases"]]
    assert all(isinstance(c.loads, S.Loads) for c in cfg.load_cases)
    raw = {"design": {"linear": [{"coefficients": 1.0, "upper": 1.0}]},
           "objective": {"terms": [{"type": "compliance", "weight": 2}, {"type": "target_normal_force"}]},
           "load_steps": [{"name": "a", "top_traction": [0.0, 0.0, -0.01]}, {"name": "b", "substeps": 3}]}
    with pytest.raises(ConfigError, match="coefficients"):       # a number is no coefficient net
        validate(raw)
    raw["design"]["linear"][0]["coefficients"] = [[1.0] * 4 for _ in range(8)]
    cfg = validate(raw)
    row = cfg.design.linear[0]
    assert (row.upper, row.equal, row.bound) == (1.0, None, 1.0)
    assert [(t.type, t.weight) for t in cfg.objective.terms] == [("compliance", 2.0), ("target_normal_force", 1.0)]
    assert cfg.objective.terms[1].target == S.Target("constant", 0.0)
    assert cfg.objective.types == {"compliance", "target_normal_force"}
    assert [(s.name, s.substeps, s.loads.top_traction) for s in cfg.load_steps] == [
        ("a", 1, [0.0, 0.0, -0.01]), ("b", 3, None)]


@pytest.mark.parametrize("path", FILES + list(EXAMPLES), ids=lambda p: getattr(p, "name", p))
def test_json_schema_takes_every_example(path, validator):
    errors = [f"{'/'.join(map(str, e.path))}: {e.message}" for e in validator.iter_errors(_raw(str(path)))]
    assert not errors, errors


@pytest.mark.parametrize("raw, where", [
    ({"state": {"tool": 1e-8}}, "tool"),                                 # misspelt key
    ({"stat": {"tol": 1e-8}}, "stat"),                                   # misspelt section
    ({"state": {"tol": "small"}}, "small"),                              # wrong type
    ({"state": {"max_iter": 2.5}}, "2.5"),                               # float for an integer
    ({"state": {"method": "gauss"}}, "gauss"),                           # not one of the enum
    ({"linear_solver": {"memory_check": 1}}, "1"),                       # a number for a boolean
    ({"load_cases": [{"name": "a", "top_tracton": [0, 0, 1]}]}, "top_tracton"),
    ({"objective": {"terms": [{"type": "compliance", "wieght": 1}]}}, "wieght"),
])
def test_json_schema_refuses_misspelt_keys_and_wrong_types(raw, where, validator):
    errors = [e.message for e in validator.iter_errors(raw)]
    assert errors and any(where in m for m in errors), errors
    with pytest.raises(ConfigError):       # the validator of contactopt agrees
        validate(raw)


def test_json_schema_states_defaults_and_descriptions():
    props = json_schema()["properties"]
    assert props["state"]["properties"]["tol"]["default"] == SCHEMA["state"]["tol"][0]
    assert props["linear_solver"]["properties"]["path"]["enum"] == ["auto", "condensation", "delassus", "fullspace",
                                                                     "petsc"]
    assert all("description" in v for sec in SCHEMA for v in props[sec]["properties"].values())
    assert props["state"]["additionalProperties"] is False


def test_schema_command(tmp_path, capsys):
    assert main(["schema"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    out = tmp_path / "contactopt.schema.json"
    assert main(["schema", "-o", str(out)]) == 0
    assert json.loads(out.read_text()) == printed
