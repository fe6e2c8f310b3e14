"""Command-line interface: ``tensegrity VERB``, one verb a subcommand (:func:`build_parser`;
``--help`` says what it does: :data:`DESCRIPTION`).

A thin layer over the library.  Every error is one line on stderr with exit code 2 (bad
input), 1 (the computation failed, or an internal error: rerun with ``--debug`` for the trace) or
130 (interrupted; 128 + N for SIGTERM and SIGHUP): :mod:`tensegrity.cli.errors`, the one error
boundary.  Nothing is written under a final name unless the whole run succeeded, and every file
is written atomically.  ``simulate`` streams its samples, with checkpoints, to
``OUT/.trajectory.h5.partial`` as it goes (:func:`tensegrity.io.stream.simulate_to_file`); an
interrupted run (Ctrl-C, SIGTERM, SIGHUP, a killed process) leaves only that file, and
``--resume`` continues it.  The final names (``trajectory.h5``, ``structure.json``, the figures)
appear together when the run has ended.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import os
import re
import shutil
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn, TypeAlias

import numpy as np

from tensegrity.cli import arguments, design, outputs, visual
from tensegrity.cli.drawing import Drawing, viewer_page, worker_count
from tensegrity.cli.errors import (
    EXIT_FAILED,
    CommandError,
    blame,
    describe,
    interrupt_code,
    one_line,
    report,
    show_warnings,
    signals_as_interrupts,
    warnings_on_success,
)
from tensegrity.cli.startup import announce_compiling, seconds_since_start
from tensegrity.engine.options import (
    ADAPTIVE_METHODS,
    DEFAULT_MAX_SAMPLES,
    DEFAULT_MAX_STEPS,
    FIXED_STEP_METHODS,
    sample_count,
)
from tensegrity.io.files import (
    DISK_FULL,
    byte_text,
    folders_made,
    shown_path,
    write_staged as _write_all,
)
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

if TYPE_CHECKING:
    from tensegrity.design.files import Designed
    from tensegrity.design.materials import MemberDesign
    from tensegrity.design.utilisation import TrajectoryUtilisation
    from tensegrity.engine.result import SimulationResult
    from tensegrity.io.stream import StreamSummary
    from tensegrity.model.loads import ForceTable
    from tensegrity.plots.motion import FrameKeeper
    from tensegrity.sweep.run import SweepSpec

#: The command's name: the ``prog`` of its parser, which the verbs' parsers extend.
PROG = "tensegrity"
#: What ``tensegrity --help`` says the command does, above its verbs.
DESCRIPTION = (
    "Nonlinear dynamics of tensegrity structures (rigid rods, elastic tendons): simulate, "
    f"analyse, design, view and export them.  '{PROG} VERB --help' describes a verb."
)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, not usage + error
        verb = self.prog.removeprefix(PROG).strip()  # "" for the command's own parser
        raise CommandError(f"{verb}: {message}" if verb else message)


#: The ``tensegrity`` parser's subcommands, to which each ``_add_*_parser`` adds its own.
_Commands: TypeAlias = "argparse._SubParsersAction[_Parser]"


def _damping(text: str) -> str | float:
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


def _add_structure_options(parser: argparse.ArgumentParser) -> None:
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
        "--fixed-base", action="store_true", help="class 2 shell: fix the base ring to ground"
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


def _add_gravity_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--gravity",
        type=_gravity,
        metavar="G|GX,GY,GZ",
        help="uniform gravity [m/s^2]: G points down the last axis (-z; -y for a "
        "planar structure), or the vector's components (default none)",
    )


def _structure(args: argparse.Namespace) -> Structure:
    """The structure the options describe (a file, or a generated structure)."""
    return _designed(args).structure


def _designed(args: argparse.Namespace) -> Designed:
    """The structure the options describe and its members' design (a file in the material
    form, or ``--material`` and ``--section``; None otherwise)."""
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
    return _with_materials(args, designed)


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
        rod_material, tendon_material = design.parse_materials(material)
    with blame(f"--section {section}"):
        rod_section, tendon_section = design.parse_sections(section)
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


def _read_structure(path: Path, option: str) -> Structure:
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


def _apply_damping(structure: Structure, damping: str | float | None) -> Structure:
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


# ------------------------------------------------------------------------------ commands
#: Name of the file a ``simulate`` run streams its samples into, inside ``--out`` (the run's data
#: are in this name + ``.partial`` until it ends); not a final name: the finished file becomes
#: ``trajectory.h5`` only together with the other outputs.
WORK_FILE = ".trajectory.h5"
#: The tendon-length figure reads at most this many samples of a run (and its last); the other
#: figures and the printed summary its first and last.
FIGURE_SAMPLES = 1000
#: ``simulate`` checkpoints a run at least this many times (segments of at most this fraction of
#: it), and at least every 1000 samples (or about 64 MiB of samples: the default of
#: :func:`tensegrity.io.stream.simulate_to_file`).
MIN_SEGMENTS = 10


def _check_samples(
    t_end: float,
    sample_dt: float,
    names: tuple[str, str] = ("--t-end", "--sample-dt"),
    where: str = "",
) -> None:
    """Fail up front, before any work, if a run of ``t_end`` sampled every ``sample_dt`` has
    more samples than the engine's limit (``max_samples`` of :func:`tensegrity.simulate`); the
    error names them ``names`` (in ``where``, e.g. a file).  Far beyond the limit, the run's
    bookkeeping (segment bounds, sample times) would overflow or outgrow memory."""
    samples = t_end / sample_dt + 1
    if not samples <= DEFAULT_MAX_SAMPLES:  # inf too
        t_name, dt_name = names
        raise CommandError(
            f"{where}{t_name}: {t_end:g} s at {dt_name} {sample_dt:g} s is {samples:,.0f} "
            f"samples, more than {DEFAULT_MAX_SAMPLES:,}; use a shorter {t_name} or a larger "
            f"{dt_name}"
        )


def _run_end(t_end: float, sample_dt: float, *, steady_state: bool) -> float:
    """The end [s] of ``simulate``'s run: ``--t-end``, checked by :func:`_check_samples`; for a
    steady-state run, which stops when it comes to rest, ``--t-end`` only bounds it: beyond the
    end of the samples limit (``1e308`` too), that end, said on stderr."""
    end = (DEFAULT_MAX_SAMPLES - 1) * sample_dt
    if not (steady_state and t_end > end):
        _check_samples(t_end, sample_dt)
        return t_end
    print(
        f"tensegrity: --t-end {t_end:g} s: the run stops when it comes to rest, at the latest at "
        f"{end:g} s ({DEFAULT_MAX_SAMPLES:,} samples at --sample-dt {sample_dt:g} s)",
        file=sys.stderr,
    )
    return end


#: ``simulate`` says before a run that writes at least this many bytes what it will write.
LARGE_RUN_BYTES = 2**30


def _announce_large_run(structure: Structure, t_end: float, sample_dt: float, out: Path) -> None:
    """Before a run whose trajectory file would reach :data:`LARGE_RUN_BYTES`, say on stderr
    how large it will be, how much of it is held in memory at a time, and whether the disk of
    ``out`` has room for it (a run stopped at a steady state writes less)."""
    from tensegrity.io.stream import sample_bytes, samples_per_segment

    row = sample_bytes(structure)
    samples = sample_count(0.0, t_end, sample_dt)
    if samples * row < LARGE_RUN_BYTES:
        return
    held = 2 * samples_per_segment(structure, _segment(structure, t_end, sample_dt), sample_dt)
    try:
        free = shutil.disk_usage(out).free
    except OSError:
        free = None
    room = (
        f" - more than the {byte_text(free)} free there"
        if free is not None and free < samples * row
        else ""
    )
    print(
        f"tensegrity: a large run: up to {samples:,} samples of {row / 2**20:.3g} MiB, about "
        f"{byte_text(samples * row)} in trajectory.h5{room}, written as the run goes (at most "
        f"{byte_text(held * sample_bytes(structure, held=True))} of samples in memory at a "
        "time); a larger --sample-dt writes less",
        file=sys.stderr,
    )


#: A run estimated to take longer than this [s] is announced on stderr before it starts.
LONG_RUN_SECONDS = 30.0


def _check_run_cost(
    structure: Structure,
    t_end: float,
    *,
    method: str = "DOP853",
    dt: float | None = None,
    atol: float = 1e-12,
    steady_state: bool = False,
    acceleration_tol: float = 1e-6,
    max_steps: int = DEFAULT_MAX_STEPS,
    max_wall_time: float = math.inf,
    remedy: str = "softer tendons, a shorter --t-end, a larger --max-steps or an implicit "
    "method (--method Radau or BDF)",
) -> None:
    """Before a run of ``structure`` to ``t_end`` [s], by
    :func:`tensegrity.engine.budget.estimate`: refuse it if it needs more than ``max_steps``
    steps or (``"rk4"``) its ``dt`` [s] is unstable, naming ``remedy`` (what to change); say on
    stderr if it takes longer than :data:`LONG_RUN_SECONDS` and ``max_wall_time`` [s] (a
    steady-state run that may come to rest early: not)."""
    from tensegrity.engine.budget import RK4_STABLE, estimate

    cost = estimate(
        structure,
        t_end,
        method=method,
        dt=dt,
        atol=atol,
        steady_state=steady_state,
        acceleration_tol=acceleration_tol,
    )
    if cost is None:
        return
    stiffest = structure.tendon_stiffness.max(initial=0.0)
    why = f"highest rate {cost.rate:.3g} 1/s, tendons up to {stiffest:g} N/m"
    if not cost.stable:
        raise CommandError(
            f"--dt: {dt:g} s is beyond RK4's stability limit for this structure (about "
            f"{RK4_STABLE / cost.rate:.2g} s; {why}); use --dt {cost.safe_dt:.2g} or less, or an "
            "adaptive --method"
        )
    if cost.settles:
        return
    if steady_state:
        why += (
            f"; round-off of its forces keeps its accelerations above {acceleration_tol:g} m/s^2, "
            "so it cannot come to rest"
        )
    if method not in FIXED_STEP_METHODS and cost.least_steps > max_steps:
        raise CommandError(
            f"a run to {t_end:g} s needs at least {cost.least_steps:.3g} {method} steps ({why}), "
            f"more than --max-steps {max_steps:,}; use {remedy}"
        )
    seconds = min(cost.steps, max_steps) * cost.step_seconds
    if min(seconds, max_wall_time) > LONG_RUN_SECONDS:
        stops = (
            f", more than --max-steps {max_steps:,}: it would stop there after"
            if cost.steps > max_steps
            else ","
        )
        print(
            f"tensegrity: a long run: about {cost.steps:.3g} {method} steps{stops} about "
            f"{seconds:,.0f} s ({why}); quicker: {remedy}",
            file=sys.stderr,
        )


#: ``simulate``'s memory [bytes]: a part per member (rod or tendon) and the rest, fitted to the
#: peak resident memory of runs of 10,000, 100,000 and 300,000 members (2026-11-27, 2-core
#: machine: 224, 494 and 1,054 MB; the issue's 10^6 members: 2.5-3.6 GB).
MEMBER_BYTES = 2800
BASE_BYTES = 214 * 10**6
#: ... and its time [s] beside the steps (building, checking, writing, drawing) per member
#: (the 300,000 members' run: 27 s of its 35 s).
MEMBER_SECONDS = 90e-6
#: ``simulate`` says what a structure of at least this many members will cost before it starts.
LARGE_STRUCTURE_MEMBERS = 100_000


def _available_memory() -> int | None:
    """The memory available to a new process [bytes] (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as file:
            for line in file:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _refuse_beyond_memory(needed: int, what: str, purpose: str, instead: str) -> None:
    """``CommandError`` if ``needed`` [bytes] exceeds the memory available (when it can be read):
    ``"<what> needs about <needed> of memory <purpose>, more than the <available> available;
    <instead>"``."""
    available = _available_memory()
    if available is not None and needed > available:
        raise CommandError(
            f"{what} needs about {byte_text(needed)} of memory {purpose}, more than the "
            f"{byte_text(available)} available; {instead}"
        )


def _check_structure_size(structure: Structure) -> None:
    """Before ``simulate``'s run of a structure of :data:`LARGE_STRUCTURE_MEMBERS` members or
    more: refuse it if its memory (:data:`MEMBER_BYTES`) exceeds the memory available, else say
    on stderr how much memory and time it takes before its steps."""
    from tensegrity.engine.budget import STEP_SECONDS

    members = structure.n_rods + structure.n_tendons
    if members < LARGE_STRUCTURE_MEMBERS:
        return
    needed = BASE_BYTES + MEMBER_BYTES * members
    _refuse_beyond_memory(
        needed, f"a structure of {members:,} members", "to simulate", "simulate a smaller one"
    )
    fixed, per_member = STEP_SECONDS["DOP853"]
    print(
        f"tensegrity: a large structure: {members:,} members, about {byte_text(needed)} of "
        f"memory, {members * MEMBER_SECONDS:,.0f} s to set up and write and "
        f"{fixed + per_member * members:.2g} s a step",
        file=sys.stderr,
    )


def _check_simulation_cost(args: argparse.Namespace, structure: Structure) -> None:
    """:func:`_check_run_cost` of ``simulate``'s run of ``structure`` with the options ``args``."""
    _check_run_cost(
        structure,
        args.t_end,
        method=args.method,
        dt=args.dt,
        atol=args.atol,
        steady_state=not args.no_steady_state,
        max_steps=args.max_steps,
        max_wall_time=args.max_wall_time,
    )


def _segment(structure: Structure, t_end: float, sample_dt: float) -> float:
    """Segment duration [s] of a ``simulate`` run: at most a tenth of it, rounded to samples.

    Depends only on the structure and the options, so that a resumed run has the segment grid of
    the interrupted one.
    """
    from tensegrity.io.stream import samples_per_segment

    default = samples_per_segment(structure, None, sample_dt)
    tenth = max(1, math.ceil((sample_count(0.0, t_end, sample_dt) - 1) / MIN_SEGMENTS))
    return min(default, tenth) * sample_dt


def _simulation_inputs(
    args: argparse.Namespace,
) -> tuple[Structure, ForceTable | None, np.ndarray | None, _DesignedRun | None]:
    """The structure (damped as the options say), the force table and the gravity of a run,
    and, if its members have a design, what :func:`_print_summary`'s utilisation report
    needs."""
    structure, members = _designed(args)
    damping = args.damping
    if damping is None and getattr(args, "structure", None) is None:
        damping = next(iter(dynamics.DAMPING_KINDS))  # a generated structure: internal
    structure = _apply_damping(structure, damping)
    if args.method in FIXED_STEP_METHODS and args.dt is None:
        raise CommandError(f"--dt: method {args.method!r} is fixed-step and needs --dt")
    if args.method not in FIXED_STEP_METHODS and args.dt is not None:
        raise CommandError(f"--dt: only for fixed-step methods ({', '.join(FIXED_STEP_METHODS)})")
    force = None
    if args.force_table is not None:
        from tensegrity.io.tables import read_force_table

        with blame("--force-table", args.force_table):
            force = read_force_table(args.force_table)
        if force.n_nodes != structure.n_nodes:
            raise CommandError(
                f"--force-table: {shown_path(args.force_table)} has forces for {force.n_nodes} "
                f"nodes, the structure has {structure.n_nodes}"
            )
    gravity = None
    if args.gravity is not None:
        from tensegrity.model.loads import gravity_vector

        gravity = gravity_vector(args.gravity, structure.dim)
    if members is None:
        for option, value in (("--safety-factor", args.safety_factor != 1.0),
                              ("--stop-on-failure", args.stop_on_failure)):  # fmt: skip
            if value:
                raise CommandError(
                    f"{option}: needs members with a design (--material and --section, or a "
                    "structure file in the material form)"
                )
        return structure, force, gravity, None
    return structure, force, gravity, _DesignedRun(structure, members, force, args.safety_factor)


@dataclasses.dataclass(frozen=True)
class _DesignedRun:
    """The structure of a ``simulate`` run whose members have a design, that design and the
    run's force table (the trajectory file holds neither)."""

    structure: Structure
    members: MemberDesign
    force: ForceTable | None
    safety_factor: float  #: divides the rods' Euler load

    def peaks(self, path: Path, n_samples: int) -> TrajectoryUtilisation:
        """The members' largest utilisation over the run of ``n_samples`` samples in the
        trajectory file ``path`` (:func:`tensegrity.design.utilisation.trajectory_utilisation`;
        the figures, the viewer and the summary show it)."""
        from tensegrity.design.utilisation import trajectory_utilisation

        return trajectory_utilisation(
            path,
            self.members.properties(self.structure),
            n_samples=n_samples,
            safety_factor=self.safety_factor,
            external_force=self.force,
        )


@dataclasses.dataclass(frozen=True)
class _RunFiles:
    """The files of one ``simulate`` call in ``--out``: the run streams into ``partial`` and ends
    as ``work``; ``created`` are the folders this call made, ``fresh`` whether it starts a new
    partial file (not ``--resume``, or nothing to resume)."""

    out: Path
    work: Path
    partial: Path
    created: list[Path]
    fresh: bool

    @classmethod
    def prepare(cls, out: Path, resume: bool) -> _RunFiles:
        """The files of a run in ``out``, which is made (with its parents) if need be."""
        from tensegrity.io.stream import PARTIAL_SUFFIX

        work = out / WORK_FILE
        partial = Path(str(work) + PARTIAL_SUFFIX)
        created = [folder for folder in (out, *out.parents) if not folder.exists()]
        out.mkdir(parents=True, exist_ok=True)
        fresh = not resume or not partial.exists()  # this call starts a new partial file
        return cls(out, work, partial, created, fresh)

    def discard(self) -> None:
        """Remove what this call made that holds nothing: an empty fresh partial, new folders."""
        from tensegrity.io.stream import read_checkpoint

        if self.fresh and self.partial.exists():
            try:
                empty = read_checkpoint(self.partial).next_segment == 0
            except ValueError:
                empty = True
            if empty:
                self.partial.unlink(missing_ok=True)
        _remove_empty(self.created)

    def kept(self) -> str:
        """The end of a failed or interrupted run's message: where the run so far is kept and
        how to continue it (``--resume``), or that nothing was written."""
        kept = next((p for p in (self.partial, self.work) if p.exists()), None)
        if kept is not None:
            return (
                f"; the run so far is in {shown_path(kept)}: continue it with the same "
                "options and --resume"
            )
        return " (nothing written)"

    def interrupted(self, exc: KeyboardInterrupt) -> int:
        """Report an interrupted run (what it left, if anything); its exit code."""
        left = self.kept()
        if not (self.partial.exists() or self.work.exists()):
            _remove_empty(self.created)
        print(f"tensegrity: interrupted{left}", file=sys.stderr)
        return interrupt_code(exc)


#: The library's words for its options, as the CLI's (messages of ``simulate``).
_CLI_WORDS = (
    ("pass resume=False to start again", "run without --resume to start again"),
    ("start again with resume=False", "run without --resume to start again"),
    ("max_wall_time = ", "--max-wall-time "),
    ("max_steps = ", "--max-steps "),
    ("raise max_wall_time", "raise --max-wall-time"),
    ("raise max_steps", "raise --max-steps"),
    ("loosen rtol and atol", "loosen --rtol and --atol"),
    ("method='Radau'", "--method Radau"),
)


def _in_cli_words(exc: ValueError | str) -> str:
    """The library's error (or message) as one line, in the CLI's words."""
    message = " ".join(str(exc).split())
    for library, cli in _CLI_WORDS:
        message = message.replace(library, cli)
    return message


def _stream_run(
    args: argparse.Namespace,
    structure: Structure,
    force: ForceTable | None,
    gravity: np.ndarray | None,
    files: _RunFiles,
    keeper: FrameKeeper | None,
    designed: _DesignedRun | None,
) -> StreamSummary:
    """Simulate into ``files.work`` (through its partial file), the viewer's frames into
    ``keeper`` as they come, stopping at a member's failure with ``--stop-on-failure``; a
    rejected or failed run leaves nothing of this call's making behind, an interrupted one its
    partial file."""
    from tensegrity.io.stream import OutOfTimeError, simulate_to_file

    stop = None
    if designed is not None and args.stop_on_failure:
        from tensegrity.design.utilisation import stop_at_failure

        stop = stop_at_failure(
            structure,
            designed.members.properties(structure),
            safety_factor=designed.safety_factor,
            external_force=force,
            gravity=gravity,
        )

    try:
        summary = simulate_to_file(
            structure,
            (0.0, args.t_end),
            files.work,
            segment=_segment(structure, args.t_end, args.sample_dt),
            resume=args.resume,
            progress=sys.stderr.isatty(),
            external_force=force,
            gravity=gravity,
            method=args.method,
            rtol=args.rtol,
            atol=args.atol,
            dt=args.dt,
            sample_dt=args.sample_dt,
            steady_state=not args.no_steady_state,
            max_steps=args.max_steps,
            max_wall_time=args.max_wall_time,
            observe=None if keeper is None else keeper.add,
            stop=stop,
        )
    except KeyboardInterrupt:
        raise
    except OutOfTimeError as exc:  # the finished segments stay in the partial file, for --resume
        files.discard()
        raise CommandError(
            f"simulation {_in_cli_words(str(exc))}{files.kept()}", EXIT_FAILED
        ) from None
    except OSError as exc:
        if exc.errno not in DISK_FULL:
            files.discard()
            raise
        files.discard()  # (the partial file is at its last checkpoint: kept if it holds any)
        raise CommandError(f"{describe(exc)}{files.kept()}", EXIT_FAILED) from None
    except ValueError as exc:
        files.discard()
        raise CommandError(_in_cli_words(exc)) from None
    except BaseException:
        files.discard()
        raise
    if not summary.success:
        files.work.unlink(missing_ok=True)
        _remove_empty(files.created)
        raise CommandError(
            f"simulation failed: {_in_cli_words(summary.message)} (nothing written)", EXIT_FAILED
        )
    return summary


#: ``simulate``'s file of the run's structure in the material form, beside ``structure.json``
#: (members with a design only).
MATERIAL_STRUCTURE = "structure-material.json"
#: ``simulate``'s video: frames per second (a GIF frame's delay is a whole number of hundredths
#: of a second; at 20 fps, 5 of them, so that the video plays in real time) and its width and
#: height [pixels].  ``tensegrity animate`` draws others.
VIDEO_FPS = 20.0
VIDEO_SIZE = (640, 512)
#: The time [s] to draw and encode a frame of ``simulate``'s GIF: a part per frame and a part
#: per member (rod or tendon), fitted to measurements on a 2-core machine (2026-11-26,
#: ``cli.visual.write_video`` in one process: 5.9, 12.4 and 105 ms a frame for the (3,1),
#: (10,10) and (30,30) shells, their 30, 1,180 and 10,740 members, the set-up included).
VIDEO_FRAME_SECONDS = 5e-3
VIDEO_MEMBER_SECONDS = 7e-6
#: ``simulate`` draws its GIF unasked when that takes at most this long [s] by the estimate
#: above (the paper's (3,1) example, 81 frames, about 0.4 s; the (10,10) shell's 60 s run, 400
#: frames, about 5 s, over it), so that a default run stays quick; ``--animation`` draws it
#: always.
DEFAULT_VIDEO_SECONDS = 3.0


def _write_run(
    args: argparse.Namespace,
    structure: Structure,
    summary: StreamSummary,
    files: _RunFiles,
    keeper: FrameKeeper | None,
    designed: _DesignedRun | None,
    drawing: Drawing,
) -> tuple[SimulationResult, float, list[Path], TrajectoryUtilisation | None]:
    """Write the finished run's files to ``--out`` together; the trajectory read back for the
    figures and the summary, the largest energy balance error [J], the files written and the
    members' largest utilisation over the run (members with a design: ``designed``).  The
    figures, the viewer's page and the video are ``drawing``'s jobs, drawn while this process
    writes the rest.  The viewer's frames are ``keeper``'s, or (a resumed run, or members with
    a design: ``designed``, their utilisation in the frames and in utilisation.png, drawn at
    the last sample) read from the file."""
    from tensegrity.design.files import write_design
    from tensegrity.io.formats import write_structure
    from tensegrity.io.trajectory import read_dataset, read_trajectory
    from tensegrity.plots.motion import MAX_BYTES, MAX_FRAMES, MemberCheck, read_frames

    work = files.work
    # the first and last samples for the structure figures and the summary, the tendon lengths
    # at most FIGURE_SAMPLES times (and the last), the energy balance from every sample; the
    # viewer's frames as kept during the run, or (a resumed or designed run) from the datasets
    # they show
    trajectory = read_trajectory(work, every=max(1, summary.n_samples - 1))
    peaks = check = None
    if designed is not None:
        peaks = designed.peaks(work, summary.n_samples)
        check = MemberCheck(
            designed.members.properties(designed.structure),
            safety_factor=designed.safety_factor,
            external_force=designed.force,
            largest=peaks.largest,
        )
    frames = None
    if keeper is not None and summary.resumed_from is None and summary.segments_run:
        frames = keeper.frames(summary.message)
    elif not args.no_view:
        frames, _ = read_frames(work, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES, check=check)
    every = max(1, -(-summary.n_samples // FIGURE_SAMPLES))
    history = (
        read_dataset(work, "t", every=every),
        read_dataset(work, "tendon_length", every=every),
    )

    video = _video_format(args, structure, summary)

    def write(staging: Path, drawing: Drawing) -> list[Path]:
        # the longest first, each to the next free worker
        videos = [] if video is None else [drawing.submit(_video, work, staging, video)]
        jobs = [
            *(  # (the names of plots.figures.FIGURE_NAMES: not imported here, the workers draw;
                # the tendon-length series, up to 8 MB at (10,10), sent only to its own figure)
                drawing.submit(_figures, trajectory, staging, series, (name,))
                for name, series in (
                    ("initial.png", None),
                    ("equilibrium.png", None),
                    ("tendon_lengths.png", history),
                )
            ),
            *(
                []
                if frames is None
                else [drawing.submit(viewer_page, frames, staging / "view.html")]
            ),
            *(
                []
                if peaks is None
                else [drawing.submit(_utilisation_figure, trajectory, peaks, staging)]
            ),
        ]
        outputs = [
            write_structure(staging / "structure.json", structure),
            *(  # the same structure by material and section (`tensegrity view --structure`)
                []
                if designed is None
                else [write_design(staging / MATERIAL_STRUCTURE, structure, designed.members)]
            ),
            *(_vtk_files(staging / "vtk", read_trajectory(work)) if args.vtk else []),
        ]
        drawn = [path for job in [*jobs, *videos] for path in job.result()]
        # Last, so that the finished run stays in ``work`` if anything before fails.
        target = staging / "trajectory.h5"
        _link_or_move(work, target)
        return [target, *outputs, *drawn]

    balance = _energy_balance_error(work)
    written = _write_all(files.out, drawing.writing(write))
    work.unlink(missing_ok=True)  # a second name of trajectory.h5, if linked
    return trajectory, balance, written, peaks


def _figures(
    trajectory: SimulationResult,
    folder: Path,
    history: tuple[np.ndarray, np.ndarray] | None,
    names: Sequence[str],
) -> list[Path]:
    """The run's figures ``names`` in ``folder`` (:func:`tensegrity.plots.figures.save_figures`;
    ``history`` its tendon-length series, needed by ``tendon_lengths.png`` only)."""
    from tensegrity.plots.figures import save_figures

    return save_figures(trajectory, folder, history=history, names=names)


def _utilisation_figure(
    trajectory: SimulationResult, peaks: TrajectoryUtilisation, folder: Path
) -> list[Path]:
    """``folder / utilisation.png``: every member coloured by its largest utilisation over the
    run (``peaks``), drawn at the run's last sample."""
    from tensegrity.plots.figures import FIGURE_DPI, figure_utilisation, save_png

    figure = figure_utilisation(
        trajectory.structure,
        trajectory.node_position[-1],
        peaks.rod_peak,
        peaks.tendon_peak,
        title="Largest member utilisation over the run, t = "
        f"{trajectory.t[0]:.4g} .. {trajectory.t[-1]:.4g} s",
    )
    return [save_png(figure, folder / "utilisation.png", dpi=FIGURE_DPI)]


def _video_format(
    args: argparse.Namespace, structure: Structure, summary: StreamSummary
) -> str | None:
    """The format of ``simulate``'s video of the finished run ``summary`` (``--animation``), or
    None for none (``--no-animation``); unasked, a GIF if drawing it takes at most
    :data:`DEFAULT_VIDEO_SECONDS` by the estimate of :data:`VIDEO_FRAME_SECONDS` and
    :data:`VIDEO_MEMBER_SECONDS`, else none, and a line on stderr that says so."""
    if args.no_animation or args.animation is not None:
        return None if args.no_animation else args.animation
    from tensegrity.plots.motion import playback_times

    frames = playback_times(summary.t_first, summary.t_last, fps=VIDEO_FPS).size
    members = structure.n_rods + structure.n_tendons
    seconds = frames * (VIDEO_FRAME_SECONDS + members * VIDEO_MEMBER_SECONDS)
    if seconds <= DEFAULT_VIDEO_SECONDS:
        return "gif"
    print(
        f"tensegrity: motion.gif not drawn: {frames:,} frames of {members:,} members would take "
        f"about {seconds:.0f} s (--animation gif draws it; `tensegrity animate` draws any part "
        "of trajectory.h5)",
        file=sys.stderr,
    )
    return None


def _video(trajectory: Path, folder: Path, kind: str) -> list[Path]:
    """``folder / motion.<kind>``: the run in ``trajectory`` as a video of :data:`VIDEO_SIZE`
    at :data:`VIDEO_FPS` (:func:`tensegrity.cli.visual.write_video`; a progress bar on a
    terminal)."""
    path = folder / f"motion.{kind}"
    visual.write_video(trajectory, path, fps=VIDEO_FPS, size=VIDEO_SIZE)
    return [path]


def _cmd_simulate(args: argparse.Namespace) -> int:
    outputs.check_folder(args.out, "--out")
    args.t_end = _run_end(args.t_end, args.sample_dt, steady_state=not args.no_steady_state)
    # the drawing's workers start now: they import matplotlib while the run is set up and goes on
    with Drawing(worker_count(2)) as drawing:
        return _simulate_and_write(args, drawing)


def _simulate_and_write(args: argparse.Namespace, drawing: Drawing) -> int:
    """``tensegrity simulate`` once its options are checked: the run, its files (the figures,
    page and video drawn by ``drawing``) and its summary."""
    announce_compiling()
    structure, force, gravity, designed = _simulation_inputs(args)
    _check_outputs(args, designed is not None)
    _check_structure_size(structure)
    _check_simulation_cost(args, structure)
    files = _RunFiles.prepare(args.out, args.resume)
    _announce_large_run(structure, args.t_end, args.sample_dt, files.out)
    keeper = None
    if not args.no_view and designed is None:  # (a design's frames are read with their forces)
        from tensegrity.plots.motion import MAX_BYTES, MAX_FRAMES, FrameKeeper, frame_budget

        budget = frame_budget(structure, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES)
        keeper = FrameKeeper(structure, t0=0.0, sample_dt=args.sample_dt, max_frames=budget)
    try:
        summary = _stream_run(args, structure, force, gravity, files, keeper, designed)
        try:
            trajectory, balance, written, peaks = _write_run(
                args, structure, summary, files, keeper, designed, drawing
            )
        except (ValueError, OSError) as exc:  # the finished run stays, for --resume
            code = EXIT_FAILED if isinstance(exc, OSError) and exc.errno in DISK_FULL else 2
            raise CommandError(f"{describe(exc)}{files.kept()}", code) from None
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM/SIGHUP (signals_as_interrupts)
        drawing.cancel()
        return files.interrupted(exc)
    _print_summary(
        trajectory,
        summary,
        balance,
        args.resume,
        [f for f in written if f.parent == files.out or f.suffix == ".pvd"],
        peaks,
    )
    return 0


def _check_outputs(args: argparse.Namespace, designed: bool) -> None:
    """Fail before the run if a folder stands where one of ``simulate``'s files goes in
    ``--out`` (or a file where its ``vtk`` folder goes): the rule :func:`write_staged` applies
    at the end (:func:`tensegrity.io.files.check_targets`)."""
    from tensegrity.io.files import check_targets

    names = ["trajectory.h5", "structure.json", "initial.png", "equilibrium.png"]
    names += ["tendon_lengths.png"]
    names += [] if args.no_view else ["view.html"]
    names += [] if args.no_animation else [f"motion.{args.animation or 'gif'}"]
    names += [MATERIAL_STRUCTURE, "utilisation.png"] if designed else []
    names += ["vtk/tensegrity.pvd"] if args.vtk else []
    try:
        check_targets(args.out, [args.out / name for name in names])
    except ValueError as exc:
        raise CommandError(f"--out: {exc}") from None


def _link_or_move(source: Path, target: Path) -> None:
    """Give ``source`` the name ``target`` too (a hard link), or move it if links are refused."""
    try:
        os.link(source, target)
    except OSError:
        os.replace(source, target)


def _remove_empty(folders: Sequence[Path]) -> None:
    """Remove those of ``folders`` that are empty, deepest first."""
    for folder in sorted(folders, key=lambda f: len(f.parts), reverse=True):
        with contextlib.suppress(OSError):
            folder.rmdir()


def _vtk_files(folder: Path, result) -> list[Path]:
    from tensegrity.io.vtk import write_vtk

    return write_vtk(folder, result)  # the .vtp files, then the .pvd collection


def _energy_balance_error(path: Path) -> float:
    """Largest change of the energy balance [J] over every sample of the trajectory file."""
    from tensegrity.engine.result import total_energy
    from tensegrity.io.trajectory import ENERGY_COLUMNS, read_dataset

    energy = read_dataset(path, "energy")
    total = total_energy({name: energy[:, k] for k, name in enumerate(ENERGY_COLUMNS)})
    return float(np.abs(total - total[0]).max())


def _print_summary(
    trajectory,
    summary,
    balance: float,
    resume: bool,
    files: Sequence[Path],
    peaks: TrajectoryUtilisation | None,
) -> None:
    """The summary of a run: ``trajectory`` read back from its file (its last sample matters),
    the :class:`tensegrity.io.stream.StreamSummary` of the streamed run, the largest energy
    balance error [J], and the members' largest utilisation if they have a design (``peaks``)."""
    structure = trajectory.structure
    e = trajectory.energy
    tension = trajectory.tendon_tension[-1]
    rows = [
        ("status", trajectory.message),
        ("samples", f"{summary.n_samples} from t = {summary.t_first:g} to {summary.t_last:.6g} s"),
        ("damping", dynamics.describe_damping(structure)),
        ("final residual acceleration", f"{trajectory.residual_acceleration[-1]:.3e} m/s^2"),
        ("final largest node speed", f"{np.abs(trajectory.node_velocity[-1]).max():.3e} m/s"),
        ("largest rod-length error", f"{summary.max_rod_length_error:.3e} (relative)"),
        *(
            [("largest joint/support error", f"{summary.max_constraint_error:.3e} m")]
            if structure.has_constraints
            else []
        ),
        ("energy dissipated", f"{e['dissipated'][-1]:.6g} J"),
        ("energy balance error", f"{balance:.3e} J"),
        ("slack tendons at the end", f"{int(np.sum(tension <= 0))} of {structure.n_tendons}"),
        (
            "tension range at the end",
            f"{tension.min():.6g} .. {tension.max():.6g} N"
            if structure.n_tendons
            else "no tendons",
        ),
        (
            "integration",
            f"{trajectory.settings['method']}: {_counted(summary.nsteps, 'step')}, "
            f"{_counted(summary.nfev, 'evaluation')}, "
            f"{_counted(summary.nswitches, 'slack/taut switch', 'slack/taut switches')} located",
        ),
        (
            "checkpoints",
            f"{_counted(summary.segments_stored, 'segment')} of "
            f"{_counted(summary.samples_per_segment, 'sample')}",
        ),
        *([("resumed", _resumed(summary))] if resume else []),
        ("simulation wall time", f"{summary.wall_time:.2f} s"),
        ("time to result", f"{seconds_since_start():.2f} s since the command started"),
    ]
    failures: list[str] = []
    if peaks is not None:
        more, failures = _utilisation_rows(peaks, structure)
        rows += more
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    print("wrote " + ", ".join(str(f) for f in files))
    if failures:
        shown = "; ".join(failures[:3]) + (
            f"; and {len(failures) - 3} more" if len(failures) > 3 else ""
        )
        print(
            f"tensegrity: warning: {len(failures)} member{'s' * (len(failures) > 1)} beyond "
            f"{'their' if len(failures) > 1 else 'its'} limits (utilisation > 1): {shown}",
            file=sys.stderr,
        )


def _utilisation_rows(
    u: TrajectoryUtilisation, s: Structure
) -> tuple[list[tuple[str, str]], list[str]]:
    """The summary's rows of the members' largest utilisation over a run of ``s`` (``u``) and
    a line per member beyond its limits."""
    from tensegrity.design.utilisation import Peak

    def shown(name: str, p: Peak | None, member: Sequence[str], every: int) -> str:
        if p is None:
            return f"{name} -"
        sampled = f", from one sample in {every}" if every > 1 else ""
        return f"{name} {p.value:.4g} ({member[p.member]}, t = {p.time:.6g} s{sampled})"

    rods = [f"rod {r}" for r in range(s.n_rods)]
    tendons = [f"tendon {name!r}" for name in s.tendon_name]
    rows = [
        (
            "largest rod utilisation",
            ", ".join(
                shown(kind, p, rods, u.rod_every)
                for kind, p in (("buckling", u.rod_buckling), ("yield", u.rod_yield))
            )
            if s.n_rods
            else "no rods",
        ),
        (
            "largest tendon utilisation",
            shown("yield", u.tendon_yield, tendons, u.tendon_every)
            if s.n_tendons
            else "no tendons",
        ),
    ]
    return rows, u.failures(s)


def _counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun``, in the plural (default ``noun + "s"``) unless ``n`` is 1: ``1
    segment``, ``2 segments``, ``3 switches``."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def _resumed(summary) -> str:
    if summary.resumed_from is not None:
        return (
            f"from segment {summary.resumed_from + 1} of {summary.n_segments} "
            f"({summary.segments_run} run now)"
        )
    if summary.segments_run == 0:
        return "the run had ended already; its files written now"
    return "nothing to resume: started afresh"


#: ``info`` counts the degrees of freedom the joints and supports leave (a dense SVD) up to this
#: many degrees of freedom before them.
_INFO_DOF_LIMIT = 3000


def _cmd_info(args: argparse.Namespace) -> int:
    s = _structure(args)
    lengths = dynamics.tendon_lengths(s, s.node_position)
    low, high = s.node_position.min(axis=0), s.node_position.max(axis=0)
    slack = int(np.sum(lengths <= s.tendon_rest_length))
    masses = f", {s.dim} per point mass" if s.point_mass_nodes.size else ""
    dof = f"{s.n_dof} ({2 * s.dim - 1} per rod{masses})"
    if s.has_constraints:
        if s.n_dof <= _INFO_DOF_LIMIT:
            from tensegrity.analysis.coordinates import admitted_dof

            held = s.n_dof - admitted_dof(s)
            dof = (
                f"{s.n_dof - held} ({2 * s.dim - 1} per rod{masses}, less {held} held by the "
                "joints and supports in this layout)"
            )
        else:
            dof += " before the joints and supports"
    rows = [
        ("nodes", s.n_nodes),
        ("rods", s.n_rods),
        ("tendons", s.n_tendons),
        ("degrees of freedom", dof),
        (
            "coordinates q",
            f"{s.n_coordinates} ({2 * s.dim} per rod: q1 = p_a + p_b, q2 = p_b - p_a{masses})",
        ),
        ("total mass", f"{s.total_mass:.6g} kg"),
        ("rod length", _range(s.rod_length, "m")),
        ("tendon stiffness", _range(s.tendon_stiffness, "N/m")),
        ("tendon rest length", _range(s.tendon_rest_length, "m")),
        ("damping", dynamics.describe_damping(s)),
        ("initial tendon length", _range(lengths, "m")),
        ("initially slack tendons", slack),
        (
            "bounding box",
            f"[{', '.join(f'{x:.4g}' for x in low)}] .. [{', '.join(f'{x:.4g}' for x in high)}] m",
        ),
    ]
    supports = (
        ("ball joints (node pairs)", len(s.joint_nodes)),
        ("fixed nodes", int(s.node_fixed.sum())),
        ("point masses", len(s.point_mass_nodes)),
        ("nodes on planes", len(s.plane_nodes)),
        ("nodes on lines", len(s.line_nodes)),
    )
    rows += [(name, count) for name, count in supports if count]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    return 0


def _range(values: np.ndarray, unit: str) -> str:
    if values.size == 0:
        return "-"
    low, high = values.min(), values.max()
    return f"{low:.6g} {unit}" if low == high else f"{low:.6g} .. {high:.6g} {unit}"


def _cmd_export(args: argparse.Namespace) -> int:
    from tensegrity.io.formats import FORMATS, write_network

    structure = _apply_damping(_structure(args), args.damping)
    outputs.check_file(args.output, "--output")
    fmt = args.format or FORMATS.get(args.output.suffix.lower(), "json")
    with folders_made(args.output.parent):
        write_network(args.output, structure, format=fmt, keep_joints=args.keep_joints)
    print(
        f"wrote {args.output} ({fmt}: {structure.n_nodes} nodes, {structure.n_rods} rods, "
        f"{structure.n_tendons} tendons)"
    )
    return 0


def _cmd_vtk(args: argparse.Namespace) -> int:
    from tensegrity.io.trajectory import read_trajectory
    from tensegrity.io.vtk import write_vtk

    outputs.check_folder(args.output, "--output")
    with blame("vtk", args.trajectory):
        trajectory = read_trajectory(args.trajectory)
    written = write_vtk(args.output, trajectory, every=args.every, name=args.name)
    print(f"wrote {len(written) - 1} VTK files and {written[-1]} (open it in ParaView)")
    return 0


#: ``matrices --at equilibrium`` is at rest when node speeds [m/s] and accelerations [m/s^2]
#: are below this.
MATRICES_REST_TOL = 1e-9


def _cmd_matrices(args: argparse.Namespace) -> int:
    from tensegrity.engine.simulate import simulate
    from tensegrity.io.matrices import write_matrices

    outputs.check_folder(args.out, "--out")
    structure = dynamics.undamped(_structure(args))
    _check_matrix_size(structure)
    if args.at == "equilibrium":
        announce_compiling()
        _check_run_cost(
            structure,
            args.t_end,
            steady_state=True,
            acceleration_tol=MATRICES_REST_TOL,
            remedy="softer tendons or a shorter --t-end",
        )
        # Tight rest tolerances: with the damping removed, K_p q = q'' is then below ~1e-8.
        result = simulate(
            dynamics.artificial_damping(structure),
            (0.0, args.t_end),
            steady_state=True,
            velocity_tol=MATRICES_REST_TOL,
            acceleration_tol=MATRICES_REST_TOL,
            rtol=1e-10,
            sample_dt=0.1,
            progress=sys.stderr.isatty(),
        )
        if result.status != 1:
            raise CommandError(
                f"no equilibrium found by damped simulation within --t-end {args.t_end:g} s: "
                f"{result.message}",
                EXIT_FAILED,
            )
        state = result.final_state
    else:
        state = dynamics.initial_state(structure)
    rows: list = []

    def write(staging: Path) -> list[Path]:
        rows.extend(write_matrices(staging, structure, state.q, state.qdot, at=args.at))
        return sorted(staging.iterdir())

    written = _write_all(args.out, write)
    width = max(len(name) for name, _, _ in rows)
    print(f"{'matrix':<{width}}  {'shape':>13}  non-zeros")
    for name, (n_rows, n_cols), nnz in rows:
        print(f"{name:<{width}}  {n_rows:>6} x {n_cols:<6}  {nnz}")
    print(f"evaluated at the {args.at} state; wrote {len(written)} files to {args.out}")
    return 0


#: ``matrices`` builds dense (nodes x nodes) arrays: at most this many nodes (0.5 GiB each).
_MATRICES_NODE_LIMIT = 8192


def _check_matrix_size(structure: Structure) -> None:
    """Fail up front if the matrix model of ``structure`` would need too large dense arrays."""
    n = structure.n_nodes
    if n > _MATRICES_NODE_LIMIT:
        raise CommandError(
            f"matrices: the matrix model of {n} nodes builds dense {n} x {n} arrays "
            f"({n * n * 8 / 2**30:.3g} GiB each); expected at most {_MATRICES_NODE_LIMIT} nodes "
            "(a smaller shell)"
        )


def _cmd_analysis(args: argparse.Namespace) -> int:
    """``equilibrium | modes | controllability | control``: :mod:`tensegrity.cli.analysis`."""
    from tensegrity.cli import analysis as commands

    run = getattr(commands, f"run_{args.command}")
    outputs.check_folder(args.out, "--out")
    # the drawing's workers start now: they import matplotlib while the analysis computes
    workers = worker_count(2) if args.command in _DRAWN_IN_WORKERS else 0
    with Drawing(workers) as drawing:
        return _analysis_and_write(args, run, drawing)


#: The analysis verbs whose figures and pages are drawn in workers: it paid for these
#: (whole processes paired with drawing in the command, 2026-11-26: equilibrium 0.91x, modes
#: 0.85x), not for ``controllability`` (python-control imports matplotlib into the command
#: anyway) nor ``control`` (its figures' plan holds closures, which do not pickle; made
#: picklable, the verb was still 1.06x with workers: its LQR design imports python-control, and
#: so matplotlib): there the workers' imports only competed with the computation (1.14x, 1.11x).
_DRAWN_IN_WORKERS = ("equilibrium", "modes")


def _analysis_and_write(args: argparse.Namespace, run: Callable, drawing: Drawing) -> int:
    """An analysis verb once its output folder is checked: ``run`` on the structure of
    ``args``, its files (the figures and pages drawn by ``drawing``) and its tables."""
    import inspect

    announce_compiling()
    structure = _structure(args)
    if args.command == "equilibrium" and args.method != "least_squares":
        _check_run_cost(
            structure,
            args.t_end,
            steady_state=True,
            acceleration_tol=args.acceleration_tol,
            remedy="softer tendons, a shorter --t-end or --method least_squares",
        )
    options = {
        name: getattr(args, name)
        for name in inspect.signature(run).parameters
        if name != "structure" and hasattr(args, name)
    }
    # The whole computation first, with nothing in --out; then only the writing is staged.
    try:
        output = run(structure, **options)
    except RuntimeError as exc:  # no equilibrium, a failed simulation: nothing written
        raise CommandError(f"{exc} (nothing written)", EXIT_FAILED) from None
    except KeyError as exc:  # a tendon or output pattern that matches nothing
        raise CommandError(str(exc.args[0])) from None
    written = _write_all(args.out, drawing.writing(output.write))
    print(output.text)
    print("\nwrote " + ", ".join(str(f) for f in written))
    if output.problem:
        raise CommandError(f"{output.problem} (results written)", EXIT_FAILED)
    return 0


def _add_analysis_parsers(sub: _Commands) -> None:
    """The analysis verbs (issue 4); option names are the keywords of ``commands.run_<verb>``."""
    verbs = {
        "equilibrium": "static equilibrium by least squares and by damped simulation: node "
        "positions, tensions, slack tendons, residuals",
        "modes": "natural frequencies [Hz], mode shapes, rigid-body modes, mechanisms and the "
        "stability verdict at the equilibrium",
        "controllability": "controllability (observability) ranks, PBH test per mode and "
        "Gramians per set of actuated tendons (measured outputs)",
        "control": "shape control: shorten to --height of the equilibrium height, twist back; "
        "open loop (equilibria) and closed loop (LQR on the nonlinear model)",
    }
    parsers = {}
    for verb, text in verbs.items():
        parsers[verb] = p = sub.add_parser(
            verb,
            help=text,
            description=text[0].upper() + text[1:] + f"; writes {verb}.json and figures to --out.",
        )
        _add_structure_options(p)
        p.add_argument(
            "--out",
            type=arguments.name,
            default=Path(verb),
            help=f"output folder (default ./{verb})",
        )
        p.set_defaults(run=_cmd_analysis)
    for verb in ("equilibrium", "modes", "controllability"):  # shape control: without gravity
        _add_gravity_option(parsers[verb])
    _add_equilibrium_options(parsers["equilibrium"])
    _add_modes_options(parsers["modes"])
    _add_controllability_options(parsers["controllability"])
    _add_control_options(parsers["control"])
    _add_closed_loop_options(parsers["control"])


def _add_equilibrium_options(p: argparse.ArgumentParser) -> None:
    """``equilibrium``: the method and the damped simulation's limits."""
    p.add_argument(
        "--method",
        choices=("both", "least_squares", "simulation"),
        default="both",
        help="least squares (eq. 18.61, analytic Jacobian), damped simulation to rest, "
        "or both and their agreement (default both)",
    )
    p.add_argument(
        "--t-end", type=arguments.positive, default=60.0, help="longest damped simulation [s]"
    )
    p.add_argument(
        "--velocity-tol",
        type=arguments.positive,
        default=1e-6,
        help="at rest when node speeds are below this [m/s] (default 1e-6)",
    )
    p.add_argument(
        "--acceleration-tol",
        type=arguments.positive,
        default=1e-6,
        help="... and node accelerations below this [m/s^2] (default 1e-6)",
    )


def _add_modes_options(p: argparse.ArgumentParser) -> None:
    """``modes``: the shapes drawn and the optional checks."""
    p.add_argument(
        "--shapes",
        type=arguments.whole_non_negative,
        default=6,
        help="mode shapes to draw, the lowest non-rigid modes (default 6)",
    )
    p.add_argument(
        "--check-fft",
        action="store_true",
        help="measure the best-separated frequency by FFT of an undamped simulation",
    )
    p.add_argument(
        "--check-simulation",
        action="store_true",
        help="perturb the equilibrium and simulate with and without damping",
    )


def _patterns(text: str) -> str:
    """``--inputs`` / ``--outputs``: one set, comma-separated names or patterns (none empty)."""
    from tensegrity.analysis.controllability import split_patterns

    try:
        split_patterns(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _add_controllability_options(p: argparse.ArgumentParser) -> None:
    """``controllability``: the input and output sets and the damping."""
    p.add_argument(
        "--inputs",
        nargs="+",
        type=_patterns,
        metavar="PATTERN",
        help="sets of actuated tendons, each 'all' or comma-separated name patterns "
        "(default: all, each family, the first tendon)",
    )
    p.add_argument(
        "--outputs",
        nargs="+",
        type=_patterns,
        metavar="PATTERN",
        help="sets of outputs: position, length, tension, all or name patterns like "
        "'p0_*' (default: position, length, tension, p0_*)",
    )
    p.add_argument(
        "--damping",
        choices=("artificial", "as-is"),
        default="artificial",
        help="damping of the linearization used for the Gramians: the paper's artificial "
        "critical damping (default) or the structure's own",
    )


def _add_control_options(p: argparse.ArgumentParser) -> None:
    """``control``: the targets, the actuators, the steps and the rings."""
    p.add_argument(
        "--height",
        type=arguments.positive,
        default=0.8,
        help="target height as a fraction of the equilibrium height (default 0.8)",
    )
    p.add_argument(
        "--no-twist-back",
        dest="twist_back",
        action="store_false",
        help="only shorten (twist free), do not restore the twist",
    )
    p.add_argument(
        "--actuators",
        default="t1_*",
        help="tendons that shorten the structure (default 't1_*'); every tendon "
        "takes part in the twist-back",
    )
    p.add_argument(
        "--steps",
        type=int,
        nargs=2,
        default=(8, 4),
        metavar=("SHORTEN", "TWIST"),
        help="quasi-static steps per phase (default 8 4)",
    )
    p.add_argument(
        "--bottom",
        type=int,
        nargs="+",
        metavar="NODE",
        help="bottom ring nodes (default: the lowest nodes)",
    )
    p.add_argument(
        "--top",
        type=int,
        nargs="+",
        metavar="NODE",
        help="top ring nodes (default: the highest nodes)",
    )


def _add_closed_loop_options(p: argparse.ArgumentParser) -> None:
    """``control``: the closed loop's times, the bounds and the tolerance."""
    p.add_argument(
        "--no-closed-loop",
        dest="closed_loop",
        action="store_false",
        help="open loop only (no LQR simulation)",
    )
    p.add_argument(
        "--move-time", type=arguments.positive, default=2.0, help="closed loop: time per phase [s]"
    )
    p.add_argument(
        "--settle-time",
        type=arguments.positive,
        default=4.0,
        help="closed loop: time at the final target [s]",
    )
    p.add_argument(
        "--min-rest-length",
        type=arguments.non_negative,
        default=0.05,
        help="bound: rest lengths >= this [m] (default 0.05)",
    )
    p.add_argument(
        "--max-change",
        type=arguments.positive,
        default=0.25,
        help="bound: |rest-length change| <= this [m] (default 0.25)",
    )
    p.add_argument(
        "--min-tension",
        type=arguments.positive,
        default=1.0,
        help="bound: every tendon taut with at least this tension [N] (default 1)",
    )
    p.add_argument(
        "--tolerance",
        type=arguments.positive,
        default=1e-6,
        help="targets reached within this [m, rad] (default 1e-6)",
    )


def _sweep_parameter(text: str) -> tuple[str, list[float], bool]:
    """``--param NAME=V1,V2,...`` (a grid's values, or one value) or ``NAME=LOW:HIGH`` (a Monte
    Carlo range): ``(name, values, whether a range)``."""
    name, sep, values = text.partition("=")
    is_range = ":" in values
    parts = values.split(":") if is_range else values.split(",")
    try:
        numbers = [float(v) for v in parts]
    except ValueError:
        numbers = []
    if not sep or not numbers or (is_range and len(numbers) != 2):
        raise argparse.ArgumentTypeError(f"expected NAME=V1,V2,... or NAME=LOW:HIGH, got {text!r}")
    return name, numbers, is_range


def _sweep_parameters(
    params: Sequence[tuple[str, list[float], bool]], monte_carlo: bool
) -> dict[str, list[float]]:
    """The values of the ``--param`` options, each in the form of the sweep's mode: ranges
    ``LOW:HIGH`` for a Monte Carlo sample (``--samples``), lists ``V1,V2,...`` for a grid (one
    value fits both)."""
    for name, values, is_range in params:
        if is_range and not monte_carlo:
            raise CommandError(
                f"--param {name}: LOW:HIGH is a range to draw from and needs --samples N (a "
                "Monte Carlo sample); a grid takes the values V1,V2,..."
            )
        if not is_range and len(values) > 1 and monte_carlo:
            raise CommandError(
                f"--param {name}: V1,V2,... are a grid's values; with --samples give a range "
                "LOW:HIGH or one value"
            )
    return {name: values for name, values, _ in params}


def _cmd_sweep(args: argparse.Namespace) -> int:
    from tensegrity.sweep.run import SweepSpec, run_sweep

    outputs.check_file(args.output, "--output")
    options = {
        name: getattr(args, name)
        for name in ("samples", "seed", "t_end", "sample_dt", "method", "dt")
        if getattr(args, name) is not None
    }
    if args.no_batch:
        options["batch"] = False
    if args.spec is not None:
        if args.param or options or args.structure is not None:
            raise CommandError(
                "--spec: cannot be combined with --param, --structure or run options"
            )
        with blame("--spec", args.spec):
            spec = SweepSpec.from_file(args.spec)
        where = f"--spec: {shown_path(args.spec)}: "
        _check_samples(spec.t_end, spec.sample_dt, ("t_end", "sample_dt"), where)
    elif not args.param:
        raise CommandError("sweep: give --spec FILE or at least one --param NAME=VALUES")
    else:
        defaults = {field.name: field.default for field in dataclasses.fields(SweepSpec)}
        _check_samples(
            options.get("t_end", defaults["t_end"]), options.get("sample_dt", defaults["sample_dt"])
        )
        mode = "monte-carlo" if args.samples is not None else "grid"
        if args.structure is not None:
            options["structure"] = _read_structure(args.structure, "--structure")
        with _in_sweep_options():
            spec = SweepSpec(
                _sweep_parameters(args.param, args.samples is not None), mode=mode, **options
            )
    _check_sweep_size(spec)
    with _in_sweep_options():
        result = run_sweep(
            spec, scheduler=args.scheduler, n_workers=args.workers, progress=sys.stderr.isatty()
        )
    with folders_made(args.output.parent):
        path = result.save(args.output)
    n = result.dataset.sizes["case"]
    print(
        f"{n - len(result.failed)} of {n} cases reached t_end in {result.wall_time:.1f} s; "
        f"wrote {path}"
    )
    for i in result.failed:
        print(f"{result.describe_case(i)}: {result.dataset['message'].values[i]}", file=sys.stderr)
    return EXIT_FAILED if result.failed else 0


#: ``sweep``'s memory [bytes]: a part per case (with its series' own bytes per sample) and the
#: rest, fitted to the peak resident memory of default grids of 1,000 and 4,000 cases (2026-11-27,
#: 2-core machine: 306 and 604 MB at 101 samples a case: 99 kB a case).
SWEEP_CASE_BYTES = 94_000
SWEEP_BASE_BYTES = 207 * 10**6
#: ``sweep`` says how much memory a sweep of at least this many cases takes before it starts.
LARGE_SWEEP_CASES = 10_000


def _check_sweep_size(spec: SweepSpec) -> None:
    """Before a sweep of :data:`LARGE_SWEEP_CASES` cases or more (``spec``, a
    :class:`tensegrity.sweep.run.SweepSpec`): refuse it if its memory exceeds the memory
    available, else say on stderr how much it takes."""
    from tensegrity.sweep.run import SERIES

    cases = spec.n_cases
    if cases < LARGE_SWEEP_CASES:
        return
    per_case = SWEEP_CASE_BYTES + 8 * len(SERIES) * spec.times.size
    needed = SWEEP_BASE_BYTES + cases * per_case
    _refuse_beyond_memory(
        needed, f"a sweep of {cases:,} cases", "for its results", "sweep fewer cases"
    )
    print(
        f"tensegrity: a large sweep: {cases:,} cases, about {byte_text(needed)} of memory",
        file=sys.stderr,
    )


#: The sweep's arguments (``SweepSpec`` fields, ``run_sweep`` keywords) the options set.
_SWEEP_OPTIONS = {
    "parameters": "--param",
    "samples": "--samples",
    "seed": "--seed",
    "t_end": "--t-end",
    "sample_dt": "--sample-dt",
    "method": "--method",
    "dt": "--dt",
    "n_workers": "--workers",
    "scheduler": "--scheduler",
}


@contextlib.contextmanager
def _in_sweep_options() -> Iterator[None]:
    """A sweep's ``ValueError`` raised within the block (``SweepSpec``, ``run_sweep``) as a
    one-line error naming the options the user typed instead of the library's arguments:
    ``parameters.n[1]: ...`` -> ``--param n: ...``, ``t_end: ... of sample_dt`` ->
    ``--t-end: ... of --sample-dt``.  A message that names no argument (a case's) stays."""
    try:
        yield
    except ValueError as exc:
        message = one_line(exc)
        field, sep, problem = message.partition(": ")
        parameter = re.fullmatch(r"parameters\.(.+?)(?:\[\d+\])?", field)
        if parameter is not None:
            message = f"--param {parameter.group(1)}: {problem}"
        elif sep and field in _SWEEP_OPTIONS:
            problem = re.sub(r"\b(t_end|sample_dt|dt)\b", lambda m: _SWEEP_OPTIONS[m[1]], problem)
            message = f"{_SWEEP_OPTIONS[field]}: {problem}"
        raise CommandError(message) from exc


def _add_simulate_parser(sub: _Commands) -> None:
    """``simulate``: run a structure and write its trajectory, structure and figures."""
    sim = sub.add_parser(
        "simulate",
        help="simulate a structure (default: the paper's damped (3,1) shell, until steady state)",
        description="Simulate a structure and write trajectory.h5, structure.json, figures, "
        "view.html (the run in an interactive 3-D viewer) and motion.gif (the run as a "
        "video). "
        "Samples are streamed to OUT/.trajectory.h5.partial as the run goes, with "
        "checkpoints; an interrupted run continues with --resume.",
    )
    _add_structure_options(sim)
    sim.add_argument(
        "--damping",
        type=_damping,
        metavar="internal|artificial|none|VALUE",
        help="'internal' (default for a generated structure: each tendon and the rods' "
        "motion relative to the rigid-body motion critically damped; a free fall is not "
        "slowed), 'artificial' (the paper's: the same rates, the rods damped to ground), "
        "'none', or c in N s/m for every tendon and no rod damping (default for --structure: "
        "as in the file). The summary names the damping used; see docs/simulation.md",
    )
    sim.add_argument(
        "--t-end", type=arguments.positive, default=60.0, help="end time [s] (default 60)"
    )
    sim.add_argument(
        "--no-steady-state",
        action="store_true",
        help="run to --t-end even after the structure has come to rest",
    )
    sim.add_argument(
        "--out",
        type=arguments.name,
        default=Path("results"),
        help="output folder (default ./results)",
    )
    sim.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted run in --out from its last checkpoint (same "
        "structure and options; without it a run starts afresh)",
    )
    sim.add_argument(
        "--force-table",
        type=arguments.name,
        metavar="FILE.npz|FILE.csv",
        help="external nodal forces [N] from a time table, linear in between, held "
        "after its end (.npz: time (T,), force (T, N, 3); .csv: rows t, f0x, "
        "f0y, f0z, f1x, ...)",
    )
    _add_gravity_option(sim)
    sim.add_argument(
        "--vtk",
        action="store_true",
        help="also write the run for ParaView: OUT/vtk/tensegrity.pvd + .vtp files",
    )
    sim.add_argument(
        "--no-view",
        action="store_true",
        help="do not write OUT/view.html, the run in an interactive 3-D viewer (one offline "
        "HTML file; `tensegrity view` makes one from trajectory.h5 later)",
    )
    from tensegrity.plots.motion import MAX_REAL_TIME  # (light: no matplotlib)

    video = sim.add_mutually_exclusive_group()
    video.add_argument(
        "--animation",
        choices=("gif", "mp4", "webm"),
        help="the format of OUT/motion.gif (or .mp4, .webm): the run as a video at "
        f"{VIDEO_FPS:g} fps in real time (at most {MAX_REAL_TIME:g} s of video; `tensegrity "
        "animate` makes "
        "others later). Default gif, drawn unasked when that takes about "
        f"{DEFAULT_VIDEO_SECONDS:g} s or less (frames x members; the run says when not); "
        "given, always drawn",
    )
    video.add_argument(
        "--no-animation",
        action="store_true",
        help="do not write OUT/motion.gif",
    )
    design = sim.add_argument_group("design checks (members with a material and section)")
    arguments.add_safety_factor(design)
    design.add_argument(
        "--stop-on-failure",
        action="store_true",
        help="stop the run at the first sample where a member is over its limits "
        "(utilisation > 1); the files hold the run up to there",
    )
    _add_integration_options(sim)
    sim.set_defaults(run=_cmd_simulate)


def _add_integration_options(parser: argparse.ArgumentParser) -> None:
    """``simulate``'s integration options (method, step, tolerances, sampling)."""
    integration = parser.add_argument_group("integration")
    integration.add_argument(
        "--method",
        default="DOP853",
        choices=[*ADAPTIVE_METHODS, *FIXED_STEP_METHODS],
        help="adaptive scipy method or fixed-step 'rk4' (default DOP853)",
    )
    integration.add_argument("--dt", type=arguments.positive, help="fixed step [s] (rk4 only)")
    integration.add_argument(
        "--rtol", type=arguments.positive, default=1e-9, help="relative tolerance (default 1e-9)"
    )
    integration.add_argument(
        "--atol", type=arguments.positive, default=1e-12, help="absolute tolerance (default 1e-12)"
    )
    integration.add_argument(
        "--sample-dt",
        type=arguments.positive,
        default=0.01,
        help="output spacing [s] (default 0.01)",
    )
    integration.add_argument(
        "--max-steps",
        type=arguments.whole_positive,
        default=DEFAULT_MAX_STEPS,
        help=f"stop (exit 1) after this many steps (default {DEFAULT_MAX_STEPS:,})",
    )
    integration.add_argument(
        "--max-wall-time",
        type=arguments.positive,
        default=math.inf,
        metavar="SECONDS",
        help="stop (exit 1) after this much wall-clock time (default: none)",
    )


def _add_info_parser(sub: _Commands) -> None:
    """``info``: counts and sizes of a structure."""
    info = sub.add_parser("info", help="print counts and sizes of a structure")
    _add_structure_options(info)
    info.set_defaults(run=_cmd_info)


def _add_export_parser(sub: _Commands) -> None:
    """``export``: a structure to a file in any format."""
    export = sub.add_parser(
        "export", help="write a generated structure or a structure file to a file (any format)"
    )
    _add_structure_options(export)
    export.add_argument(
        "--damping",
        type=_damping,
        metavar="internal|artificial|none|VALUE",
        help="damping to store, as for simulate (default: none for a generated structure, "
        "as in the file for --structure)",
    )
    export.add_argument(
        "--format",
        choices=("json", "yaml", "toml", "connectivity", "mjcf"),
        help="file format (default: from the suffix .json .yaml .toml .npz .xml, else json)",
    )
    export.add_argument(
        "--keep-joints",
        action="store_true",
        help="yaml/toml/connectivity: keep every rod's end nodes and list the ball "
        "joints (reads back identical) instead of merging joined nodes into "
        "nodes shared by bars (class k, the default)",
    )
    export.add_argument("-o", "--output", type=arguments.name, required=True, help="output file")
    export.set_defaults(run=_cmd_export)


def _add_vtk_parser(sub: _Commands) -> None:
    """``vtk``: a trajectory file to VTK files for ParaView."""
    vtk = sub.add_parser(
        "vtk",
        help="convert a trajectory to VTK files for ParaView",
        description="Write a trajectory (trajectory.h5) as one VTK PolyData file "
        "per sample (.vtp) and a collection (.pvd) for ParaView.",
    )
    vtk.add_argument("trajectory", type=arguments.name, help="a trajectory.h5 written by simulate")
    vtk.add_argument("-o", "--output", type=arguments.name, required=True, help="output folder")
    vtk.add_argument("--every", type=int, default=1, help="keep one sample in EVERY (default 1)")
    vtk.add_argument("--name", default="tensegrity", help="file name stem (default tensegrity)")
    vtk.set_defaults(run=_cmd_vtk)


def _add_matrices_parser(sub: _Commands) -> None:
    """``matrices``: the paper's matrix model of a shell to files."""
    matrices = sub.add_parser(
        "matrices",
        help="write the paper's matrices (Q, R, T, B^d, B^o, H, K_r, K_p, B, D, ...) of a shell",
        description="Write the matrix model (18.59) of a class 1 shell as .npz and Matrix Market "
        "(.mtx) files with an index (matrices.json).",
    )
    _add_structure_options(matrices)
    matrices.add_argument(
        "--at",
        choices=("initial", "equilibrium"),
        default="initial",
        help="state at which the state-dependent matrices are evaluated: the "
        "initial layout, or the equilibrium reached by damped simulation",
    )
    matrices.add_argument(
        "--t-end",
        type=arguments.positive,
        default=60.0,
        help="longest damped simulation when looking for the equilibrium [s]",
    )
    matrices.add_argument(
        "--out",
        type=arguments.name,
        default=Path("matrices"),
        help="output folder (default ./matrices)",
    )
    matrices.set_defaults(run=_cmd_matrices)


def _add_sweep_parser(sub: _Commands) -> None:
    """``sweep``: a parameter sweep on Dask."""
    sweep = sub.add_parser(
        "sweep",
        help="simulate many shells or copies of a structure file (a grid or Monte Carlo "
        "sample of parameters) on Dask",
        description="Run a parameter sweep on Dask and write one netCDF/HDF5 dataset; exit code 1 "
        "if some case failed (reported per case, the others are kept).",
    )
    sweep.add_argument(
        "--spec", type=arguments.name, metavar="FILE", help="sweep spec (.json or .yaml)"
    )
    sweep.add_argument(
        "--structure",
        type=arguments.name,
        metavar="FILE",
        help="sweep this structure file (any format) instead of the class 1 shell: "
        "then stiffness, rest_scale, damping and load can vary",
    )
    sweep.add_argument(
        "--param",
        type=_sweep_parameter,
        action="append",
        metavar="NAME=VALUES",
        help="vary NAME (n, m, stiffness, rest_scale, damping, load): V1,V2,... "
        "for a grid, LOW:HIGH with --samples; repeatable",
    )
    sweep.add_argument("--samples", type=int, help="Monte Carlo sample of this many cases")
    sweep.add_argument("--seed", type=int, help="Monte Carlo seed (default 0)")
    sweep.add_argument(
        "--t-end", type=arguments.positive, help="simulated time per case [s] (default 0.1)"
    )
    sweep.add_argument(
        "--sample-dt", type=arguments.positive, help="output spacing [s] (default 1e-3)"
    )
    sweep.add_argument("--method", help="rk4 (default) or an adaptive scipy method")
    sweep.add_argument("--dt", type=arguments.positive, help="rk4 step [s] (default 1e-4)")
    sweep.add_argument(
        "--no-batch",
        action="store_true",
        help="run rk4 cases one by one through simulate, not batched",
    )
    sweep.add_argument(
        "--scheduler", metavar="ADDRESS", help="Dask scheduler address (default: a local cluster)"
    )
    sweep.add_argument("--workers", type=int, help="local cluster workers (default: CPU count)")
    sweep.add_argument(
        "-o",
        "--output",
        type=arguments.name,
        required=True,
        help="output .nc file (missing folders are made, as for every verb's outputs)",
    )
    sweep.set_defaults(run=_cmd_sweep)


def build_parser() -> argparse.ArgumentParser:
    """The parser of the ``tensegrity`` command: one subcommand per verb, and ``--debug``."""
    parser = _Parser(prog=PROG, description=DESCRIPTION)
    _add_debug_option(parser, default=False)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_simulate_parser(sub)
    _add_info_parser(sub)
    _add_export_parser(sub)
    _add_vtk_parser(sub)
    _add_matrices_parser(sub)
    _add_analysis_parsers(sub)
    _add_sweep_parser(sub)
    visual.add_parsers(sub)  # animate, view
    design.add_parsers(sub)  # design: minimal-mass members
    for verb in sub.choices.values():  # after the verb too; not given there: the command's value
        _add_debug_option(verb, default=argparse.SUPPRESS)
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
    args, unknown = build_parser().parse_known_args(argv)
    if unknown:
        raise CommandError(
            f"{args.command}: unrecognized arguments: {' '.join(unknown)} "
            f"(see {PROG} {args.command} --help)"
        )
    return args


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
