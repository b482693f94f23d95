"""The configuration reference as a reader sees it: the page built by Sphinx (with the site's own
conf.py) has one table row for every key of the JSON Schema, under the heading of its section."""

import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import pytest

from contactopt.config.json_schema import json_schema

sphinx = pytest.importorskip("sphinx.application")

DOCS = Path(__file__).resolve().parents[1] / "docs"


def schema_keys() -> set[tuple[str, str]]:
    """(section, key) of every key of the schema; a top-level key has the section ''. The arrays of
    tables ([[load_cases]], …) count as sections."""
    keys = set()
    for name, spec in json_schema()["properties"].items():
        props = spec.get("properties") or (spec.get("items") or {}).get("properties")
        if spec.get("type") in ("object", "array") and props:
            keys |= {(name, k) for k in props}
        else:
            keys.add(("", name))
    return keys


class _Rows(HTMLParser):
    """(section, first cell) of every body row of every table; the section is the h2 above it."""

    def __init__(self):
        super().__init__()
        self.rows, self.section, self._where, self._text, self._cell = [], None, None, [], 0

    def handle_starttag(self, tag, attrs):
        if tag == "h2":
            self._where, self._text = "h2", []
        elif tag == "tr":
            self._cell = 0
        elif tag == "td":
            self._cell += 1
            if self._cell == 1:
                self._where, self._text = "td", []

    def handle_endtag(self, tag):
        if tag == "h2" and self._where == "h2":
            self.section, self._where = "".join(self._text).strip(), None
        elif tag == "td" and self._where == "td":
            self.rows.append((self.section, "".join(self._text).strip()))
            self._where = None

    def handle_data(self, data):
        if self._where:
            self._text.append(data)


def section_name(heading: str) -> str:
    """'[body]' → 'body', '[[load_cases]]' → 'load_cases', 'Top level' → ''."""
    return "" if heading.lower().startswith("top level") else heading.strip("[]¶ ")


@pytest.fixture(scope="module")
def built_page(tmp_path_factory):
    """docs/configuration.md and docs/theory.md built to HTML with docs/conf.py (the rest of the site
    is not needed); the configuration page's HTML."""
    tmp = tmp_path_factory.mktemp("site")
    src = tmp / "src"
    src.mkdir()
    for page in ("configuration.md", "theory.md"):
        shutil.copy(DOCS / page, src / page)
    app = sphinx.Sphinx(str(src), str(DOCS), str(tmp / "html"), str(tmp / "doctrees"), "html",
                        confoverrides={"master_doc": "configuration"}, status=None, warning=None,
                        freshenv=True)
    app.build()
    page = _Page((tmp / "html" / "configuration.html").read_text())
    page.html_dir = str(tmp / "html")
    return page


class _Page(str):
    """The HTML of the configuration page, with the directory of the built pages."""


def test_every_schema_key_has_its_own_row(built_page):
    parser = _Rows()
    parser.feed(built_page)
    rows = {(section_name(sec or ""), cell) for sec, cell in parser.rows}
    missing = sorted(f"{s}.{k}" if s else k for s, k in schema_keys() if (s, k) not in rows)
    assert not missing, f"schema keys without a row of their own in the built reference: {missing}"
    assert len(schema_keys()) > 100


class _Prose(HTMLParser):
    """The text of the page outside tables, code and the footer."""

    def __init__(self):
        super().__init__()
        self.text, self._skip = [], 0

    def handle_starttag(self, tag, attrs):
        self._skip += tag in ("table", "pre", "code", "script", "style")
        if tag == "div" and "footer" in (dict(attrs).get("class") or ""):
            self._skip += 10**6      # the theme's footer, not the page

    def handle_endtag(self, tag):
        self._skip -= tag in ("table", "pre", "code", "script", "style")

    def handle_data(self, data):
        if not self._skip:
            self.text.append(data)


def test_no_table_falls_apart(built_page):
    """A default written over several lines breaks its table: the rest of the rows become prose
    and code blocks with stray '|' between them."""
    parser = _Prose()
    parser.feed(built_page)
    stray = [t.strip() for t in parser.text if "|" in t]
    assert not stray, f"table text outside a table: {stray[:5]}"


def test_math_renders_without_a_network(built_page):
    """The theory page loads MathJax from the site itself (docs/_static), never from a network."""
    theory = (Path(built_page.html_dir) / "theory.html").read_text()
    scripts = re.findall(r'<script[^>]*src="([^"]*)"', theory)
    assert any(s.startswith("_static/mathjax/tex-svg.js") for s in scripts), scripts
    assert not [s for s in scripts if "://" in s or s.startswith("//")], scripts
    assert (DOCS / "_static" / "mathjax" / "tex-svg.js").stat().st_size > 1_000_000
    assert (DOCS / "_static" / "mathjax" / "LICENSE").exists()


class _RowText(_Rows):
    """As :class:`_Rows`, with the whole text of every body row by (section, first cell)."""

    def __init__(self):
        super().__init__()
        self.text, self._row, self._first = {}, None, 0

    def handle_starttag(self, tag, attrs):
        super().handle_starttag(tag, attrs)
        if tag == "tr":
            self._row, self._first = [], len(self.rows)

    def handle_endtag(self, tag):
        super().handle_endtag(tag)
        if tag == "tr" and self._row is not None and len(self.rows) > self._first:    # a body row, not a header
            self.text[(section_name(self.rows[-1][0] or ""), self.rows[-1][1])] = "".join(self._row)
            self._row = None

    def handle_data(self, data):
        super().handle_data(data)
        if self._row is not None:
            self._row.append(data)


def test_a_placeholder_in_angle_brackets_is_shown(built_page):
    """'{ on = <part>, … }': in a browser's text of the page, not hidden as an unknown HTML tag."""
    parser = _RowText()
    parser.feed(built_page)
    assert "{ on = <part>, components = [1, 3] }" in parser.text[("body", "clamped")]
    assert "{ on = <part>, value = [t1, t2, t3] }" in parser.text[("loads", "traction")]
    assert "{ on = <part of the foundation>, value = … }" in parser.text[("foundation", "loads")]
