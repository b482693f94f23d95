"""Loading a configuration: a TOML file, a built-in example, a dict or a Config."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from ..errors import ConfigError
from .configuration import Config, validate
from .schema import EXAMPLES


def load_config(path_or_name) -> Config:
    """Load a TOML file or a built-in example (``example1``, ``example2``, ``example3``)."""
    if isinstance(path_or_name, Config):
        return path_or_name
    if isinstance(path_or_name, dict):
        return validate(path_or_name)
    name = str(path_or_name)
    if name in EXAMPLES:
        text = resources.files("contactopt").joinpath("examples", f"{name}.toml").read_text()
        source = f"built-in {name}"
    else:
        p = Path(name)
        if not p.exists():
            raise ConfigError([f"{name}: no such file, and not a built-in example ({', '.join(EXAMPLES)})"])
        if p.is_dir():
            raise ConfigError([f"{name}: is a directory, expected a TOML file"])
        text = p.read_text()
        source = str(p)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([f"{source}: not valid TOML: {exc}"]) from None
    if name not in EXAMPLES:
        # a mesh path is relative to the TOML file; the resolved configuration keeps it absolute
        tables = [raw.get("body"), raw.get("obstacle"), raw.get("foundation")]
        bodies = raw.get("bodies")
        tables += list(bodies.values()) if isinstance(bodies, dict) else []
        contacts = raw.get("contacts")
        tables += [c.get("counterpart") for c in contacts if isinstance(c, dict)] if isinstance(contacts, list) else []
        for t in tables:
            if isinstance(t, dict) and isinstance(t.get("mesh"), str) and t["mesh"]:
                t["mesh"] = str((Path(name).parent / t["mesh"]).resolve())
    return validate(raw, source)

