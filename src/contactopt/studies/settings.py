"""The settings of a sweep: ``--set KEY=V1,V2,…`` parsed, combined and validated up front.

A KEY is a dotted path into the configuration (``friction.coefficient``, ``mesh.nx``,
``objective.target.value``); each value is a TOML scalar (``0.3``, ``8``, ``true``, ``"newton"``;
a bare word such as ``newton`` is taken as a string). The tasks are the cartesian product of the
settings, first key slowest, in the order given. Every task's configuration is validated before
anything runs; all problems are listed in one :class:`~contactopt.errors.ConfigError`.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import re
import tomllib
from dataclasses import dataclass

from ..config import Config, load_config, validate
from ..errors import ConfigError

__all__ = ["SweepTask", "parse_setting", "parse_settings", "build_tasks", "format_value"]

_BARE_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_.+-]*")
_SAFE = re.compile(r"[^A-Za-z0-9._=+-]")


@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep: its settings (key, value) in the order of the sweep and its configuration."""

    index: int
    settings: tuple
    config: Config
    name: str                 # run directory name below <sweep>/runs/, from the settings alone

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={format_value(v)}" for k, v in self.settings)


def format_value(value) -> str:
    """A value as TOML writes it (``0.1``, ``8``, ``true``), strings unquoted."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return value
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _split_values(text: str) -> list[str]:
    """Split at the commas outside quotes and brackets (``[1, 2],[3, 4]`` is two values)."""
    out, depth, quote, cur = [], 0, None, []
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append("".join(cur).strip())
            cur = []
            continue
        cur.append(ch)
    out.append("".join(cur).strip())
    return out


def _parse_value(text: str):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        if _BARE_WORD.fullmatch(text):
            return text
        raise ValueError(f"{text!r} is not a TOML value") from None


def parse_setting(text: str, problems: list) -> tuple[str, list] | None:
    """``KEY=V1,V2,…`` -> (KEY, [values]); problems are appended to ``problems``."""
    key, sep, rhs = text.partition("=")
    key = key.strip()
    if not sep or not key:
        problems.append(f"--set {text!r}: expected KEY=V1,V2,… (for example friction.coefficient=0,0.1)")
        return None
    if not all(part.isidentifier() or part.replace("_", "").isalnum() for part in key.split(".")):
        problems.append(f"--set {key}: a key is a dotted name such as friction.coefficient")
        return None
    values = []
    for item in _split_values(rhs):
        if item == "":
            problems.append(f"--set {key}: empty value in {rhs!r}")
            continue
        try:
            values.append(_parse_value(item))
        except ValueError as exc:
            problems.append(f"--set {key}: {exc}")
    return key, values


def parse_settings(texts) -> list[tuple[str, list]]:
    """Parse every ``--set`` argument; raise one ConfigError listing every problem."""
    problems, out, seen = [], [], set()
    for text in texts:
        parsed = parse_setting(text, problems)
        if parsed is None:
            continue
        if parsed[0] in seen:
            problems.append(f"--set {parsed[0]}: given twice (list all its values in one --set)")
            continue
        seen.add(parsed[0])
        out.append(parsed)
    if not texts:
        problems.append("--set: at least one setting KEY=V1,V2,… is needed")
    if problems:
        raise ConfigError(problems)
    return out


def _set_path(data: dict, key: str, value):
    """Set a dotted key in a nested dict; the sections on the way must be tables (or absent)."""
    parts = key.split(".")
    node = data
    for n, part in enumerate(parts[:-1]):
        nxt = node.setdefault(part, {})
        if not isinstance(nxt, dict):
            raise ValueError(f"{'.'.join(parts[:n + 1])} is not a table")
        node = nxt
    node[parts[-1]] = copy.deepcopy(value)


def _lookup(data: dict, key: str):
    node = data
    for part in key.split("."):
        node = node[part]
    return node


def _task_name(settings) -> str:
    raw = "__".join(f"{k}={format_value(v)}" for k, v in settings)
    safe = _SAFE.sub("_", raw)
    if safe != raw or len(safe) > 120:
        # the settings must stay distinguishable after the file-name clean-up
        safe = f"{safe[:100]}-{hashlib.sha256(raw.encode()).hexdigest()[:8]}"
    return safe


def build_tasks(config, settings, *, updates: dict | None = None) -> list[SweepTask]:
    """The tasks of a sweep: one validated Config per combination of the settings.

    ``updates`` (section -> {key: value}) applies to every task first (``optimizer.max_iter`` of
    ``--max-iter``). Each value is checked with the whole configuration; the combinations are
    checked too (a value may be valid alone and not with another, as design.C0 with geometry.c).
    Values are the resolved ones (``0`` for a float key becomes ``0.0``); two values that
    resolve alike are an error, since they would be the same task.
    """
    base = load_config(config)
    if updates:
        base = base.with_updates(updates)
    problems = []
    for key, values in settings:
        resolved = []
        for value in values:
            data = base.to_dict()
            try:
                _set_path(data, key, value)
                cfg = validate(data, base.source)
            except ValueError as exc:
                problems.append(f"--set {key}={format_value(value)}: {exc}")
                continue
            except ConfigError as exc:
                problems += [f"--set {key}={format_value(value)}: {p}" for p in exc.problems]
                continue
            resolved.append(_lookup(cfg.to_dict(), key))
        dup = {format_value(v) for v in resolved if resolved.count(v) > 1}
        if dup:
            problems.append(f"--set {key}: the values {', '.join(sorted(dup))} occur more than once")
    if problems:
        raise ConfigError(problems)
    tasks = []
    keys = [k for k, _ in settings]
    for n, combo in enumerate(itertools.product(*(v for _, v in settings))):
        data = base.to_dict()
        for key, value in zip(keys, combo):
            _set_path(data, key, value)
        try:
            cfg = validate(data, base.source)
        except ConfigError as exc:
            label = ", ".join(f"{k}={format_value(v)}" for k, v in zip(keys, combo))
            problems += [f"task {label}: {p}" for p in exc.problems]
            continue
        resolved = tuple((k, _lookup(cfg.to_dict(), k)) for k in keys)
        tasks.append(SweepTask(n, resolved, cfg, _task_name(resolved)))
    if problems:
        raise ConfigError(problems)
    return tasks
