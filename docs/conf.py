"""Sphinx configuration of the roughvib documentation.

Build (from the repository root, after ``python -m pip install -e ".[docs]"``)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

The Markdown pages are read by MyST, the API reference is generated from the numpydoc
docstrings (autosummary + autodoc + numpydoc), and the gallery runs ``examples/*.py`` at build
time (sphinx-gallery). CI builds with ``-W``: a warning (a broken cross-reference, a docstring
that does not parse, an example that raises) fails the build.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# document this checkout's sources, whether or not (and wherever) roughvib is installed
sys.path.insert(0, str(ROOT / "src"))

import roughvib  # noqa: E402

project = "roughvib"
author = "the roughvib developers"
copyright = "the roughvib developers"  # noqa: A001 (Sphinx's name)
release = version = roughvib.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = ["_build", "auto_examples/*.ipynb", "auto_examples/*.py",
                    "figures/*.py", "**/sg_execution_times.rst", "sg_execution_times.rst",
                    "_fragments/*"]  # included into pages, not pages of their own

# every cross-reference must resolve (a broken one is a warning, and CI builds with -W)
nitpicky = True
nitpick_ignore_regex = [
    # Objects of other projects named in docstrings. Resolving them needs intersphinx
    # inventories fetched over the network, which the CI machines do not have; they are
    # rendered as plain names instead.
    ("py:(class|func|meth|obj|mod|exc|data)",
     r"(numpy|np|scipy|pandas|pd|xarray|xr|matplotlib|dask|numba|sksundae|tqdm)(\..+)?"),
    # Python's own names (builtins, the standard library): same reason.
    ("py:(class|exc|obj)", r"(DeprecationWarning|ValueError|KeyboardInterrupt|Path|"
                           r"pathlib\.Path|os\.PathLike|collections\.abc\.\w+)"),
]

# -- MyST (the Markdown pages) ---------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3  # links such as performance.md#cost-of-a-restart resolve

# -- API reference -----------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_member_order = "bysource"
# the types are in the numpydoc Parameters/Returns sections; signatures with annotations would
# need the other projects' inventories to link (see nitpick_ignore_regex)
autodoc_typehints = "none"
autodoc_default_options = {"members": True}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_attributes_as_param_list = True
numpydoc_xref_param_type = False

# -- gallery -----------------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/\d\d_",  # run every numbered example at build time
    "within_subsection_order": "FileNameSortKey",
    "ignore_pattern": r"__init__\.py",
    "download_all_examples": False,
    "remove_config_comments": True,
    "min_reported_time": 1,
    "abort_on_example_error": False,  # report every failing example (each one is a warning)
    "only_warn_on_example_error": False,
    "matplotlib_animations": False,
    "reset_modules": ("matplotlib",),
    "show_memory": False,
    "plot_gallery": "True",
}

# -- HTML --------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"roughvib {release}"
html_static_path: list[str] = []
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 7,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_sidebars = {"index": [], "api": []}
html_show_sourcelink = False
