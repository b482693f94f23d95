"""Sphinx configuration of the contactopt documentation site.

Build: ``python -m sphinx -n -W --keep-going -b html docs docs/_build/html`` (warnings and unresolved
cross-references are errors).
Pages are Markdown (MyST); the API reference is generated from the numpydoc docstrings.
"""

import os
import sys

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "src")))

project = "contactopt"
author = "the contactopt developers"
copyright = "2026, the contactopt developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]
source_suffix = {".md": "markdown"}
master_doc = "index"
exclude_patterns = ["_build", "_static"]
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
napoleon_google_docstring = False
napoleon_numpy_docstring = True
# parameter types are prose ("(p, 3) array", "callable, optional"), not cross-references
napoleon_use_param = False
napoleon_use_rtype = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"
html_theme = "alabaster"
html_title = "contactopt"
html_static_path = ["_static"]
# MathJax served with the site (docs/_static/mathjax, Apache-2.0): formulas render offline
mathjax_path = "mathjax/tex-svg.js"
