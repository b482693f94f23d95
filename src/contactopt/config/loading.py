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
    body = raw.get("body")
    if name not in EXAMPLES and isinstance(body, dict) and isinstance(body.get("mesh"), str) and body["mesh"]:
        # a mesh path is relative to the TOML file; the resolved configuration keeps it absolute
        body["mesh"] = str((Path(name).parent / body["mesh"]).resolve())
    obst = raw.get("obstacle")
    if name not in EXAMPLES and isinstance(obst, dict) and isinstance(obst.get("mesh"), str) and obst["mesh"]:
        obst["mesh"] = str((Path(name).parent / obst["mesh"]).resolve())
    found = raw.get("foundation")
    if name not in EXAMPLES and isinstance(found, dict) and isinstance(found.get("mesh"), str) and found["mesh"]:
        found["mesh"] = str((Path(name).parent / found["mesh"]).resolve())
    return validate(raw, source)

