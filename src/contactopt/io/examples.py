"""The example configurations shipped with contactopt, copied out for a user who installed the
package (``contactopt examples DIR``): the paper's Examples 1–3 and the gallery of the repository's
``examples/`` (bodies from Gmsh meshes with their ``.geo`` files, load cases, load paths,
obstacles, foundations). The copy is a directory a user can run from: the TOML files refer to
their meshes by paths relative to themselves."""

from __future__ import annotations

import logging
import shutil
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ..errors import ConfigError

log = logging.getLogger(__name__)

SUFFIXES = (".toml", ".geo", ".msh", ".stl", ".py")      # .stl: an obstacle's surface


@dataclass(frozen=True)
class Example:
    """One configuration: its file name, the ``description`` it gives, the files it needs."""

    name: str
    description: str
    files: tuple[str, ...]


def _sources() -> dict[str, object]:
    """{relative path: resource} of every shipped example file (the built-in three first)."""
    root = resources.files("contactopt")
    out = {f"{p.name}": p for p in sorted(root.joinpath("examples").iterdir(), key=lambda p: p.name)
           if p.name.endswith(".toml")}
    gallery = root.joinpath("gallery")
    if gallery.is_dir():
        for p in sorted(gallery.iterdir(), key=lambda p: p.name):
            if p.is_file() and p.name.endswith(SUFFIXES):
                out.setdefault(p.name, p)
            elif p.is_dir() and not p.name.startswith(("_", ".")):
                for q in sorted(p.iterdir(), key=lambda q: q.name):
                    if q.is_file() and q.name.endswith(SUFFIXES):
                        out[f"{p.name}/{q.name}"] = q
    return out


def _mesh_paths(data: dict) -> list[str]:
    """The mesh files a configuration names: its body's, a foundation's or obstacle's, and in an
    assembly each body's and each rigid counterpart's."""
    tables = [data.get("body"), data.get("foundation"), data.get("obstacle")]
    bodies = data.get("bodies")
    tables += list(bodies.values()) if isinstance(bodies, dict) else []
    tables += [c.get("counterpart") for c in data.get("contacts", []) if isinstance(c, dict)]
    return [t["mesh"] for t in tables if isinstance(t, dict) and isinstance(t.get("mesh"), str) and t["mesh"]]


def list_examples() -> list[Example]:
    """The shipped configurations, each with the files it needs (a mesh in a folder of its name)."""
    sources = _sources()
    out = []
    for rel, res in sources.items():
        if "/" in rel or not rel.endswith(".toml"):
            continue
        data = tomllib.loads(res.read_text())
        folders = {m.split("/")[0] for m in _mesh_paths(data) if "/" in m}
        extra = tuple(r for r in sources if any(r.startswith(f + "/") for f in sorted(folders)))
        out.append(Example(rel[:-5], str(data.get("description", "")), (rel,) + extra))
    return out


def copy_examples(dest, *, overwrite: bool = False) -> list[Path]:
    """Copy every shipped example file into ``dest`` (created), keeping the layout that the TOML
    files' relative mesh paths expect. A file that exists already is refused (ConfigError naming
    it, nothing written) unless ``overwrite``. Returns the paths written."""
    dest = Path(dest)
    if dest.exists() and not dest.is_dir():
        raise ConfigError([f"{dest}: exists and is not a directory"])
    sources = _sources()
    clash = [rel for rel in sources if (dest / rel).exists()]
    if clash and not overwrite:
        raise ConfigError([f"{dest}: already holds {', '.join(clash[:3])}"
                           f"{f' and {len(clash) - 3} more' if len(clash) > 3 else ''}; "
                           "choose another directory or pass --overwrite"])
    written = []
    for rel, res in sources.items():
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        with resources.as_file(res) as path:
            shutil.copyfile(path, target)
        written.append(target)
    log.info("copied %d example files to %s", len(written), dest)
    return written
