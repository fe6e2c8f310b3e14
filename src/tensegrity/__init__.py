"""tensegrity: nonlinear dynamics of tensegrity structures.

Rigid rods and elastic tendons, modelled with the explicit end-point formulation of Skelton,
Pinaud and Mingori ("The Dynamics of the Class 1 Shell Tensegrity Structure", Theorem 18.1).

The names below are imported when first used (PEP 562), so that ``import tensegrity`` and the
command line load no more of the package, SciPy or NumPy than they need.  In Jupyter (IPython
running when the package is imported) a result or a structure shows the viewer inline
(:func:`tensegrity.plots.show_inline`).
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
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

#: Each name the package re-exports -> the module that defines it.
_ORIGIN = {
    "SimulationResult": "tensegrity.engine.simulate",
    "simulate": "tensegrity.engine.simulate",
    "class1_shell": "tensegrity.model.shell",
    "Structure": "tensegrity.model.structure",
    **dict.fromkeys(
        (
            "State",
            "accelerations",
            "artificial_damping",
            "elastic_energy",
            "initial_state",
            "internal_damping",
            "kinetic_energy",
            "nodes_from_coordinates",
            "tendon_lengths",
            "tendon_tensions",
            "undamped",
        ),
        "tensegrity.physics.dynamics",
    ),
}

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


def __getattr__(name: str) -> Any:
    """A re-exported name, imported from its module when first used (then kept here)."""
    from tensegrity.model.lazy import imported_name

    return imported_name(globals(), _ORIGIN, name)


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


if "IPython" in sys.modules:  # a notebook or an IPython shell (never imported here otherwise)
    from tensegrity.plots import show_inline

    show_inline()
