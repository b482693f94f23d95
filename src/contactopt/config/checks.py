"""Checks of single values of a configuration: each returns whether a value is allowed."""

from __future__ import annotations

import math

_NUM = (int, float)


def _pos(x):
    return isinstance(x, _NUM) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def _nonneg(x):
    return isinstance(x, _NUM) and not isinstance(x, bool) and math.isfinite(x) and x >= 0


def _finite(x):
    return isinstance(x, _NUM) and not isinstance(x, bool) and math.isfinite(x)


def _posint(x):
    return isinstance(x, int) and not isinstance(x, bool) and x >= 1


def _natint(x):
    return isinstance(x, int) and not isinstance(x, bool) and x >= 0


def _unit3(x):
    return _vec3(x) and abs(math.sqrt(sum(float(v) ** 2 for v in x)) - 1.0) <= 1e-9


def _vec3(x):
    return isinstance(x, (list, tuple)) and len(x) == 3 and all(_finite(v) for v in x)


def _axis(x):
    return x == [] or (isinstance(x, list) and len(x) >= 2 and all(_finite(v) for v in x))


def _oneof(*options):
    def check(x):
        return x in options
    check.__doc__ = "one of " + ", ".join(repr(o) for o in options)
    check.options = options         # the JSON Schema's enum
    return check


def _part_specs(x):
    """A part, or (the faces of several contact pairs on one body) a list of two or more parts."""
    return _part_spec(x) or (isinstance(x, list) and len(x) > 1 and all(_part_spec(p) for p in x))


def _part_spec(x):
    """A part: a group name, or a predicate table {x1|x2|x3 = v, box = [[lo, hi]] × 3}."""
    if isinstance(x, str):
        return x != ""
    if not isinstance(x, dict) or not x or set(x) - {"x1", "x2", "x3", "box"}:
        return False
    for k, v in x.items():
        if k == "box":
            if not (isinstance(v, list) and len(v) == 3 and all(
                    isinstance(iv, list) and len(iv) == 2 and all(_finite(t) for t in iv) and iv[0] <= iv[1]
                    for iv in v)):
                return False
        elif not _finite(v):
            return False
    return True



ALL_COMPONENTS = [1, 2, 3]      # a clamp that names no components fixes every one


def _clamp_spec(x):
    items = x if isinstance(x, list) else [x]
    if not items:
        return isinstance(x, list)      # [] : no clamp (a body held only by contact)
    for it in items:
        if isinstance(it, dict) and "on" in it:
            comps = it.get("components", ALL_COMPONENTS)
            if set(it) - {"on", "components"} or not _part_spec(it["on"]):
                return False
            if not (isinstance(comps, list) and comps and all(c in (1, 2, 3, "x1", "x2", "x3") for c in comps)):
                return False
        elif not _part_spec(it):
            return False
    return True


def _load_list(value_check):
    def check(x):
        return isinstance(x, list) and all(
            isinstance(it, dict) and set(it) == {"on", "value"} and _part_spec(it["on"]) and value_check(it["value"])
            for it in x)
    return check



def _block_spec(x):
    """A foundation block: {size = [s1, s2, s3] > 0, cells = [n1, n2, n3] ≥ 1, origin = [o1, o2],
    element = 'hexahedron' | 'tetra'} (origin and element optional)."""
    if not isinstance(x, dict) or set(x) - {"size", "cells", "origin", "element"} or not {"size", "cells"} <= set(x):
        return False
    size, cells = x["size"], x["cells"]
    origin, element = x.get("origin", [0.0, 0.0]), x.get("element", "hexahedron")
    return (isinstance(size, list) and len(size) == 3 and all(_pos(v) for v in size)
            and isinstance(cells, list) and len(cells) == 3 and all(_posint(v) for v in cells)
            and isinstance(origin, list) and len(origin) == 2 and all(_finite(v) for v in origin)
            and element in ("hexahedron", "tetra"))


def _material_spec(x):
    if not isinstance(x, dict) or set(x) - {"E", "nu"}:
        return False
    return _pos(x.get("E", 1.0)) and _finite(x.get("nu", 0.0)) and -1.0 < x.get("nu", 0.0) < 0.5


def _check_value(key: str, val, check, desc: str, problems: list) -> None:
    """Append ``"key = val: must be desc"`` to ``problems`` when ``check(val)`` fails or raises."""
    try:
        ok = check(val)
    except Exception:
        ok = False
    if not ok:
        problems.append(f"{key} = {val!r}: must be {desc}")


def _check_step_list(chosen, key: str, data, problems: list) -> None:
    """A list of step names (``objective.steps`` or a constraint's ``steps``, under ``key``) names
    steps of every load path of ``data`` (the resolved [[load_steps]] or [[load_cases.steps]])."""
    if not isinstance(chosen, list):
        return
    cases = data.get("load_cases", [])
    paths = [("load_steps", data.get("load_steps"))] if "load_steps" in data else []
    paths += [(f"load_cases[{n}].steps", c.get("steps")) for n, c in enumerate(cases) if "steps" in c]
    if not paths:
        problems.append(f"{key} = {chosen!r}: names load steps, but the configuration has no [[load_steps]]")
    for where, steps in paths:
        names = [s.get("name") for s in steps or []]
        for v in chosen:
            if v not in names:
                problems.append(f"{key}: {v!r} is no step of {where} (steps: {', '.join(map(str, names))})")
