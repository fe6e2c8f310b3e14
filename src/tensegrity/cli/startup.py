"""What a command says about its own start: the time since its process started (the time to
result the user waited, :func:`seconds_since_start`) and, once, that the engine is being
compiled (:func:`announce_compiling`).

The engine's compiled code (numba, ``cache=True``) is cached on disk; a process that finds no
cached copy of a function it calls (a new machine, a new version, an empty
``NUMBA_CACHE_DIR``) compiles it first, which takes tens of seconds (measured in
``benchmarks/README.md``, "The first run").  numba reports each compilation (a cache miss
only) as a ``numba:compile`` event; :func:`announce_compiling` prints one line at the first of
them, so a run that loads everything from the cache prints nothing.
"""

from __future__ import annotations

import os
import sys
import time

#: ``time.perf_counter()`` when this module was imported: the start of the clock where the
#: process's own start time cannot be read.
_IMPORTED = time.perf_counter()
#: :func:`announce_compiling`'s numba event listener, once registered.
_announcer: object | None = None

#: The line :func:`announce_compiling` prints (on stderr) before the first compilation.  The
#: span: `benchmarks/README.md`'s 18.9 s (an idle 2-core machine) to 59 s (the same machine, busy).
#: The engine is compiled for each kind of run it meets (ground contact, a controller, fixed
#: steps, force tables...: each a specialization of its own), so a new kind says it again.
COMPILING_MESSAGE = (
    "tensegrity: compiling the engine for this kind of run (about 20-60 s, once per machine "
    "and kind of run; later runs of the kind load it from the cache)"
)


def seconds_since_start() -> float:
    """Wall-clock time since this process started [s].

    On Linux the process's start time from ``/proc/self/stat`` (clock ticks since boot, 10 ms)
    against ``CLOCK_BOOTTIME``; elsewhere, or if that is unreadable or earlier than this module's
    import, the time since this module was imported (which misses the interpreter's start and
    the imports before it).
    """
    imported = time.perf_counter() - _IMPORTED
    try:
        with open("/proc/self/stat", encoding="ascii") as file:
            fields = file.read().rsplit(")", 1)[1].split()
        started = int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22, starttime
        since = time.clock_gettime(time.CLOCK_BOOTTIME) - started
    except (OSError, ValueError, IndexError, AttributeError):
        return imported
    return since if since >= imported else imported


def announce_compiling() -> None:
    """Print :data:`COMPILING_MESSAGE` on stderr at the first compilation of numba code in this
    process from now on (none if everything the command calls is in the cache); once per process,
    however often called."""
    global _announcer
    if _announcer is not None:
        return
    from numba.core import event

    class Announcer(event.Listener):
        def __init__(self) -> None:
            self.said = False

        def on_start(self, ev: event.Event) -> None:
            if not self.said:
                self.said = True
                print(COMPILING_MESSAGE, file=sys.stderr, flush=True)

        def on_end(self, ev: event.Event) -> None:
            pass

    _announcer = Announcer()
    event.register("numba:compile", _announcer)
