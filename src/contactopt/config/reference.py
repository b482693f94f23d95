"""The Markdown reference of the configuration (docs/configuration.md), generated from the schema."""

from __future__ import annotations

import tomli_w

from .constraints import REFERENCE as CONSTRAINTS_REFERENCE
from .schema import FOUNDATION, OBSTACLE, SCHEMA, SECTION_DOCS, TOP_LEVEL


def reference_markdown() -> str:
    """The configuration reference (docs/configuration.md): every key with its default and meaning."""
    lines = ["# Configuration reference", "",
             "A configuration is a TOML file (or a built-in example: `example1`, `example2`, `example3`).",
             "Every key is optional; the whole file is validated up front and every problem is listed at",
             "once. This page is generated from the schema in `src/contactopt/config/schema.py`",
             "(`python -m contactopt.config > docs/configuration.md`).", "",
             "The same schema is published as a JSON Schema (draft 2020-12) for TOML editors:", "",
             "```", "contactopt schema -o contactopt.schema.json", "```", "",
             "An editor that reads it completes every key, shows its default and meaning, and marks a",
             "misspelt key or a value of the wrong type. With Taplo (VS Code's Even Better TOML), write",
             "`#:schema ./contactopt.schema.json` as the first line of a configuration file. The JSON",
             "Schema checks the form of each key; contactopt itself still checks what depends on other",
             "keys (the size of a control net, the names of load cases).", "",
             "| key | default | meaning |", "|---|---|---|"]
    for key, (default, _, desc) in TOP_LEVEL.items():
        lines.append(f"| `{key}` | `{default!r}` | {desc} |")
    for sec, keys in SCHEMA.items():
        lines += ["", f"## [{sec}]", "", SECTION_DOCS.get(sec, ""), "", "| key | default | meaning |", "|---|---|---|"]
        for k, (default, _, desc) in keys.items():
            shown = tomli_w.dumps({"v": default}).split("=", 1)[1].strip() if default != [] else "[]"
            text = desc.replace("|", "\\|")
            lines.append(f"| `{k}` | `{shown}` | {text} |")
    lines += ["", "## [foundation]", "",
              "Optional: an elastic foundation under the body (docs/foundation.md). Absent, the foundation is "
              "the rigid half-space x3 ≤ 0. Its top face lies on x3 = 0 under the contact face; each contact "
              "node has a partner on that face (`partner`). Runs on the condensation path.",
              "", "| key | default | meaning |", "|---|---|---|"]
    for k, (default, _, desc) in FOUNDATION.items():
        shown = tomli_w.dumps({"v": default}).split("=", 1)[1].strip() if default not in ([], {}) else repr(default)
        text = desc.replace("|", "\\|")
        lines.append(f"| `{k}` | `{shown}` | {text} |")
    lines += ["", "## [obstacle]", "",
              "Optional: a rigid obstacle of any shape (docs/obstacles.md). Absent, it is the plane x3 = 0, "
              "fixed. Each contact node gets a frame (t1, t2, n) from the obstacle at its closest point; the "
              "gap and the Coulomb law act in that frame. A shape other than the plane, and force control, run "
              "on the condensation, Delassus and full-space paths; excludes [foundation].",
              "", "| key | default | meaning |", "|---|---|---|"]
    for k, (default, _, desc) in OBSTACLE.items():
        shown = tomli_w.dumps({"v": default}).split("=", 1)[1].strip()
        text = desc.replace("|", "\\|")
        lines.append(f"| `{k}` | `{shown}` | {text} |")
    lines += ["", "## [[load_cases]]", "",
              "Optional named load cases (an array of tables). Each has a `name` (letters, digits, `_ . + -`), "
              "any of the keys of [loads] (none required) and optionally a `target` in the form of "
              "`objective.target`. A case's loads are its own plus those written in [loads] (with cases, "
              "the block's default `top_traction`/`right_traction` are off unless [loads] writes them). "
              "`objective.combine` joins the cases' objectives: the max (worst case) or the weighted sum. "
              "A case may have its own load path, `[[load_cases.steps]]` in the form of [[load_steps]].",
              "", "## [[load_steps]]", "",
              "Optional load path (an array of tables, in order; docs/load_paths.md): quasi-static steps, each "
              "with a `name`, the TOTAL loads at its end in the keys of [loads] ([loads] adds to every step) and "
              "`substeps` (default 1: equal increments, linear in the loads, from the previous step's loads). "
              "Coulomb's law acts on the slip of each step. `objective.steps` says which steps Θ is taken on. "
              "With a force-controlled [obstacle] a step may give `obstacle_force` = [f1, f2, f3], the force at "
              "its end, a positive multiple of `obstacle.force` (absent: `obstacle.force`), ramped like the "
              "loads over its substeps (the first step's from zero). "
              "Without steps the problem is one step, the static problem."]
    lines += CONSTRAINTS_REFERENCE
    return "\n".join(lines) + "\n"

