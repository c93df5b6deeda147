"""Sphinx configuration.

    pip install -e ".[docs]" && sphinx-build -W -b html docs docs/_build
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import rotoruq  # noqa: E402

project = "rotoruq"
author = "rotoruq developers"
copyright = "rotoruq developers"  # noqa: A001
version = release = rotoruq.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "public_api",
    "plain_docstrings",
    "generated_blocks",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
# api.rst and generated/ are what builds before the grouped API reference wrote into the source
# tree; a checkout that still has them must not read them as pages
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "api.rst", "generated"]
root_doc = "index"

myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

# the API pages (docs/api/) are written by public_api's directives when they are read; the
# summary tables link to the entries on the same pages, so autosummary writes no stub files
# into the source tree
autosummary_generate = False
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()

html_theme = "alabaster"
# wide enough for a 100-column code line (the project's line length) in full; narrower screens
# scroll it (docs/_static/rotoruq.css)
html_theme_options = {"page_width": "1280px", "sidebar_width": "220px",
                      "code_font_size": "0.75em"}
html_static_path = ["_static"]
html_css_files = ["rotoruq.css"]
html_title = f"rotoruq {release}"
