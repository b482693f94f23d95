"""The README and the user guide run: their Python blocks execute, their TOML blocks agree with the
example files they show, and every `contactopt …` command line they give parses with the CLI."""

import re
import shlex
import tomllib
from pathlib import Path

import pytest

from contactopt import load_config
from contactopt.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "docs" / "guide").glob("*.md"))]
FENCE = re.compile(r"^( *)```(\w*)\n(.*?)^\1```", re.M | re.S)


def blocks(kind):
    for page in PAGES:
        for m in FENCE.finditer(page.read_text()):
            if m.group(2) == kind:
                text = "\n".join(line[len(m.group(1)):] for line in m.group(3).splitlines())
                yield pytest.param(text, id=f"{page.relative_to(ROOT)}:{page.read_text()[:m.start()].count(chr(10)) + 1}")


def _leaves(d, prefix=""):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from _leaves(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}", v


def _get(d, dotted):
    for k in dotted.split("."):
        d = d[k]
    return d


@pytest.mark.parametrize("code", list(blocks("python")))
def test_python_blocks_run(code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "<docs>", "exec"), {"__name__": "__docs__"})


@pytest.mark.parametrize("text", list(blocks("toml")))
def test_toml_blocks_match_the_examples_they_show(text):
    """A block that names an example (`name = "…"`) shows that file's keys with that file's values."""
    data = tomllib.loads(text)
    if "name" not in data:
        return
    example = ROOT / "examples" / f"{data['name']}.toml"
    assert example.exists(), f"the block names example {data['name']!r}, which examples/ does not have"
    raw = tomllib.loads(example.read_text())
    full = load_config(example).data          # the file with every default filled in
    for key, value in _leaves(data):
        try:
            actual = _get(raw, key)
        except KeyError:
            actual = _get(full, key)
        assert actual == value, f"{example.name}: {key} is {actual!r}, the docs say {value!r}"


def _commands():
    for kind in ("", "console", "bash", "sh"):
        for p in blocks(kind):
            for line in p.values[0].splitlines():
                line = line.split(" #")[0].strip().lstrip("$ ").strip()
                for part in line.split("&&"):
                    part = part.strip()
                    if part.startswith("mpiexec") and " contactopt " in part:
                        part = part[part.index("contactopt "):]
                    if part.startswith("contactopt "):
                        yield pytest.param(part, id=f"{p.id}:{part[:40]}")


@pytest.mark.parametrize("line", list(_commands()))
def test_command_lines_parse(line):
    argv = shlex.split(line.replace("\\", ""))[1:]
    build_parser().parse_args(argv)     # SystemExit on an unknown command or option


def test_sources_cite_only_the_repository():
    """Docstrings and comments point to the project's own docs, never to a file outside it."""
    files = [p for base in ("src", "tests", "benchmarks", "docs", "examples") for p in sorted((ROOT / base).rglob("*"))]
    files += sorted(ROOT.glob("*.md"))                  # README, REPRODUCTION, ...
    offenders = [f"{p.relative_to(ROOT)}:{n}"
                 for p in files if p.suffix in (".py", ".md") and p.name != Path(__file__).name
                 for n, line in enumerate(p.read_text(errors="replace").splitlines(), 1) if "DESIGN.md" in line]
    assert not offenders, offenders
