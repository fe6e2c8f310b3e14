"""tensegrity: nonlinear dynamics of tensegrity structures.

Rigid rods and elastic tendons, modelled with the explicit end-point formulation of Skelton,
Pinaud and Mingori ("The Dynamics of the Class 1 Shell Tensegrity Structure", Theorem 18.1).
"""

from tensegrity.engine.simulate import SimulationResult, simulate
from tensegrity.model.shell import class1_shell
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import (
    State,
    accelerations,
    critical_damping,
    elastic_energy,
    initial_state,
    kinetic_energy,
    nodes_from_coordinates,
    tendon_lengths,
    tendon_tensions,
)

__all__ = [
    "SimulationResult",
    "State",
    "Structure",
    "accelerations",
    "class1_shell",
    "critical_damping",
    "elastic_energy",
    "initial_state",
    "kinetic_energy",
    "nodes_from_coordinates",
    "simulate",
    "tendon_lengths",
    "tendon_tensions",
]
__version__ = "0.1.0"
