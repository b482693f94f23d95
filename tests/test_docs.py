"""The configuration reference in docs/ is the one the schema generates (it cannot drift)."""

from pathlib import Path

import pytest

from contactopt.config import SCHEMA, reference_markdown

DOC = Path(__file__).resolve().parents[1] / "docs" / "configuration.md"
TABLE_HEAD = "| key | default | meaning |\n|---|---|---|\n"


def test_configuration_reference_is_up_to_date():
    text = DOC.read_text()
    assert text == reference_markdown(), "regenerate with: python -m contactopt.config > docs/configuration.md"
    for section, keys in SCHEMA.items():
        for key in keys:
            assert f"| `{key}` |" in text, (section, key)


def test_placeholders_of_the_reference_are_text_not_html_tags():
    """'{ on = <part>, … }' of [body] clamped: CommonMark takes '<part>' for an HTML tag, which a
    browser hides; the reference escapes it, so that MyST's parser (markdown-it) makes it text."""
    markdown_it = pytest.importorskip("markdown_it")
    text = reference_markdown()
    row = next(line for line in text.splitlines() if line.startswith("| `clamped` | `\"clamped\"` |"))
    assert "{ on = \\<part>, components = [1, 3] }" in row
    md = markdown_it.MarkdownIt("commonmark").enable("table")
    assert "{ on = &lt;part&gt;, components = [1, 3] }" in md.render(TABLE_HEAD + row + "\n")
    raw = [t.content for block in md.parse(text) for t in [block, *(block.children or [])]
           if t.type in ("html_inline", "html_block")]
    assert not raw, f"raw HTML in the reference: {raw[:5]}"
