"""The structure options every verb that takes a structure shares: ``--structure FILE`` or a
generated one (``--kind``, ``--n``, ``--set NAME=VALUE``, ...), ``--material``/``--section``,
``--damping`` and ``--gravity``, and the structure they describe (:func:`designed_of`)."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tensegrity.cli import arguments
from tensegrity.cli.errors import CommandError, blame, describe
from tensegrity.io.files import shown_path
from tensegrity.physics import dynamics

if TYPE_CHECKING:
    from tensegrity.design.files import Designed
    from tensegrity.design.materials import Factors, Material, Section
    from tensegrity.model.structure import Structure


def parse_materials(text: str) -> tuple[Material, Material]:
    """``--material ROD[,TENDON]``: the rods' and the tendons' table materials (the same one
    if only one is named); a one-line ``ValueError`` otherwise."""
    from tensegrity.design.materials import material

    names = text.split(",")
    if len(names) > 2:
        raise ValueError(f"expected ROD or ROD,TENDON, got {text!r}")
    return material(names[0]), material(names[-1])


def parse_sections(text: str) -> tuple[Section, Section]:
    """``--section ROD,TENDON`` of ``tensegrity simulate``: the rods' section ``rod:D`` or
    ``tube:D:T`` and the tendons' ``cable:D``, millimetres
    (:func:`tensegrity.design.materials.parse_section`); a one-line ``ValueError`` otherwise."""
    from tensegrity.design.materials import Cable, parse_section

    parts = text.split(",")
    if len(parts) != 2:
        raise ValueError(
            f"expected ROD,TENDON, e.g. rod:20,cable:3 or tube:40:2,cable:3 (mm), got {text!r}"
        )
    rod, tendon = parse_section(parts[0]), parse_section(parts[1])
    if isinstance(rod, Cable):
        raise ValueError(f"a cable cannot be a rod (no bending stiffness): {parts[0]!r}")
    return rod, tendon


def damping_kind(text: str) -> str | float:
    if text in dynamics.DAMPING_KINDS:
        return text
    if text == "critical":  # the name before internal damping existed
        raise argparse.ArgumentTypeError(
            "'critical' is now 'artificial' (the paper's damping, to ground: it drags the "
            "structure) or 'internal' (the same rates on deformation only, the default)"
        )
    try:
        return arguments.non_negative(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected {', '.join(map(repr, dynamics.DAMPING_KINDS))} or a damping >= 0 in "
            f"N s/m, got {text!r}"
        ) from None


def add_structure_options(parser: argparse.ArgumentParser) -> None:
    """The structure options: a file or a generated structure (:func:`add_source_options`),
    and members by material and section."""
    group = add_source_options(parser)
    group.add_argument(
        "--material",
        metavar="ROD[,TENDON]",
        help="members of these table materials (with --section): tendon stiffness E A / Lbar, "
        "rod mass rho A L, each taut tendon's tension at the start kept (its rest length "
        "changed); a file in the material form gives its own (docs/design.md)",
    )
    group.add_argument(
        "--section",
        metavar="ROD,TENDON",
        help="with --material: the rods' rod:D or tube:D:T and the tendons' cable:D, in mm "
        "(e.g. tube:40:2,cable:3)",
    )
    group.add_argument(
        "--tendon-mass",
        action="store_true",
        help="with --material: add the tendons' own mass rho A Lbar to their end nodes",
    )


def add_source_options(parser: argparse.ArgumentParser) -> argparse._ArgumentGroup:
    """``--structure FILE`` or a generated structure (``--kind``, ``--n``, ``--set``, ...);
    returns the group they are in."""
    from tensegrity.design.catalogue import KINDS

    group = parser.add_argument_group("structure (default: the paper's (3,1) class 1 shell)")
    group.add_argument(
        "--structure",
        type=arguments.name,
        metavar="FILE",
        help="a structure file (.json, .yaml, .toml or connectivity .npz) "
        "instead of a generated one",
    )
    group.add_argument(
        "--kind",
        choices=list(KINDS),
        metavar="|".join(KINDS),
        help="generated structure (default shell): "
        + "; ".join(f"{name}: {kind.summary}" for name, kind in KINDS.items()),
    )
    group.add_argument(
        "--n", type=int, help="shell elements around (default 3), or bars of a prism or tower stage"
    )
    group.add_argument("--m", type=int, help="shell or tower stages (default 1 for a shell)")
    group.add_argument(
        "--fixed-base",
        action="store_true",
        help="fix the base to ground: the bottom ring of a prism, tower or shell (class 1 or "
        "2); the octahedron stood on a string triangle, its three nodes fixed",
    )
    group.add_argument("--primal", action="store_true", help="primal shell: no t9, t10 tendons")
    group.add_argument(
        "--stiffness", type=arguments.positive, help="tendon stiffness k [N/m] (default 100)"
    )
    group.add_argument(
        "--rest-length",
        type=arguments.non_negative,
        help="shell tendon rest length L0 [m] (default: half the shortest initial tendon)",
    )
    group.add_argument(
        "--set",
        type=_assignment,
        action="append",
        metavar="NAME=VALUE",
        help="any other option of the generator, e.g. tension=8 or overlap=0.2 "
        "(repeatable; see the generator's docstring)",
    )
    return group


def _assignment(text: str) -> tuple[str, object]:
    name, sep, value = text.partition("=")
    if not sep or not name.isidentifier():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    for kind in (int, float):
        try:
            return name, kind(value)
        except ValueError:
            pass
    return name, {"true": True, "false": False}.get(value.lower(), value)


_SHELL_OPTIONS = ("n", "m", "primal", "stiffness", "rest_length", "fixed_base")


def _gravity(text: str) -> float | list[float]:
    """``--gravity G`` (m/s^2 down the last axis) or ``--gravity GX,GY[,GZ]`` (the vector)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected G or GX,GY,GZ in m/s^2, got {text!r}") from None
    return values[0] if len(values) == 1 else values


def add_gravity_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--gravity",
        type=_gravity,
        metavar="G|GX,GY,GZ",
        help="uniform gravity [m/s^2]: G points down the last axis (-z; -y for a "
        "planar structure), or the vector's components (default none)",
    )


def structure_of(args: argparse.Namespace) -> Structure:
    """The structure the options describe (a file, or a generated structure)."""
    return designed_of(args).structure


def designed_of(args: argparse.Namespace) -> Designed:
    """The structure the options describe and its members' design (a file in the material
    form, or ``--material`` and ``--section``; None otherwise), with the factors of
    :func:`factors_of`."""
    designed = _with_materials(args, source_of(args))
    if designed.design is None:
        return designed
    factors = factors_of(args, designed.design.factors)
    return designed._replace(design=dataclasses.replace(designed.design, factors=factors))


def factors_of(args: argparse.Namespace, given: Factors) -> Factors:
    """``given`` (a structure file's factors) with ``--safety-factor`` and ``--strength-factor``
    (where the verb has them and they are given) in their place."""
    from tensegrity.design.materials import Factors

    safety, strength = (getattr(args, name, None) for name in ("safety_factor", "strength_factor"))
    return Factors(
        given.safety if safety is None else safety,
        given.strength if strength is None else strength,
    )


def source_of(args: argparse.Namespace) -> Designed:
    """The structure :func:`add_source_options` describe (a file in either form, or a generated
    one) and its members' design (None unless a file in the material form gives it)."""
    from tensegrity.design.files import Designed

    flags = {
        name: getattr(args, name)
        for name in _SHELL_OPTIONS
        if getattr(args, name) is not None and getattr(args, name) is not False
    }
    if getattr(args, "structure", None) is not None:
        given = [
            *map(_flag, flags),
            *["--kind"] * (args.kind is not None),
            *["--set"] * bool(args.set),
        ]
        if given:
            raise CommandError(
                f"{' '.join(given)}: generator options cannot be combined with --structure"
            )
        designed = _read_designed(args.structure, "--structure")
    else:
        designed = Designed(_generated(args.kind or "shell", flags, args.set or ()), None)
    return designed


def _with_materials(args: argparse.Namespace, designed: Designed) -> Designed:
    """``designed`` built from ``--material``, ``--section`` (and ``--tendon-mass``) if given:
    :meth:`~tensegrity.design.materials.MemberDesign.apply`, tensions at the start kept."""
    from tensegrity.design.files import Designed
    from tensegrity.design.materials import MemberDesign

    material, section = getattr(args, "material", None), getattr(args, "section", None)
    if material is None and section is None:
        if getattr(args, "tendon_mass", False):
            raise CommandError("--tendon-mass: only with --material and --section")
        return designed
    if material is None or section is None:
        given, needed = (
            ("--section", "--material") if material is None else ("--material", "--section")
        )
        raise CommandError(f"{given}: needs {needed} too (materials and sections make the members)")
    if designed.design is not None:
        raise CommandError(
            f"--material: {shown_path(args.structure)} gives its members' materials and "
            "sections already (the material form); give them in one place"
        )
    if getattr(args, "stiffness", None) is not None:
        raise CommandError(
            "--stiffness: cannot be combined with --material (E A / Lbar is the stiffness)"
        )
    with blame(f"--material {material}"):
        rod_material, tendon_material = parse_materials(material)
    with blame(f"--section {section}"):
        rod_section, tendon_section = parse_sections(section)
    with blame(f"--material {material} --section {section}"):
        members = MemberDesign.of(
            designed.structure,
            rod_material=rod_material,
            rod_section=rod_section,
            tendon_material=tendon_material,
            tendon_section=tendon_section,
            tendon_mass=args.tendon_mass,
        )
        return Designed(members.apply(designed.structure, keep_tension=True), members)


def _flag(name: str) -> str:
    """The option of a generator's keyword: ``rest_length`` -> ``--rest-length``."""
    return f"--{name.replace('_', '-')}"


def read_structure(path: Path, option: str) -> Structure:
    """The structure file ``path``; an error names ``option`` and the file."""
    return _read_designed(path, option).structure


def _read_designed(path: Path, option: str) -> Designed:
    """The structure file ``path`` in either form (members by stiffness and mass, or by
    material and section) and its members' design; an error names ``option`` and the file."""
    from tensegrity.design.files import read_design

    with blame(option, path):
        return read_design(path)


def _generated(
    kind: str, flags: dict[str, object], assignments: Sequence[tuple[str, object]]
) -> Structure:
    """The structure ``--kind`` generates with the options ``flags`` (``--n``, ...) and
    ``assignments`` (``--set NAME=VALUE``), each given once; an error names them."""
    from tensegrity.design import catalogue as generators

    valid = generators.options(kind)
    for name in flags:
        if name not in valid:
            raise CommandError(
                f"{_flag(name)}: not an option of --kind {kind} (its options: {', '.join(valid)})"
            )
    options = dict(flags)
    for name, value in assignments:
        if name not in valid:
            raise CommandError(
                f"--set {name}: not an option of --kind {kind} (its options: {', '.join(valid)})"
            )
        if name in options:
            twice = f"by {_flag(name)} too" if name in flags else "twice"
            raise CommandError(f"--set {name}={value}: {name} is given {twice}; give it once")
        options[name] = value
    source = " ".join(
        [
            f"--kind {kind}",
            *(
                _flag(name) if value is True else f"{_flag(name)} {value}"
                for name, value in flags.items()
            ),
            *(f"--set {name}={value}" for name, value in assignments),
        ]
    )
    with blame(source):
        return generators.generate(kind, **options)


def apply_damping(structure: Structure, damping: str | float | None) -> Structure:
    """``structure`` with the damping ``--damping`` names (None: its own); an error names the
    option."""
    if damping is None:
        return structure
    if isinstance(damping, float):
        return dynamics.undamped(structure).replace(
            tendon_damping=np.full(structure.n_tendons, damping)
        )
    try:
        with np.errstate(over="raise"):
            return dynamics.DAMPING_KINDS[damping](structure)
    except FloatingPointError:
        raise CommandError(
            f"--damping {damping}: overflows for tendon stiffness up to "
            f"{structure.tendon_stiffness.max():g} N/m and rod mass up to "
            f"{structure.rod_mass.max():g} kg: lower them or give --damping VALUE"
        ) from None
    except ValueError as exc:
        raise CommandError(f"--damping {damping}: {describe(exc)}") from exc
