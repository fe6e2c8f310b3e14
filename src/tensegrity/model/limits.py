"""Limits a user may raise through the environment (docs/reliability.md): the size of a
generated structure (``TENSEGRITY_MAX_MEMBERS``), of a sweep (``TENSEGRITY_MAX_CASES``) and of
what a reader takes from a file (``TENSEGRITY_MAX_INPUT_BYTES``, ``TENSEGRITY_MAX_ARRAY_BYTES``).
"""

from __future__ import annotations

import os


def environment_limit(variable: str, default: int, *, unit: str = "a whole number") -> int:
    """The limit named by the environment variable ``variable``: its value if set, else
    ``default``.

    Raises
    ------
    ValueError
        One line naming the variable if it is set to anything but a whole number >= 1
        (``"TENSEGRITY_MAX_CASES: expected a whole number >= 1, got 'lots'"``; ``unit`` names
        what the number counts).
    """
    text = os.environ.get(variable, "").strip()
    if not text:
        return default
    if not text.isdigit() or int(text) < 1:
        raise ValueError(f"{variable}: expected {unit} >= 1, got {text!r}")
    return int(text)
