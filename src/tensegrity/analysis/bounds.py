"""The bounds of shape control (:class:`Bounds`), in a module of its own so that the command
line's options take their defaults from it without loading the analysis (SciPy, the engine)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from tensegrity.model.structure import Structure


@dataclasses.dataclass(frozen=True)
class Bounds:
    """Limits on the control: ``Lbar = L0 - u >= min_rest_length`` [m], ``|u| <= max_change``
    [m], and every tendon's tension ``>= min_tension`` [N] (taut, with a margin)."""

    min_rest_length: float = 0.05
    max_change: float = 0.25
    min_tension: float = 1.0

    def u_limits(self, structure: Structure) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` for ``u`` (S,)."""
        high = np.minimum(self.max_change, structure.tendon_rest_length - self.min_rest_length)
        return np.full(structure.n_tendons, -self.max_change), high
