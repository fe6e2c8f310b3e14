"""The command line's one error boundary: every exception of a command ends as one line on stderr
and an exit code (:func:`exit_status`, :func:`report`).

====  ========================================================================================
code  when
====  ========================================================================================
0     success
1     the computation failed: an unstable run, no equilibrium, failed sweep cases, out of
      memory or disk space, an arithmetic or linear-algebra failure; or an internal error (a
      bug, or an input no check caught: the line says so and asks for a rerun with
      ``--debug``)
2     bad input: an option, a file or a folder (:class:`CommandError`, ``ValueError``,
      ``KeyError``, ``OSError``, and any error raised while reading an input file or building
      the structure the options describe, :func:`blame`)
130   interrupted by Ctrl-C; ``128 + N`` for the termination signal ``N`` (SIGTERM: 143,
      SIGHUP: 129), which :func:`signals_as_interrupts` turns into :class:`Interrupted`
141   the reader of stdout went away (``tensegrity modes | head``): quietly
====  ========================================================================================

Warnings raised by a command are shown after it, and only if it succeeded
(:func:`warnings_on_success`): none around an error line.  ``--debug`` prints the traceback
before the line and shows warnings as they come.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import traceback
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from tensegrity.io.files import DISK_FULL, shown_path

EXIT_FAILED, EXIT_USAGE = 1, 2
#: Exit code of a command interrupted by Ctrl-C (128 + SIGINT, as a shell reports it).
EXIT_INTERRUPTED = 128 + signal.SIGINT
#: Exit code when the reader of stdout closed it early (128 + SIGPIPE, as a shell reports it).
EXIT_BROKEN_PIPE = 141
#: The signals that stop a command as Ctrl-C does (those the platform has).
TERMINATION_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)
)
#: The hint closing the line of an unexpected error.
DEBUG_HINT = "rerun with --debug for the trace"


class CommandError(Exception):
    """A one-line error for the user, with its exit code."""

    def __init__(self, message: str, code: int = EXIT_USAGE) -> None:
        super().__init__(message)
        self.code = code


class Interrupted(KeyboardInterrupt):
    """A termination signal turned into an exception, so that clean-ups run as for Ctrl-C."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def interrupt_code(exc: KeyboardInterrupt) -> int:
    """Exit code of an interrupted command: ``128 + N`` for signal ``N``, 130 for Ctrl-C."""
    return 128 + exc.signum if isinstance(exc, Interrupted) else EXIT_INTERRUPTED


@contextlib.contextmanager
def signals_as_interrupts() -> Iterator[None]:
    """Within the block, the first SIGTERM or SIGHUP raises :class:`Interrupted`; later ones are
    ignored while the command cleans up.  Outside the main thread, signals are left alone."""

    def handler(signum: int, frame: object) -> None:
        for number in previous:
            signal.signal(number, signal.SIG_IGN)
        raise Interrupted(signum)

    previous: dict[int, Any] = {}  # the handlers to restore
    try:
        for number in TERMINATION_SIGNALS:
            previous[number] = signal.signal(number, handler)
    except ValueError:  # not the main thread: signal handlers cannot be set there
        pass
    try:
        yield
    finally:
        for number, action in previous.items():
            signal.signal(number, action)


@contextlib.contextmanager
def warnings_on_success(show_now: bool) -> Iterator[list[warnings.WarningMessage]]:
    """Hold the warnings raised within the block; the caller shows them with
    :func:`show_warnings` if the command succeeded.  With ``show_now`` they are shown as they
    come (and the list stays empty)."""
    if show_now:
        yield []
        return
    with warnings.catch_warnings(record=True) as caught:
        yield caught


def show_warnings(caught: list[warnings.WarningMessage]) -> None:
    """Show the warnings held by :func:`warnings_on_success`, as Python would have."""
    for w in caught:
        warnings.showwarning(w.message, w.category, w.filename, w.lineno, w.file, w.line)


def one_line(text: object) -> str:
    """``text`` with every run of whitespace (newlines too) made one space."""
    return " ".join(str(text).split())


def describe(exc: BaseException) -> str:
    """The message of ``exc`` in one line (an ``OSError`` as ``file: reason``, the file name
    escaped by :func:`tensegrity.io.files.shown_path`; a ``KeyError`` without quotes), or its
    type's name if it has none."""
    if isinstance(exc, OSError) and exc.strerror:
        files = [shown_path(f) for f in (exc.filename, exc.filename2) if f is not None]
        return one_line(": ".join([*map(str, files), exc.strerror]))
    if isinstance(exc, KeyError) and exc.args:
        return one_line(exc.args[0])
    return one_line(exc) or type(exc).__name__


@contextlib.contextmanager
def blame(source: str, path: Path | None = None) -> Iterator[None]:
    """Errors within the block are bad input from ``source`` (an option with its value, or the
    option of the input file ``path``): one line starting with ``source`` (and the file), exit
    code 2; out of memory, exit code 1."""
    try:
        yield
    except CommandError:
        raise
    except MemoryError as exc:
        problem = f"out of memory ({describe(exc)})"
        raise CommandError(_where(source, path, problem), EXIT_FAILED) from exc
    except RecursionError as exc:
        raise CommandError(_where(source, path, "nested too deeply")) from exc
    except (ValueError, KeyError, OSError) as exc:
        raise CommandError(_where(source, path, describe(exc))) from exc
    except (TypeError, IndexError, AttributeError, ArithmeticError) as exc:
        # a malformed value that slipped past the reader's or the generator's own checks
        problem = f"{describe(exc)} ({type(exc).__name__})"
        raise CommandError(_where(source, path, problem)) from exc


def _where(source: str, path: Path | None, problem: str) -> str:
    if path is None or problem.startswith(shown_path(path)):
        return f"{source}: {problem}"
    return f"{source}: {shown_path(path)}: {problem}"


def exit_status(exc: BaseException) -> tuple[int, str]:
    """The exit code for ``exc`` and the line that reports it (after ``tensegrity: ``)."""
    if isinstance(exc, CommandError):
        return exc.code, f"error: {one_line(exc)}"
    if isinstance(exc, KeyboardInterrupt):
        return interrupt_code(exc), "interrupted (nothing written)"
    if isinstance(exc, MemoryError):
        return EXIT_FAILED, f"error: out of memory ({describe(exc)}); nothing written"
    if isinstance(exc, (ArithmeticError, np.linalg.LinAlgError)):
        return EXIT_FAILED, f"error: the computation failed: {describe(exc)}"
    if isinstance(exc, RuntimeError) and not isinstance(exc, RecursionError):
        code = EXIT_USAGE if isinstance(exc, NotImplementedError) else EXIT_FAILED
        return code, f"error: {describe(exc)}"
    if isinstance(exc, OSError) and exc.errno in DISK_FULL:  # a failed run, not bad input
        return EXIT_FAILED, f"error: {describe(exc)}"
    if isinstance(exc, (ValueError, KeyError, OSError)):
        return EXIT_USAGE, f"error: {describe(exc)}"
    return (
        EXIT_FAILED,
        f"error: internal error ({type(exc).__name__}: {describe(exc)}); {DEBUG_HINT}",
    )


def report(exc: BaseException, debug: bool) -> int:
    """Report ``exc`` in one line on stderr (after its traceback with ``debug``); its exit
    code.  A closed stdout (``BrokenPipeError``) ends the command quietly."""
    if isinstance(exc, BrokenPipeError):
        # ``tensegrity modes | head``: stdout pointed at /dev/null so that Python's flush at
        # exit does not fail again.
        with contextlib.suppress(OSError, ValueError, AttributeError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    code, line = exit_status(exc)
    if debug:
        traceback.print_exception(exc)
    print(f"tensegrity: {line}", file=sys.stderr)
    return code
