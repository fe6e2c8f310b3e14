"""tensegrity: nonlinear dynamics of tensegrity structures.

Rigid rods and elastic tendons, modelled with the explicit end-point formulation of Skelton,
Pinaud and Mingori ("The Dynamics of the Class 1 Shell Tensegrity Structure", Theorem 18.1).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from tensegrity.engine.simulate import SimulationResult, simulate
from tensegrity.model.shell import class1_shell
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import (
    State,
    accelerations,
    artificial_damping,
    elastic_energy,
    initial_state,
    internal_damping,
    kinetic_energy,
    nodes_from_coordinates,
    tendon_lengths,
    tendon_tensions,
    undamped,
)

__all__ = [
    "SimulationResult",
    "State",
    "Structure",
    "accelerations",
    "artificial_damping",
    "class1_shell",
    "elastic_energy",
    "initial_state",
    "internal_damping",
    "kinetic_energy",
    "nodes_from_coordinates",
    "simulate",
    "tendon_lengths",
    "tendon_tensions",
    "undamped",
]
__version__ = "0.1.0"

if TYPE_CHECKING:
    from tensegrity.io.files import PathLike


# ----------------------------------------------------------------------------- showing a run
# The engine and the model sit below the plots layer and do not import it
# (docs/architecture.md), so the methods that show a result or a structure are attached here,
# at the package's root; matplotlib and the viewer's page are loaded when one is called.
def _animate(self: SimulationResult, path: PathLike, **options: Any) -> Path:
    """Write an animation of the run to ``path`` (``.mp4``, ``.webm`` or ``.gif``), atomically
    (:func:`tensegrity.plots.animation.animate`, whose keyword options it takes)."""
    from tensegrity.plots.animation import animate

    return animate(self, path, **options)


def _view(self: SimulationResult | Structure, path: PathLike, **options: Any) -> Path:
    """Write the interactive viewer page (one offline HTML file) to ``path``, atomically
    (:func:`tensegrity.plots.viewer.view`, whose keyword options it takes)."""
    from tensegrity.plots.viewer import view

    return view(self, path, **options)


def _repr_html_(self: SimulationResult | Structure) -> str:
    """The viewer inline in Jupyter (:func:`tensegrity.plots.viewer.notebook_html`)."""
    from tensegrity.plots.viewer import notebook_html

    return notebook_html(self)


SimulationResult.animate = _animate  # type: ignore[attr-defined]
SimulationResult.view = _view  # type: ignore[attr-defined]
SimulationResult._repr_html_ = _repr_html_  # type: ignore[attr-defined]
Structure.view = _view  # type: ignore[attr-defined]
Structure._repr_html_ = _repr_html_  # type: ignore[attr-defined]
