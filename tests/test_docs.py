"""The configuration reference in docs/ is the one the schema generates (it cannot drift)."""

from pathlib import Path

from contactopt.config import SCHEMA, reference_markdown

DOC = Path(__file__).resolve().parents[1] / "docs" / "configuration.md"


def test_configuration_reference_is_up_to_date():
    text = DOC.read_text()
    assert text == reference_markdown(), "regenerate with: python -m contactopt.config > docs/configuration.md"
    for section, keys in SCHEMA.items():
        for key in keys:
            assert f"| `{key}` |" in text, (section, key)
