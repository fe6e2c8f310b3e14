"""Command-line interface: ``tensegrity VERB``, one verb a subcommand (:func:`build_parser`;
``--help`` says what it does: :data:`DESCRIPTION`; ``--version`` prints the installed version).
This module assembles the parser and dispatches to the verbs, each in its own module:
:mod:`~tensegrity.cli.simulate`, :mod:`~tensegrity.cli.inspection` (``info``, ``export``,
``vtk``, ``matrices``), :mod:`~tensegrity.cli.analysis_verbs` (``equilibrium``, ``modes``,
``controllability``, ``lqr``, ``control``), :mod:`~tensegrity.cli.sweep`,
:mod:`~tensegrity.cli.visual` (``animate``, ``view``), :mod:`~tensegrity.cli.design` and
:mod:`~tensegrity.cli.fit`; a verb imports what it needs when it runs.

A thin layer over the library.  Every error is one line on stderr with exit code 2 (bad
input), 1 (the computation failed, or an internal error: rerun with ``--debug`` for the trace) or
130 (interrupted; 128 + N for SIGTERM and SIGHUP): :mod:`tensegrity.cli.errors`, the one error
boundary.  Nothing is written under a final name unless the whole run succeeded, and every file
is written atomically.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn

from tensegrity.cli import analysis_verbs, design, fit, inspection, simulate, sweep, visual
from tensegrity.cli.errors import (
    CommandError,
    report,
    show_warnings,
    signals_as_interrupts,
    warnings_on_success,
)

#: The command's name: the ``prog`` of its parser, which the verbs' parsers extend.
PROG = "tensegrity"


#: What ``tensegrity --help`` says the command does, above its verbs.
DESCRIPTION = (
    "Nonlinear dynamics of tensegrity structures (rigid rods, elastic tendons): simulate, "
    f"analyse, design, view and export them.  '{PROG} VERB --help' describes a verb."
)


#: The distribution whose version ``tensegrity --version`` prints.
DISTRIBUTION = "tensegrity-dynamics"


def version() -> str:
    """The installed version of the package (:data:`DISTRIBUTION`)."""
    import importlib.metadata

    try:
        return importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return f"unknown ({DISTRIBUTION} is not installed)"


class _Version(argparse.Action):
    """``--version``: print ``tensegrity VERSION`` and exit 0 (the version looked up only
    then)."""

    def __init__(self, option_strings: Sequence[str], dest: str, help: str | None = None) -> None:
        super().__init__(option_strings, dest=dest, default=argparse.SUPPRESS, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> NoReturn:
        print(f"{PROG} {version()}")
        parser.exit()


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, not usage + error
        verb = self.prog.removeprefix(PROG).strip()  # "" for the command's own parser
        raise CommandError(f"{verb}: {message}" if verb else message)


#: Verbs whose options import large parts of the library (their defaults and choices come from
#: it: SciPy's optimisation and statistics, the design, identification and sweep packages), by
#: name: their one-line help and what adds them with their options; named only, without them,
#: unless the command line asks for the verb.
DEFERRED = {
    "sweep": (sweep.HELP, sweep.add_parser),
    "design": (design.HELP, design.add_parsers),
    "fit": (fit.HELP, fit.add_parser),
}


def build_parser(verb: str | None = None) -> argparse.ArgumentParser:
    """The parser of the ``tensegrity`` command: one subcommand per verb, ``--debug`` and
    ``--version``.  ``verb``: the verb of the command line ("" for none): a verb of
    :data:`DEFERRED` other than it is named with its help only (``tensegrity simulate`` does
    not import the design package, 0.3 s); None: every verb with its options.  :func:`_parse`
    parses with the verbs named only, then again with the one the command line gives."""
    parser = _Parser(prog=PROG, description=DESCRIPTION)
    parser.add_argument(
        "--version", action=_Version, help=f"print the installed version ({PROG} VERSION) and exit"
    )
    _add_debug_option(parser, default=False)
    # not required: without a verb, _parse says so in its own words
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    simulate.add_parser(sub)
    inspection.add_parsers(sub)  # info, export, vtk, matrices
    analysis_verbs.add_parsers(sub)  # equilibrium, modes, controllability, lqr, control
    visual.add_parsers(sub)  # animate, view
    for name, (line, add) in DEFERRED.items():  # sweep on Dask, design, fit to measured motion
        if verb is None or verb == name:
            add(sub)
        else:  # (its --help too is left to the parse with its options)
            sub.add_parser(name, help=line, add_help=False)
    for verb_parser in sub.choices.values():  # after the verb too; not given: the command's
        _add_debug_option(verb_parser, default=argparse.SUPPRESS)
    return parser


def _add_debug_option(parser: argparse.ArgumentParser, default: object) -> None:
    parser.add_argument(
        "--debug",
        action="store_true",
        default=default,
        help="on an error, print the traceback before the one-line message; show warnings "
        "as they come",
    )


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    """The options of ``argv``; an unknown option fails in one line naming the verb."""
    words = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser("")
    args, unknown = parser.parse_known_args(words)
    if args.command in DEFERRED:  # (named only: now with its options)
        parser = build_parser(args.command)
        args, unknown = parser.parse_known_args(words)
    if args.command is None:
        given = f"unrecognized arguments: {' '.join(unknown)}; " if unknown else ""
        raise CommandError(
            f"{given}a verb is required ({', '.join(_verbs(parser))}): see {PROG} --help"
        )
    if unknown:
        raise CommandError(
            f"{args.command}: unrecognized arguments: {' '.join(unknown)} "
            f"(see {PROG} {args.command} --help)"
        )
    return args


def _verbs(parser: argparse.ArgumentParser) -> list[str]:
    """The verbs of the command's ``parser``, in the order of its help."""
    return [
        verb
        for action in parser._actions
        if isinstance(action, argparse._SubParsersAction)
        for verb in action.choices
    ]


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``tensegrity`` command; returns the exit code.

    The one error boundary (:mod:`tensegrity.cli.errors`): whatever a verb raises ends as one
    line on stderr and exit code 2 (bad input), 1 (the computation failed, or an internal error)
    or 130 (interrupted; 128 + N for SIGTERM and SIGHUP).  Warnings are shown only after a
    verb that succeeded.  ``--debug`` prints the traceback before the line and shows warnings
    as they come.
    """
    try:
        args = _parse(argv)
    except CommandError as exc:
        return report(exc, debug=False)
    try:
        with signals_as_interrupts(), warnings_on_success(show_now=args.debug) as caught:
            code = args.run(args)
            sys.stdout.flush()  # a reader that went away shows here, not at the interpreter's exit
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 - the boundary: every error becomes one line
        return report(exc, debug=args.debug)
    if code == 0:
        show_warnings(caught)
    return code
