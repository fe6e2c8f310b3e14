"""The drawing of a command's figures, viewer page and video in worker processes, beside the
command's own work.

Drawing needs matplotlib, 0.3 s to import, and each figure takes 0.1-0.2 s more: on a machine
with two or more processors, :class:`Drawing` forks its first worker when the command starts
(Linux, ``fork``); it imports matplotlib while the command simulates or computes, then forks
the other workers, which so have it without importing it again (a second import competed with
the command for the processors: the default ``simulate`` took 1.63 s against 1.50 s, paired).
The workers draw while the command reads its results and writes its other files.  Elsewhere
(one processor, another platform) each job runs in the command's own process when it is
submitted: the same files, one after the other.

A job is a module-level function and its arguments, pickled to a free worker in the order
submitted; what it returns and the warnings it raised come back (the warnings are raised again
in the command, so that they are shown as the command's own).  A failed job raises its
exception in the command at :meth:`Job.result` (without workers: at :meth:`Drawing.submit`).
On any failure or interrupt, :meth:`Drawing.cancel` stops the workers and waits until each is
gone (:meth:`Drawing.writing` does so before a staging folder is removed): nothing writes into
a folder after the command has removed it.  The first worker is forked with the command's
signals blocked, then ignores Ctrl-C and takes SIGTERM's and SIGHUP's default actions (the
command stops it itself), and the others inherit that; Linux kills the first worker when the
command's process ends, even by SIGKILL, and the others when the first ends.
"""

from __future__ import annotations

import collections
import ctypes
import importlib
import itertools
import multiprocessing
import os
import signal
import sys
import traceback
import warnings
from collections.abc import Callable
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Generic, TypeVar, cast

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


def _end_with_parent(parent: int) -> None:
    """Ask Linux to kill this process when its parent, ``parent``, ends, however it ends (so
    that a killed command leaves no worker drawing into its folder); end now if it already
    has."""
    ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # it ended before the request
        os._exit(1)


def _first_worker(command: int, ends: list[Connection], theirs: list[Connection]) -> None:
    """The first worker: ended with the command's process ``command``; Ctrl-C ignored and the
    termination signals' default actions restored (the command stops its workers itself),
    then those signals let through (one sent meanwhile waited, instead of running the
    command's handler here); the drawing modules imported while the command goes on; then the
    other workers forked, one for each of ``ends[1:]`` (each ended with this one), and the
    jobs of ``ends[0]`` served until the command closes it.  ``theirs`` are the command's
    ends of the pipes, closed here (else the workers would not see the command close them)."""
    _end_with_parent(command)
    for end in theirs:
        end.close()
    for number in HANDLED_SIGNALS:
        signal.signal(number, signal.SIG_IGN if number == signal.SIGINT else signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, HANDLED_SIGNALS)
    for module in ("tensegrity.plots.animation", "tensegrity.plots.viewer"):  # (matplotlib)
        importlib.import_module(module)
    first, others = os.getpid(), []
    for end in ends[1:]:
        pid = os.fork()
        if pid == 0:  # another worker: it never returns here, whatever happens
            try:
                _end_with_parent(first)
                for other in ends:
                    if other is not end:
                        other.close()
                _serve(end)
            finally:
                os._exit(0)
        others.append(pid)
        end.close()
    _serve(ends[0])
    for pid in others:
        os.waitpid(pid, 0)


def _serve(end: Connection) -> None:
    """A worker's loop: run each job the command sends on ``end`` and send back its outcome,
    until the command closes its end."""
    while True:
        try:
            fn, args, kwargs = end.recv()
        except EOFError:
            return
        try:
            outcome: tuple = (True, _call(fn, args, kwargs))
        except Exception as exc:  # noqa: BLE001 - any: the command raises it again
            outcome = (False, exc, traceback.format_exc())
        try:
            end.send(outcome)
        except Exception as exc:  # noqa: BLE001 - an outcome that does not pickle, whatever says so
            end.send((False, RuntimeError(f"a drawing job's outcome: {exc}"), ""))


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
            A worker ended before its job did (killed, or out of memory).
        """
        value, caught = self._wait()
        for message, category, filename, lineno in caught:
            warnings.warn_explicit(message, category, filename, lineno)
        return value


class Drawing:
    """Worker processes that draw while the command goes on; a context manager.

    Parameters
    ----------
    workers : int
        Worker processes to start (:func:`worker_count`): the first now, the others forked by
        it once it has imported the drawing modules; 0 runs every job in this process when it
        is submitted.

    Attributes
    ----------
    workers : int
        As given.
    """

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._first: Any = None  # the first worker (a multiprocessing.Process)
        self._idle: list[Connection] = []  # this end of each free worker's pipe, first first
        self._running: dict[Connection, int] = {}  # a busy worker's end: the number of its job
        self._waiting: collections.deque[tuple[int, tuple]] = collections.deque()
        self._outcomes: dict[int, tuple] = {}
        self._numbers = itertools.count()
        if workers > 0:
            pipes = [multiprocessing.Pipe() for _ in range(workers)]
            blocked = signal.pthread_sigmask(signal.SIG_BLOCK, HANDLED_SIGNALS)
            try:  # (the first worker inherits the mask: see _first_worker)
                context = multiprocessing.get_context("fork")
                self._first = context.Process(
                    target=_first_worker,
                    args=(os.getpid(), [far for _, far in pipes], [near for near, _ in pipes]),
                )
                self._first.start()
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
            for near, far in pipes:
                far.close()
                self._idle.append(near)

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Job[T]:
        """Run ``fn(*args, **kwargs)`` in a free worker, in the order submitted (``fn`` a
        module-level function, the arguments picklable); or here and now without workers."""
        if self._first is None:
            done = _call(fn, args, kwargs)
            return Job(lambda: done)
        number = next(self._numbers)
        self._waiting.append((number, (fn, args, kwargs)))
        self._send()
        return Job(lambda: self._outcome(number))

    def _send(self) -> None:
        """Send waiting jobs to free workers."""
        while self._idle and self._waiting:
            end = self._idle.pop(0)
            number, job = self._waiting.popleft()
            self._running[end] = number
            end.send(job)

    def _outcome(self, number: int) -> tuple[Any, list]:
        """The value and warnings of job ``number`` once it is done; its exception raised if
        it failed."""
        while number not in self._outcomes:
            self._receive()
        ok, *rest = self._outcomes.pop(number)
        if ok:
            return rest[0]
        exc, remote = rest
        if remote:
            exc.add_note(f"(in a drawing worker:)\n{remote}")
        raise exc

    def _receive(self) -> None:
        """Wait for the outcome of one or more of the running jobs, and send waiting jobs to
        the workers that become free."""
        for end in cast(list[Connection], wait(list(self._running))):
            try:
                outcome = end.recv()
            except (EOFError, OSError):
                raise RuntimeError(
                    "a drawing worker process ended abruptly (killed, or out of memory?)"
                ) from None
            self._outcomes[self._running.pop(end)] = outcome
            self._idle.append(end)
        self._send()

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
        if self._first is not None:
            self._first.terminate()  # (and the others are killed as it ends)
            self._first.join()
            for end in [*self._idle, *self._running]:
                try:  # until its worker is gone (a killed worker's last words read)
                    while True:
                        end.recv_bytes()
                except (EOFError, OSError):
                    pass
            self._forget()

    def close(self) -> None:
        """Let the workers finish their jobs and wait until they are gone (stopped, if one
        of them has died or this is interrupted meanwhile)."""
        if self._first is not None:
            try:
                while self._running:  # (and those waiting, sent as workers become free)
                    self._receive()
            except BaseException:
                self.cancel()
                raise
            for end in self._idle:
                end.close()  # the workers end: the first waits for the others
            self._first.join()
            self._forget()

    def _forget(self) -> None:
        """No workers any more: this end of their pipes closed, their jobs forgotten."""
        for end in [*self._idle, *self._running]:
            end.close()
        self._first = None
        self._idle, self._running = [], {}
        self._waiting.clear()
        self._outcomes.clear()

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
