"""``python -m contactopt.config > docs/configuration.md``: the configuration reference."""

from .reference import reference_markdown

print(reference_markdown(), end="")
