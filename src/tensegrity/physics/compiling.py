"""What every compiled function of the package is compiled with: numba's options
(:data:`JIT_OPTIONS`), :func:`compiled_only` for functions only compiled code calls, the
columns of ``Model.rod_param`` (``ROD_*``), and the check that numba's cache of the package is
not stale (:func:`refresh_stale_cache`, run when this module is imported)."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, TypedDict

from numba import njit
from numba.core import caching
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


#: The folders of the package that hold compiled code (and their numba caches).
COMPILED_FOLDERS = ("physics", "engine")

#: The folders whose sources the compiled code depends on: those, and the model's constants
#: (e.g. the contact modes of ``model/ground.py``) that compiled code freezes.
STAMPED_FOLDERS = ("model", *COMPILED_FOLDERS)

#: The file, in each folder's numba cache directory, naming the compiled sources its cache
#: files were made from (:func:`sources_stamp`).
STAMP_FILE = "tensegrity-sources.stamp"


def sources_stamp(package: Path) -> str:
    """A digest of the compiled sources of ``package`` (the ``tensegrity`` folder): the
    relative path and content of every ``.py`` file of :data:`STAMPED_FOLDERS` (about 0.7 MB,
    2 ms)."""
    digest = hashlib.sha256()
    for folder in STAMPED_FOLDERS:
        for path in sorted((package / folder).glob("*.py")):
            digest.update(f"{folder}/{path.name}\n".encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def cache_folder(source: Path) -> Path | None:
    """numba's cache directory for the functions of the module file ``source``, as numba picks
    it (``NUMBA_CACHE_DIR``, else the module's ``__pycache__`` if writable, else the user-wide
    cache); None if none is writable (numba then caches nothing)."""
    locators = (
        caching.UserProvidedCacheLocator,
        caching.InTreeCacheLocator,
        caching.UserWideCacheLocator,
    )
    for locator in locators:
        found = locator.from_function(sources_stamp, str(source))
        if found is not None:
            return Path(found.get_cache_path())
    return None


def refresh_stale_cache(package: Path | None = None) -> int:
    """Delete numba's cache files of the package's compiled code if its sources changed since
    they were written, and return how many were deleted.

    numba checks a cached function against its own source file only: a changed callee in
    another file (an edit, or a new version of the package that left the caller's file as it
    was) would otherwise run from a stale cache, silently.  Each cache directory of
    :data:`COMPILED_FOLDERS` keeps a :data:`STAMP_FILE` with the :func:`sources_stamp` of the
    sources its files were made from; when it differs (or is missing), the folder's cache files
    (``<module>.*.nbi`` and ``.nbc``) are deleted and the stamp rewritten, so that numba compiles
    afresh.  A directory that cannot be written is left to numba.  ``package``: default this
    package's folder.

    Left open: a process still running the old sources that compiles after another has written
    the new stamp leaves cache files of the old sources under it (an edit or upgrade while a
    long run is going), and they stay in use until the sources change again (then delete the
    cache by hand)."""
    package = Path(__file__).resolve().parents[1] if package is None else package
    stamp = sources_stamp(package)
    deleted = 0
    for folder in COMPILED_FOLDERS:
        modules = sorted((package / folder).glob("*.py"))
        where = cache_folder(modules[0]) if modules else None
        if where is None:
            continue
        marker = where / STAMP_FILE
        with contextlib.suppress(OSError):
            if marker.read_text() == stamp:
                continue
        stems = {path.stem for path in modules}
        with contextlib.suppress(OSError):
            for cached in where.iterdir():
                if cached.suffix in (".nbi", ".nbc") and cached.name.split(".")[0] in stems:
                    with contextlib.suppress(FileNotFoundError):
                        cached.unlink()
                        deleted += 1
            partial = marker.with_name(f"{STAMP_FILE}.{os.getpid()}")
            partial.write_text(stamp)
            partial.replace(marker)
    return deleted


refresh_stale_cache()
