"""Sphinx configuration of rotorlab's documentation site.

Build: ``pip install -e ".[docs]"``, then ``sphinx-build -W -b html docs docs/_build/html`` (warnings are errors,
so a broken cross-reference, a missing image or a malformed docstring fails the build). The Markdown pages are
read by MyST, the API reference comes from the numpydoc docstrings, the gallery from ``examples/`` (sphinx-gallery
runs every example and keeps its output), the CLI reference from the argparse parser the ``rotorlab`` command builds.
"""

import os
from importlib.metadata import version as _version

os.environ.setdefault("MUJOCO_GL", "egl")
# the API reference documents the Python source: autodoc reads it (signatures, [source] links) from the .py modules,
# not from the extensions a build compiled from them (rotorlab.compiled)
os.environ.setdefault("ROTORLAB_PURE_PYTHON", "1")

project = "rotorlab"
author = "rotorlab developers"
copyright = "2026, rotorlab developers"
release = _version("rotorlab")
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "sphinxarg.ext",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "auto_examples/*.ipynb", "auto_examples/*.py", "**.zip"]
# generated pages (autosummary stubs, the gallery) are written into the source tree at build time
templates_path = []

myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3

autosummary_generate = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()

sphinx_gallery_conf = {
    "examples_dirs": "../examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r".*\.py$",  # every example runs (the test suite runs them as well, at the same settings)
    "ignore_pattern": r"(__init__|_common)\.py$",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "abort_on_example_error": True,
}

intersphinx_mapping = {}  # no network at build time: links to other projects are written as plain URLs

html_theme = "pydata_sphinx_theme"
html_title = "rotorlab"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path = []
suppress_warnings = ["myst.header"]
