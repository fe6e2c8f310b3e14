"""The files of a ``tensegrity simulate`` run in ``--out`` (:class:`RunFiles`: the partial
file it streams into, the folders it made) and the files written when it has ended
(:func:`write_run`: the trajectory, the structure, the figures, the viewer's page, the video);
the summary it prints is :mod:`tensegrity.cli.simulate_summary`'s."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.cli import visual
from tensegrity.cli.drawing import Drawing, viewer_page
from tensegrity.cli.errors import interrupt_code
from tensegrity.io.files import shown_path, write_staged as _write_all

if TYPE_CHECKING:
    from tensegrity.design.materials import MemberDesign
    from tensegrity.design.utilisation import TrajectoryUtilisation
    from tensegrity.engine.result import SimulationResult
    from tensegrity.io.measurements import SensorFile
    from tensegrity.io.stream import StreamSummary
    from tensegrity.model.ground import Scene
    from tensegrity.model.loads import ForceTable
    from tensegrity.model.structure import Structure
    from tensegrity.plots.motion import FrameKeeper


#: Name of the file a ``simulate`` run streams its samples into, inside ``--out`` (the run's data
#: are in this name + ``.partial`` until it ends); not a final name: the finished file becomes
#: ``trajectory.h5`` only together with the other outputs.
WORK_FILE = ".trajectory.h5"


#: The tendon-length figure reads at most this many samples of a run (and its last); the other
#: figures and the printed summary its first and last.
FIGURE_SAMPLES = 1000


@dataclasses.dataclass(frozen=True)
class DesignedRun:
    """The structure of a ``simulate`` run whose members have a design, that design (with the
    factors its utilisation is computed with; the trajectory file carries it,
    :meth:`material_form`) and the run's force table (which the trajectory file does not
    hold)."""

    structure: Structure
    members: MemberDesign
    force: ForceTable | None

    def material_form(self, scene: Scene) -> dict[str, Any]:
        """The run's structure in the material form with its ``scene``
        (:func:`tensegrity.design.files.design_to_dict`; the run's own nodes, joints kept, so
        that ``view`` matches them): the trajectory's ``structure_material`` and
        :data:`MATERIAL_STRUCTURE`."""
        from tensegrity.design.files import design_to_dict

        return design_to_dict(self.structure, self.members, keep_joints=True, scene=scene)

    def peaks(self, path: Path, n_samples: int) -> TrajectoryUtilisation:
        """The members' largest utilisation over the run of ``n_samples`` samples in the
        trajectory file ``path`` (:func:`tensegrity.design.utilisation.trajectory_utilisation`;
        the figures, the viewer and the summary show it)."""
        from tensegrity.design.utilisation import trajectory_utilisation

        return trajectory_utilisation(
            path,
            self.members.properties(self.structure),
            n_samples=n_samples,
            safety_factor=self.members.factors.safety,
            strength_factor=self.members.factors.strength,
            external_force=self.force,
        )


@dataclasses.dataclass(frozen=True)
class RunFiles:
    """The files of one ``simulate`` call in ``--out``: the run streams into ``partial`` and ends
    as ``work``; ``created`` are the folders this call made, ``fresh`` whether it starts a new
    partial file (not ``--resume``, or nothing to resume)."""

    out: Path
    work: Path
    partial: Path
    created: list[Path]
    fresh: bool

    @classmethod
    def prepare(cls, out: Path, resume: bool) -> RunFiles:
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
        remove_empty(self.created)

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
            remove_empty(self.created)
        print(f"tensegrity: interrupted{left}", file=sys.stderr)
        return interrupt_code(exc)


def remove_empty(folders: Sequence[Path]) -> None:
    """Remove those of ``folders`` that are empty, deepest first."""
    for folder in sorted(folders, key=lambda f: len(f.parts), reverse=True):
        with contextlib.suppress(OSError):
            folder.rmdir()


#: ``simulate``'s file of the run's structure in the material form, beside ``structure.json``
#: (members with a design only): what runs it again with its design (``--structure``); the
#: trajectory carries the same document (``structure_material``).
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


def write_run(
    args: argparse.Namespace,
    structure: Structure,
    scene: Scene,
    summary: StreamSummary,
    files: RunFiles,
    keeper: FrameKeeper | None,
    designed: DesignedRun | None,
    drawing: Drawing,
    sensors: SensorFile | None = None,
) -> tuple[SimulationResult, float, list[Path], TrajectoryUtilisation | None]:
    """Write the finished run's files to ``--out`` together (``structure.json`` with the run's
    ``scene``, so that ``--structure OUT/structure.json`` runs it again); the trajectory read
    back for the figures and the summary, the largest energy balance error [J], the files
    written and the members' largest utilisation over the run (members with a design:
    ``designed``).  The figures, the viewer's page and the video are ``drawing``'s jobs, drawn
    while this process writes the rest.  The viewer's frames are ``keeper``'s, or (a resumed
    run, or members with a design: ``designed``, their utilisation in the frames and in
    utilisation.png, drawn at the last sample) read from the file.  With ``sensors`` (the
    sensor file of ``--sensors``), their measurements of the run: ``measurements.csv``, and
    ``markers.csv`` if some are position sensors."""
    from tensegrity.io.formats import write_document, write_structure
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
            safety_factor=designed.members.factors.safety,
            strength_factor=designed.members.factors.strength,
            external_force=designed.force,
            largest=peaks.largest,
        )
    frames = None
    if keeper is not None and summary.resumed_from is None and summary.segments_run:
        frames = keeper.frames(summary.message, run=trajectory)
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
            write_structure(staging / "structure.json", structure, scene=scene),
            *(  # the same structure by material and section, to run it again with its design
                []
                if designed is None
                else [write_document(staging / MATERIAL_STRUCTURE, designed.material_form(scene))]
            ),
            *(_vtk_files(staging / "vtk", read_trajectory(work)) if args.vtk else []),
            *(
                []
                if sensors is None
                else _measurement_files(staging, read_trajectory(work), sensors)
            ),
        ]
        drawn = [path for job in [*jobs, *videos] for path in job.result()]
        # Last, so that the finished run stays in ``work`` if anything before fails.
        target = staging / "trajectory.h5"
        _link_or_move(work, target)
        return [target, *outputs, *drawn]

    balance = _energy_balance_error(work)
    written = _write_all(files.out, drawing.writing(write), record="simulate")
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
        f"about {seconds:.1f} s, more than {DEFAULT_VIDEO_SECONDS:g} s (--animation gif draws "
        "it; `tensegrity animate` draws any part of trajectory.h5)",
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


def _link_or_move(source: Path, target: Path) -> None:
    """Give ``source`` the name ``target`` too (a hard link), or move it if links are refused."""
    try:
        os.link(source, target)
    except OSError:
        os.replace(source, target)


def _vtk_files(folder: Path, result) -> list[Path]:
    from tensegrity.io.vtk import write_vtk

    return write_vtk(folder, result)  # the .vtp files, then the .pvd collection


def _measurement_files(folder: Path, run: SimulationResult, sensors: SensorFile) -> list[Path]:
    """The measurements of ``sensors`` over ``run`` (:func:`tensegrity.engine.sensors.measure`)
    in ``folder``: ``measurements.csv``, and ``markers.csv`` if some are position sensors."""
    from tensegrity.engine.sensors import measure
    from tensegrity.io.measurements import write_markers, write_measurements

    measured = measure(run, sensors.sensors, seed=sensors.seed)
    written = [write_measurements(folder / "measurements.csv", measured)]
    if any(sensor.kind == "position" for sensor in sensors.sensors):
        written.append(write_markers(folder / "markers.csv", measured))
    return written


def _energy_balance_error(path: Path) -> float:
    """Largest change of the energy balance [J] over every sample of the trajectory file."""
    from tensegrity.engine.result import total_energy
    from tensegrity.io.trajectory import ENERGY_COLUMNS, read_dataset

    energy = read_dataset(path, "energy")
    total = total_energy({name: energy[:, k] for k, name in enumerate(ENERGY_COLUMNS)})
    return float(np.abs(total - total[0]).max())
