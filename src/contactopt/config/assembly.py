"""Assemblies in the configuration: ``[bodies.<name>]``, ``[[contacts]]`` and ``[[designs]]``.

A model is a list of bodies, a list of contact pairs and a list of designed faces. ``[body]``,
``[foundation]``, ``[obstacle]`` and ``[design]`` are its one- and two-body spellings: ``[body]`` is
the body ``body``, ``[foundation]`` a second body ``foundation`` with its pair, ``[obstacle]`` a
rigid counterpart, ``[design]`` the one design on the body's contact face. :func:`desugar` reads the
assembly spelling as those sections, so both spellings resolve to one configuration and give the
same numbers; the resolved configuration keeps the assembly's names in ``[assembly]``
(:class:`Assembly`), from which :class:`~contactopt.config.Config` answers ``cfg.assembly`` for
either spelling.

Contact convention of a pair: the nodes of ``face`` carry the contact forces (λ ≥ 0 on the face's
body, per node (t1, t2, ν) with ν the normal from the counterpart to the face); ``counterpart`` is
a part of another body (an elastic counterpart, its partners below the face's nodes) or a rigid
counterpart, a table with the keys of ``[obstacle]``.

Several designs (``[[designs]]`` with more than one entry) are faces of the face body, each the
face of one of several pairs: the first is ``[design]`` on ``[body] contact``, the others are
``more_designs`` (each its face and the keys of ``[design]``), α the concatenation of their
control points in ``[[designs]]`` order. A design may also lie on a counterpart body, on the part
that is a pair's counterpart face (:mod:`contactopt.fem.cpdesigns`): it follows the face body's
designs, and its ``more_designs`` entry names its body (``body``). A configuration beyond what the
mechanics take is refused here, naming what it asks for.
"""

from __future__ import annotations

import contextlib
import copy
import re
from dataclasses import dataclass

from ..errors import ConfigError
from .schema import BODIES, CONTACTS, DESIGNS, FOUNDATION, OBSTACLE, SCHEMA

NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]*")
NEW_KEYS = ("bodies", "contacts", "designs")
OLD_KEYS = ("body", "foundation", "obstacle", "design")

# the keys of a body: [body]'s that describe a body, and [foundation]'s of a counterpart body
FACE_BODY_KEYS = ("mesh", "clamped", "fixed_shape", "tolerance", "min_jacobian_ratio", "graph_tolerance",
                  "penetration_tolerance")
COUNTERPART_BODY_KEYS = ("mesh", "block", "clamped", "tolerance", "control", "loaded", "displacement", "force")
BODY_KEYS = tuple(BODIES)
CONTACT_KEYS = tuple(CONTACTS)
DESIGN_KEYS = tuple(DESIGNS)

# descriptions of the keys (the configuration reference)
ASSEMBLY_DOCS = {
    "bodies": "A body of an assembly, `[bodies.<name>]`: a mesh file (`mesh`) or, without one, the built-in "
              "block of [geometry] and [mesh] (the body that carries the contact face) or a generated box "
              "(`block`, a counterpart body); its clamps, tolerances, `material` (else [material]) and "
              "`body_force`. A counterpart body may be moved by `control`, `loaded`, `displacement`, `force` "
              "as in [foundation].",
    "contacts": "A contact pair, `[[contacts]]`: `face = \"<body>.<part>\"` (its nodes carry the contact "
                "forces), `counterpart = \"<body>.<part>\"` (an elastic counterpart) or a table with the keys of "
                "[obstacle] (a rigid one), `friction` (else [friction] coefficient), `partner` (as "
                "foundation.partner), `interference`, `initial_gap` (as in [body]), an optional `name`. With several "
                "pairs every face lies on the face body (the body of the first pair's face), or on a counterpart "
                "body of another pair against a third, elastic body (a chain such as head, plate, plate, nut; no "
                "design moves that body; the condensation, full-space and PETSc paths, Delassus refuses it by name).",
    "designs": "A designed face, `[[designs]]`: `face = \"<body>.<part>\"` and the keys of [design]. Several "
               "entries design several faces of the face body in a model of several pairs, each a pair's face (α "
               "their control points one after the other); after them, a counterpart body's part that is a "
               "pair's counterpart face may be designed too (its mesh moves along +x3 with its design). A model "
               "without designs solves states only.",
}


@dataclass(frozen=True)
class Pair:
    """One contact pair by name: ``face`` and ``counterpart`` as ``"<body>.<part>"`` (a part given
    as a predicate table is written ``"<body>.<table>"``), ``counterpart`` ``"rigid <shape>"`` for a
    rigid counterpart."""

    name: str
    face: str
    counterpart: str


@dataclass(frozen=True)
class Assembly:
    """The names of a model's bodies (the first carries the contact face), pairs and designed faces."""

    bodies: tuple[str, ...]
    contacts: tuple[Pair, ...]
    designs: tuple[str, ...]
    spelled: bool = False        # written in the assembly spelling (else [body], [foundation], …)

    @classmethod
    def of(cls, data: dict) -> "Assembly":
        """The assembly of a resolved configuration: its ``[assembly]`` record, or the one- and
        two-body spelling's (the bodies ``body`` and ``foundation``, one pair, the design on the
        contact face)."""
        rec = data.get("assembly")
        if rec is not None:
            return cls(tuple(rec["bodies"]), tuple(Pair(**p) for p in rec["contacts"]), tuple(rec["designs"]), True)
        face = f"body.{_part_name(data['body']['contact'])}"
        if data.get("foundation") is not None:
            bodies, other = ("body", "foundation"), f"foundation.{_part_name(data['foundation']['top'])}"
        else:
            obst = data.get("obstacle")
            bodies, other = ("body",), f"rigid {obst['shape'] if obst else 'plane'}"
        return cls(bodies, (Pair("contact", face, other),), (face,))


    def renames(self) -> list[tuple[str, str]]:
        """(one-body key, the assembly's key) of every key a problem may name, most specific first;
        none for a model written in the one-body spelling."""
        if not self.spelled:
            return []
        face = self.bodies[0]
        out = [("body.contact", "contacts[0].face"), ("friction.coefficient", "contacts[0].friction")]
        out += [(f"body.{k}", f"contacts[0].{k}") for k in ("interference", "initial_gap")]
        out += [(f"body.{k}", f"bodies.{face}.{k}") for k in FACE_BODY_KEYS]
        if len(self.bodies) > 1:
            other = self.bodies[1]
            out += [("foundation.top", "contacts[0].counterpart"), ("foundation.partner", "contacts[0].partner"),
                    ("[foundation]", f"bodies.{other}")]
            out += [(f"foundation.{k}", f"bodies.{other}.{k}") for k in FOUNDATION if k not in ("top", "partner")]
        else:
            out += [("[obstacle]", "contacts[0].counterpart"), ("obstacle.", "contacts[0].counterpart.")]
        return out + [("design.", "designs[0].")]

    def rename_error(self, exc: ConfigError) -> ConfigError:
        """``exc`` with its problems in the keys the model was written in (a problem found while the
        meshes are read names the one-body sections the assembly is read as)."""
        return ConfigError(rename(exc.problems, self.renames())) if self.spelled else exc

    @contextlib.contextmanager
    def named_as_written(self):
        """A ConfigError raised inside, raised again in the keys the model was written in
        (:meth:`rename_error`)."""
        try:
            yield
        except ConfigError as exc:
            raise self.rename_error(exc) from None

    def require_design(self, source: str, what: str) -> None:
        """ConfigError when the model has no designed face: ``what`` (an optimization, a gradient
        check) needs design variables."""
        if not self.designs:
            raise ConfigError([f"{source}: {what} needs a designed face, and the model has no [[designs]]: it "
                               "solves states only (contactopt state); add [[designs]] with face = "
                               "\"<body>.<part>\" to optimize it"])


def _part_name(part) -> str:
    return part if isinstance(part, str) else repr(part)


def _split(ref, key: str, bodies: dict, problems: list):
    """(body, part) of ``"<body>.<part>"``; None with a problem appended."""
    if not (isinstance(ref, str) and "." in ref):
        problems.append(f"{key} = {ref!r}: must be \"<body>.<part>\", a body of [bodies] and one of its parts")
        return None
    name, part = ref.split(".", 1)
    if name not in bodies:
        problems.append(f"{key} = {ref!r}: no body is named {name!r} (bodies: {', '.join(bodies) or 'none'})")
        return None
    if not part:
        problems.append(f"{key} = {ref!r}: names no part of body {name!r}")
        return None
    return name, part


def _load_target(on, key: str, bodies: dict, problems: list):
    """(body, part) of a load's ``on``: ``"<body>.<part>"`` or a predicate table with ``body``."""
    if isinstance(on, dict):
        part = {k: v for k, v in on.items() if k != "body"}
        if on.get("body") not in bodies:
            problems.append(f"{key} = {on!r}: a predicate table needs body = \"<name>\", a body of [bodies] "
                            f"(bodies: {', '.join(bodies)})")
            return None
        return on["body"], part
    return _split(on, key, bodies, problems)


def desugar(raw: dict, problems: list) -> tuple[dict, list]:
    """``raw`` in the assembly spelling read as the one- and two-body sections, and the renames
    ``(old key, new key)`` that turn a problem found later in those sections into the key the user
    wrote (:func:`rename`); problems of the assembly itself are appended to ``problems``. A
    configuration without ``[bodies]`` is returned as it is."""
    if not any(k in raw for k in NEW_KEYS):
        return raw, []
    old = [k for k in OLD_KEYS if k in raw]
    for k in old:
        problems.append(f"[{k}]: is the one-body spelling of a model; with [bodies], [[contacts]] and [[designs]] "
                        f"write it there (docs/assemblies.md)")
    bodies, contacts, designs = raw.get("bodies"), raw.get("contacts"), raw.get("designs", [])
    if not (isinstance(bodies, dict) and bodies and all(isinstance(b, dict) for b in bodies.values())):
        problems.append("bodies: must be one or more tables [bodies.<name>]")
        return _rest(raw), []
    for name in bodies:
        if not NAME.fullmatch(name):
            problems.append(f"bodies.{name}: a body's name is a letter followed by letters, digits, _ and - "
                            "(it is written \"<body>.<part>\" in contacts, designs and loads)")
    if not (isinstance(contacts, list) and contacts and all(isinstance(c, dict) for c in contacts)):
        problems.append("contacts: must be one or more tables [[contacts]] with face and counterpart")
        return _rest(raw), []
    if not (isinstance(designs, list) and all(isinstance(d, dict) for d in designs)):
        problems.append("designs: must be tables [[designs]] with face and the keys of a design")
        return _rest(raw), []
    n0 = len(problems)
    pairs = [_pair(c, n, bodies, raw, problems) for n, c in enumerate(contacts)]
    faces = [_design_face(d, n, bodies, problems) for n, d in enumerate(designs)]
    if len(problems) > n0:
        return _rest(raw), []
    face_body, part, counter = pairs[0]
    if len(contacts) > 1:
        _check_star(pairs, problems, bodies)
    used = {face_body} | {c[0] for _, _, c in pairs if isinstance(c, tuple)}
    for name in bodies:
        if name not in used:
            problems.append(f"bodies.{name}: takes part in no contact pair (a body of an assembly is held by its "
                            "clamps and its contacts with the others)")
    counters = [c for _, _, c in pairs if isinstance(c, tuple)]
    carriers = {b for b, _, _ in pairs if b != face_body}      # bodies that carry a face off the face body
    for n, f in enumerate(faces):
        if f[0] in carriers:
            problems.append(f"designs[{n}].face = {'.'.join(map(_part_name, f))!r}: body {f[0]!r} carries the face "
                            "of a pair (off the face body); a design moves the face body or a counterpart body "
                            "that carries no face so far")
        elif carriers and f[0] != face_body:
            problems.append(f"designs[{n}].face = {'.'.join(map(_part_name, f))!r}: a design of a counterpart body "
                            f"in a model whose faces lie on several bodies ({', '.join(sorted(carriers))} carry "
                            "faces) is not taken so far; design the face body")
    own = [n for n, f in enumerate(faces) if f[0] == face_body]
    for n, f in enumerate(faces):
        if f[0] != face_body:
            _check_counterpart_design(n, f, (face_body, part) if len(contacts) == 1 else face_body, counters, own,
                                      problems)
        elif len(contacts) == 1 and f != (face_body, part):
            problems.append(f"designs[{n}].face = {'.'.join(f)!r}: contactopt designs the face of the contact pair "
                            f"({face_body}.{part}) so far, not another face")
    if len(own) > 1 and len(contacts) == 1:
        problems.append(f"designs: {len(own)} designed faces of {face_body!r} in a model of one pair; contactopt "
                        "designs several faces of the face body in a model of several pairs so far (each designed "
                        "face a pair's face)")
    if len(problems) > n0:
        return _rest(raw), []
    out, renames = _sections(raw, bodies, contacts[0], pairs[0], designs, faces, problems, several=len(contacts) > 1)
    if len(contacts) > 1:
        _more_pairs(out, raw, bodies, contacts, pairs, faces, problems)
    return out, renames


def _check_counterpart_design(n: int, face, owner, counters: list, own: list, problems: list) -> None:
    """A design on a counterpart body (fem.cpdesigns): its face is a pair's counterpart part, and it
    comes after every design of the face body (α: the face body's designs, then the counterparts').
    ``owner``: the face body's name, or (body, face) of a model of one pair."""
    name = '.'.join(map(_part_name, face))
    face_body = owner if isinstance(owner, str) else owner[0]
    first = (f"contactopt designs the face of the contact pair ({face_body}.{_part_name(owner[1])}) so far"
             if isinstance(owner, tuple) else
             f"contactopt designs a face of the body that carries the pairs' faces ({face_body!r}) so far")
    if face not in counters:
        others = ", ".join(f"{b}.{_part_name(p)}" for b, p in counters) or "none"
        problems.append(f"designs[{n}].face = {name!r}: {first}, or after it a counterpart body's part that is a "
                        f"pair's counterpart face (here: {others})")
    elif not own or n < max(own):
        problems.append(f"designs[{n}].face = {name!r}: {first}, first: a design of a counterpart body comes after "
                        f"the designs of the face body {face_body!r} in [[designs]]")


def _check_star(pairs: list, problems: list, bodies: dict | None = None) -> None:
    """Several pairs, as the mechanics take them so far: every face on one body (the face body),
    every counterpart a part of another body; a body may be the counterpart of several pairs
    (condensed once onto all their supports, fem.counterparts), each on a part of its own. One
    counterpart per model pressed by a force (a rigid one, or a counterpart body of ``bodies``
    with control = 'force', once however many pairs it holds): its translation is searched."""
    face_body = pairs[0][0]
    seen = {}
    held = {c[0] for _, _, c in pairs if isinstance(c, tuple)}      # the counterpart bodies
    off = []                                                        # the faces off the face body taken
    for n, (body, _, counter) in enumerate(pairs):
        key = f"contacts[{n}]"
        if body != face_body:
            before = len(problems)
            _check_off_face(n, pairs, held, bodies or {}, problems)
            if len(problems) == before:
                off.append(key)
        if not isinstance(counter, tuple):
            _check_rigid_pair(counter, key, problems)
        elif counter in seen.values():
            first = next(m for m, c in seen.items() if c == counter)
            problems.append(f"{key}.counterpart = '{counter[0]}.{_part_name(counter[1])}': is already the "
                            f"counterpart of contacts[{first}]; two pairs on one body meet it on two parts "
                            "(each pair's partners are searched on its own part)")
        else:
            seen[n] = counter
    pressed, elastic = [], {}
    for n, (_, _, c) in enumerate(pairs):
        if isinstance(c, dict) and c.get("control") == "force":
            pressed.append(f"contacts[{n}]")
        elif (isinstance(c, tuple) and isinstance((bodies or {}).get(c[0]), dict)
              and bodies[c[0]].get("control") == "force"):
            if c[0] not in elastic:
                elastic[c[0]] = len(pressed)
                pressed.append(None)
            pressed[elastic[c[0]]] = (pressed[elastic[c[0]]] or []) + [f"contacts[{n}]"]
    if off and pressed:
        names = {i: name for name, i in elastic.items()}
        words = [w if isinstance(w, str) else f"bodies.{names[i]} ({' and '.join(w)})" for i, w in enumerate(pressed)]
        problems.append(f"{' and '.join(words)}: a "
                        f"counterpart pressed by control = 'force' in a model whose faces lie on several bodies "
                        f"({', '.join(off)}) is not taken so far; press it by control = 'displacement'")
    if len(pressed) > 1:
        what = "rigid counterparts" if not elastic else "counterparts"
        names = {i: name for name, i in elastic.items()}
        words = [w if isinstance(w, str) else f"bodies.{names[i]} ({' and '.join(w)})" for i, w in enumerate(pressed)]
        problems.append(f"{' and '.join(words)}: {len(pressed)} {what} pressed by control = 'force'; "
                        "contactopt searches the translation of one counterpart per model so far (press the "
                        "others by control = 'displacement')")


def _check_off_face(n: int, pairs: list, held: set, bodies: dict, problems: list) -> None:
    """A pair whose face lies on a body other than the face body (fem.faces): that body is the
    counterpart of another pair (condensed once onto its supports, its face's nodes among them), no
    design moves it and no translation; the pair's counterpart is a part of a third body, elastic
    (neither the face body, whose contact DOFs are those of its own faces, nor a rigid one). The
    bodies that carry such faces must not form a cycle with their counterparts (each is condensed
    before the counterpart of its face)."""
    face_body = pairs[0][0]
    body, part, counter = pairs[n]
    key = f"contacts[{n}]"
    face = (f"{key}.face = '{body}.{_part_name(part)}': with several pairs contactopt takes the faces of every pair "
            f"on one body so far ({face_body!r}, the face of contacts[0]), or a face on a counterpart body of another "
            "pair against a third, elastic body (paths: condensation, fullspace, petsc)")
    swap = "write the pair the other way round (face and counterpart swapped) where it can be"
    if body not in held:
        problems.append(f"{face}; {body!r} is the counterpart of no pair: {swap}")
    elif not isinstance(counter, tuple):
        problems.append(f"{face}; this face meets a rigid counterpart: make {body!r} the face body or {swap}")
    elif counter[0] == face_body:
        problems.append(f"{face}; its counterpart lies on the face body {face_body!r}, whose contact DOFs are those "
                        f"of its own faces: {swap}")
    elif isinstance(bodies.get(body), dict) and bodies[body].get("control", "fixed") != "fixed":
        problems.append(f"{face}; body {body!r}, which carries it, is moved by control = "
                        f"{bodies[body]['control']!r}: a body that carries such a face is fixed or held by its "
                        "contacts so far")
    elif isinstance(bodies.get(counter[0]), dict) and bodies[counter[0]].get("control") == "force":
        problems.append(f"{face}; its counterpart body {counter[0]!r} is pressed by control = 'force': the "
                        "counterpart of such a face is fixed or moved by control = 'displacement' so far")
    elif _cycle(body, pairs):
        problems.append(f"{face}; the bodies {' → '.join(_cycle(body, pairs))} carry each other's faces in a "
                        "cycle; contactopt condenses a body that carries a face before the counterpart of that "
                        "face, so such faces form a chain or a tree so far")


def _cycle(start: str, pairs: list) -> list:
    """The bodies of a cycle through ``start`` of the pairs whose faces lie off the face body (face
    body → counterpart body), else []."""
    face_body = pairs[0][0]
    edges = {}
    for b, _, c in pairs:
        if b != face_body and isinstance(c, tuple):
            edges.setdefault(b, []).append(c[0])

    def walk(path):
        for nxt in edges.get(path[-1], []):
            if nxt == start:
                return path + [nxt]
            if nxt not in path:
                found = walk(path + [nxt])
                if found:
                    return found
        return []
    return walk([start])


def _check_rigid_pair(counter: dict, key: str, problems: list) -> None:
    """A rigid counterpart in a model of several pairs: fixed, moved by a prescribed translation
    (its motion enters as the counterparts' q, fem.counterparts) or pressed by a force (its
    translation an unknown of the state, paths/force.py; one per model, :func:`_check_star`); the
    mortar-weighted gap takes a model of one pair."""
    if counter.get("weighting", "node") != "node":
        problems.append(f"{key}.counterpart.weighting = {counter['weighting']!r}: the mortar-weighted gap of a rigid "
                        "counterpart takes a model of one pair so far; use weighting = 'node'")


def _more_pairs(out: dict, raw: dict, bodies: dict, contacts: list, pairs: list, faces: list,
                problems: list) -> None:
    """The sections of a model of several pairs on one face body: ``pairs`` lists every pair's face
    part, friction and counterpart body (as ``[foundation]``); ``[body] contact`` is the designed
    face, or without a design the list of the pairs' faces (the contact nodes are the pairs')."""
    base = (raw.get("friction") or {}).get("coefficient", SCHEMA["friction"]["coefficient"][0])
    counter_loads = {}
    for kind in ("traction", "pressure"):
        items = (raw.get("loads") or {}).get(kind) if isinstance(raw.get("loads"), dict) else None
        for n, item in enumerate(items if isinstance(items, list) else []):
            target = _load_target(item.get("on"), f"loads.{kind}[{n}].on", bodies, []) if isinstance(item, dict) else None
            if target is not None and target[0] != pairs[0][0]:
                counter_loads.setdefault(target[0], {}).setdefault(kind, []).append({**item, "on": target[1]})
    more = []
    for n, (contact, (_, part, counter)) in enumerate(zip(contacts, pairs)):
        if not isinstance(counter, tuple):       # a rigid counterpart: the table of [obstacle]
            if "partner" in contact:
                problems.append(f"contacts[{n}].partner: a rigid counterpart has no partners (each contact node's "
                                "gap is its distance to the obstacle along the obstacle's normal)")
            more.append({"contact": copy.deepcopy(part), "friction": contact.get("friction", base),
                         "obstacle": copy.deepcopy(counter)})
            continue
        holder = {}
        _counterpart_body(holder, bodies, counter, contact, raw, counter_loads.get(counter[0], {}), problems)
        more.append({"contact": copy.deepcopy(part), "friction": contact.get("friction", base),
                     "foundation": holder["foundation"]})
    out.pop("foundation", None)
    out.pop("obstacle", None)          # (the first pair's rigid counterpart is its own, not the model's)
    out["pairs"] = more
    out["friction"] = {**(raw.get("friction") or {}), "coefficient": base}
    own = [copy.deepcopy(p[1]) for p in pairs if p[0] == pairs[0][0]]     # (a face off it: fem.faces)
    out["body"]["contact"] = copy.deepcopy(faces[0][1]) if faces else own if len(own) > 1 else own[0]
    for k in ("interference", "initial_gap"):
        given = {c[k] for c in contacts if k in c}
        if len(given) > 1:
            problems.append(f"contacts: {k} differs between the pairs; contactopt takes one value for the pairs "
                            "of one face body so far")
    rec = out["assembly"]
    rec["bodies"] = [pairs[0][0]] + list(dict.fromkeys(c[0] for _, _, c in pairs if isinstance(c, tuple)))
    rec["contacts"] = [{"name": c.get("name", f"{b}-{o[0] if isinstance(o, tuple) else 'rigid'}"),
                        "face": f"{b}.{_part_name(p)}", "counterpart": _counterpart_name(o)}
                       for c, (b, p, o) in zip(contacts, pairs)]
    rec["designs"] = [f"{b}.{_part_name(p)}" for b, p in faces]


def _counterpart_name(counter) -> str:
    """``"<body>.<part>"`` of an elastic counterpart, ``"rigid <shape>"`` of a rigid one."""
    if isinstance(counter, tuple):
        return f"{counter[0]}.{_part_name(counter[1])}"
    return f"rigid {counter.get('shape', 'plane')}"


def _rest(raw: dict) -> dict:
    return {k: v for k, v in raw.items() if k not in NEW_KEYS}


def _pair(c: dict, n: int, bodies: dict, raw: dict, problems: list):
    """(face body, face part, counterpart) of ``[[contacts]]`` entry n; the counterpart (body, part)
    or the rigid table."""
    key = f"contacts[{n}]"
    for k in c:
        if k not in CONTACT_KEYS:
            problems.append(f"{key}.{k}: unknown key (allowed: {', '.join(CONTACT_KEYS)})")
    if "name" in c and not (isinstance(c["name"], str) and NAME.fullmatch(c["name"])):
        problems.append(f"{key}.name = {c['name']!r}: must be a letter followed by letters, digits, _ and -")
    for k in ("face", "counterpart"):
        if k not in c:
            problems.append(f"{key}.{k}: required (\"<body>.<part>\"{', or a rigid counterpart table' if k == 'counterpart' else ''})")
    face = _load_target(c["face"], f"{key}.face", bodies, problems) if "face" in c else None
    other = c.get("counterpart")
    if isinstance(other, dict):
        counter = other
    elif "counterpart" in c:
        counter = _split(other, f"{key}.counterpart", bodies, problems)
        if face is not None and counter is not None:
            if counter == face:
                problems.append(f"{key}: face and counterpart are the same part {c['face']!r}")
            elif counter[0] == face[0]:
                problems.append(f"{key}: face and counterpart are parts of one body {face[0]!r}; contactopt "
                                "takes contact between two bodies or with a rigid counterpart, not self-contact")
    else:
        counter = None
    return (*face, counter) if face is not None else (None, None, counter)


def _design_face(d: dict, n: int, bodies: dict, problems: list):
    for k in d:
        if k not in DESIGN_KEYS:
            problems.append(f"designs[{n}].{k}: unknown key (allowed: {', '.join(DESIGN_KEYS)})")
    if "face" not in d:
        problems.append(f"designs[{n}].face: required (\"<body>.<part>\", the designed face)")
        return None
    return _load_target(d["face"], f"designs[{n}].face", bodies, problems)


def _sections(raw: dict, bodies: dict, contact: dict, pair, designs: list, faces: list,
              problems: list, several: bool = False) -> tuple[dict, list]:
    """The one- and two-body sections of a checked assembly of one pair (module docstring);
    ``several``: the first of several pairs (the loads on counterpart bodies are read with them)."""
    face_body, part, counter = pair
    out = _rest(raw)
    b = bodies[face_body]
    out["body"] = _body_keys(face_body, b, FACE_BODY_KEYS, "a key of a counterpart body; body {name!r} carries "
                             "the contact face", problems)
    out["body"]["contact"] = part
    for k in ("interference", "initial_gap"):
        if k in contact:
            out["body"][k] = contact[k]
    given = raw.get("material", {})
    if isinstance(b.get("material"), dict) and isinstance(given, dict):
        out["material"] = {**given, **b["material"]}
    if "friction" in contact:
        out["friction"] = {**(raw.get("friction") or {}), "coefficient": contact["friction"]}
    loads = copy.deepcopy(raw.get("loads", {})) if isinstance(raw.get("loads"), dict) else raw.get("loads")
    if loads is None and "body_force" in b:          # the face body's own body force, without [loads]
        loads = {}
    counter_loads = {}
    if isinstance(loads, dict):
        if "body_force" in loads:
            problems.append("loads.body_force: in an assembly a body force is a body's own: "
                            "bodies.<name>.body_force")
        if "body_force" in b:
            loads["body_force"] = b["body_force"]
        for kind in ("traction", "pressure"):
            mine, theirs = [], []
            for n, item in enumerate(loads.get(kind, []) if isinstance(loads.get(kind), list) else []):
                target = (_load_target(item.get("on"), f"loads.{kind}[{n}].on", bodies, problems)
                          if isinstance(item, dict) else None)
                if target is None:
                    continue
                (mine if target[0] == face_body else theirs).append({**item, "on": target[1]})
            if kind in loads:
                loads[kind] = mine
            if theirs:
                counter_loads[kind] = theirs
        out["loads"] = loads
    for where in ("load_cases", "load_steps"):
        if not isinstance(raw.get(where), list):
            continue
        out[where] = copy.deepcopy(raw[where])
        for n, item in enumerate(out[where]):
            if not isinstance(item, dict):
                continue
            if "body_force" in item:
                problems.append(f"{where}[{n}].body_force: in an assembly a body force is a body's own: "
                                "bodies.<name>.body_force")
            for kind in ("traction", "pressure"):
                for m, load in enumerate(item.get(kind, []) if isinstance(item.get(kind), list) else []):
                    target = (_load_target(load.get("on"), f"{where}[{n}].{kind}[{m}].on", bodies, problems)
                              if isinstance(load, dict) else None)
                    if target is None:
                        continue
                    if target[0] != face_body:
                        problems.append(f"{where}[{n}].{kind}[{m}].on: a load on body {target[0]!r}, which does "
                                        "not carry the contact face, is the same in every case and step: put it "
                                        "in [loads]")
                    load["on"] = target[1]
    if isinstance(counter, tuple):
        _counterpart_body(out, bodies, counter, contact, raw, counter_loads, problems)
    else:
        if counter_loads and not several:
            problems.append("loads: a load on a body that takes part in no pair")
        if any(k not in OBSTACLE or OBSTACLE[k][0] != v for k, v in counter.items()):
            out["obstacle"] = copy.deepcopy(counter)       # the fixed plane x3 = 0 is the model without one
    if designs:
        out["design"] = {k: copy.deepcopy(v) for k, v in designs[0].items() if k != "face"}
        if len(designs) > 1:          # the designs after the first, each with its face (resolved spelling)
            out["more_designs"] = [{**copy.deepcopy(d), "face": copy.deepcopy(f[1]),
                                    **({"body": f[0]} if f[0] != face_body else {})}
                                   for d, f in zip(designs[1:], faces[1:])]
    else:                               # no design: the reference shape, ϑ = 0 (``run`` refuses the model)
        out["design"] = {"degree": [0, 0], "initial": 0.0, "C2": 0.0}
    name = contact.get("name", f"{face_body}-{counter[0] if isinstance(counter, tuple) else 'rigid'}")
    other = (f"{counter[0]}.{_part_name(counter[1])}" if isinstance(counter, tuple)
             else f"rigid {counter.get('shape', 'plane')}")
    out["assembly"] = {"bodies": [face_body] + ([counter[0]] if isinstance(counter, tuple) else []),
                       "contacts": [{"name": name, "face": f"{face_body}.{_part_name(part)}", "counterpart": other}],
                       "designs": [f"{face_body}.{_part_name(part)}"] + [f"{b}.{_part_name(p)}" for b, p in faces[1:]]
                       if designs else []}
    return out, Assembly.of(out).renames()


def _body_keys(name: str, body: dict, keys: tuple, other: str, problems: list) -> dict:
    """The keys of ``body`` that a body in its role takes (``keys``; material and body force are
    read apart); a key of the other role is a problem with the sentence ``other``."""
    for k in body:
        if k not in BODY_KEYS:
            problems.append(f"bodies.{name}.{k}: unknown key (allowed: {', '.join(BODY_KEYS)})")
        elif k not in keys and k not in ("material", "body_force"):
            problems.append(f"bodies.{name}.{k}: " + other.format(name=name))
    return {k: copy.deepcopy(v) for k, v in body.items() if k in keys}


def _counterpart_body(out, bodies, counter, contact, raw, counter_loads, problems) -> list:
    """``[foundation]`` of a counterpart body."""
    name, part = counter
    c = bodies[name]
    fnd = _body_keys(name, c, COUNTERPART_BODY_KEYS, "a key of the body that carries the contact face; body "
                     "{name!r} is a counterpart (its mesh is not morphed)", problems)
    fnd["top"] = part
    if "partner" in contact:
        fnd["partner"] = contact["partner"]
    given = raw.get("material") if isinstance(raw.get("material"), dict) else {}
    own = c.get("material", {}) if isinstance(c.get("material"), dict) else {}
    if "formulation" in own:
        problems.append(f"bodies.{name}.material.formulation: a counterpart body takes E and nu")
    # the counterpart's own material, else [material] (not the other body's)
    fnd["material"] = {k: own.get(k, given.get(k, SCHEMA["material"][k][0])) for k in ("E", "nu")}
    loads = dict(counter_loads)
    if "body_force" in c:
        loads["body_force"] = c["body_force"]
    if loads:
        fnd["loads"] = loads
    out["foundation"] = fnd


def check_record(data: dict, problems: list) -> None:
    """``[assembly]`` of a resolved configuration (written back and read again) agrees with its
    sections: one or two bodies as [foundation] says, one design and one per ``more_designs`` entry."""
    rec = data.get("assembly")
    ok = (isinstance(rec, dict) and set(rec) == {"bodies", "contacts", "designs"}
          and isinstance(rec["bodies"], list) and isinstance(rec["contacts"], list)
          and len(rec["contacts"]) == max(1, len(data.get("pairs") or []))
          and all(isinstance(p, dict) for p in rec["contacts"]))
    if ok:        # the counterpart bodies of several pairs, each once (a body may hold several pairs)
        others = ({str(p.get("counterpart", "")).split(".")[0] for p in rec["contacts"]
                   if not str(p.get("counterpart", "")).startswith("rigid ")} if data.get("pairs") else ())
        ok = len(rec["bodies"]) == 1 + ("foundation" in data) + len(others)
    ok = (ok and all(isinstance(p, dict) and set(p) == {"name", "face", "counterpart"} for p in rec["contacts"])
          and isinstance(rec["designs"], list)
          and (len(rec["designs"]) == 1 + len(data["more_designs"]) if data.get("more_designs")
               else len(rec["designs"]) <= 1))
    if not ok:
        problems.append("[assembly]: is the record of a resolved assembly (bodies, contacts, designs); write the "
                        "model with [bodies], [[contacts]] and [[designs]] instead")



def rename(problems: list, renames: list) -> list:
    """``problems`` with the one-body keys of ``renames`` written as the assembly's keys."""
    out = []
    for p in problems:
        for old, new in renames:
            end = r"(?!\w)" if old[-1].isalnum() or old[-1] == "_" else ""
            p = re.sub(r"(?<![\w.\[])" + re.escape(old) + end, new, p)
        out.append(p)
    return out
