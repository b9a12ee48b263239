"""Sphinx configuration of the pacam_render documentation (``make docs``).

The API and CLI reference pages are written at build time from the code itself
(:mod:`docs._generate`): one page per public name of ``pacam_render.__all__`` and of every
subpackage's ``__all__``, and one page per ``pacam`` command from the real argparse parser
(``pacam_render.cli.build_parser``). The build runs with warnings as errors and nitpicky
cross-references (``make docs``: ``sphinx-build -W --keep-going -n``).
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import _generate  # noqa: E402

import pacam_render  # noqa: E402

project = "pacam_render"
author = "the pacam_render authors"
copyright = "2026, the pacam_render authors"
release = pacam_render.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinxarg.ext",
    "sphinx_design",
    "myst_nb",  # Markdown pages (myst-parser) and the executed tutorial notebook
]

# Pages: Markdown (MyST) and notebooks; generated API/CLI pages are reStructuredText.
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
exclude_patterns = [
    "_build",
    "validate/scenes/summary.md",  # the table of validate_scene.md, as run.sh writes it
    "**/.partial",
    "**/.renders",
    "Thumbs.db",
    ".DS_Store",
]

# The tutorial is rendered from the outputs stored in it: the test suite executes it
# (tests/test_tutorial.py), the docs build never does.
nb_execution_mode = "off"
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]  # generated reports start at ### under a ## page

# Warnings are errors (-W), references are checked (-n). Types in signatures are left out: the
# numpydoc Parameters sections state them with their units.
nitpicky = True
autodoc_typehints = "none"
autodoc_member_order = "bysource"
autosummary_generate = True
autosummary_imported_members = False
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()
nitpick_ignore_regex = [
    # names of other projects (numpy, Mitsuba, Dask ...) and of the standard library: no
    # intersphinx here (the build reaches no network)
    ("py:.*", r"(np|numpy|mi|mitsuba|dr|drjit|dask|distributed|scipy|pathlib|typing)\..*"),
    ("py:.*", r"(Path|ndarray|Any|Callable|Iterable|Iterator|Sequence|Mapping|Client)"),
    ("py:.*", r"(int|float|str|bool|dict|list|tuple|None|object|type|bytes|complex)"),
]

html_theme = "pydata_sphinx_theme"
html_title = f"pacam_render {release}"
html_static_path: list[str] = []
templates_path = ["_templates"]
html_theme_options = {
    "navigation_depth": 3,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_show_sourcelink = False
html_last_updated_fmt = None


# Written before Sphinx reads any source (autosummary then writes one page per name).
_generate.write_reference_pages()

# A summary is a docstring's first sentence: "(Eq. 13)" and "Sec. 4" do not end one (the
# tables showed "phi (Eq.").
import sphinx.ext.autosummary as _autosummary  # noqa: E402

_autosummary.WELL_KNOWN_ABBREVIATIONS = (
    *_autosummary.WELL_KNOWN_ABBREVIATIONS, "Eq.", "Eqs.", "Sec.", "Fig.", "Figs.", "cf."
)


def setup(app):
    app.connect("autodoc-process-docstring", _generate.constant_docs)
    app.connect("autodoc-process-docstring", _generate.escape_bars)
    app.connect("missing-reference", _generate.resolve_reference)
