"""Start states shared by the engine's tests."""

from __future__ import annotations

import numpy as np

from tensegrity.physics import dynamics
from tensegrity.physics.dynamics import State


def perturbed_state(structure, seed: int, jitter: float, speed: float) -> State:
    """The structure's layout moved by ``jitter`` [m] and set moving at about ``speed`` [m/s]
    (normal random numbers from ``seed``), projected onto its constraints."""
    rng = np.random.default_rng(seed)
    start = dynamics.initial_state(structure)
    q, qdot = dynamics.project_to_constraints(
        structure,
        start.q + jitter * rng.standard_normal(start.q.size),
        speed * rng.standard_normal(start.q.size),
    )
    return State(0.0, q, qdot)
