"""``tensegrity simulate``'s parser: its options, their help and the types that read them
(:func:`simulate_parser`); the command that runs them is :mod:`tensegrity.cli.simulate`."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tensegrity.cli import arguments
from tensegrity.cli.simulate_files import DEFAULT_VIDEO_SECONDS, VIDEO_FPS
from tensegrity.cli.structures import add_gravity_option, add_structure_options, damping_kind
from tensegrity.engine.options import ALL_METHODS, OPTION_FIELDS, option_help

if TYPE_CHECKING:
    from tensegrity.model.loads import NodalLoad


def simulate_parser(sub: Any) -> argparse.ArgumentParser:
    """``simulate``'s parser, added to the verbs ``sub``: run a structure and write its
    trajectory, structure and figures (the command it runs: :mod:`tensegrity.cli.simulate`)."""
    sim = sub.add_parser(
        "simulate",
        help="simulate a structure (default: the paper's damped (3,1) shell, until steady state)",
        description="Simulate a structure and write trajectory.h5, structure.json, figures, "
        "view.html (the run in an interactive 3-D viewer) and motion.gif (the run as a "
        "video). "
        "Samples are streamed to OUT/.trajectory.h5.partial as the run goes, with "
        "checkpoints; an interrupted run continues with --resume.",
    )
    add_structure_options(sim)
    sim.add_argument(
        "--damping",
        type=damping_kind,
        metavar="internal|artificial|none|VALUE",
        help="'internal' (default for a generated structure: each tendon and the rods' "
        "motion relative to the rigid-body motion critically damped; a free fall is not "
        "slowed), 'artificial' (the paper's: the same rates, the rods damped to ground), "
        "'none', or c in N s/m for every tendon and no rod damping (default for --structure: "
        "as in the file). The summary names the damping used; see docs/simulation.md",
    )
    sim.add_argument(
        "--t-end", type=arguments.positive, default=60.0, help="end time [s] (default %(default)g)"
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
        "f0y, f0z, f1x, ... for every node, after an optional row of column names)",
    )
    sim.add_argument(
        "--load",
        type=nodal_load,
        action="append",
        default=[],
        metavar="NODE:FX,FY,FZ[@RAMP]",
        help="a constant force [N] on NODE (a node name of the structure, or a 0-based index; "
        "digits name a node if one has that name) for the whole run, or ramped in linearly "
        "from 0 over RAMP seconds and then held (@0.5); repeatable, forces add up, and add to "
        "--force-table's",
    )
    sim.add_argument(
        "--control-table",
        type=arguments.name,
        metavar="FILE.csv|FILE.npz",
        help="the tendons' rest-length changes u [m] from a time table (rest length L0 - u: "
        "u > 0 shortens a tendon), linear in between, held after its end (.csv: a header "
        "row t, then tendon names, and rows of numbers; tendons not named keep u = 0; .npz: "
        "time (T,), control (T, S), or time, names (K,), control (T, K))",
    )
    control = sim.add_argument_group("feedback control")
    control.add_argument(
        "--controller",
        type=arguments.name,
        metavar="FILE.npz",
        help="linear feedback u = u_ref - K (y - y_ref) run inside the compiled loop every "
        "period (a controller file: K, y_ref, u_ref, period, outputs, tendons; `tensegrity lqr` "
        "writes one); its commands and saturations are in the summary and the trajectory",
    )
    control.add_argument(
        "--rest-range",
        type=_fractions,
        metavar="LOW:HIGH",
        help="the controlled tendons' rest lengths stay within LOW..HIGH times their own "
        "(e.g. 0.8:1.2; default 0 and no upper bound): commands beyond are clipped",
    )
    control.add_argument(
        "--max-rate",
        type=arguments.positive,
        metavar="M_PER_S",
        help="the controlled tendons' rest lengths change at most this fast [m/s] (a rate "
        "limit; default none)",
    )
    control.add_argument(
        "--lag",
        type=arguments.positive,
        metavar="SECONDS",
        help="the controlled tendons follow their commands with this first-order lag [s] "
        "(default none: at once)",
    )
    sim.add_argument(
        "--sensors",
        type=arguments.name,
        metavar="FILE.json",
        help="sensors measuring the run (a JSON list of sensors: kind position, velocity, "
        "length, tension, orientation, angular_rate or contact; nodes, tendons or rods by name; "
        "noise, bias, delay [s], rate [Hz]; and a seed; see docs/sensors.md): their samples in "
        "OUT/measurements.csv (time,channel,value) and the position sensors' in "
        "OUT/markers.csv (time,marker,x,y,z)",
    )
    add_gravity_option(sim)
    _add_ground_options(sim)
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
    arguments.add_factors(design, from_file=True)
    design.add_argument(
        "--stop-on-failure",
        action="store_true",
        help="stop the run at the first sample where a member is over its limits "
        "(utilisation > 1); the files hold the run up to there",
    )
    _add_integration_options(sim)
    return sim


#: ``simulate``'s integration options: the fields of :class:`~tensegrity.engine.options.Options`
#: each sets (``--max-steps`` sets ``max_steps``), with its default, help and check, and how
#: its text is read (the check is the field's, made once, when the run's options are made).
INTEGRATION_OPTIONS = {
    "method": None,
    "dt": float,
    "rtol": float,
    "atol": float,
    "sample_dt": float,
    "max_steps": int,
    "max_wall_time": float,
}
#: ``simulate``'s own default of ``--sample-dt`` [s] (the library's: a thousandth of the span).
SAMPLE_DT = 0.01


def nodal_load(text: str) -> tuple[str, NodalLoad]:
    """``--load NODE:FX,FY,FZ[@RAMP]``: the text and its :class:`NodalLoad` (a force [N] on a
    node, a name or a 0-based index, ramped in from 0 over RAMP [s], default 0)."""
    from tensegrity.model.loads import NodalLoad

    head, at, ramp = text.rpartition("@")
    if not at or ":" in ramp:  # (no ramp: an '@' in the node's name, or none)
        head, ramp = text, ""
    node, force = arguments.node_force(head, "NODE:FX,FY,FZ[@RAMP]", text)
    try:
        seconds = arguments.non_negative(ramp) if ramp else 0.0
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"RAMP in {text!r}: {exc}") from None
    return text, NodalLoad(node, tuple(force), seconds)


def _fractions(text: str) -> tuple[float, float]:
    """``LOW:HIGH``, two numbers ``0 <= LOW <= 1 <= HIGH`` (``argparse`` type)."""
    try:
        low, high = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LOW:HIGH, two numbers, got {text!r}") from None
    if not (math.isfinite(low) and math.isfinite(high) and 0 <= low <= 1 <= high):
        raise argparse.ArgumentTypeError(f"need 0 <= LOW <= 1 <= HIGH, got {text!r}")
    return low, high


def _numbers(count: int) -> Callable[[str], tuple[float, ...]]:
    """An argparse type: ``count`` comma-separated numbers (or fewer, for ``--friction``)."""

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(x) for x in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected numbers, got {text!r}") from None
        if not 1 <= len(values) <= count:
            raise argparse.ArgumentTypeError(f"expected up to {count} numbers, got {text!r}")
        return values

    return parse


def _add_ground_options(parser: argparse.ArgumentParser) -> None:
    """``simulate``'s ground: a plane the rods' ends touch (docs/simulation.md, "Ground
    contact")."""
    from tensegrity.model.ground import Plane

    ground = parser.add_argument_group(
        "ground contact",
        "A --structure file may carry its scene (planes, contact radius, gravity: its 'scene' "
        "key); these options override it: --ground replaces its planes, --friction, "
        "--contact-stiffness and --contact-damping without --ground change those of its "
        "planes, --contact-radius and --gravity replace its own.",
    )
    ground.add_argument(
        "--ground",
        type=float,
        metavar="Z",
        help="a rigid plane through (0, 0, Z) [m] the rods' ends touch, with friction "
        "(default: the --structure file's planes, else none)",
    )
    ground.add_argument(
        "--ground-normal",
        type=_numbers(3),
        metavar="NX,NY,NZ",
        help="with --ground: its normal, out of the ground (default "
        f"{','.join(f'{x:g}' for x in Plane.normal)})",
    )
    ground.add_argument(
        "--friction",
        type=_numbers(2),
        metavar="MU[,MU_K]",
        help=f"static and kinetic friction coefficients (default {Plane.friction:g}; MU_K = MU)",
    )
    ground.add_argument(
        "--contact-radius",
        type=arguments.non_negative,
        metavar="R",
        help="radius of the rods' ends as contact spheres [m] (default: the file's, else 0)",
    )
    ground.add_argument(
        "--contact-stiffness",
        type=float,
        metavar="K",
        help=f"the contact's normal stiffness [N/m] (default {Plane.stiffness:g})",
    )
    ground.add_argument(
        "--contact-damping",
        type=float,
        metavar="C",
        help=f"the contact's normal damping [N s/m] (default {Plane.damping:g})",
    )


def _add_integration_options(parser: argparse.ArgumentParser) -> None:
    """``simulate``'s integration options (method, step, tolerances, sampling, limits), made
    from the fields of :class:`~tensegrity.engine.options.Options`."""
    integration = parser.add_argument_group("integration")
    for name, kind in INTEGRATION_OPTIONS.items():
        field = OPTION_FIELDS[name]
        default = SAMPLE_DT if name == "sample_dt" else field.default
        integration.add_argument(
            "--" + name.replace("_", "-"),
            **({"choices": ALL_METHODS} if kind is None else {"type": kind}),
            default=default,
            metavar="SECONDS" if name == "max_wall_time" else None,
            help=option_help(name, default),
        )
