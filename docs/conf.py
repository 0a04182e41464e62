"""Sphinx configuration of the allsky documentation site.

Build (offline, warnings as errors, every cross-reference and internal link
checked)::

    pip install '.[docs]' && sphinx-build -W -n -b html docs docs/_build/html

The pages are the Markdown documents of this folder (MyST), the API
reference generated from the docstrings (autodoc + numpydoc), and the
tutorials, notebooks executed during the build (myst-nb). Each tutorial
writes the replay page of its mission into the site (``replays/``).
"""

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

# The per-frame blocks are compiled (allsky.jit): a module holds a wrapper or numba's
# dispatcher where autodoc looks for a function. NUMBA_DISABLE_JIT=1 turns them back into
# the plain Python functions they are, in this process only: the tutorials' kernels, which
# inherit the environment, fly compiled.
os.environ["NUMBA_DISABLE_JIT"] = "1"
import allsky
from allsky import jit

jit.load_numba()
del os.environ["NUMBA_DISABLE_JIT"]

project = "allsky"
author = "the allsky authors"
copyright = "the allsky authors, MIT licence"
version = release = allsky.__version__

extensions = [
    "myst_nb",  # Markdown pages (MyST) and notebooks, executed at build
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "api_reference",  # docs/_ext: compiled blocks, constants, references by Python's rules
    "site_links",  # docs/_ext: every internal link of the built site resolves
]
root_doc = "index"
exclude_patterns = ["_build", "**.ipynb_checkpoints", "examples", "README.md"]
templates_path = ["_templates"]

# -- every reference checked, offline ------------------------------------------------
# Nitpicky: a cross-reference to an object the reference does not document is an error.
# Other projects' objects (NumPy, pandas, ...) would need their inventories, which the
# build does not fetch (it runs offline); they are named, not linked.
nitpicky = True
EXTERNAL = ("numpy", "np", "pandas", "pd", "matplotlib", "scipy", "control", "tqdm", "dask",
            "distributed", "pyarrow", "numba", "ephem", "os", "pathlib", "typing",
            "collections", "concurrent", "datetime", "argparse", "enum", "IPython", "tomllib",
            "importlib", "json", "threading", "signal", "types", "functools", "inspect")
nitpick_ignore_regex = [(r"py:.*", rf"({'|'.join(EXTERNAL)})(\..*)?")]
nitpick_ignore = [("py:class", name) for name in (
    "str", "int", "float", "bool", "dict", "list", "tuple", "set", "object", "callable",
    "bytes", "type", "Exception", "ValueError", "KeyError", "TypeError", "OSError",
    "RuntimeError", "ImportError", "KeyboardInterrupt", "UserWarning", "NamedTuple",
    "path-like", "optional")]

# -- the API reference ----------------------------------------------------------------
autosummary_generate = True  # the module pages, into api/generated/ (not committed)
autosummary_imported_members = False
autodoc_typehints = "none"  # types are in the numpydoc sections, as NumPy's reference does
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "undoc-members": True, "show-inheritance": True}
# Many docstrings name their parameters in prose (``name`` in backticks) rather than in a
# Parameters section; numpydoc renders them as written and validates nothing, so they
# build. The public API (allsky.fly, Flight, compare, montecarlo) has full sections.
numpydoc_show_class_members = False  # autodoc documents the members; no second table
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False  # types as text: they name other projects' classes too
numpydoc_validation_checks = set()

# -- Markdown and notebooks -------------------------------------------------------------
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]
nb_execution_mode = "force"  # the tutorials run at every build
nb_execution_timeout = 900
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_output_stderr = "warn"  # anything a tutorial prints on stderr (a warning) fails -W
nb_ipywidgets_js = {}  # no widget scripts from a CDN: the site makes no network request
nb_merge_streams = True

# -- HTML -----------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"allsky {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 3,
    # The tutorials' replays and tables get the page's whole width (names after the
    # pattern: the last match wins).
    "secondary_sidebar_items": {"**": ["page-toc"], **{
        f"tutorials/{name}": [] for name in ("first_mission", "calibration_comparison",
                                             "faults_and_campaigns")}},
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_show_sourcelink = False
# Search: the public names (allsky.fly, allsky.Flight ...) before the modules' own pages.
html_search_scorer = str(DOCS / "_ext" / "search_scorer.js")
html_copy_source = False


def _replays_into_site(app):
    """Give the tutorials the folder of the site their replay pages go to."""
    folder = Path(app.outdir) / "replays"
    folder.mkdir(parents=True, exist_ok=True)
    os.environ["ALLSKY_SITE_REPLAYS"] = str(folder)


def setup(app):
    """Connect the replay folder to the build."""
    app.connect("builder-inited", _replays_into_site)
