"""``tensegrity design``: minimal-mass members for a structure's geometry under load cases, at
the given geometry or at each case's loaded equilibrium (:func:`tensegrity.design.loaded.size`,
``docs/design.md``); writes the sized structure and a report to ``--out``::

    tensegrity design --structure crane.json --material steel,dyneema \\
        --load down:1:0,0,-1000 --load side:1:0,-1000,-1000 --prestress 0 -o out/

writes ``out/structure.json`` (the sized structure in the material form: its members by
material and section, and the safety and strength factors it was sized with under ``factors``;
:func:`tensegrity.design.files.write_design`), so that ``tensegrity simulate --structure
out/structure.json`` and ``view --structure`` report the members' utilisation with those
factors, and ``out/design.json`` (masses, areas, sections, forces and utilisations per case),
together or not at all (:func:`tensegrity.io.files.write_staged`), and prints a summary.  No
numeric form is written: every verb reads the material form (in Python,
:func:`~tensegrity.design.files.read_design`; ``Structure.to_dict`` of its structure is the
numeric form).  Bad input and a load case the structure cannot carry are one line with exit
code 2.  The first paragraph is the verb's ``--help`` description
(:func:`tensegrity.cli.arguments.description`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.cli import arguments, structures
from tensegrity.cli.errors import EXIT_FAILED, CommandError, blame, one_line
from tensegrity.cli.startup import announce_compiling
from tensegrity.io.files import atomic_path, shown_path, write_staged

if TYPE_CHECKING:
    from tensegrity.design.materials import Material, MemberDesign

__all__ = ["add_parsers"]


def _load(text: str) -> tuple[str, str, list[float]]:
    """``CASE:NODE:FX,FY[,FZ]`` [N], NODE a node name or 0-based index (resolved by
    :meth:`Structure.node_index <tensegrity.model.structure.Structure.node_index>`)."""
    case, sep, rest = text.partition(":")
    if not (sep and case):
        raise argparse.ArgumentTypeError(f"expected CASE:NODE:FX,FY,FZ (newtons), got {text!r}")
    return (case, *arguments.node_force(rest, "CASE:NODE:FX,FY,FZ", text))


def _prestress(text: str) -> float | tuple[float, float]:
    """``N`` (>= 0) or ``LOW:HIGH`` (0 < LOW < HIGH) [N]."""
    low, sep, high = text.partition(":")
    try:
        values = [float(low)] + ([float(high)] if sep else [])
    except ValueError:
        values = [math.nan]
    if not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected N or LOW:HIGH (newtons), got {text!r}")
    if not sep:
        if values[0] < 0:
            raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
        return values[0]
    if not 0 < values[0] < values[1]:
        raise argparse.ArgumentTypeError(f"a range must be 0 < LOW < HIGH, got {text!r}")
    return values[0], values[1]


def _shape(text: str) -> float | None:
    """``solid`` (None) or ``tube:RATIO`` (wall thickness over outer diameter)."""
    if text == "solid":
        return None
    kind, _, ratio = text.partition(":")
    try:
        value = float(ratio)
    except ValueError:
        value = math.nan
    if kind != "tube" or not 0 < value <= 0.5:
        raise argparse.ArgumentTypeError(
            f"expected solid or tube:T/D with 0 < T/D <= 0.5, got {text!r}"
        )
    return value


#: The verb's line in ``tensegrity --help``.
HELP = "minimal-mass rods and tendons under yield and buckling for load cases"


def add_parsers(sub: Any) -> None:
    """Add the ``design`` verb to the ``tensegrity`` subcommands ``sub``."""
    from tensegrity.design.dynamic import DAMPING_RATIO
    from tensegrity.design.loaded import STATICS
    from tensegrity.design.materials import MATERIALS

    names = ", ".join(sorted(MATERIALS))
    p = sub.add_parser(
        "design",
        help=HELP,
        description=arguments.description(__doc__),
    )
    structures.add_source_options(p)
    p.add_argument(
        "--statics",
        choices=STATICS,
        default="auto",
        help="the members' forces: at the given geometry (linear: a statically determinate or "
        "stiff structure), at each load case's loaded equilibrium (equilibrium: a tensegrity "
        "stiffened by its prestress), or auto: linear unless the structure has a mechanism "
        "(default %(default)s)",
    )
    p.add_argument(
        "--form-find",
        action="store_true",
        help="size at the structure's own unloaded equilibrium (its rest lengths and "
        "stiffness; e.g. a generated shell, whose layout is not one) instead of its node "
        "positions",
    )
    p.add_argument(
        "--material",
        required=True,
        metavar="ROD[,TENDON]",
        help=f"material of the rods, and of the tendons if different: {names}",
    )
    p.add_argument(
        "--section",
        type=_shape,
        default=None,
        metavar="solid|tube:T/D",
        help="rod section: solid round bars (default) or round tubes of wall thickness T/D "
        "times the outer diameter; tendons are round cables",
    )
    p.add_argument(
        "--load",
        type=_load,
        action="append",
        default=[],
        metavar="CASE:NODE:FX,FY,FZ",
        help="a nodal force [N] of load case CASE on NODE, a node name of the structure file "
        "or a 0-based index (digits name a node if one has that name) (repeat: forces of one "
        "case add up)",
    )
    p.add_argument(
        "--gravity",
        type=arguments.at_least(0.0, strict=False),
        default=0.0,
        metavar="G",
        help="gravity [m/s^2] down the last axis on the members' weight in every load case "
        "(default %(default)g: none)",
    )
    p.add_argument(
        "--prestress",
        type=_prestress,
        default=0.0,
        metavar="N|LOW:HIGH",
        help="the smallest tendon tension [N] of the unloaded, prestressed state (default "
        "%(default)g), or a range in which the lightest design is searched (at the loaded "
        "equilibrium)",
    )
    p.add_argument(
        "--max-displacement",
        type=arguments.at_least(0.0, strict=True),
        metavar="M",
        help="the largest node displacement [m] allowed under each load case (at the loaded "
        "equilibrium; default: no limit)",
    )
    p.add_argument(
        "--min-frequency",
        type=arguments.at_least(0.0, strict=True),
        metavar="HZ",
        help="the lowest natural frequency [Hz] allowed, prestressed and under each load case "
        "(at the loaded equilibrium; default: no limit)",
    )
    p.add_argument(
        "--least-mass",
        action="store_true",
        help="from the fully stressed design, search the least mass under every limit (SLSQP "
        "with the equilibria's sensitivities; a local minimum; at the loaded equilibrium)",
    )
    p.add_argument(
        "--stability-margin",
        type=arguments.at_least(0.0, strict=True),
        default=None,
        metavar="F",
        help="with --least-mass: along every load path, the softest mode's omega^2 at least F "
        "times the fully stressed design's (default 0.25)",
    )
    arguments.add_factors(p, from_file=False)
    p.add_argument(
        "--min-area",
        type=arguments.at_least(0.0, strict=True),
        default=1e-8,
        metavar="M2",
        help="the smallest member area [m^2] (default %(default)g)",
    )
    p.add_argument(
        "--tendon-mass", action="store_true", help="count the tendons' own weight and mass"
    )
    p.add_argument(
        "--check-dynamics",
        action="store_true",
        help="simulate the sized structure under each load case applied suddenly (from rest at "
        "the prestressed equilibrium) and report the members' largest utilisation in motion",
    )
    p.add_argument(
        "--damping-ratio",
        type=arguments.at_least(0.0, strict=False),
        default=None,
        metavar="ZETA",
        help="with --check-dynamics: each tendon's damping as a fraction of its critical "
        f"damping (default {DAMPING_RATIO:g}; 0: undamped)",
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.set_defaults(run=_cmd_design)


def _cmd_design(args: argparse.Namespace) -> int:
    from tensegrity.design.files import write_design
    from tensegrity.design.loaded import size
    from tensegrity.design.materials import member_table
    from tensegrity.design.sizing import LoadCase

    if args.out.exists() and not args.out.is_dir():
        raise CommandError(f"--out: {shown_path(args.out)} is a file, expected a folder")
    with blame("--material", None):
        rod_material, tendon_material = structures.parse_materials(args.material)
    if args.stability_margin is not None and not args.least_mass:
        raise CommandError("--stability-margin: only with --least-mass")
    structure = structures.source_of(args).structure  # its geometry and topology
    if args.form_find:
        structure = _form_found(structure)
    d = structure.dim
    forces: dict[str, np.ndarray] = {}
    for case, node, force in args.load:
        where = f"--load {case}:{node}"
        try:
            index = structure.node_index(node)
        except KeyError as exc:
            raise CommandError(f"{where}: {exc.args[0]}") from None
        if len(force) != d:
            raise CommandError(f"{where}: expected {d} force components, got {len(force)}")
        forces.setdefault(case, np.zeros((structure.n_nodes, d)))[index] += force
    gravity = None
    if args.gravity:
        gravity = np.zeros(d)
        gravity[-1] = -args.gravity
    if args.gravity and not forces:
        forces["gravity"] = np.zeros((structure.n_nodes, d))
    cases = [LoadCase(name, w, gravity) for name, w in forces.items()]
    if not cases and not args.prestress:
        raise CommandError("--load: give at least one load case (or --prestress N > 0)")
    try:
        sizing = size(
            structure,
            statics=args.statics,
            rod_material=rod_material,
            tendon_material=tendon_material,
            load_cases=cases,
            prestress=args.prestress,
            wall_ratio=args.section,
            safety_factor=args.safety_factor,
            strength_factor=args.strength_factor,
            min_area=args.min_area,
            tendon_mass=args.tendon_mass,
            **{
                name: value
                for name, value in (
                    ("max_displacement", args.max_displacement),
                    ("min_frequency", args.min_frequency),
                    ("least_mass", args.least_mass or None),
                    ("stability_margin", args.stability_margin),
                )
                if value is not None
            },
        )
    except ValueError as exc:
        hint = ""
        if str(exc).startswith("prestress: no self-stress") and not args.form_find:
            hint = " at the given geometry (--form-find sizes at the structure's own equilibrium)"
        raise CommandError(one_line(exc) + hint) from None
    dynamic = _dynamic(args, sizing, cases)
    report = sizing.to_dict() | {
        "settings": dict(
            structure=None if args.structure is None else str(args.structure),
            kind=None if args.structure is not None else args.kind or "shell",
            statics=sizing.statics,
            form_find=args.form_find,
            rod_material=rod_material.name,
            tendon_material=tendon_material.name,
            section="solid" if args.section is None else f"tube, t/D = {args.section:g}",
            prestress_N=args.prestress,
            max_displacement_m=args.max_displacement,
            min_frequency_hz=args.min_frequency,
            least_mass=args.least_mass,
            stability_margin=args.stability_margin,
            gravity_m_per_s2=args.gravity,
            safety_factor=args.safety_factor,
            strength_factor=args.strength_factor,
            min_area_m2=args.min_area,
            tendon_mass=args.tendon_mass,
        ),
        "members": member_table(sizing.structure, sizing.members),
    }
    if dynamic is not None:
        report["dynamic"] = dynamic

    members = _member_design(args, sizing, rod_material, tendon_material)

    def write(staging: Path) -> list[Path]:
        target = write_design(
            staging / "structure.json", sizing.structure, members, keep_joints=True
        )
        with atomic_path(staging / "design.json") as tmp:
            tmp.write_text(json.dumps(report, indent=2, allow_nan=False) + "\n", "utf-8")
        return [target, staging / "design.json"]

    written = write_staged(args.out, write)
    u = sizing.utilisation
    print(
        f"total mass {sizing.total_mass:.6g} kg (rods {sizing.rod_mass.sum():.6g} kg, tendons "
        f"{sizing.tendon_mass.sum():.6g} kg); {sizing.message}"
    )
    moves = [] if sizing.displacement is None else sizing.displacement.tolist()
    shown = dict(zip(sizing.cases[::-1], moves[::-1], strict=False))
    hz = [] if sizing.frequency is None else sizing.frequency.tolist()
    for k, case in enumerate(sizing.cases):
        rod = u.rod[k].max(initial=0.0)
        tendon = u.tendon[k].max(initial=0.0)
        moved = f", largest displacement {shown[case]:.4g} m" if case in shown else ""
        lowest = f", lowest frequency {hz[k]:.4g} Hz" if hz else ""
        print(
            f"case {case!r}: largest utilisation rods {rod:.4g}, tendons {tendon:.4g}"
            f"{moved}{lowest}"
        )
    print(_governing(sizing))
    failing = []
    dynamic = dynamic or {"cases": []}
    for case in dynamic["cases"]:
        verdict = "a member exceeds its limits" if case["exceeds"] else "within limits"
        print(
            f"case {case['case']!r} applied suddenly: largest utilisation "
            f"{case['largest_utilisation']:.4g} in motion ({case['duration_s']:.4g} s simulated, "
            f"damping ratio {dynamic['damping_ratio']:g}): {verdict}"
        )
        failing += [f"case {case['case']!r}: {line}" for line in case["failures"]]
    print("wrote " + ", ".join(str(f) for f in written))
    if failing:
        more = f"; and {len(failing) - 3} more" if len(failing) > 3 else ""
        print(
            "tensegrity: warning: under loads applied suddenly, members exceed their limits: "
            + "; ".join(failing[:3])
            + more,
            file=sys.stderr,
        )
    return 0


def _governing(sizing: Any) -> str:
    """One line: how many members each constraint governs (``--min-area`` and ``stability``
    named), and the statics used."""
    counts: dict[str, int] = {}
    for what in sizing.governs:
        counts[what] = counts.get(what, 0) + 1
    least = "least mass" in sizing.message  # above its force area: set by a limit of the whole
    stiffened = "kept above their force areas" if least else "tendons stiffened"
    words = {
        "yield": "yield",
        "buckling": "buckling",
        "min_area": "the least area (--min-area)",
        "stability": f"stability ({stiffened} against a limit point)",
        "displacement": f"--max-displacement ({stiffened})",
        "frequency": f"--min-frequency ({stiffened})",
        "stiffness": "no limit of their own (kept above their force areas: little mass)",
    }
    parts = [
        f"{n} by {' and '.join(words.get(w, w) for w in what.split('+'))}"
        for what, n in counts.items()
    ]
    statics = {
        "linear": "forces at the given geometry",
        "equilibrium": "forces at each case's loaded equilibrium",
    }[sizing.statics]
    return f"members governed: {', '.join(parts)} ({statics})"


def _form_found(structure: Any) -> Any:
    """``--form-find``: ``structure`` at its own stable unloaded equilibrium, all tendons taut;
    a one-line error otherwise."""
    from tensegrity.analysis.equilibrium import find_equilibrium
    from tensegrity.analysis.linearize import linearize
    from tensegrity.analysis.modes import modal_analysis

    found = find_equilibrium(structure)
    if not found.converged:
        raise CommandError(f"--form-find: no equilibrium found ({found.message})", EXIT_FAILED)
    if found.slack.any():
        raise CommandError(
            "--form-find: the equilibrium found has slack tendons "
            f"({', '.join(found.slack_names[:5])}): no prestress in them to size",
            EXIT_FAILED,
        )
    if not modal_analysis(linearize(structure, found)).stable:
        raise CommandError("--form-find: the equilibrium found is not stable", EXIT_FAILED)
    return structure.replace(node_position=found.node_position)


def _dynamic(args: argparse.Namespace, sizing: Any, cases: list[Any]) -> dict[str, Any] | None:
    """``--check-dynamics``: :func:`tensegrity.design.dynamic.dynamic_check` of the sized
    structure under the load cases, as the report's ``dynamic`` section (None without it)."""
    if not args.check_dynamics:
        if args.damping_ratio is not None:
            raise CommandError("--damping-ratio: only with --check-dynamics")
        return None
    from tensegrity.design.dynamic import DAMPING_RATIO, dynamic_check

    ratio = DAMPING_RATIO if args.damping_ratio is None else args.damping_ratio
    if not ratio < 1:
        raise CommandError(f"--damping-ratio: must be < 1, got {ratio:g}")
    if not cases:
        raise CommandError("--check-dynamics: give a load case (--load or --gravity)")
    announce_compiling()
    try:
        runs = dynamic_check(
            sizing.structure,
            sizing.members,
            cases,
            damping_ratio=ratio,
            safety_factor=args.safety_factor,
            strength_factor=args.strength_factor,
        )
    except ValueError as exc:
        raise CommandError(f"--check-dynamics: {' '.join(str(exc).split())}", EXIT_FAILED) from None
    s = sizing.structure
    return dict(
        damping_ratio=ratio,
        cases=[
            dict(
                case=run.name,
                duration_s=run.duration,
                sample_dt_s=run.sample_dt,
                largest_utilisation=run.largest,
                static_largest_utilisation=float(
                    max(
                        sizing.utilisation.tendon[sizing.cases.index(run.name)].max(initial=0.0),
                        sizing.utilisation.rod[sizing.cases.index(run.name)].max(initial=0.0),
                    )
                ),
                exceeds=run.fails,
                failures=run.utilisation.failures(s),
                tendon_peak=run.utilisation.tendon_peak.tolist(),
                tendon_peak_time_s=run.utilisation.tendon_peak_time.tolist(),
                rod_peak=run.utilisation.rod_peak.tolist(),
                rod_peak_time_s=run.utilisation.rod_peak_time.tolist(),
            )
            for run in runs
        ],
    )


def _member_design(
    args: argparse.Namespace, sizing: Any, rod_material: Material, tendon_material: Material
) -> MemberDesign:
    """The sized members (``sizing``, of ``--material``, ``--section``, ``--tendon-mass``) as a
    :class:`~tensegrity.design.materials.MemberDesign` with the ``--safety-factor`` and
    ``--strength-factor`` they were sized with: what ``out/structure.json`` carries."""
    from tensegrity.design.materials import Cable, Factors, MemberDesign, round_section

    return MemberDesign.of(
        sizing.structure,
        rod_material=rod_material,
        rod_section=[round_section(A, wall_ratio=args.section) for A in sizing.rod_area],
        tendon_material=tendon_material,
        tendon_section=[Cable(math.sqrt(4 * A / math.pi)) for A in sizing.tendon_area],
        tendon_mass=args.tendon_mass,
        factors=Factors(args.safety_factor, args.strength_factor),
    )
