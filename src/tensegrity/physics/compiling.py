"""What every compiled function of the package is compiled with: numba's options
(:data:`JIT_OPTIONS`), :func:`compiled_only` for functions only compiled code calls, and the
columns of ``Model.rod_param`` (``ROD_*``)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, Literal, TypedDict

from numba import njit
from numba.core.registry import CPUDispatcher


class JitOptions(TypedDict):
    """The keyword arguments of ``numba.njit`` used for all the compiled code (typed, so that
    ``njit(**JIT_OPTIONS)`` is checked against numba's signature)."""

    cache: bool
    fastmath: set[str]
    nogil: bool
    boundscheck: bool
    error_model: Literal["python", "numpy"]


#: No fast-math flags (not even ``contract``, fused multiply-adds): a run must be the same bit for
#: bit in every process, and with them the code LLVM makes of a function depends on whether its
#: callees were compiled in this process (and inlined) or loaded from numba's cache (measured:
#: a (3,1) shell's 2 s run took 565 steps freshly compiled and 557 from the cache; a resumed run
#: differed from the uninterrupted one).  They bought no measurable speed (``physics/kernel.py``).
JIT_OPTIONS: JitOptions = {
    "cache": True,
    "fastmath": set(),
    "nogil": True,
    "boundscheck": False,
    "error_model": "numpy",
}


class _CompiledOnly(CPUDispatcher):
    """A dispatcher that compiled code calls and Python may not (see :func:`compiled_only`)."""

    def __call__(self, *args, **kwargs):
        raise TypeError(
            f"{self.py_func.__qualname__} is called from compiled code only (it was compiled "
            "without the wrapper that lets Python call it)"
        )


def compiled_only(py_func: Callable | None = None, *, jit_options: JitOptions = JIT_OPTIONS) -> Any:
    """``njit(**JIT_OPTIONS)`` for a function only ever called from compiled code: numba makes
    no wrapper that lets Python call it (code that unboxes every argument; the tuples of arrays
    of the engine's steps make it long).  On the engine's seven heaviest callees this takes
    1.1 s off the 19.6 s of compilation of a first ``tensegrity simulate`` (CPU time, numba's
    compile events, 4 runs each alternating with the code before: 18.5 s).  Python calling
    such a function gets a TypeError (through the missing wrapper numba would crash the
    interpreter).  ``@compiled_only(jit_options=...)`` compiles with other options."""
    if py_func is None:
        return functools.partial(compiled_only, jit_options=jit_options)
    options: dict[str, Any] = {**jit_options, "no_cpython_wrapper": True, "no_cfunc_wrapper": True}
    dispatcher = njit(**options)(py_func)
    dispatcher.__class__ = _CompiledOnly
    return dispatcher


#: Columns of ``Model.rod_param`` (:mod:`tensegrity.physics.records`).
ROD_MASS, ROD_LENGTH, ROD_DAMPING, ROD_C1, ROD_C2, ROD_RELATIVE_DAMPING = range(6)
