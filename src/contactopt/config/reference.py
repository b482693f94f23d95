"""The Markdown reference of the configuration (docs/configuration.md), generated from the schema.

Every key of the JSON Schema (:func:`.json_schema.json_schema`) gets one row of a Markdown table:
its section, its default written inline on one line (TOML syntax: a list or a table never spans
lines, which would break the table) and its meaning. The arrays of tables ([[load_cases]],
[[load_steps]], [[constraints]]) have a table of their own keys too.

A placeholder of the schema's prose, ``<part>``, is written ``\\<part>``: Markdown (MyST as
CommonMark) takes ``<part>`` for an HTML tag, which a browser hides.
"""

from __future__ import annotations

import json
import math
import re

from .assembly import ASSEMBLY_DOCS
from .constraints import REFERENCE as CONSTRAINTS_REFERENCE
from .json_schema import json_schema
from .schema import BODIES, CONTACTS, DESIGNS, FOUNDATION, OBSTACLE, SCHEMA, SECTION_DOCS, TOP_LEVEL

HEADER = ["| key | default | meaning |", "|---|---|---|"]


def inline_toml(value) -> str:
    """``value`` as an inline TOML value on one line (``[0.0, 0.0, -0.08]``, ``{ kind = "constant" }``);
    None (a key without a default) as an empty string."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        if isinstance(value, float) and not math.isfinite(value):
            return "inf" if value > 0 else "-inf" if value < 0 else "nan"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, dict):
        if not value:
            return "{}"
        return "{ " + ", ".join(f"{k} = {inline_toml(v)}" for k, v in value.items()) + " }"
    return "[" + ", ".join(inline_toml(v) for v in value) + "]"


_PAGE = re.compile(r"docs/([a-z_/-]+)\.md")
_CODE = re.compile(r"(`+).*?\1")


def _prose(text: str) -> str:
    """Markdown prose that shows ``text`` as written: every ``<`` outside code spans escaped
    (``\\<``), so that a placeholder such as ``<part>`` is text, not an HTML tag; code spans
    show it as it is."""
    out, end = [], 0
    for m in _CODE.finditer(text):
        out += [text[end:m.start()].replace("<", "\\<"), m.group(0)]
        end = m.end()
    return "".join(out) + text[end:].replace("<", "\\<")


def _cell(text: str, code: bool = False) -> str:
    """Text of a table cell: a ``|`` escaped, no line breaks, a page of the manual
    ("docs/materials.md") a link to it; prose (``code=False``) also with its ``<`` escaped
    (:func:`_prose`), the content of a code span (``code=True``) as it is."""
    text = " ".join(str(text).split()).replace("|", "\\|")
    text = text if code else _prose(text)
    return _PAGE.sub(lambda m: f"[{m.group(1).split('/')[-1].replace('_', ' ').replace('-', ' ')}]({m.group(1)}.md)", text)


def _row(key: str, default, meaning: str) -> str:
    shown = inline_toml(default)
    return f"| `{key}` | {'`' + _cell(shown, code=True) + '`' if shown else '(none)'} | {_cell(meaning)} |"


def _rows(keys: dict) -> list[str]:
    """Rows of a schema table {key: (default, check, meaning)}."""
    return HEADER + [_row(k, default, desc) for k, (default, _, desc) in keys.items()]


def _array_rows(items: dict, section: str) -> list[str]:
    """Rows of the keys of an array of tables, from the JSON Schema of its items; the keys of [loads]
    are named, not repeated."""
    rows = list(HEADER)
    props, required = items["properties"], set(items.get("required", ()))
    for k, spec in props.items():
        if section != "loads" and k in SCHEMA["loads"]:
            rows.append(_row(k, SCHEMA["loads"][k][0], "as in [loads]"))
            continue
        desc = spec.get("description", "")
        if not desc and k == "name":
            desc = "a name: letters, digits, _ . + - (required)"
        elif not desc and k == "target":
            desc = "a table in the form of objective.target (this case's target)"
        elif not desc and k == "steps":
            desc = "this case's own load path: an array of tables in the form of [[load_steps]]"
        elif not desc and "enum" in spec:
            desc = "one of " + ", ".join(f"'{v}'" for v in spec["enum"])
        rows.append(_row(k, spec.get("default"), desc + (" (required)" if k in required and k != "name" else "")))
    return rows


def reference_markdown() -> str:
    """The configuration reference (docs/configuration.md): every key with its default and meaning."""
    schema = json_schema()["properties"]
    lines = ["# Configuration reference", "",
             "A configuration is a TOML file (or a built-in example: `example1`, `example2`, `example3`).",
             "Every key is optional; the whole file is validated up front and every problem is listed at",
             "once. This page is generated from the schema in `src/contactopt/config/schema.py`",
             "(`python -m contactopt.config > docs/configuration.md`); a default is written as it would",
             "be in the file, on one line.", "",
             "The same schema is published as a JSON Schema (draft 2020-12) for TOML editors:", "",
             "```", "contactopt schema -o contactopt.schema.json", "```", "",
             "An editor that reads it completes every key, shows its default and meaning, and marks a",
             "misspelt key or a value of the wrong type. With Taplo (VS Code's Even Better TOML), write",
             "`#:schema ./contactopt.schema.json` as the first line of a configuration file. The JSON",
             "Schema checks the form of each key; contactopt itself still checks what depends on other",
             "keys (the size of a control net, the names of load cases).", "", "## Top level", ""]
    lines += _rows(TOP_LEVEL)
    lines += [_row("bodies", {}, "the bodies of an assembly, a table [bodies.<name>] each (below)"),
              _row("assembly", {}, "written by contactopt in a resolved configuration: the names of an assembly's "
                   "bodies, contact pairs and designed faces")]
    for sec, keys in SCHEMA.items():
        lines += ["", f"## [{sec}]", "", _prose(SECTION_DOCS.get(sec, "")), ""] + _rows(keys)
    lines += ["", "## [foundation]", "",
              "Optional: an elastic foundation under the body ([foundation](guide/foundation.md)). Absent, "
              "the foundation is the rigid half-space x3 ≤ 0. Its top face lies on x3 = 0 under the contact "
              "face; each contact node has a partner on that face (`partner`). Held by `clamped` (control = "
              "'fixed'), or moved with its part `loaded` by a prescribed translation (control = 'displacement') "
              "or by the translation that makes the force on that part equal `force` (control = 'force', as a "
              "force-controlled [obstacle]). Runs on the condensation path.",
              ""] + _rows(FOUNDATION)
    lines += ["", "## [obstacle]", "",
              "Optional: a rigid obstacle of any shape ([obstacles](obstacles.md)). Absent, it is the plane "
              "x3 = 0, fixed. Each contact node gets a frame (t1, t2, n) from the obstacle at its closest point; "
              "the gap and the Coulomb law act in that frame. A shape other than the plane, and force control, "
              "run on the condensation, Delassus and full-space paths; excludes [foundation].",
              ""] + _rows(OBSTACLE)
    lines += ["", _prose("## [bodies.<name>]"), "",
              _prose("A model written as its bodies, contact pairs and designed faces ([assemblies](guide/assemblies.md)); "
                     "[body], [foundation], [obstacle] and [design] are its one- and two-body spellings and are not "
                     "given beside these. A part of a body is written \"<body>.<part>\", in a pair, a design and a "
                     "load's `on` (a predicate table names its body: `{ body = \"<name>\", x1 = 0.0 }`)."),
              "", _prose(ASSEMBLY_DOCS["bodies"]), ""] + _rows(BODIES)
    lines += ["", "## [[contacts]]", "", _prose(ASSEMBLY_DOCS["contacts"]), ""] + _rows(CONTACTS)
    lines += ["", "## [[designs]]", "", _prose(ASSEMBLY_DOCS["designs"]), ""] + _rows(DESIGNS)
    lines += ["", "## [[load_cases]]", "",
              "Optional named load cases (an array of tables). Each has a `name` (letters, digits, `_ . + -`), "
              "any of the keys of [loads] (none required) and optionally a `target` in the form of "
              "`objective.target`. A case's loads are its own plus those written in [loads] (with cases, "
              "the block's default `top_traction`/`right_traction` are off unless [loads] writes them). "
              "`objective.combine` joins the cases' objectives: the max (worst case) or the weighted sum. "
              "A case may have its own load path, `[[load_cases.steps]]` in the form of [[load_steps]].", ""]
    lines += _array_rows(schema["load_cases"]["items"], "load_cases")
    lines += ["", "## [[load_steps]]", "",
              "Optional load path (an array of tables, in order; [load paths](load_paths.md)): quasi-static "
              "steps, each with a `name`, the TOTAL loads at its end in the keys of [loads] ([loads] adds to "
              "every step) and `substeps` (default 1: equal increments, linear in the loads, from the previous "
              "step's loads). Coulomb's law acts on the slip of each step. `objective.steps` says which steps Θ "
              "is taken on. With a force-controlled [obstacle] a step may give `obstacle_force` = [f1, f2, f3], "
              "the force at its end, a positive multiple of `obstacle.force` (absent: `obstacle.force`), ramped "
              "like the loads over its substeps (the first step's from zero). Without steps the problem is one "
              "step, the static problem.", ""]
    lines += _array_rows(schema["load_steps"]["items"], "load_steps")
    lines += [_PAGE.sub(lambda m: f"[{m.group(1)}]({m.group(1)}.md)", _prose(line)) for line in CONSTRAINTS_REFERENCE]
    lines += [""]
    lines += _array_rows(schema["constraints"]["items"], "constraints")
    return "\n".join(lines) + "\n"
