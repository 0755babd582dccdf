"""Sphinx configuration of frictiongym's documentation site (furo theme, MyST Markdown, as Gymnasium and
stable-baselines3 build theirs). Build: `frictiongym docs` (warnings are errors, links checked)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

from frictiongym.envs.records import package_version

project = "frictiongym"
author = "the frictiongym developers"
copyright = "2026, the frictiongym developers"
release = version = package_version()

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "frictiongym_pages",  # _ext/: the pages generated from the code and configs (plants, scenarios, ...)
]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 4  # [text](page.md#a-heading) links are checked like any reference
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "bench", "_extra"]
html_theme = "furo"
html_title = f"frictiongym {release}"
html_static_path = ["_static"]
html_css_files = ["frictiongym.css"]  # tables that fit the page
html_extra_path = ["_extra"]  # copied as is: the committed leaderboard page (leaderboard/index.html)
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True}
nitpicky = False
autodoc_inherit_docstrings = False  # Gymnasium's own docstrings are theirs to render
