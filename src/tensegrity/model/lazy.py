"""Names a package imports from their modules when first used (PEP 562): the one body of the
``__getattr__`` of the root :mod:`tensegrity` and of :mod:`tensegrity.plots`.

In the lowest layer so that both may import it (the root when a name is first used, not when it
is imported: ``import tensegrity`` loads none of its modules); it imports nothing else.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, MutableMapping
from typing import Any


def imported_name(namespace: MutableMapping[str, Any], origin: Mapping[str, str], name: str) -> Any:
    """``name`` of the package whose globals are ``namespace``, imported from its module
    ``origin[name]`` and kept in ``namespace`` (so that its module's ``__getattr__`` is not asked
    again).

    Raises
    ------
    AttributeError
        If ``origin`` has no module for ``name`` (``from package import name`` then raises
        ``ImportError``).
    """
    module = origin.get(name)
    if module is None:
        raise AttributeError(f"module {namespace['__name__']!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    namespace[name] = value
    return value
