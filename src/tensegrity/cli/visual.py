"""The verbs that show a run: ``tensegrity animate TRAJECTORY.h5 -o motion.mp4|.webm|.gif`` (a
video, :mod:`tensegrity.plots.animation`) and ``tensegrity view TRAJECTORY.h5 -o view.html``
(the interactive viewer, :mod:`tensegrity.plots.viewer`; it colours the members by utilisation
too when they have a design: the one a designed run's trajectory carries, with its factors, or
that of ``--structure FILE``, a structure file in the material form, in its place).

Both read only as many samples of the trajectory as they show (``read_trajectory(every=)``),
write their file atomically (nothing is left behind by a failure or an interrupt) and report a
bad trajectory file (missing, truncated, not a trajectory) in one line with exit code 2
(:func:`tensegrity.cli.errors.blame`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from tensegrity.cli import arguments, outputs
from tensegrity.cli.errors import CommandError, blame
from tensegrity.io.files import byte_text, folders_made, shown_path

__all__ = ["add_parsers"]


#: ``animate --size``' default: the video's width and height [pixels].
_SIZE = (800, 640)


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {text!r}") from None
    if width % 16 or height % 16 or min(width, height) < 160:
        raise argparse.ArgumentTypeError(f"width and height: multiples of 16, >= 160, got {text!r}")
    return width, height


def _view(text: str) -> tuple[float, float]:
    try:
        elev, azim = (float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected ELEV,AZIM in degrees, got {text!r}") from None
    return elev, azim


def _check_output(path: Path, suffixes: tuple[str, ...]) -> None:
    """Fail before any work if ``path`` cannot be written (:func:`tensegrity.cli.outputs.
    check_file`) or its suffix is not among ``suffixes``."""
    if path.suffix.lower() not in suffixes:
        raise CommandError(
            f"--output: {shown_path(path)}: expected a name ending in {', '.join(suffixes)}"
        )
    outputs.check_file(path, "--output")


def _read(verb: str, path: Path, frames_wanted: int) -> Any:
    """The trajectory at ``path``, about ``frames_wanted`` samples of it (one in ``every``, and
    the last); one line naming the file if it cannot be read."""
    from tensegrity.io.trajectory import read_dataset, read_trajectory

    with blame(verb, path):
        n_samples = read_dataset(path, "t").size
        every = max(1, (n_samples - 1) // max(frames_wanted - 1, 1))
        return read_trajectory(path, every=every), n_samples


def write_video(
    trajectory: Path,
    output: Path,
    *,
    fps: float,
    duration: float | None = None,
    speed: float | None = None,
    size: tuple[int, int] = (800, 640),
    view: tuple[float, float] | None = None,
    progress: bool | None = None,
) -> int:
    """The animation of the run in the file ``trajectory`` written to ``output`` (its suffix
    the format; :func:`tensegrity.plots.animation.animate`), reading about twice the samples
    its frames show; returns the number of frames.  One line naming the file if it cannot be
    read."""
    from tensegrity.io.trajectory import read_dataset
    from tensegrity.plots.animation import animate
    from tensegrity.plots.motion import frame_rate, playback_times

    fps = frame_rate(output, fps)
    with blame("animate", trajectory):
        time = read_dataset(trajectory, "t")
    wanted = playback_times(time[0], time[-1], fps=fps, duration=duration, speed=speed).size
    result, _ = _read("animate", trajectory, 2 * wanted)
    animate(
        result,
        output,
        fps=fps,
        duration=duration,
        speed=speed,
        size=size,
        view=view,
        progress=progress,
    )
    return int(wanted)


def _cmd_animate(args: argparse.Namespace) -> int:
    from tensegrity.plots.animation import VIDEO_FORMATS
    from tensegrity.plots.motion import frame_rate

    _check_output(args.output, tuple(VIDEO_FORMATS))
    if args.duration is not None and args.speed is not None:
        raise CommandError("animate: give --duration or --speed, not both")
    with folders_made(args.output.parent):
        frames = write_video(
            args.trajectory,
            args.output,
            fps=args.fps,
            duration=args.duration,
            speed=args.speed,
            size=args.size,
            view=args.view,
            progress=None if args.progress else False,
        )
    size = byte_text(args.output.stat().st_size)
    fps = frame_rate(args.output, args.fps)
    print(f"wrote {args.output} ({frames} frames at {fps:.3g} fps, {size})")
    return 0


def _member_check(args: argparse.Namespace) -> Any:
    """The :class:`~tensegrity.plots.motion.MemberCheck` of ``view``: the members' design the
    trajectory carries (a designed ``simulate`` run's), or that of ``--structure FILE`` (a
    structure file in the material form, for the trajectory's structure) in its place, with its
    factors unless ``--safety-factor`` or ``--strength-factor`` is given; the run's largest
    utilisation as ``simulate`` reports it.  None without a design."""
    from tensegrity.cli.structures import factors_of
    from tensegrity.design.files import read_design, same_members, trajectory_design
    from tensegrity.design.utilisation import trajectory_utilisation
    from tensegrity.io.trajectory import read_dataset, read_trajectory_structure
    from tensegrity.plots.motion import MemberCheck

    given = None
    if args.structure is not None:
        with blame("--structure", args.structure):
            given = read_design(args.structure)
        if given.design is None:
            raise CommandError(
                f"--structure: {shown_path(args.structure)} gives no materials and sections (a "
                "structure file in the material form, as `tensegrity design` writes)"
            )
    with blame("view", args.trajectory):
        if given is None:
            structure, design = trajectory_design(args.trajectory)
        else:
            structure, design = read_trajectory_structure(args.trajectory)[0], given.design
        n_samples = read_dataset(args.trajectory, "t").size
    if given is not None and not same_members(given.structure, structure):
        raise CommandError(
            f"--structure: {shown_path(args.structure)} is not the structure of "
            f"{shown_path(args.trajectory)} (other nodes, rods or tendons)"
        )
    if design is None:
        for option, value in (("--safety-factor", args.safety_factor),
                              ("--strength-factor", args.strength_factor)):  # fmt: skip
            if value is not None:
                raise CommandError(
                    f"{option}: needs members with a design ({shown_path(args.trajectory)} "
                    "carries none: give --structure FILE in the material form)"
                )
        return None
    factors = factors_of(args, design.factors)
    members = design.properties(structure)
    with blame("view", args.trajectory):
        peaks = trajectory_utilisation(
            args.trajectory,
            members,
            n_samples=n_samples,
            safety_factor=factors.safety,
            strength_factor=factors.strength,
        )
    return MemberCheck(
        members,
        safety_factor=factors.safety,
        strength_factor=factors.strength,
        largest=peaks.largest,
    )


def _cmd_view(args: argparse.Namespace) -> int:
    from tensegrity.plots.motion import read_frames
    from tensegrity.plots.viewer import view

    _check_output(args.output, (".html", ".htm"))
    check = _member_check(args)
    with blame("view", args.trajectory):
        frames, n_samples = read_frames(
            args.trajectory,
            max_frames=args.max_frames,
            max_bytes=int(args.max_mb * 1e6),
            check=check,
        )
    with folders_made(args.output.parent):
        view(frames, args.output, title=args.title)
    size = byte_text(args.output.stat().st_size)
    print(f"wrote {args.output} ({size}; {frames.n_frames} frames of {n_samples} samples)")
    return 0


def add_parsers(sub: Any) -> None:
    """Add the verbs ``animate`` and ``view`` to the subparsers ``sub`` of ``tensegrity``."""
    from tensegrity.plots.motion import MAX_BYTES, MAX_FRAMES, MAX_REAL_TIME  # (no matplotlib)

    animate = sub.add_parser(
        "animate",
        help="a video of a trajectory (.mp4, .webm or .gif)",
        description="Write a video of a trajectory file: rods, tendons coloured by tension "
        "(slack ones dashed), supports, joints, point masses; time and energy. By default "
        f"real time, at most {MAX_REAL_TIME:g} s of video.",
    )
    animate.add_argument(
        "trajectory", type=arguments.name, help="a trajectory.h5 written by simulate"
    )
    animate.add_argument(
        "-o", "--output", type=arguments.name, required=True, help="the video: .mp4, .webm or .gif"
    )
    animate.add_argument(
        "--fps",
        type=arguments.positive,
        default=30.0,
        help="frames per second (default %(default)g; a GIF's delays are whole hundredths of a "
        "second: 33.3 for 30)",
    )
    animate.add_argument(
        "--duration",
        type=arguments.positive,
        help="length of the video [s] (default: as long as the run, at most "
        f"{MAX_REAL_TIME:g} s; with --speed, the run's length over SPEED)",
    )
    animate.add_argument(
        "--speed",
        type=arguments.positive,
        help="simulated seconds per second of video (1: real time; default 1, or what plays "
        f"a run longer than {MAX_REAL_TIME:g} s in {MAX_REAL_TIME:g} s)",
    )
    animate.add_argument(
        "--size",
        type=_size,
        default=_SIZE,
        help=f"WIDTHxHEIGHT in pixels, multiples of 16, >= 160 (default {_SIZE[0]}x{_SIZE[1]})",
    )
    animate.add_argument(
        "--view", type=_view, help="camera ELEV,AZIM in degrees (default 22,-58; planar: 90,-90)"
    )
    animate.add_argument(
        "--no-progress",
        dest="progress",
        action="store_false",
        help="no progress bar (shown by default when stderr is a terminal)",
    )
    animate.set_defaults(run=_cmd_animate)

    viewer = sub.add_parser(
        "view",
        help="an interactive 3-D viewer of a trajectory: one self-contained HTML file",
        description="Write one HTML file that shows a trajectory in 3-D in any browser, "
        "offline: orbit, zoom, pan, play, a time slider, tensions, slack tendons, supports; "
        "hover a member to read its name, length and tension. A designed run's trajectory "
        "carries its members' design: the page can colour them by utilisation too.",
    )
    viewer.add_argument(
        "trajectory", type=arguments.name, help="a trajectory.h5 written by simulate"
    )
    viewer.add_argument("-o", "--output", type=arguments.name, required=True, help="the .html file")
    viewer.add_argument(
        "--max-frames",
        type=arguments.whole_positive,
        default=MAX_FRAMES,
        help="at most this many frames, spread over the run (default %(default)d)",
    )
    viewer.add_argument(
        "--max-mb",
        type=arguments.positive,
        default=MAX_BYTES / 1e6,
        help="at most this many MB of positions and tensions (default %(default)g)",
    )
    viewer.add_argument("--title", help="the page's title (default: the structure's counts)")
    design = viewer.add_argument_group("members by utilisation")
    design.add_argument(
        "--structure",
        type=arguments.name,
        metavar="FILE",
        help="the run's structure file in the material form (members by material and "
        "section, as `tensegrity design` writes), in place of the design the trajectory of a "
        "designed run carries: the page can colour every member by its utilisation, with the "
        "design's factors unless the options below are given. Rod forces leave out "
        "a run's --force-table, which the trajectory does not hold",
    )
    arguments.add_factors(design, from_file=True)
    viewer.set_defaults(run=_cmd_view)
