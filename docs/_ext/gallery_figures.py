"""sphinx-gallery's image scraper for the package's figures: they are matplotlib ``Figure``
objects made without pyplot (``tensegrity.plots.figures.new_figure``), which sphinx-gallery's
own matplotlib scraper does not see.  Each ``Figure`` a tutorial's block leaves in its
variables is shown once, after the block that made it."""

from __future__ import annotations

import weakref
from typing import Any

from matplotlib.figure import Figure
from sphinx_gallery.scrapers import figure_rst

#: The figures already shown, by tutorial (source file).
_SHOWN: dict[str, weakref.WeakSet[Figure]] = {}


def figure_scraper(block: Any, block_vars: dict[str, Any], gallery_conf: dict[str, Any]) -> str:
    """The reST showing the new ``Figure`` objects among the tutorial's variables."""
    shown = _SHOWN.setdefault(str(block_vars["src_file"]), weakref.WeakSet())
    paths = []
    for value in list(block_vars["example_globals"].values()):
        if isinstance(value, Figure) and value not in shown:
            shown.add(value)
            path = next(block_vars["image_path_iterator"])
            value.savefig(path, dpi=90)
            paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])
