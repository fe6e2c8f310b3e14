"""Figures (matplotlib): :mod:`~tensegrity.plots.figures` for structures and trajectories,
:mod:`~tensegrity.plots.report` for the analysis verbs' figures.

A run or a structure shown: :func:`view` (:func:`tensegrity.plots.viewer.view`, the viewer's
offline HTML page) and :func:`animate` (:func:`tensegrity.plots.animation.animate`, a video),
imported when first used (they load matplotlib); :func:`show_inline`, the viewer inline in
Jupyter.  The engine and the model sit below this layer and do not import it, so these are
functions of their argument rather than methods of ``SimulationResult`` and ``Structure``.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tensegrity.engine.result import SimulationResult
    from tensegrity.model.structure import Structure
    from tensegrity.plots.animation import animate
    from tensegrity.plots.viewer import view

__all__ = ["animate", "show_inline", "view"]

#: The functions imported when first used -> their module.
_ORIGIN = {"animate": "tensegrity.plots.animation", "view": "tensegrity.plots.viewer"}

#: The classes shown inline, by module and name (IPython's formatters need not import them).
_SHOWN = (
    ("tensegrity.engine.result", "SimulationResult"),
    ("tensegrity.model.structure", "Structure"),
)


def __getattr__(name: str) -> Any:
    """:func:`view` or :func:`animate`, imported from its module when first used."""
    from tensegrity.model.lazy import imported_name

    return imported_name(globals(), _ORIGIN, name)


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


def _inline_html(what: SimulationResult | Structure) -> str:
    from tensegrity.plots.viewer import notebook_html

    return notebook_html(what)


def show_inline(shell: Any = None) -> None:
    """Show a ``SimulationResult`` or a ``Structure`` that is a cell's value as the viewer
    inline (:func:`tensegrity.plots.viewer.notebook_html`, loaded when first shown).

    Registers the page with the HTML display formatter of ``shell`` (an IPython
    ``InteractiveShell``; default: the running one, if any, else nothing is done).  Importing
    :mod:`tensegrity` under IPython (a Jupyter kernel) calls this.
    """
    if shell is None:
        ipython = sys.modules.get("IPython")
        shell = ipython.get_ipython() if ipython is not None else None
        if shell is None:
            return
    formatter = shell.display_formatter.formatters["text/html"]
    for module, name in _SHOWN:
        formatter.for_type_by_name(module, name, _inline_html)
