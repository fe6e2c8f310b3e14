"""The drawing of a command's figures, viewer page and video in worker processes, beside the
command's own work.

Drawing needs matplotlib, 0.3 s to import, and each figure takes 0.1-0.2 s more: on a machine
with two or more processors, :class:`Drawing` forks its workers when the command starts (Linux,
``fork``), so that they import matplotlib while the command simulates or computes, and then
draw while the command reads its results and writes its other files.  Elsewhere (one
processor, another platform) each job runs in the command's own process when it is submitted:
the same files, one after the other.

A job is a module-level function and its arguments, pickled to the worker; what it returns and
the warnings it raised come back (the warnings are raised again in the command, so that they
are shown as the command's own).  A failed job raises its exception in the command at
:meth:`Job.result` (without workers: at :meth:`Drawing.submit`).  On any failure or interrupt,
:meth:`Drawing.cancel` stops the workers and waits for them (:meth:`Drawing.writing` does so
before a staging folder is removed): nothing writes into a folder after the command has removed
it.  The workers are forked with the command's signals blocked, then ignore Ctrl-C and take
SIGTERM's and SIGHUP's default actions (the command stops them itself), and Linux kills them
when the command's process ends, even by SIGKILL.
"""

from __future__ import annotations

import ctypes
import importlib
import multiprocessing
import os
import signal
import sys
import warnings
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, Generic, TypeVar

__all__ = ["Drawing", "Job", "figure_png", "viewer_page", "worker_count"]

T = TypeVar("T")


def worker_count(wanted: int) -> int:
    """How many workers :class:`Drawing` starts for ``wanted`` long jobs: none with one
    processor, or where forking is not the platform's way of starting processes (not Linux);
    else ``wanted``, at most as many as the processors this process may use."""
    if not sys.platform.startswith("linux"):
        return 0
    processors = len(os.sched_getaffinity(0))
    return min(wanted, processors) if processors > 1 else 0


#: ``prctl``'s option that gives a process a signal for when its parent ends (Linux).
PR_SET_PDEATHSIG = 1


#: The signals a command handles (Ctrl-C; SIGTERM and SIGHUP as interrupts): blocked while
#: the workers are forked, until each has set its own dispositions for them.
HANDLED_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


def _start_worker(command: int) -> None:
    """A worker's start: killed when the command's process ``command`` ends, however it ends
    (so that a killed command leaves no worker drawing into its folder); Ctrl-C ignored and the
    termination signals' default actions restored (the command stops its workers itself), then
    those signals let through (one sent meanwhile waited, instead of running the command's
    handler here); the drawing modules imported while the command goes on."""
    ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != command:  # it ended before the request
        os._exit(1)
    for number in HANDLED_SIGNALS:
        signal.signal(number, signal.SIG_IGN if number == signal.SIGINT else signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, HANDLED_SIGNALS)
    for module in ("tensegrity.plots.animation", "tensegrity.plots.viewer"):  # (matplotlib)
        importlib.import_module(module)


def _call(
    fn: Callable[..., T], args: tuple, kwargs: dict[str, Any]
) -> tuple[T, list[tuple[str, type[Warning], str, int]]]:
    """Run a job (in a worker, or in the command without workers); its value and the warnings
    it raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        value = fn(*args, **kwargs)
    return value, [(str(w.message), w.category, w.filename, w.lineno) for w in caught]


class Job(Generic[T]):
    """A submitted job: :meth:`result` waits for it."""

    def __init__(self, wait: Callable[[], tuple[T, list]]) -> None:
        self._wait = wait

    def result(self) -> T:
        """The job's value, once it is done; its exception if it failed.  The warnings it raised
        are raised again here.

        Raises
        ------
        RuntimeError
            The worker ended before the job did (killed, or out of memory).
        """
        try:
            value, caught = self._wait()
        except BrokenProcessPool:
            raise RuntimeError(
                "a drawing worker process ended abruptly (killed, or out of memory?)"
            ) from None
        for message, category, filename, lineno in caught:
            warnings.warn_explicit(message, category, filename, lineno)
        return value


class Drawing:
    """Worker processes that draw while the command goes on; a context manager.

    Parameters
    ----------
    workers : int
        Worker processes to start now (:func:`worker_count`); 0 runs every job in this process
        when it is submitted.

    Attributes
    ----------
    workers : int
        As given.
    """

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._pool: ProcessPoolExecutor | None = None
        if workers > 0:
            blocked = signal.pthread_sigmask(signal.SIG_BLOCK, HANDLED_SIGNALS)
            try:  # (the workers inherit the mask: see _start_worker)
                self._pool = ProcessPoolExecutor(
                    workers,
                    mp_context=multiprocessing.get_context("fork"),
                    initializer=_start_worker,
                    initargs=(os.getpid(),),
                )
                self._pool.submit(int)  # forks the workers now: they import meanwhile
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, blocked)

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Job[T]:
        """Run ``fn(*args, **kwargs)`` in a free worker, in the order submitted (``fn`` a
        module-level function, the arguments picklable); or here and now without workers."""
        if self._pool is None:
            done = _call(fn, args, kwargs)
            return Job(lambda: done)
        return Job(self._pool.submit(_call, fn, args, kwargs).result)

    def writing(self, write: Callable[[Path, Drawing], T]) -> Callable[[Path], T]:
        """``write(folder, self)`` as a writer of one folder (for
        :func:`tensegrity.io.files.write_staged`): on any failure or interrupt the workers are
        stopped before it returns, so none writes into the folder once it is removed."""

        def write_folder(folder: Path) -> T:
            try:
                return write(folder, self)
            except BaseException:
                self.cancel()
                raise

        return write_folder

    def cancel(self) -> None:
        """Stop the workers, their jobs unfinished, and wait until they are gone."""
        if self._pool is not None:
            # (Python 3.14: ProcessPoolExecutor.terminate_workers)
            for process in list(self._pool._processes.values()):
                process.terminate()
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def close(self) -> None:
        """Let the workers finish their jobs and wait until they are gone."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> Drawing:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if kind is None:
            self.close()
        else:
            self.cancel()


# ------------------------------------------------------------------ jobs
def figure_png(maker: str, path: Path, *args: Any, **kwargs: Any) -> list[Path]:
    """Draw ``maker(*args, **kwargs)``, a figure function named ``"report.<name>"``
    (:mod:`tensegrity.plots.report`) or ``"figures.<name>"`` (:mod:`tensegrity.plots.figures`),
    and save it as the PNG file ``path`` (:func:`tensegrity.plots.report.save_figure`).  The
    command names the function instead of passing it, so as not to import matplotlib itself."""
    from tensegrity.plots import figures, report

    module, name = maker.split(".")
    make = getattr({"figures": figures, "report": report}[module], name)
    return [report.save_figure(make(*args, **kwargs), path)]


def viewer_page(source: Any, path: Path) -> list[Path]:
    """The viewer's page of ``source`` (frames, a result or a structure:
    :func:`tensegrity.plots.viewer.view`) at ``path``."""
    from tensegrity.plots.viewer import view

    return [view(source, path)]
