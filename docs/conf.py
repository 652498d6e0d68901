"""Sphinx configuration of the dgli_vision documentation site.

Build it from the repository's root with ``sphinx-build -W docs docs/_build`` (the
``docs`` extra: ``pip install '.[docs]'``); open ``docs/_build/index.html``. The pages
are the Markdown files of this folder, read by myst-parser; the API reference
(``api.rst``) is generated from the docstrings by autodoc and numpydoc.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the package of this checkout, installed or not

project = "dgli_vision"
author = "the dgli_vision authors"
copyright = "2026, the dgli_vision authors"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "myst_parser",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
#: example_report/ holds a report's own files (report.md is one of them), screenshots/
#: and states/ pictures: not pages of the site
exclude_patterns = ["_build", "example_report", "screenshots", "states"]

# Markdown: headings get anchors as GitHub makes them, so links such as
# planning.md#the-closed-loop-check work on the site as in the repository
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence"]

autodoc_typehints = "none"  # the numpydoc sections give the types
autodoc_member_order = "bysource"
autosummary_generate = False
numpydoc_show_class_members = False
numpydoc_xref_param_type = False

html_theme = "pydata_sphinx_theme"
html_title = "dgli_vision"
html_theme_options = {
    "navigation_depth": 2,
    "show_toc_level": 2,
    "navbar_align": "left",
    "header_links_before_dropdown": 4,
}
html_static_path: list[str] = []
