"""Sphinx configuration of the parastokes site; its front page is docs/index.md.

Build (docs/documentation.md): ``pip install ".[docs]"``, then from the repository root
``python -m sphinx -W --keep-going -b html docs docs/_build/html``. Add ``-D plot_gallery=0`` to
build the gallery's pages without running its scripts (no figures).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

from parastokes import __version__  # noqa: E402

# the solvers' progress lines (INFO) would fill the gallery's build log
logging.getLogger("parastokes").setLevel(logging.WARNING)

project = "parastokes"
author = "the parastokes developers"
copyright = "the parastokes developers"
release = version = __version__

extensions = [
    "myst_parser",  # the Markdown pages
    "sphinx.ext.autodoc",  # the API reference from the docstrings ...
    "sphinx.ext.autosummary",  # ... one page per module, generated (api/index.rst)
    "sphinx.ext.napoleon",  # the docstrings' "Parameters" (NumPy) and "Args:" (Google) sections
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",  # the source of every documented object
    "sphinxarg.ext",  # the command line from its argument parser (cli.md)
    "sphinx_gallery.gen_gallery",  # the gallery (gallery/*.py, run at build time)
    "apiref",  # _ext/apiref.py: public names linked to their home, sibling references
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "gallery/GALLERY_HEADER.rst", "auto_gallery/*.ipynb",
                    "auto_gallery/*.py", "auto_gallery/*.zip"]
templates_path = ["_templates"]

# MyST: anchors for the headings (links such as validation.md#rigid-bodies-resistance-and-mobility)
myst_heading_anchors = 4

# The API reference: every module of the package, found by walking it (new modules appear by
# themselves); each object documented in the module that defines it (_templates/autosummary).
autosummary_generate = True
autodoc_member_order = "bysource"
autodoc_typehints = "description"

sphinx_gallery_conf = {
    "examples_dirs": "gallery",
    "gallery_dirs": "auto_gallery",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "capture_repr": (),
    "reference_url": {"parastokes": None},  # names in the code link to the API reference
    "show_signature": False,
}

html_theme = "furo"
html_title = f"parastokes {release}"
html_static_path: list[str] = []

#: Links from a page to a file outside docs/ that the site shows as a page of its own (the same
#: link works on the repository's Markdown view).
OUTSIDE_PAGES = {"../experiments/README.md": "experiments.md"}


def _outside_links(app, docname: str, source: list[str]) -> None:
    for target, page in OUTSIDE_PAGES.items():
        source[0] = source[0].replace(f"]({target})", f"]({page})")


def setup(app) -> None:
    app.connect("source-read", _outside_links)
