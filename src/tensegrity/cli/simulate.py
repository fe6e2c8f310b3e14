"""``tensegrity simulate``: the checks before the run and the streamed run
(:func:`tensegrity.io.stream.simulate_to_file`); its options are
:mod:`tensegrity.cli.simulate_options`'s, the files it writes
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
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from tensegrity.cli import outputs
from tensegrity.cli.drawing import Drawing, worker_count
from tensegrity.cli.errors import EXIT_FAILED, CommandError, blame, describe, one_line
from tensegrity.cli.limits import check_run_cost, check_samples, check_structure_size
from tensegrity.cli.simulate_files import (
    MATERIAL_STRUCTURE,
    DesignedRun,
    RunFiles,
    remove_empty,
    write_run,
)
from tensegrity.cli.simulate_options import INTEGRATION_OPTIONS, simulate_parser
from tensegrity.cli.simulate_summary import print_summary
from tensegrity.cli.startup import announce_compiling
from tensegrity.cli.structures import apply_damping, designed_of
from tensegrity.engine.options import DEFAULT_MAX_SAMPLES, FIXED_STEP_METHODS, Options, sample_count
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
    force = with_loads(args.load, structure, force)
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


def with_loads(
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
            material_form=None if designed is None else designed.material_form(inputs.scene),
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
    """``simulate``: run a structure and write its trajectory, structure and figures (its
    options: :mod:`tensegrity.cli.simulate_options`)."""
    simulate_parser(sub).set_defaults(run=_cmd_simulate)


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


def _run_options(args: argparse.Namespace) -> Options:
    """The :class:`~tensegrity.engine.options.Options` of ``simulate``'s run: its integration
    options, checked (an error names the option)."""
    if args.method not in FIXED_STEP_METHODS and args.dt is not None:
        raise CommandError(f"--dt: only for fixed-step methods ({', '.join(FIXED_STEP_METHODS)})")
    try:
        return Options(
            steady_state=not args.no_steady_state,
            **{name: getattr(args, name) for name in INTEGRATION_OPTIONS},
        )
    except ValueError as exc:
        name, _, problem = str(exc).partition(": ")
        raise CommandError(f"--{name.replace('_', '-')}: {problem}") from None
