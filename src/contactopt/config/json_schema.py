"""The configuration as a JSON Schema (draft 2020-12), generated from :mod:`.schema`: every
section and key with its type, default, description and allowed values, and no other key
(``additionalProperties: false``), so a TOML editor completes keys and marks a misspelt one.

The JSON Schema checks the form of a file; the validator (:mod:`.validation`) remains the
authority on what depends on other keys (a control net's size, the names of load cases).
"""

from __future__ import annotations

from .assembly import ASSEMBLY_DOCS
from .checks import _nonneg, _pos, _posint
from .constraints import json_schema as constraints_schema
from .schema import (
    BODIES,
    CONTACTS,
    FOUNDATION,
    FOUNDATION_LOADS,
    OBSTACLE,
    SCHEMA,
    SECTION_DOCS,
    STEP_FORCE,
    SUBSTEPS,
    TERM_KEYS,
    TERM_WEIGHT,
    TOP_LEVEL,
)

DRAFT = "https://json-schema.org/draft/2020-12/schema"

_NUMBER = {"type": "number"}
_VEC3 = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
_NUMBERS = {"type": "array", "items": _NUMBER}
_MATRIX = {"type": "array", "items": _NUMBERS}
_INTERVAL = {"type": "array", "items": _NUMBER, "minItems": 2, "maxItems": 2}
_PART = {"anyOf": [
    {"type": "string", "minLength": 1},
    {"type": "object", "minProperties": 1, "additionalProperties": False,
     "properties": {"x1": _NUMBER, "x2": _NUMBER, "x3": _NUMBER,
                    "box": {"type": "array", "items": _INTERVAL, "minItems": 3, "maxItems": 3},
                    "body": {"type": "string", "description": "in an assembly: the body of a load's part"}}}]}
_CLAMP_TABLE = {"type": "object", "required": ["on"], "additionalProperties": False,
                "properties": {"on": _PART, "components": {"type": "array", "minItems": 1, "items": {
                    "enum": [1, 2, 3, "x1", "x2", "x3"]}}}}
# (an empty list: no clamp, a body held by its contacts alone)
_CLAMP = {"anyOf": [_PART, _CLAMP_TABLE, {"type": "array", "items": {"anyOf": [_PART, _CLAMP_TABLE]}}]}


def _part_loads(value):
    return {"type": "array", "items": {"type": "object", "required": ["on", "value"], "additionalProperties": False,
                                       "properties": {"on": _PART, "value": value}}}


def _target() -> dict:
    region = {"type": "object", "required": ["value"], "additionalProperties": False,
              "properties": {"x1": _INTERVAL, "x2": _INTERVAL, "value": _NUMBER}}
    return {"type": "object", "required": ["kind"], "additionalProperties": False,
            "description": "a table with 'kind' = 'constant' (value) | 'step' (default, regions, per_area) | "
                           "'values' (values) | 'design' (alpha)",
            "properties": {"kind": {"enum": ["constant", "step", "values", "design"]}, "value": _NUMBER,
                           "default": _NUMBER, "per_area": {"type": "boolean"},
                           "regions": {"type": "array", "items": region}, "values": _NUMBERS,
                           "alpha": {"anyOf": [_NUMBER, _MATRIX]}}}


# the form of keys whose value is not told by its default alone
_FORMS = {
    ("body", "clamped"): _CLAMP,
    ("body", "contact"): _PART,
    ("body", "fixed_shape"): {"anyOf": [{"const": "auto"}, {"type": "array", "items": _PART}]},
    ("loads", "traction"): _part_loads(_VEC3),
    ("loads", "pressure"): _part_loads(_NUMBER),
    ("design", "degree"): {"type": "array", "items": {"type": "integer", "minimum": 0}, "minItems": 2, "maxItems": 2},
    ("design", "initial"): {"anyOf": [_NUMBER, _MATRIX]},
    ("design", "domain"): {"type": "array", "items": _INTERVAL, "maxItems": 2},
    ("design", "symmetry"): {"type": "array", "items": {"enum": ["x1", "x2"]}, "uniqueItems": True},
    ("design", "fixed"): {"type": "array", "items": {"type": "array", "items": {"type": "integer"},
                                                     "minItems": 2, "maxItems": 2}},
    ("design", "linear"): {"type": "array", "items": {
        "type": "object", "required": ["coefficients"], "additionalProperties": False,
        "oneOf": [{"required": ["upper"]}, {"required": ["equal"]}],
        "properties": {"coefficients": _MATRIX, "upper": _NUMBER, "equal": _NUMBER}}},
    ("objective", "target"): _target(),
    ("objective", "region"): {"anyOf": [{"const": ""}, _PART]},
    ("objective", "contacts"): {"type": "array", "items": {"anyOf": [{"type": "string", "minLength": 1},
                                                                     {"type": "integer", "minimum": 0}]}},
    ("objective", "weights"): {"anyOf": [_NUMBERS, {"type": "object", "additionalProperties": _NUMBER}]},
    ("objective", "steps"): {"anyOf": [{"enum": ["last", "max", "sum"]},
                                       {"type": "array", "items": {"type": "string"}, "minItems": 1}]},
    ("foundation", "block"): {"type": "object", "additionalProperties": False, "properties": {
        "size": _VEC3, "cells": {"type": "array", "items": {"type": "integer", "minimum": 1}, "minItems": 3,
                                 "maxItems": 3},
        "origin": {"type": "array", "items": _NUMBER, "minItems": 2, "maxItems": 2},
        "element": {"enum": ["hexahedron", "tetra"]}}},
    ("foundation", "top"): _PART,
    ("foundation", "loaded"): _PART,
    ("foundation", "clamped"): _CLAMP,
    ("foundation", "material"): {"type": "object", "additionalProperties": False,
                                 "properties": {"E": _NUMBER, "nu": _NUMBER}},
}


def _by_default(default, check) -> dict:
    """The form of a key told by its default (and, for numbers, its check)."""
    if isinstance(default, bool):
        return {"type": "boolean"}
    if isinstance(default, int):
        return {"type": "integer", **({"minimum": 1} if check is _posint else {})}
    if isinstance(default, float):
        bound = {"exclusiveMinimum": 0} if check is _pos else {"minimum": 0} if check is _nonneg else {}
        return {"type": "number", **bound}
    if isinstance(default, str):
        return {"type": "string"}
    if isinstance(default, list):
        return _VEC3 if len(default) == 3 else _NUMBERS
    return {"type": "object"}


def _key(sec: str, k: str, default, check, desc: str) -> dict:
    out = dict(_FORMS.get((sec, k)) or _by_default(default, check))
    if getattr(check, "options", None):
        out = {"enum": list(check.options)}
    return {**out, "default": default, "description": desc}


def _table(sec: str, keys: dict, description: str = "") -> dict:
    out = {"type": "object", "additionalProperties": False,
           "properties": {k: _key(sec, k, *spec) for k, spec in keys.items()}}
    return {**out, "description": description} if description else out


def _loads_keys(extra: dict) -> dict:
    """The keys of [loads] plus ``extra`` (a load case's or step's table)."""
    return {**_table("loads", SCHEMA["loads"])["properties"], **extra}


def _assembly(props: dict) -> dict:
    """[bodies.<name>], [[contacts]], [[designs]] and the [assembly] record of a resolved file."""
    body = _table("bodies", BODIES, ASSEMBLY_DOCS["bodies"])
    body["properties"]["block"] = props["foundation"]["properties"]["block"]
    body["properties"]["material"] = {"type": "object", "additionalProperties": False, "description": BODIES["material"][2],
                                      "properties": {"E": _NUMBER, "nu": _NUMBER,
                                                     "formulation": {"enum": ["auto", "standard", "bbar"]}}}
    for k in ("clamped", "fixed_shape"):
        body["properties"][k] = {**_key("body", k, *BODIES[k])}
    body["properties"]["loaded"] = {**_PART, "description": BODIES["loaded"][2]}
    contact = _table("contacts", CONTACTS, ASSEMBLY_DOCS["contacts"])
    contact["required"] = ["face", "counterpart"]
    contact["properties"]["counterpart"] = {"anyOf": [{"type": "string", "pattern": "^[^.]+[.].+$"},
                                                      props["obstacle"]], "description": CONTACTS["counterpart"][2]}
    contact["properties"]["face"] = {"anyOf": [{"type": "string", "pattern": "^[^.]+[.].+$"},
                                               {**_PART["anyOf"][1], "required": ["body"]}],
                                     "description": CONTACTS["face"][2]}
    design = {**props["design"], "description": ASSEMBLY_DOCS["designs"], "required": ["face"],
              "properties": {**props["design"]["properties"], "face": contact["properties"]["face"]}}
    record = {"type": "object", "description": "the names of a resolved assembly's bodies, pairs and designed "
                                               "faces (written by contactopt in a run's configuration)"}
    return {"bodies": {"type": "object", "description": ASSEMBLY_DOCS["bodies"], "additionalProperties": body},
            "contacts": {"type": "array", "minItems": 1, "items": contact, "description": ASSEMBLY_DOCS["contacts"]},
            "designs": {"type": "array", "items": design, "description": ASSEMBLY_DOCS["designs"]},
            "assembly": record}


def json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a configuration file."""
    props = {k: _key("", k, *spec) for k, spec in TOP_LEVEL.items()}
    for sec, keys in SCHEMA.items():
        props[sec] = _table(sec, keys, SECTION_DOCS.get(sec, ""))
    term = {k: v for k, v in _table("objective", SCHEMA["objective"])["properties"].items()
            if k in TERM_KEYS}
    term["type"] = {"enum": list(SCHEMA["objective"]["type"][1].options[:-1])}
    term["weight"] = {"type": "number", "minimum": 0, "default": TERM_WEIGHT[0], "description": TERM_WEIGHT[2]}
    props["objective"]["properties"]["terms"] = {
        "type": "array", "description": SCHEMA["objective"]["terms"][2], "default": [],
        "items": {"type": "object", "required": ["type"], "additionalProperties": False, "properties": term}}
    name = {"type": "string", "pattern": "^[A-Za-z0-9_.+-]+$"}
    step = {"type": "object", "required": ["name"], "additionalProperties": False,
            "properties": _loads_keys({"name": name, "substeps": {"type": "integer", "minimum": 1, "default": SUBSTEPS[0],
                                                                "description": SUBSTEPS[2]},
                                       "obstacle_force": {"type": "array", "items": {"type": "number"}, "minItems": 3,
                                                          "maxItems": 3, "description": STEP_FORCE[2]}})}
    steps = {"type": "array", "minItems": 1, "items": step}
    props["load_steps"] = {**steps, "description": "the load path: steps in order, each the TOTAL loads at its end"}
    props["load_cases"] = {"type": "array", "minItems": 1, "description": "named load cases", "items": {
        "type": "object", "required": ["name"], "additionalProperties": False,
        "properties": _loads_keys({"name": name, "target": _target(), "steps": steps})}}
    found = _table("foundation", FOUNDATION, "an elastic foundation under the body (docs/foundation.md)")
    found["properties"]["loads"] = {**found["properties"]["loads"], "type": "object", "additionalProperties": False,
                                    "properties": {k: _key("loads", k, *FOUNDATION_LOADS[k]) for k in FOUNDATION_LOADS}}
    props["foundation"] = found
    props["obstacle"] = _table("obstacle", OBSTACLE, "a rigid obstacle of any shape (docs/obstacles.md)")
    props["constraints"] = constraints_schema(props["objective"]["properties"])
    props.update(_assembly(props))
    return {"$schema": DRAFT,
            "title": "contactopt configuration", "type": "object", "additionalProperties": False,
            "properties": props}
