"""Sphinx configuration of the documentation site (``python -m sphinx -W -b html docs
docs/_build/html``; built by ``tests/test_docs.py``).

The pages are the markdown files of this folder (MyST), the tutorials are the scripts of
``examples/`` run by sphinx-gallery, and the API reference is generated from the docstrings
(autosummary, one page per module of :data:`API_PACKAGES`, NumPy-style docstrings through
napoleon).  It needs the docs extra (``pip install '.[docs]'``: Sphinx, MyST, furo,
sphinx-gallery, and what the tutorials run, MuJoCo and Stable-Baselines3; the test extra has
them too).
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path
from typing import Any

os.environ.setdefault("MPLBACKEND", "Agg")
# (the sweep tutorial's Dask cluster would print its start-up and shut-down lines into the
# build's output: Dask reads its logging levels from the environment when first imported)
os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "warning")
sys.path.insert(0, str(Path(__file__).parent / "_ext"))  # (the gallery's figure scraper)

project = "tensegrity"
author = "The tensegrity developers"
copyright = "The tensegrity developers (MIT licence)"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_templates", "_ext", "images", "tutorials/*.ipynb", "tutorials/*.py"]
templates_path = ["_templates"]
html_theme = "furo"
html_title = "tensegrity"
myst_heading_anchors = 3

# API reference: every public name of the library's packages (the command line has its own page)
autosummary_generate = True
autosummary_ignore_module_all = False
autodoc_typehints = "none"
autodoc_member_order = "bysource"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_ivar = True
napoleon_use_param = False
napoleon_use_rtype = False

sphinx_gallery_conf = {
    "examples_dirs": "../examples",
    "gallery_dirs": "tutorials",
    "filename_pattern": r"/tutorial_",  # the tutorials run; the longer scripts are shown
    "ignore_pattern": r"(train_six_bar|rolling_six_bar)\.py$",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "run_stale_examples": True,  # (every build runs every tutorial: a broken one fails it)
    "image_scrapers": ("matplotlib", "gallery_figures.figure_scraper"),
}

#: A NumPy-style field line, ``name : (N, 3) array``: its name and its type.
_FIELD = re.compile(r"^(\s*[\w*][^:]*? : )(.+)$")
#: A shape in a field's name, ``(N, 3)``.
_SHAPE = re.compile(r"(?<!`)\(([^()`]*)\)(?!`)")
#: Inline literals and roles, left as they are in a type.
_MARKUP = re.compile(r"(``.*?``|:[\w:]+:`[^`]*`)")


def _literal(text: str) -> str:
    """``text`` with every run outside literals and roles made a literal."""
    parts = _MARKUP.split(text)
    for k in range(0, len(parts), 2):  # (the runs between the markup)
        run = parts[k]
        if run.strip():
            core = run.strip()
            lead, tail = run[: len(run) - len(run.lstrip())], run[len(run.rstrip()) :]
            lead = lead or ("\\ " if k > 0 else "")  # (an escaped space parts two literals)
            tail = tail or ("\\ " if k < len(parts) - 1 else "")
            parts[k] = f"{lead}``{core}``{tail}"
    return "".join(parts)


def _literal_types(
    app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]
) -> None:
    """The types of NumPy-style fields (``node_position : (N, 3) array``) kept as literals:
    napoleon makes each word of a type a link, and ``N`` would link to whichever field called
    ``N`` Sphinx finds (the package's one-line fields, ``name : what it is``, too)."""
    for i, line in enumerate(lines):
        match = _FIELD.match(line)
        if match:  # (shapes in the name, ``a (N,), b (S,) : ...``, go to the type)
            name, kind = match.group(1), match.group(2)
            shapes = [f"({shape})" for shape in _SHAPE.findall(name)]
            indent = name[: len(name) - len(name.lstrip())]
            name = indent + re.sub(
                r"\s+,", ",", re.sub(r" {2,}", " ", _SHAPE.sub("", name.lstrip()))
            )
            if shapes:
                kind = ", ".join(shapes) + "; " + kind
            lines[i] = name + _literal(kind)


#: The first line of a record field's comment, ``(3, F) float64: anchor positions [m]``: the
#: shape or type before the colon, and the text.
_TYPED_COMMENT = re.compile(r"^(\([^()]*\)[\w ,.|\[\]]*?|[\w.|\[\]]{1,30}): (.+)$")


def _literal_inline_type(
    app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]
) -> None:
    """A field's, property's or constant's comment ``(3, F) float64: anchor positions [m]``
    with its type as a literal: napoleon reads the part of the first line before a colon as the
    type, and makes each word of a plain type a link (``F`` to whichever field of that name
    Sphinx finds).  A first line with a colon that is not after a type starts after an empty
    comment instead, which napoleon takes for the type line."""
    if what in ("attribute", "property", "data") and lines:
        match = _TYPED_COMMENT.match(lines[0])
        if match and "`" not in match.group(1):
            lines[0] = f"``{match.group(1)}``: {match.group(2)}"
        elif re.search(r"(?<!:):(?!:)", _MARKUP.sub("", lines[0])):
            lines[:0] = ["..", ""]


def setup(app: Any) -> None:
    app.connect("autodoc-process-docstring", _literal_inline_type, priority=400)
    app.connect("autodoc-process-docstring", _literal_types, priority=400)
