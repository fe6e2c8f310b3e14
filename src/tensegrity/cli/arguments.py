"""The types of the command's options (``argparse`` ``type=`` functions), shared by its verbs:
each turns an option's text into its value, or raises ``ArgumentTypeError`` saying what was
expected, which the parser prints as one line naming the option
(``simulate: argument --t-end: must be > 0, got '-1'``)."""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = [
    "add_factors",
    "at_least",
    "description",
    "finite",
    "name",
    "node_force",
    "non_negative",
    "positive",
    "whole",
    "whole_non_negative",
    "whole_positive",
]


def description(doc: str | None) -> str | None:
    """A verb's ``--help`` description from its module's docstring ``doc``: the whole first
    paragraph as one line of plain text, its reST markup removed (````code```` and
    ``:func:`~a.b``` as ``code`` and ``b``; a closing ``::``, whose literal block the help does
    not show, as a full stop), and a leading ````tensegrity VERB``:`` (the usage line names the
    verb) left out."""
    if not doc:
        return None
    text = " ".join(doc.strip().split("\n\n")[0].split())
    text = re.sub(  # a role: its target, only the last name after a ~
        r":[a-z]+:`(~?)([^`]*)`", lambda m: m[2].rpartition(".")[2] if m[1] else m[2], text
    )
    text = re.sub(r"``(.*?)``", r"\1", text)
    text = re.sub(r"::$", ".", text)
    text = re.sub(r"^tensegrity [a-z-]+: ", "", text)
    return text[:1].upper() + text[1:]


def finite(text: str) -> float:
    """A finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def whole(text: str) -> int:
    """A whole number."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def at_least(
    low: float, *, strict: bool, parse: Callable[[str], Any] = finite
) -> Callable[[str], Any]:
    """The type of a number ``>= low`` (``> low`` if ``strict``), read by ``parse`` (default
    :func:`finite`; :func:`whole` for a whole number)."""

    def number(text: str) -> Any:
        value = parse(text)
        if value < low or (strict and value == low):
            raise argparse.ArgumentTypeError(
                f"must be {'>' if strict else '>='} {low:g}, got {text!r}"
            )
        return value

    return number


#: A finite number > 0.
positive = at_least(0.0, strict=True)
#: A finite number >= 0.
non_negative = at_least(0.0, strict=False)
#: A whole number >= 1.
whole_positive = at_least(0, strict=True, parse=whole)
#: A whole number >= 0.
whole_non_negative = at_least(0, strict=False, parse=whole)


def name(text: str) -> Path:
    """A file or folder name; not empty (``Path("")`` would be the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a file or folder name, got {text!r}")
    return Path(text)


def node_force(text: str, usage: str, given: str) -> tuple[str, list[float]]:
    """``NODE:FX,FY[,FZ]`` [N] (the last ``:`` ends the node, which may contain one): the node
    as written (a name or a 0-based index, :meth:`Structure.node_index
    <tensegrity.model.structure.Structure.node_index>` resolves it) and the force's
    components; ``usage`` (``CASE:NODE:FX,FY,FZ``) and ``given`` (the option's whole text) for
    the message."""
    node, sep, components = text.rpartition(":")
    try:
        force = [float(v) for v in components.split(",")]
    except ValueError:
        force = []
    if not (sep and node and force):
        raise argparse.ArgumentTypeError(
            f"expected {usage} with a node name or index and numbers (newtons), got {given!r}"
        )
    if not all(math.isfinite(f) for f in force):
        raise argparse.ArgumentTypeError(f"forces must be finite, got {given!r}")
    return node, force


def add_factors(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, *, from_file: bool
) -> None:
    """``--safety-factor GAMMA`` (divides the rods' Euler buckling load) and ``--strength-factor
    S`` (divides the yield strengths), each >= 1.  With ``from_file``, their default is None:
    the structure file's ``factors`` (``docs/design.md``), else 1, which an option given
    overrides; otherwise 1."""
    default = None if from_file else 1.0
    where = "the structure file's factors, else 1" if from_file else "1"
    for option, metavar, divides in (
        ("--safety-factor", "GAMMA", "the rods' Euler buckling load"),
        ("--strength-factor", "S", "the yield strengths of rods and tendons"),
    ):
        parser.add_argument(
            option,
            type=at_least(1.0, strict=False),
            default=default,
            metavar=metavar,
            help=f"divides {divides} (>= 1; default {where})",
        )
