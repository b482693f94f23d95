"""``[[constraints]]``: limits on responses of the state. Each table is an objective of its type
(with that objective's keys) and a limit ``max``; :mod:`contactopt.sensitivity.objectives`
builds it with the objective's code and :mod:`contactopt.optimize.constrained` takes the limits."""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

from .checks import _check_step_list, _check_value, _finite, _pos
from .schema import SCHEMA

CONSTRAINT_TYPES = ("peak_stress", "max_pressure", "compliance", "frictional_dissipation")
# the keys of the objective of each type that a constraint of that type takes
CONSTRAINT_KEYS = {"peak_stress": ("region", "aggregate", "rho", "p"),
                   "max_pressure": ("aggregate", "rho", "p", "contacts"),
                   "compliance": (), "frictional_dissipation": ()}
CONSTRAINT_TOL = (1e-4, lambda x: _pos(x) and x < 1,
                  "a number in (0, 1): the largest violation (value − max)/max a result may keep")
# on a load path a limit holds at the end of every step (as in every load case) unless `steps` names
# others; the objective's default, the last step, would let a peak on the way there pass unseen
CONSTRAINT_STEPS = ("max", SCHEMA["objective"]["steps"][1],
                    "'max' (the limit holds at the end of every step of a load path), 'last', 'sum' or a "
                    "list of step names (it holds at the end of each of them), as objective.steps")


@dataclass(frozen=True)
class ResponseConstraint:
    """One ``[[constraints]]`` table: the response ``type`` must stay ≤ ``max`` (to ``tol``,
    relative); ``region``, ``aggregate``, ``rho``, ``p`` as in ``[objective]`` (its defaults
    where the type does not take the key); on a load path ``steps`` chooses the steps it holds at
    (the values of ``objective.steps``; default every step, "max")."""

    type: str
    max: float
    tol: float
    region: Any
    aggregate: str
    rho: float
    p: float
    steps: Any = CONSTRAINT_STEPS[0]
    contacts: tuple = ()          # max_pressure: the pairs whose nodes it reads (empty: every pair)

    @classmethod
    def from_dict(cls, d: dict) -> "ResponseConstraint":
        obj = SCHEMA["objective"]
        return cls(d["type"], d["max"], d["tol"],
                   *(copy.deepcopy(d.get(k, obj[k][0])) for k in ("region", "aggregate", "rho", "p")),
                   copy.deepcopy(d.get("steps", CONSTRAINT_STEPS[0])), tuple(d.get("contacts", ())))


def check_constraints(given, data, problems) -> list:
    """The resolved [[constraints]] tables: each {type, max, tol} and the keys of an objective of
    that type (defaults filled in). A limit max ≤ 0 on a quantity that is ≥ 0 and positive under
    load leaves no admissible design."""
    if not (isinstance(given, list) and all(isinstance(t, dict) for t in given)):
        problems.append("constraints: must be an array of tables [[constraints]] with `type` and `max`")
        return []
    out = []
    for n, t in enumerate(given):
        key = f"constraints[{n}]"
        kind = t.get("type")
        if kind not in CONSTRAINT_TYPES:
            problems.append(f"{key}.type = {kind!r}: must be one of {', '.join(map(repr, CONSTRAINT_TYPES))}")
        allowed = {"type", "max", "tol", "steps", *CONSTRAINT_KEYS.get(kind, ("region", "aggregate", "rho", "p"))}
        for k in t:
            if k not in allowed:
                problems.append(f"{key}.{k}: unknown key for type {kind!r} (allowed: {', '.join(sorted(allowed))})")
        row = {"type": kind}
        if "max" not in t:
            problems.append(f"{key}.max: missing (the limit of the {kind} of the design)")
        elif not (_finite(t["max"]) and t["max"] > 0):
            problems.append(f"{key}.max = {t['max']!r}: must be a number > 0 (the {kind} is ≥ 0 and positive under "
                            "load: a limit ≤ 0 leaves no admissible design)")
        else:
            row["max"] = float(t["max"])
        tol = t.get("tol", CONSTRAINT_TOL[0])
        _check_value(f"{key}.tol", tol, *CONSTRAINT_TOL[1:], problems)
        row["tol"] = float(tol) if _finite(tol) else tol
        steps = t.get("steps", CONSTRAINT_STEPS[0])
        _check_value(f"{key}.steps", steps, *CONSTRAINT_STEPS[1:], problems)
        _check_step_list(steps, f"{key}.steps", data, problems)
        row["steps"] = copy.deepcopy(steps)
        for k in CONSTRAINT_KEYS.get(kind, ()):
            if k == "contacts" and k not in t:       # absent: every pair (resolved as before the key)
                continue
            default, check, desc = SCHEMA["objective"][k]
            val = t.get(k, default)
            _check_value(f"{key}.{k}", val, check, desc, problems)
            row[k] = float(val) if k in ("rho", "p") and _finite(val) else val
        out.append(row)
    return out


def json_schema(objective_properties: dict) -> dict:
    """The JSON Schema of [[constraints]] (``objective_properties``: those of [objective])."""
    props = {"type": {"enum": list(CONSTRAINT_TYPES)},
             "max": {"type": "number", "exclusiveMinimum": 0, "description": "the limit (the response ≤ max)"},
             "tol": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1, "default": CONSTRAINT_TOL[0],
                     "description": CONSTRAINT_TOL[2]}}
    props.update({k: objective_properties[k] for k in ("region", "aggregate", "rho", "p", "contacts")})
    props["steps"] = {**objective_properties["steps"], "default": CONSTRAINT_STEPS[0],
                      "description": CONSTRAINT_STEPS[2]}
    return {"type": "array", "description": "limits on responses of the state (docs/objectives.md)",
            "items": {"type": "object", "required": ["type", "max"], "additionalProperties": False,
                      "properties": props}}


REFERENCE = ["", "## [[constraints]]", "",
             "Optional limits on responses of the state (an array of tables; docs/objectives.md): each has a "
             f"`type` ({', '.join(f'`{t}`' for t in CONSTRAINT_TYPES)}), the limit `max` (> 0; the response must "
             "stay ≤ max), `tol` (default 1e-4: the relative violation (value − max)/max a result may keep) and "
             "the keys of an objective of that type (`region`, `aggregate`, `rho`, `p`, with the defaults of "
             "[objective]). The bundle method takes them by an exact penalty whose weight it adapts; an "
             "infeasible initial design is allowed. With load cases a constraint holds in every case; on a "
             "load path at the end of every step, or of the steps its `steps` names (the values of "
             "`objective.steps`; default \"max\": every step)."]
