"""Small structures shared by the design tests."""

from __future__ import annotations

from typing import Any

from tensegrity.model.structure import Structure


def crane(**changes: Any) -> Structure:
    """Statically determinate: a 1 m rod from a pin (node 0) along x, its head (node 1) held by
    two tendons to anchors at (0, +-1, 1) (nodes 2, 3); ``changes`` replace its fields."""
    fields: dict[str, Any] = dict(
        node_position=[[0, 0, 0], [1, 0, 0], [0, 1, 1], [0, -1, 1]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        tendon_nodes=[[1, 2], [1, 3]],
        tendon_stiffness=[1.0, 1.0],
        tendon_rest_length=[1.0, 1.0],
        node_fixed=[True, False, True, True],
    )
    return Structure(**(fields | changes))
