"""Sphinx configuration of the snake_pin documentation.

Build (from the repository root; warnings are errors, the gallery runs)::

    python3 -m sphinx -W --keep-going -b html docs docs/_build/html

Everything is local: no intersphinx mappings, nothing fetched at build time. A build
writes generated pages into this folder (``api/generated``, ``auto_examples``, emptied at
its start), so two builds of one checkout must not run at once; ``tests/test_docs.py``
builds a copy of the sources.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")
# one thread per BLAS/OpenMP pool: the examples do tiny-matrix work on a shared machine
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import snake_pin  # noqa: E402

project = "snake_pin"
author = "The snake_pin authors"
copyright = "The snake_pin authors, BSD-3-Clause"
release = snake_pin.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "matplotlib.sphinxext.plot_directive",
    "snake_pin_docs",
]

templates_path = ["_templates"]
exclude_patterns = ["_build", "api/generated/*.rst.new", "auto_examples/*.ipynb",
                    "auto_examples/*.py", "auto_examples/*.zip", "auto_examples/*.json",
                    "auto_examples/*.md5", "sg_execution_times.rst"]
root_doc = "index"
nitpicky = False
default_role = "py:obj"

# --------------------------------------------------------------------- API reference
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"           # numpydoc's Parameters sections carry the types
autodoc_class_signature = "mixed"
autodoc_preserve_defaults = True
numpydoc_show_class_members = False  # members are documented in full on the module page
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()  # issue 16 item 3 owns docstring validation

# --------------------------------------------------------------------------- gallery
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"\.py$",            # run every example
    "ignore_pattern": r"__init__\.py",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": True,
    "remove_config_comments": True,
    "min_reported_time": 1,
    "abort_on_example_error": False,        # report every broken example, then fail
    "only_warn_on_example_error": False,
    "reset_modules": ("matplotlib",),
    "image_scrapers": ("matplotlib",),
    "backreferences_dir": None,
    "show_memory": False,
    "plot_gallery": "True",
    "run_stale_examples": True,             # every build runs every example
}

# --------------------------------------------------------------------------- figures
plot_include_source = False
plot_html_show_source_link = False
plot_html_show_formats = False
plot_formats = [("png", 110)]

# ---------------------------------------------------------------------------- HTML
html_theme = "pydata_sphinx_theme"
html_title = f"snake_pin {release}"
html_static_path = ["_static"]
html_css_files = ["snake_pin.css"]
html_show_sourcelink = False
html_theme_options = {
    "navbar_align": "left",
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "secondary_sidebar_items": ["page-toc"],
}
html_sidebars: dict[str, list[str]] = {"index": [], "installation": [], "errata": [],
                                       "equations": [], "cli": []}


#: Folders generated from the code at every build, emptied first so that nothing stale
#: (a removed module's page, a removed example's page) survives into a build.
GENERATED = (DOCS / "api" / "generated", DOCS / "auto_examples")


def _clean_generated(app: Any) -> None:
    for folder in GENERATED:
        shutil.rmtree(folder, ignore_errors=True)


def setup(app: Any) -> None:
    """Empty the generated folders before autosummary and sphinx-gallery fill them."""
    app.connect("builder-inited", _clean_generated, priority=100)
