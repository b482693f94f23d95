"""Validation: defaults filled in and every key checked; every problem is collected and reported
at once in a :class:`~contactopt.errors.ConfigError`, each naming the key and the allowed values."""

from __future__ import annotations

import copy
import math
from pathlib import Path

from ..errors import ConfigError
from .assembly import NEW_KEYS, check_record, desugar, rename
from .checks import (
    _NUM,
    _axis,
    _block_spec,
    _check_step_list,
    _check_value,
    _finite,
    _material_spec,
    _natint,
    _nonneg,
    _part_spec,
    _pos,
    _posint,
    _vec3,
)
from .constraints import check_constraints
from .migration import _legacy_backend
from .schema import (
    BLOCK_LOADS,
    CASE_NAME,
    FOUNDATION,
    FOUNDATION_LOADS,
    OBJECTIVE_TYPES,
    OBSTACLE,
    SCHEMA,
    STEP_FORCE,
    SUBSTEPS,
    TERM_KEYS,
    TERM_WEIGHT,
    TOP_LEVEL,
)


def _check_target(target, d1d2, problems, key="objective.target"):
    n0 = len(problems)
    _check_target_at(target, d1d2, problems)
    if key != "objective.target":
        problems[n0:] = [p.replace("objective.target", key, 1) for p in problems[n0:]]


def _check_target_at(target, d1d2, problems):
    kind = target.get("kind")
    allowed = {"constant": {"kind", "value"},
               "step": {"kind", "default", "regions", "per_area"},
               "values": {"kind", "values"},
               "design": {"kind", "alpha"}}
    if kind not in allowed:
        problems.append(f"objective.target.kind = {kind!r}: must be one of {sorted(allowed)}")
        return
    for k in set(target) - allowed[kind]:
        problems.append(f"objective.target.{k}: unknown key for kind {kind!r} (allowed: {sorted(allowed[kind])})")
    # absent keys take the defaults of the Target and Region records (config/sections.py)
    if kind == "constant" and "value" in target and not _finite(target["value"]):
        problems.append("objective.target.value: must be a finite number")
    if kind == "step":
        if "default" in target and not _finite(target["default"]):
            problems.append("objective.target.default: must be a finite number")
        if "per_area" in target and not isinstance(target["per_area"], bool):
            problems.append("objective.target.per_area: must be true or false")
        regions = target.get("regions", [])
        if not isinstance(regions, list):
            problems.append("objective.target.regions: must be a list of tables {x1=[lo,hi], x2=[lo,hi], value}")
            regions = []
        for n, r in enumerate(regions):
            if not isinstance(r, dict) or set(r) - {"x1", "x2", "value"} or "value" not in r:
                problems.append(f"objective.target.regions[{n}]: must be a table with keys x1, x2 (optional) and value")
                continue
            for ax in (a for a in ("x1", "x2") if a in r):
                iv = r[ax]
                if not (isinstance(iv, list) and len(iv) == 2 and all(isinstance(v, _NUM) for v in iv) and iv[0] <= iv[1]):
                    problems.append(f"objective.target.regions[{n}].{ax}: must be [lo, hi] with lo ≤ hi")
            if not _finite(r["value"]):
                problems.append(f"objective.target.regions[{n}].value: must be a finite number")
    if kind == "values":
        vals = target.get("values")
        if not (isinstance(vals, list) and all(_finite(v) for v in vals)):
            problems.append("objective.target.values: must be a list of numbers, one per contact node")
    if kind == "design":
        _check_matrix(target.get("alpha"), d1d2, "objective.target.alpha", problems)


def _check_matrix(value, d1d2, key, problems):
    if d1d2 is None:
        return
    n1, n2 = d1d2[0] + 1, d1d2[1] + 1
    if _finite(value):
        return
    ok = (isinstance(value, list) and len(value) == n1
          and all(isinstance(r, list) and len(r) == n2 and all(_finite(v) for v in r) for r in value))
    if not ok:
        problems.append(f"{key}: must be a number or a {n1}×{n2} nested list of numbers")


def _check_design_constraints(dsg, d1d2, problems):
    """[design] fixed inside the control net, [[design.linear]] coefficients of its shape."""
    if d1d2 is None:
        return
    n1, n2 = d1d2[0] + 1, d1d2[1] + 1
    fixed = dsg.get("fixed")
    if isinstance(fixed, list):
        for p in fixed:
            if isinstance(p, list) and len(p) == 2 and not (0 <= p[0] < n1 and 0 <= p[1] < n2):
                problems.append(f"design.fixed: control point {p} is outside the {n1}×{n2} control net "
                                f"(i in 0..{n1 - 1}, j in 0..{n2 - 1})")
    rows = dsg.get("linear")
    if isinstance(rows, list):
        for k, r in enumerate(rows):
            if isinstance(r, dict) and "coefficients" in r:
                c = r["coefficients"]
                if _finite(c) or not (isinstance(c, list) and len(c) == n1 and all(
                        isinstance(v, list) and len(v) == n2 and all(_finite(t) for t in v) for v in c)):
                    problems.append(f"design.linear[{k}].coefficients: must be a {n1}×{n2} nested list of numbers "
                                    "(one per control point, like design.initial)")



def _check_load_cases(cases, d1d2, problems) -> list:
    """[[load_cases]]: each a name, loads in the form of [loads] (none required) and an optional
    target in the form of objective.target. Returns the cases as written (validated)."""
    if not (isinstance(cases, list) and cases and all(isinstance(c, dict) for c in cases)):
        problems.append("load_cases: must be a non-empty array of tables [[load_cases]] with a name, "
                        "loads as in [loads] and an optional target")
        return []
    allowed = ["name", *SCHEMA["loads"], "target", "steps"]
    _check_named_loads(cases, "load_cases", allowed, "case", "the case's history column and plots", problems)
    for n, case in enumerate(cases):
        if "steps" in case:
            case["steps"] = _check_load_steps(case["steps"], f"load_cases[{n}].steps", problems)
        if "target" in case:
            if isinstance(case["target"], dict):
                _check_target(case["target"], d1d2, problems, f"load_cases[{n}].target")
            else:
                problems.append(f"load_cases[{n}].target: must be a table like objective.target")
    return cases


def _check_named_loads(items, where, allowed, what, names_what, problems) -> None:
    """Load cases or load steps: each a unique name and loads in the form of [loads] (plus the
    keys ``allowed``); every problem appended to ``problems``."""
    seen = set()
    for n, item in enumerate(items):
        name = item.get("name")
        if not (isinstance(name, str) and CASE_NAME.fullmatch(name)):
            problems.append(f"{where}[{n}].name = {name!r}: must be a name of letters, digits and _ . + - "
                            f"(it names {names_what})")
        elif name in seen:
            problems.append(f"{where}[{n}].name = {name!r}: another {what} has this name")
        seen.add(name)
        for k, val in item.items():
            if k not in allowed:
                problems.append(f"{where}[{n}].{k}: unknown key (allowed: {', '.join(allowed)})")
            elif k in SCHEMA["loads"]:
                _, check, desc = SCHEMA["loads"][k]
                if not check(val):
                    problems.append(f"{where}[{n}].{k} = {val!r}: must be {desc}")


def _check_load_steps(steps, where, problems) -> list:
    """[[load_steps]] (or a case's [[load_cases.steps]]): in order, each a name, the TOTAL loads at
    its end in the form of [loads] and an optional ``substeps`` ≥ 1. Returns them with substeps."""
    if not (isinstance(steps, list) and steps and all(isinstance(c, dict) for c in steps)):
        problems.append(f"{where}: must be a non-empty array of tables with a name, loads as in [loads] "
                        "and an optional substeps")
        return []
    allowed = ["name", *SCHEMA["loads"], "substeps", "obstacle_force"]
    _check_named_loads(steps, where, allowed, "step", "the step's output directory", problems)
    for n, step in enumerate(steps):
        sub = step.setdefault("substeps", SUBSTEPS[0])
        if not _posint(sub):
            problems.append(f"{where}[{n}].substeps = {sub!r}: must be an integer ≥ 1 (equal increments of "
                            "the loads from the previous step's)")
        if "obstacle_force" in step and not STEP_FORCE[1](step["obstacle_force"]):
            problems.append(f"{where}[{n}].obstacle_force = {step['obstacle_force']!r}: must be {STEP_FORCE[2]}")
    return steps


def _check_step_forces(steps, where, obstacle, problems) -> None:
    """A step's ``obstacle_force`` needs a force-controlled ``obstacle`` (the raw [obstacle] table)
    and points along its force: the obstacle translates along one direction in every step."""
    force = obstacle.get("force") if isinstance(obstacle, dict) and obstacle.get("control") == "force" else None
    for n, step in enumerate(steps):
        f = step.get("obstacle_force") if isinstance(step, dict) else None
        if f is None or not _vec3(f):
            continue
        if force is None:
            problems.append(f"{where}[{n}].obstacle_force: needs [obstacle] control = 'force' (the force the "
                            "obstacle presses with in this step)")
        elif _vec3(force) and any(force):
            norm_f, norm_s = math.sqrt(sum(x * x for x in force)), math.sqrt(sum(x * x for x in f))
            cos = sum(a * b for a, b in zip(f, force)) / (norm_f * norm_s) if norm_s else 0.0
            if cos < 1 - 1e-12:
                problems.append(f"{where}[{n}].obstacle_force = {f!r}: must be a positive multiple of "
                                f"obstacle.force = {force!r} (the obstacle translates along its force in every step)")


def _check_step_names(data, problems, obstacle=None) -> None:
    """objective.steps names steps of every path; steps at the top level and in cases exclude each
    other; a step's ``obstacle_force`` is checked against ``obstacle`` (the raw [obstacle] table)."""
    cases = data.get("load_cases", [])
    if "load_steps" in data and any("steps" in c for c in cases):
        problems.append("load_steps: the configuration has [[load_steps]] and [[load_cases.steps]]; give each "
                        "load case its own steps, or the top-level steps without steps in the cases")
    paths = [("load_steps", data["load_steps"])] if "load_steps" in data else []
    paths += [(f"load_cases[{n}].steps", c["steps"]) for n, c in enumerate(cases) if "steps" in c]
    for where, steps in paths:
        _check_step_forces(steps or [], where, obstacle, problems)
    _check_step_list(data["objective"]["steps"], "objective.steps", data, problems)


def _check_combination(raw, data, problems):
    """objective.combine/weights name the load cases; without cases only the default max is allowed."""
    obj, cases = data["objective"], data.get("load_cases", [])
    names = [c.get("name") for c in cases]
    weights = obj["weights"]
    if not cases:
        if obj["combine"] != "max":
            problems.append(f"objective.combine = {obj['combine']!r}: combines load cases, but the "
                            "configuration has no [[load_cases]]")
        if weights:
            problems.append("objective.weights: weighs load cases, but the configuration has no [[load_cases]]")
    elif isinstance(weights, list) and weights and len(weights) != len(cases):
        problems.append(f"objective.weights: has {len(weights)} number(s) for {len(cases)} load cases "
                        f"({', '.join(map(str, names))})")
    elif isinstance(weights, dict):
        for k in weights:
            if k not in names:
                problems.append(f"objective.weights.{k}: no load case has this name "
                                f"(cases: {', '.join(map(str, names))})")
    w = list(weights.values()) if isinstance(weights, dict) else weights
    if cases and w and all(_nonneg(v) for v in w) and not any(v > 0 for v in w) and (
            isinstance(weights, list) or len(weights) == len(cases)):
        problems.append("objective.weights: at least one load case must weigh more than 0")
    has_target = obj["type"] == "target_normal_force" or any(
        isinstance(t, dict) and t.get("type") == "target_normal_force" for t in obj.get("terms") or [])
    if any("target" in c for c in cases) and not has_target:
        problems.append(f"load_cases: a case's target is the target of objective.type = "
                        f"'target_normal_force', not {obj['type']!r}")




def _check_objective(raw, data, d1d2, problems):
    """[[objective.terms]]: each a known type with its weight and keys (defaults filled in); with
    terms the type is 'sum' (implied), and 'sum' needs terms."""
    obj = data["objective"]
    given = raw.get("objective", {}) if isinstance(raw.get("objective"), dict) else {}
    terms = obj["terms"] if isinstance(obj["terms"], list) else []
    if terms and "type" not in given:
        obj["type"] = "sum"
    if terms and obj["type"] != "sum":
        problems.append(f"objective.type = {obj['type']!r}: with [[objective.terms]] the objective is their "
                        "weighted sum (write type = 'sum' or leave it out)")
    if obj["type"] == "sum" and not terms:
        problems.append("objective.type = 'sum': needs [[objective.terms]]")
    out = []
    for n, t in enumerate(terms):
        key = f"objective.terms[{n}]"
        for k in t:
            if k not in TERM_KEYS:
                problems.append(f"{key}.{k}: unknown key (allowed: {', '.join(sorted(TERM_KEYS))})")
        if t.get("type") not in OBJECTIVE_TYPES:
            problems.append(f"{key}.type = {t.get('type')!r}: must be one of "
                            f"{', '.join(repr(v) for v in OBJECTIVE_TYPES)}")
        term = {"type": t.get("type")}
        for k in ("weight", "region", "aggregate", "rho", "p", "contacts"):
            if k == "contacts" and k not in t:      # absent: every pair (resolved as before the key)
                continue
            default, check, desc = TERM_WEIGHT if k == "weight" else SCHEMA["objective"][k]
            val = t.get(k, default)
            _check_value(f"{key}.{k}", val, check, desc, problems)
            term[k] = float(val) if isinstance(val, int) and not isinstance(val, bool) and k != "region" else val
        if "target" in t:
            if t.get("type") != "target_normal_force":
                problems.append(f"{key}.target: only a target_normal_force term has a target")
            elif isinstance(t["target"], dict):
                _check_target(t["target"], d1d2, problems, key=f"{key}.target")
            else:
                problems.append(f"{key}.target: must be a table like objective.target")
            term["target"] = t["target"]
        elif t.get("type") == "target_normal_force":
            term["target"] = {"kind": "constant", "value": 0.0}
        out.append(term)
    if terms and not any(_nonneg(t["weight"]) and t["weight"] > 0 for t in out):
        problems.append("objective.terms: at least one term must weigh more than 0")
    obj["terms"] = out if terms else obj["terms"]


def _check_body(raw, data, problems):
    """A body from a file has no [geometry]/[mesh] and no block loads; on the block, a configuration
    that lists its own tractions or pressures gets no default block loads."""
    loads_raw = raw.get("loads", {}) if isinstance(raw.get("loads"), dict) else {}
    if data["body"]["mesh"]:
        path = Path(data["body"]["mesh"])
        if not path.is_file():
            problems.append(f"body.mesh = {data['body']['mesh']!r}: no such file")
        for sec in ("geometry", "mesh"):
            if sec in raw:
                problems.append(f"[{sec}]: describes the built-in block; with body.mesh the body comes from the "
                                f"mesh file (remove [{sec}])")
            data.pop(sec, None)
        for k in BLOCK_LOADS:
            if k in loads_raw:
                problems.append(f"loads.{k}: is a load on a part of the built-in block; on a body from a file "
                                "use [[loads.traction]] with on = \"<part>\"")
            data["loads"].pop(k, None)
            for n, case in enumerate(data.get("load_cases", [])):
                if k in case:
                    problems.append(f"load_cases[{n}].{k}: is a load on a part of the built-in block; on a "
                                    "body from a file use traction = [{ on = \"<part>\", value = [...] }]")
            for n, step in enumerate(data.get("load_steps", [])):
                if k in step:
                    problems.append(f"load_steps[{n}].{k}: is a load on a part of the built-in block; on a "
                                    "body from a file use traction = [{ on = \"<part>\", value = [...] }]")
    elif ("traction" in loads_raw or "pressure" in loads_raw or data.get("load_cases")
          or data.get("load_steps")):
        # with load cases a case's loads are exactly [loads] as written plus the case's own
        for k in BLOCK_LOADS:
            if k not in loads_raw:
                data["loads"][k] = [0.0, 0.0, 0.0]


def _check_graded_block(raw, data, problems) -> None:
    """[mesh] x1/x2/x3: node coordinates from 0 to a/b/c, strictly increasing, instead of nx/ny/nz.
    A coordinate list sets its side of the block when [geometry] does not (and must end on it when
    it does); the resolved configuration keeps either the list or the count of a direction."""
    m, g = data["mesh"], data["geometry"]
    raw_m = raw.get("mesh", {}) if isinstance(raw.get("mesh"), dict) else {}
    raw_g = raw.get("geometry", {}) if isinstance(raw.get("geometry"), dict) else {}
    for ax, n, side in (("x1", "nx", "a"), ("x2", "ny", "b"), ("x3", "nz", "c")):
        x = m[ax]
        if x == []:
            m.pop(ax)            # equal elements: the resolved configuration keeps the count alone
            continue
        if not _axis(x):
            continue
        if n in raw_m:
            problems.append(f"mesh.{ax} and mesh.{n}: give the node coordinates or the number of elements "
                            f"in {ax}, not both")
        m.pop(n, None)
        m[ax] = x = [float(v) for v in x]
        drops = [k for k in range(1, len(x)) if not x[k] > x[k - 1]]
        if drops:
            k = drops[0]
            problems.append(f"mesh.{ax} = {x}: must be strictly increasing ({ax}[{k}] = {x[k]:g} ≤ "
                            f"{ax}[{k - 1}] = {x[k - 1]:g}; {len(drops)} such step(s))")
            continue
        if x[0] != 0.0:
            problems.append(f"mesh.{ax} = {x}: must start at 0 (the block is [0, a]×[0, b]×[0, c], its contact "
                            "face on x3 = 0)")
            continue
        if side in raw_g:
            if _pos(g[side]) and not math.isclose(x[-1], g[side], rel_tol=1e-12):
                problems.append(f"mesh.{ax} ends at {x[-1]:g}, geometry.{side} = {g[side]:g}: the coordinates "
                                f"run from 0 to geometry.{side} (or leave geometry.{side} out: the last "
                                "coordinate sets it)")
        else:
            g[side] = x[-1]


def _check_foundation(given, data, problems) -> dict:
    """[foundation]: exactly one of `mesh` and `block`; the material's missing keys are the body's."""
    if not isinstance(given, dict):
        problems.append("[foundation]: must be a table")
        return {}
    out = _check_table(given, FOUNDATION, "foundation", problems)
    if isinstance(out["mesh"], str) and isinstance(out["block"], dict):
        if bool(out["mesh"]) == bool(out["block"]):
            problems.append("[foundation]: give exactly one of `mesh` (a mesh file) and `block` (a generated box)")
        elif out["mesh"] and not Path(out["mesh"]).is_file():
            problems.append(f"foundation.mesh = {out['mesh']!r}: no such file")
    if isinstance(out["block"], dict) and out["block"] and _block_spec(out["block"]):
        b = out["block"]
        out["block"] = {"size": [float(v) for v in b["size"]], "cells": list(b["cells"]),
                        "origin": [float(v) for v in b.get("origin", [0.0, 0.0])],
                        "element": b.get("element", "hexahedron")}
    if isinstance(out["loads"], dict):
        out["loads"] = {**{k: copy.deepcopy(v[0]) for k, v in FOUNDATION_LOADS.items()}, **out["loads"]}
    if isinstance(out["material"], dict) and _material_spec(out["material"]):
        out["material"] = {k: float(out["material"].get(k, data["material"][k])) for k in ("E", "nu")}
    _check_foundation_control(given, out, problems)
    return out


def _check_pairs(given, data, problems) -> list:
    """``pairs`` (the resolved spelling of several ``[[contacts]]``, config/assembly.py): per pair its
    face part, friction coefficient and counterpart body (as [foundation])."""
    if not (isinstance(given, list) and len(given) > 1 and all(isinstance(p, dict) for p in given)):
        problems.append("pairs: is the resolved spelling of several [[contacts]]; write them as [[contacts]]")
        return []
    out = []
    for n, pair in enumerate(given):
        if set(pair) not in ({"contact", "friction", "foundation"}, {"contact", "friction", "obstacle"}):
            problems.append(f"pairs[{n}]: must have the keys contact, friction and foundation (an elastic "
                            "counterpart) or obstacle (a rigid one)")
            continue
        mu = pair["friction"]
        if not (_finite(mu) and mu >= 0):
            problems.append(f"contacts[{n}].friction = {mu!r}: must be a number ≥ 0")
        if not _part_spec(pair["contact"]):
            problems.append(f"contacts[{n}].face: must name a part")
        sub = []
        if "obstacle" in pair:          # a rigid counterpart (config/assembly.py takes it fixed or displaced)
            obst = _check_obstacle(pair["obstacle"], {k: v for k, v in data.items() if k != "foundation"}, sub)
            problems += [p.replace("obstacle.", f"contacts[{n}].counterpart.", 1)
                         .replace("[obstacle]", f"contacts[{n}].counterpart", 1) for p in sub]
            out.append({"contact": copy.deepcopy(pair["contact"]), "friction": float(mu) if _finite(mu) else mu,
                        "obstacle": obst})
            continue
        fnd = _check_foundation(pair["foundation"], data, sub)
        problems += [p.replace("foundation.", f"pairs[{n}].foundation.", 1).replace("[foundation]", f"pairs[{n}].foundation", 1)
                     for p in sub]
        out.append({"contact": copy.deepcopy(pair["contact"]), "friction": float(mu) if _finite(mu) else mu,
                    "foundation": fnd})
    return out


def _check_more_designs(given, data, problems) -> list:
    """``more_designs`` (the resolved spelling of the second and further ``[[designs]]``,
    config/assembly.py): per design its face part and the keys of [design], checked as [design]'s
    and named ``designs[n]``."""
    if not (isinstance(given, list) and given and all(isinstance(d, dict) and "face" in d for d in given)):
        problems.append("more_designs: is the resolved spelling of several [[designs]]; write them as [[designs]]")
        return []
    out = []
    for n, d in enumerate(given, start=1):
        key = f"designs[{n}]"
        sub = []
        dsg = _check_table({k: v for k, v in d.items() if k not in ("face", "body")}, SCHEMA["design"], "design", sub)
        deg = dsg["degree"]
        d1d2 = deg if isinstance(deg, list) and len(deg) == 2 and all(_natint(v) for v in deg) else None
        _check_matrix(dsg["initial"], d1d2, "design.initial", sub)
        _check_design_constraints(dsg, d1d2, sub)
        if _finite(dsg["lower"]) and _pos(dsg["C0"]) and dsg["lower"] > dsg["C0"]:
            sub.append(f"design.lower = {dsg['lower']}: must be ≤ design.C0 = {dsg['C0']}")
        g = data.get("geometry")
        if "body" not in d and g is not None and _pos(g["c"]) and _pos(dsg["C0"]) and dsg["C0"] >= g["c"]:
            sub.append(f"design.C0 = {dsg['C0']}: must be < geometry.c = {g['c']} (a surface reaching the top "
                       "face inverts the mesh)")
        if not _part_spec(d["face"]):
            sub.append("design.face: must name a part")
        if "body" in d and not isinstance(d["body"], str):
            sub.append("design.body: must name a counterpart body")
        problems += [p.replace("design.", f"{key}.", 1) for p in sub]
        out.append({"face": copy.deepcopy(d["face"]), **dsg, **({"body": d["body"]} if "body" in d else {})})
    return out


def _check_foundation_control(given, out, problems) -> None:
    """[foundation] control: a `force` other than zero only with 'force' (and there not zero), a
    `displacement` other than zero only with 'displacement', a `loaded` part other than the default
    only with either (a resolved configuration, written back, holds every key at its default)."""
    control = out["control"]
    for key, needs in (("force", "force"), ("displacement", "displacement")):
        if key in given and control != needs and given[key] != FOUNDATION[key][0]:
            problems.append(f"foundation.{key} = {given[key]!r}: given with foundation.control = {control!r}; it is "
                            f"read only with control = {needs!r}")
    if "loaded" in given and control == "fixed" and given["loaded"] != FOUNDATION["loaded"][0]:
        problems.append("foundation.loaded: given with foundation.control = 'fixed'; it names the part moved or "
                        "loaded with control = 'displacement' or 'force'")
    if control == "force" and "force" not in given:
        problems.append("foundation.force: required with foundation.control = 'force'")
    elif control == "force" and _vec3(out["force"]) and not any(v != 0 for v in out["force"]):
        problems.append("foundation.force = [0, 0, 0]: with control = 'force' the foundation translates along the "
                        "force, which has no direction")
    if control == "displacement" and "displacement" not in given:
        problems.append("foundation.displacement: required with foundation.control = 'displacement'")
    for k in ("displacement", "force"):
        if _vec3(out[k]):
            out[k] = [float(v) for v in out[k]]


def _check_obstacle(given, data, problems) -> dict:
    """[obstacle]: the keys its shape needs; excludes [foundation]."""
    if not isinstance(given, dict):
        problems.append("[obstacle]: must be a table")
        return {}
    out = _check_table(given, OBSTACLE, "obstacle", problems)
    shape = out["shape"]
    need = {"sphere": ("center", "radius"), "cylinder": ("point", "axis", "radius"), "surface": ("mesh",)}
    for k in need.get(shape, ()):
        if k not in given:
            problems.append(f"obstacle.{k}: required with shape = {shape!r}")
    if shape in ("sphere", "cylinder") and "radius" in given and _nonneg(out["radius"]) and not out["radius"] > 0:
        problems.append(f"obstacle.radius = {out['radius']!r}: must be > 0")
    if shape == "surface" and out["mesh"] and isinstance(out["mesh"], str) and not Path(out["mesh"]).is_file():
        problems.append(f"obstacle.mesh = {out['mesh']!r}: no such file")
    if out["control"] == "force" and _vec3(out["force"]) and not any(v != 0 for v in out["force"]):
        problems.append("obstacle.force = [0, 0, 0]: with control = 'force' the obstacle translates along the "
                        "force, which has no direction (a force with no component along any free direction)")
    obj = data.get("objective", {})
    types = [obj.get("type")] + [t.get("type") for t in obj.get("terms") or [] if isinstance(t, dict)]
    moves = out["control"] == "force" or (out["control"] == "displacement" and _vec3(out["displacement"])
                                          and any(out["displacement"][:2]))
    if "frictional_dissipation" in types and (shape != "plane" or moves):
        problems.append(f"objective 'frictional_dissipation' with obstacle.shape = {shape!r}, control = "
                        f"{out['control']!r}: the objective takes the slip as the body's own (x1, x2) "
                        "displacement, which holds on the fixed plane only")
    if "foundation" in data:
        problems.append("[obstacle] and [foundation] exclude each other: the body touches either a rigid "
                        "obstacle or an elastic foundation")
    for k in ("center", "point", "axis", "displacement", "force"):
        if _vec3(out[k]):
            out[k] = [float(v) for v in out[k]]
    return out



def check_interactions(config, *, pinned: int = 0, rigid: str | None = None, pinned_held: bool = False) -> None:
    """Rules between features of a configuration that hold whatever solver path runs it: raise
    ConfigError naming each pair that excludes the other.

    ``pinned``: the number of clamped tangential components of contact nodes (a symmetry plane through
    the contact face); ``rigid``: the names of the rigid motions the clamps leave free (a body held
    only by contact), or None; ``pinned_held``: the pinned components are clamped at their partners
    on an elastic foundation too (symmetry planes through both bodies). These are properties of the
    bodies built from ``config``. An elastic ``[foundation]`` does not take pinned components its
    partners do not hold (the foundation's compliance would add to a clamped direction). No rule
    reads ``rigid`` today: a body held only by contact rests on an elastic foundation as on a rigid
    support (the anchor acts on the coupled stiffness, ``contactopt.paths.rigid``)."""
    problems = []
    if config.foundation is not None and pinned and not pinned_held:
        problems.append(f"body.clamped: {pinned} tangential component(s) of contact nodes are clamped (a symmetry "
                        "plane through the contact face), which an elastic [foundation] does not take (its "
                        "compliance would add to the clamped direction); the rigid foundation does")
    if config.foundation is not None and config.foundation.control == "force":
        if config.load_steps or any(case.steps for case in config.load_cases):
            problems.append("[[load_steps]] with foundation.control = 'force': the force search runs on single "
                            "load steps only; press the foundation by a force without load steps, or prescribe "
                            "its displacement (control = 'displacement')")
        types = config.objective.types | {t.type for t in config.constraints}
        if "frictional_dissipation" in types:
            problems.append("objective 'frictional_dissipation' with foundation.control = 'force': the objective "
                            "takes the slip relative to the foundation without its translation; prescribe the "
                            "foundation's displacement (control = 'displacement') instead")
    if config.off_faces:             # faces on several bodies (fem.faces): ∂J/∂u on every DOF is not taken
        types = config.objective.types | {t.type for t in config.constraints}
        full = sorted(types & {"peak_stress", "frictional_dissipation"})
        if full:
            pairs = ", ".join(f"contacts[{k}]" for k in config.off_faces)
            problems.append(f"objective {', '.join(map(repr, full))}: an objective of the whole displacement in a "
                            f"model whose faces lie on several bodies ({pairs}) is not taken so far")
    if problems:
        raise ConfigError(problems)


def _check_table(given: dict, keys: dict, sec: str, problems: list) -> dict:
    """The keys of table ``sec`` with their defaults filled in; unknown keys and values that fail
    their check are appended to ``problems`` (an integer where a float is expected becomes one)."""
    for k in given:
        if k not in keys:
            problems.append(f"{sec}.{k}: unknown key (allowed: {', '.join(keys)})")
    out = {}
    for k, (default, check, desc) in keys.items():
        val = given.get(k, copy.deepcopy(default))
        _check_value(f"{sec}.{k}", val, check, desc, problems)
        out[k] = float(val) if isinstance(val, int) and isinstance(default, float) and not isinstance(val, bool) else val
    return out


def resolve(raw: dict, source: str = "<dict>") -> dict:
    """The resolved nested dict of ``raw``: defaults filled in and every key checked; raise
    ConfigError listing all problems at once."""
    if not isinstance(raw, dict):
        raise ConfigError([f"{source}: the configuration must be a table"])
    problems = []
    data = {}
    raw, renames = desugar(raw, problems)       # [bodies], [[contacts]], [[designs]] (config/assembly.py)
    n_assembly = len(problems)
    optional = ["foundation", "obstacle", "load_cases", "load_steps", "constraints", "pairs", "more_designs"]
    for key in raw:
        if key not in SCHEMA and key not in TOP_LEVEL and key not in optional and key != "assembly":
            problems.append(f"{key}: unknown section (allowed: "
                            f"{', '.join(list(TOP_LEVEL) + list(SCHEMA) + optional + list(NEW_KEYS))})")
    for key, (default, check, desc) in TOP_LEVEL.items():
        val = raw.get(key, default)
        if not check(val):
            problems.append(f"{key} = {val!r}: must be {desc}")
        data[key] = val
    if not raw.get("length_unit"):
        # absent: no unit named, and a configuration that does not name one resolves as before the key
        data.pop("length_unit", None)
    raw = _legacy_backend(raw, source, problems)
    for sec, keys in SCHEMA.items():
        given = raw.get(sec, {})
        if not isinstance(given, dict):
            problems.append(f"[{sec}]: must be a table")
            given = {}
        data[sec] = _check_table(given, keys, sec, problems)
    if not (isinstance(raw.get("objective"), dict) and "contacts" in raw["objective"]):
        data["objective"].pop("contacts", None)      # absent: every pair (resolved as before the key)
    if not (isinstance(raw.get("material"), dict) and "formulation" in raw["material"]):
        # absent means 'auto': a configuration that does not name it resolves as it did before the key
        data["material"].pop("formulation", None)
    deg = data["design"]["degree"]
    d1d2 = deg if isinstance(deg, list) and len(deg) == 2 and all(_natint(v) for v in deg) else None
    _check_matrix(data["design"]["initial"], d1d2, "design.initial", problems)
    _check_design_constraints(data["design"], d1d2, problems)
    if isinstance(data["objective"]["target"], dict):
        _check_target(data["objective"]["target"], d1d2, problems)
    if "load_cases" in raw:
        data["load_cases"] = _check_load_cases(raw["load_cases"], d1d2, problems)
    _check_objective(raw, data, d1d2, problems)
    if "load_steps" in raw:
        data["load_steps"] = _check_load_steps(raw["load_steps"], "load_steps", problems)
    _check_step_names(data, problems, obstacle=raw.get("obstacle"))
    if "constraints" in raw:                      # [[constraints]]: config/constraints.py
        data["constraints"] = check_constraints(raw["constraints"], data, problems)
    _check_combination(raw, data, problems)
    _check_body(raw, data, problems)
    if "foundation" in raw:
        data["foundation"] = _check_foundation(raw["foundation"], data, problems)
    if "obstacle" in raw:
        data["obstacle"] = _check_obstacle(raw["obstacle"], data, problems)
    if "pairs" in raw:
        data["pairs"] = _check_pairs(raw["pairs"], data, problems)
    if "more_designs" in raw:
        data["more_designs"] = _check_more_designs(raw["more_designs"], data, problems)
    if "mesh" in data:
        _check_graded_block(raw, data, problems)
    dsg = data["design"]
    if _finite(dsg["lower"]) and _pos(dsg["C0"]) and dsg["lower"] > dsg["C0"]:
        problems.append(f"design.lower = {dsg['lower']}: must be ≤ design.C0 = {dsg['C0']} (the control "
                        "points' lower bound above their upper bound leaves no admissible design)")
    designed = not (isinstance(raw.get("assembly"), dict) and raw["assembly"].get("designs") == [])
    if "geometry" in data and designed:          # (a model without designs moves no node)
        g = data["geometry"]
        if _pos(g["c"]) and _pos(data["design"]["C0"]) and data["design"]["C0"] >= g["c"]:
            problems.append(f"design.C0 = {data['design']['C0']}: must be < geometry.c = {g['c']} "
                            "(a surface reaching the top face inverts the mesh)")
    if "assembly" in raw:
        check_record(raw, problems)
        data["assembly"] = copy.deepcopy(raw["assembly"])
    problems[n_assembly:] = rename(problems[n_assembly:], renames)
    if problems:
        raise ConfigError([f"{source}: {p}" for p in problems])
    return data

