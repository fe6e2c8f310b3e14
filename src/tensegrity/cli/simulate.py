"""``tensegrity simulate``: its parser, the checks before the run and the streamed run
(:func:`tensegrity.io.stream.simulate_to_file`); the files it writes are
:mod:`tensegrity.cli.simulate_files`'s, its summary :mod:`tensegrity.cli.simulate_summary`'s.

The samples stream, with checkpoints, to ``OUT/.trajectory.h5.partial`` as the run goes; an
interrupted run (Ctrl-C, SIGTERM, SIGHUP, a killed process) leaves only that file, and
``--resume`` continues it.  The final names (``trajectory.h5``, ``structure.json``, the figures)
appear together when the run has ended."""

from __future__ import annotations

import argparse
import dataclasses
import math
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from tensegrity.cli import arguments, outputs
from tensegrity.cli.drawing import Drawing, worker_count
from tensegrity.cli.errors import EXIT_FAILED, CommandError, blame, describe, one_line
from tensegrity.cli.limits import check_run_cost, check_samples, check_structure_size
from tensegrity.cli.simulate_files import (
    DEFAULT_VIDEO_SECONDS,
    MATERIAL_STRUCTURE,
    VIDEO_FPS,
    DesignedRun,
    RunFiles,
    remove_empty,
    write_run,
)
from tensegrity.cli.simulate_summary import print_summary
from tensegrity.cli.startup import announce_compiling
from tensegrity.cli.structures import (
    add_gravity_option,
    add_structure_options,
    apply_damping,
    damping_kind,
    designed_of,
)
from tensegrity.engine.options import (
    ALL_METHODS,
    DEFAULT_MAX_SAMPLES,
    FIXED_STEP_METHODS,
    OPTION_FIELDS,
    Options,
    option_help,
    sample_count,
)
from tensegrity.io.files import DISK_FULL, byte_text, shown_path
from tensegrity.physics import dynamics

if TYPE_CHECKING:
    from tensegrity.engine.feedback import LinearFeedback
    from tensegrity.io.measurements import SensorFile
    from tensegrity.io.stream import StreamSummary
    from tensegrity.model.actuators import Actuators
    from tensegrity.model.ground import Scene
    from tensegrity.model.loads import ControlTable, ForceTable, NodalLoad
    from tensegrity.model.structure import Structure
    from tensegrity.plots.motion import FrameKeeper


#: ``simulate`` checkpoints a run at least this many times (segments of at most this fraction of
#: it), and at least every 1000 samples (or about 64 MiB of samples: the default of
#: :func:`tensegrity.io.stream.simulate_to_file`).
MIN_SEGMENTS = 10


def _run_end(t_end: float, sample_dt: float, *, steady_state: bool) -> float:
    """The end [s] of ``simulate``'s run: ``--t-end``, checked by :func:`check_samples`; for a
    steady-state run, which stops when it comes to rest, ``--t-end`` only bounds it: beyond the
    end of the samples limit (``1e308`` too), that end, said on stderr."""
    end = (DEFAULT_MAX_SAMPLES - 1) * sample_dt
    if not (steady_state and t_end > end):
        check_samples(t_end, sample_dt)
        return t_end
    print(
        f"tensegrity: --t-end {t_end:g} s: the run stops when it comes to rest, at the latest at "
        f"{end:g} s ({DEFAULT_MAX_SAMPLES:,} samples at --sample-dt {sample_dt:g} s)",
        file=sys.stderr,
    )
    return end


#: ``simulate`` says before a run that writes at least this many bytes what it will write.
LARGE_RUN_BYTES = 2**30


def _announce_large_run(
    structure: Structure, t_end: float, sample_dt: float, out: Path, *, planes: int
) -> None:
    """Before a run whose trajectory file would reach :data:`LARGE_RUN_BYTES`, say on stderr
    how large it will be, how much of it is held in memory at a time, and whether the disk of
    ``out`` has room for it (a run stopped at a steady state writes less); ``planes`` planes
    add their contact columns."""
    from tensegrity.io.stream import sample_bytes, samples_per_segment

    row = sample_bytes(structure, planes=planes)
    samples = sample_count(0.0, t_end, sample_dt)
    if samples * row < LARGE_RUN_BYTES:
        return
    segment = _segment(structure, t_end, sample_dt, planes=planes)
    held = 2 * samples_per_segment(structure, segment, sample_dt, planes=planes)
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
        f"{byte_text(held * sample_bytes(structure, held=True, planes=planes))} of samples in "
        "memory at a time); a larger --sample-dt writes less",
        file=sys.stderr,
    )


def _segment(structure: Structure, t_end: float, sample_dt: float, *, planes: int) -> float:
    """Segment duration [s] of a ``simulate`` run with ``planes`` planes: at most a tenth of it,
    rounded to samples.

    Depends only on the structure and the options, so that a resumed run has the segment grid of
    the interrupted one.
    """
    from tensegrity.io.stream import samples_per_segment

    default = samples_per_segment(structure, None, sample_dt, planes=planes)
    tenth = max(1, math.ceil((sample_count(0.0, t_end, sample_dt) - 1) / MIN_SEGMENTS))
    return min(default, tenth) * sample_dt


class RunInputs(NamedTuple):
    """What a ``simulate`` run puts on its structure: the force table, the control table, the
    scene (the ground, the contact radius and gravity), a linear feedback controller and the
    actuators it drives."""

    force: ForceTable | None
    control: ControlTable | None
    scene: Scene
    controller: LinearFeedback | None = None
    actuators: Actuators | None = None


def _simulation_inputs(
    args: argparse.Namespace,
) -> tuple[Structure, RunInputs, DesignedRun | None]:
    """The structure (damped as the options say) and the inputs of a run, and, if its members
    have a design, what :func:`print_summary`'s utilisation report needs."""
    structure, members = designed_of(args)
    damping = args.damping
    if damping is None and getattr(args, "structure", None) is None:
        damping = next(iter(dynamics.DAMPING_KINDS))  # a generated structure: internal
    structure = apply_damping(structure, damping)
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
    force = _with_loads(args.load, structure, force)
    control = None
    if args.control_table is not None:
        from tensegrity.io.tables import read_control_table

        with blame("--control-table", args.control_table):
            control = read_control_table(args.control_table, structure)
    controller, driven = _controller_of(args, structure)
    if controller is not None and control is not None:
        raise CommandError("--controller: a run takes a controller or --control-table, not both")
    inputs = RunInputs(force, control, _scene_of(args, structure), controller, driven)
    if members is None:
        for option, value in (("--safety-factor", args.safety_factor is not None),
                              ("--strength-factor", args.strength_factor is not None),
                              ("--stop-on-failure", args.stop_on_failure)):  # fmt: skip
            if value:
                raise CommandError(
                    f"{option}: needs members with a design (--material and --section, or a "
                    "structure file in the material form)"
                )
        return structure, inputs, None
    return structure, inputs, DesignedRun(structure, members, force)


def _nodal_load(text: str) -> tuple[str, NodalLoad]:
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


def _with_loads(
    loads: list[tuple[str, NodalLoad]], structure: Structure, force: ForceTable | None
) -> ForceTable | None:
    """The force table ``force`` (or None) plus the ``--load`` forces on ``structure``
    (:func:`~tensegrity.model.loads.nodal_load_table`): one table, exactly their sum."""
    from tensegrity.model.loads import add_force_tables, nodal_load_table

    for text, load in loads:
        with blame(f"--load {text}"):
            table = nodal_load_table(structure, [load])
        force = table if force is None else add_force_tables(force, table)
    return force


def _controller_of(
    args: argparse.Namespace, structure: Structure
) -> tuple[LinearFeedback | None, Actuators | None]:
    """The linear feedback law of ``--controller`` and the actuators of its tendons with the
    limits ``--rest-range``, ``--max-rate`` and ``--lag`` set (those need a controller)."""
    limits = {"--rest-range": args.rest_range, "--max-rate": args.max_rate, "--lag": args.lag}
    if args.controller is None:
        for option, value in limits.items():
            if value is not None:
                raise CommandError(f"{option}: limits the actuators of a --controller; give one")
        return None, None
    from tensegrity.io.controllers import read_controller
    from tensegrity.model.actuators import actuators

    with blame("--controller", args.controller):
        law = read_controller(args.controller)
    try:
        tendons = law.check(structure)
    except ValueError as exc:
        raise CommandError(f"--controller: {one_line(exc)}") from None
    rest = structure.tendon_rest_length[tendons]
    low, high = (0.0, math.inf) if args.rest_range is None else args.rest_range
    driven = actuators(
        structure,
        tendons.tolist(),
        min_rest_length=low * rest,
        max_rest_length=high * rest,
        max_rate=math.inf if args.max_rate is None else args.max_rate,
        time_constant=0.0 if args.lag is None else args.lag,
    )
    return law, driven


def _stream_run(
    args: argparse.Namespace,
    options: Options,
    structure: Structure,
    inputs: RunInputs,
    files: RunFiles,
    keeper: FrameKeeper | None,
    designed: DesignedRun | None,
) -> StreamSummary:
    """Simulate with ``options`` into ``files.work`` (through its partial file), the viewer's
    frames into ``keeper`` as they come, stopping at a member's failure with
    ``--stop-on-failure``; a rejected or failed run leaves nothing of this call's making
    behind, an interrupted one its partial file."""
    from tensegrity.io.stream import OutOfTimeError, simulate_to_file

    stop = None
    if designed is not None and args.stop_on_failure:
        from tensegrity.design.utilisation import stop_at_failure

        stop = stop_at_failure(
            structure,
            designed.members.properties(structure),
            safety_factor=designed.members.factors.safety,
            strength_factor=designed.members.factors.strength,
            external_force=inputs.force,
            gravity=inputs.scene.gravity,
        )

    try:
        summary = simulate_to_file(
            structure,
            (0.0, args.t_end),
            files.work,
            segment=_segment(
                structure, args.t_end, args.sample_dt, planes=len(inputs.scene.planes)
            ),
            resume=args.resume,
            progress=sys.stderr.isatty(),
            observe=None if keeper is None else keeper.add,
            stop=stop,
            external_force=inputs.force,
            control=inputs.control,
            controller=inputs.controller,
            actuators=inputs.actuators,
            **inputs.scene.simulate_options(),
            **dataclasses.asdict(options),
        )
    except KeyboardInterrupt:
        raise
    except OutOfTimeError as exc:  # the finished segments stay in the partial file, for --resume
        files.discard()
        raise CommandError(f"simulation {one_line(exc)}{files.kept()}", EXIT_FAILED) from None
    except OSError as exc:
        if exc.errno not in DISK_FULL:
            files.discard()
            raise
        files.discard()  # (the partial file is at its last checkpoint: kept if it holds any)
        raise CommandError(f"{describe(exc)}{files.kept()}", EXIT_FAILED) from None
    except ValueError as exc:
        files.discard()
        raise CommandError(one_line(exc)) from None
    except BaseException:
        files.discard()
        raise
    if not summary.success:
        files.work.unlink(missing_ok=True)
        remove_empty(files.created)
        raise CommandError(
            f"simulation failed: {one_line(summary.message)} (nothing written)", EXIT_FAILED
        )
    return summary


def _cmd_simulate(args: argparse.Namespace) -> int:
    options = _run_options(args)
    outputs.check_folder(args.out, "--out")
    args.t_end = _run_end(args.t_end, args.sample_dt, steady_state=not args.no_steady_state)
    # the drawing's workers start now: they import matplotlib while the run is set up and goes on
    with Drawing(worker_count(2)) as drawing:
        return _simulate_and_write(args, options, drawing)


def _simulate_and_write(args: argparse.Namespace, options: Options, drawing: Drawing) -> int:
    """``tensegrity simulate`` once its options are checked (the run's: ``options``): the run,
    its files (the figures, page and video drawn by ``drawing``) and its summary."""
    announce_compiling()
    structure, inputs, designed = _simulation_inputs(args)
    sensors = _sensors_of(args, structure, len(inputs.scene.planes))
    _check_outputs(args, designed is not None)
    check_structure_size(structure)
    check_run_cost(structure, args.t_end, options)
    files = RunFiles.prepare(args.out, args.resume)
    planes = len(inputs.scene.planes)
    _announce_large_run(structure, args.t_end, args.sample_dt, files.out, planes=planes)
    keeper = None
    if not args.no_view and designed is None:  # (a design's frames are read with their forces)
        from tensegrity.plots.motion import MAX_BYTES, MAX_FRAMES, FrameKeeper, frame_budget

        budget = frame_budget(structure, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES, planes=planes)
        keeper = FrameKeeper(structure, t0=0.0, sample_dt=args.sample_dt, max_frames=budget)
    try:
        summary = _stream_run(args, options, structure, inputs, files, keeper, designed)
        try:
            trajectory, balance, written, peaks = write_run(
                args, structure, inputs.scene, summary, files, keeper, designed, drawing, sensors
            )
        except (ValueError, OSError) as exc:  # the finished run stays, for --resume
            code = EXIT_FAILED if isinstance(exc, OSError) and exc.errno in DISK_FULL else 2
            raise CommandError(f"{describe(exc)}{files.kept()}", code) from None
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM/SIGHUP (signals_as_interrupts)
        drawing.cancel()
        return files.interrupted(exc)
    print_summary(
        trajectory,
        summary,
        balance,
        args.resume,
        [f for f in written if f.parent == files.out or f.suffix == ".pvd"],
        peaks,
        None if designed is None else designed.members.factors,
    )
    return 0


def _sensors_of(args: argparse.Namespace, structure: Structure, planes: int) -> SensorFile | None:
    """The sensor file of ``--sensors`` (or None), checked against ``structure`` run with
    ``planes`` planes before the run: one line naming the file and the field at fault."""
    if args.sensors is None:
        return None
    from tensegrity.engine.sensors import SensorReader
    from tensegrity.io.measurements import read_sensors

    with blame("--sensors", args.sensors):
        sensors = read_sensors(args.sensors)
        SensorReader(structure, sensors.sensors, planes=planes, seed=sensors.seed)
    return sensors


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
    names += [] if args.sensors is None else ["measurements.csv", "markers.csv"]
    try:
        check_targets(args.out, [args.out / name for name in names])
    except ValueError as exc:
        raise CommandError(f"--out: {exc}") from None


def add_parser(sub: Any) -> None:
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
        "f0y, f0z, f1x, ...)",
    )
    sim.add_argument(
        "--load",
        type=_nodal_load,
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
    sim.set_defaults(run=_cmd_simulate)


#: ``simulate``'s integration options: the fields of :class:`~tensegrity.engine.options.Options`
#: each sets (``--max-steps`` sets ``max_steps``), with its default, help and check, and how
#: its text is read (the check is the field's, made once, when the run's options are made).
_INTEGRATION_OPTIONS = {
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


#: ``simulate``'s ground options, by the field of :class:`~tensegrity.model.ground.Plane` each
#: sets (``--ground`` the plane's point, ``(0, 0, Z)``).
_GROUND_OPTIONS = {
    "point": "--ground",
    "normal": "--ground-normal",
    "friction": "--friction",
    "kinetic_friction": "--friction",
    "stiffness": "--contact-stiffness",
    "damping": "--contact-damping",
}


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


def _scene_of(args: argparse.Namespace, structure: Structure) -> Scene:
    """The scene of the run: the ``--structure`` file's (:func:`tensegrity.io.formats.read_scene`),
    overridden by the options given (``--ground`` replaces its planes, ``--friction``,
    ``--contact-stiffness`` and ``--contact-damping`` alone change its planes', ``--contact-radius``
    and ``--gravity`` replace its own); ``CommandError`` naming the option of a bad value, or
    the file of a bad scene."""
    from tensegrity.io.formats import read_scene
    from tensegrity.model.ground import Plane, Scene
    from tensegrity.model.loads import gravity_vector

    scene = Scene()
    if getattr(args, "structure", None) is not None:
        with blame("--structure", args.structure):
            scene = read_scene(args.structure)
    given: dict[str, Any] = {
        field: value
        for field, value in (
            ("normal", args.ground_normal),
            ("friction", None if args.friction is None else args.friction[0]),
            ("kinetic_friction", None if args.friction is None else args.friction[-1]),
            ("stiffness", args.contact_stiffness),
            ("damping", args.contact_damping),
        )
        if value is not None
    }
    try:
        if args.ground is not None:
            planes: tuple[Plane, ...] = (Plane(point=(0.0, 0.0, args.ground), **given),)
        elif "normal" in given:
            raise CommandError("--ground-normal: only with --ground (a file's planes keep theirs)")
        elif given and not scene.planes:
            option = _GROUND_OPTIONS[next(iter(given))]
            raise CommandError(f"{option}: needs --ground, or a --structure file with planes")
        else:
            planes = tuple(dataclasses.replace(plane, **given) for plane in scene.planes)
    except ValueError as exc:
        field, _, problem = str(exc).partition(": ")
        raise CommandError(f"{_GROUND_OPTIONS.get(field, '--ground')}: {problem}") from None
    radius = scene.contact_radius if args.contact_radius is None else args.contact_radius
    gravity = scene.gravity
    if args.gravity is not None:
        gravity = gravity_vector(args.gravity, structure.dim)
    return Scene(planes, radius, gravity)


def _add_integration_options(parser: argparse.ArgumentParser) -> None:
    """``simulate``'s integration options (method, step, tolerances, sampling, limits), made
    from the fields of :class:`~tensegrity.engine.options.Options`."""
    integration = parser.add_argument_group("integration")
    for name, kind in _INTEGRATION_OPTIONS.items():
        field = OPTION_FIELDS[name]
        default = SAMPLE_DT if name == "sample_dt" else field.default
        integration.add_argument(
            "--" + name.replace("_", "-"),
            **({"choices": ALL_METHODS} if kind is None else {"type": kind}),
            default=default,
            metavar="SECONDS" if name == "max_wall_time" else None,
            help=option_help(name, default),
        )


def _run_options(args: argparse.Namespace) -> Options:
    """The :class:`~tensegrity.engine.options.Options` of ``simulate``'s run: its integration
    options, checked (an error names the option)."""
    if args.method not in FIXED_STEP_METHODS and args.dt is not None:
        raise CommandError(f"--dt: only for fixed-step methods ({', '.join(FIXED_STEP_METHODS)})")
    try:
        return Options(
            steady_state=not args.no_steady_state,
            **{name: getattr(args, name) for name in _INTEGRATION_OPTIONS},
        )
    except ValueError as exc:
        name, _, problem = str(exc).partition(": ")
        raise CommandError(f"--{name.replace('_', '-')}: {problem}") from None
