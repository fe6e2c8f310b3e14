"""A run as frames to show: the one source of what the animation (:mod:`.animation`) and the
interactive viewer (:mod:`.viewer`) draw.

A :class:`Frames` holds, for ``F`` frames picked from a run's ``T`` samples (or the one frame of
a structure at rest):

- the frame times and the samples they show (``index``): each frame shows a recorded sample
  exactly, the last at or before its playback time (no interpolation, so rods keep their lengths);
- node positions ``(F, N, 3)`` [m]: a planar structure's ``(x, y)`` are drawn in the plane
  ``z = 0``;
- tendon tensions ``(F, S)`` [N] and the slack tendons (tension ``<= 0``) of each frame;
- the tension range [N] of the colour map, fixed over the whole run (every sample, not only the
  frames shown), and the box [m] that holds every node of every frame (fixed camera and axes);
- the energies [J] of each frame;
- for a run whose members have a design (materials and sections, :class:`MemberCheck`), each
  member's utilisation at each frame (:mod:`tensegrity.design.utilisation`: a rod's larger of
  yield and buckling, a tendon's yield) and the top of its colour scale, ``max(1, largest)``;
- what the structure is: rods, tendons and their names, fixed nodes (supports, anchors), ball
  joints, point masses;
- for a run with planes (the ground, an incline, a wall: ``SimulationResult.planes``), each
  plane's patch to draw and the mode of each contact pair (free, slip, stick) at each frame
  (:class:`FrameContacts`).

:func:`playback_times` turns a video's length (``duration``, ``fps`` or ``speed``) into frame
times (:func:`frame_rate`: the rate a format can play); :func:`frame_indices` finds the samples
they show; :func:`decimated_indices` picks at most a number of samples spread evenly over a run
(the viewer's frames).

SI units throughout: m, s, N, J.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from tensegrity.engine.result import ENERGY_NAMES, total_energy
from tensegrity.model.ground import SLIP, STICK
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import elastic_tensions, tendon_lengths

if TYPE_CHECKING:
    from tensegrity.design.materials import MemberProperties
    from tensegrity.engine.result import Samples, SimulationResult
    from tensegrity.io.files import PathLike

__all__ = [
    "MAX_BYTES",
    "MAX_FRAMES",
    "MAX_REAL_TIME",
    "PLANE_MARGIN",
    "FrameContacts",
    "FrameUtilisation",
    "Frames",
    "MemberCheck",
    "decimated_indices",
    "frame_indices",
    "frame_rate",
    "gif_delay",
    "make_frames",
    "motion_frames",
    "plane_patches",
    "playback_times",
    "structure_frames",
    "tension_colors",
]

#: A run up to this long [s] is played at its own speed by default; a longer one in this time.
MAX_REAL_TIME = 20.0
#: Default largest number of frames of a viewer page (:mod:`.viewer`).
MAX_FRAMES = 300
#: Default largest size of a viewer page's positions and tensions [bytes] (before base64, which
#: adds a third): about 36 frames of the (100, 100) shell.
MAX_BYTES = 32_000_000
#: A plane's patch reaches this fraction of the run's size (its box's longest side) beyond the
#: footprint of the nodes on it (every node of every sample, projected on the plane).
PLANE_MARGIN = 0.15


class MemberCheck(NamedTuple):
    """What the utilisation of a run's members needs besides the run's samples (its gravity
    is in its settings): :func:`make_frames` and :func:`read_frames` colour the members by it.

    Attributes
    ----------
    members : MemberProperties
        The materials and sections of the members
        (:meth:`~tensegrity.design.materials.MemberDesign.properties`).
    safety_factor : float
        Divides the rods' Euler load (>= 1).
    strength_factor : float
        Divides the yield strengths of rods and tendons (>= 1).
    external_force : ndarray, shape (N, dim), or callable, optional
        The run's external forces [N] (constant, or ``w(t)`` such as a
        :class:`~tensegrity.model.loads.ForceTable`): neither a result nor a trajectory file
        holds them.
    largest : float
        The run's largest utilisation if known from more samples than the frames show (e.g.
        :attr:`~tensegrity.design.utilisation.TrajectoryUtilisation.largest`): the colour scale
        reaches at least this.
    """

    members: MemberProperties
    safety_factor: float = 1.0
    strength_factor: float = 1.0
    external_force: np.ndarray | Callable[[float], np.ndarray] | None = None
    largest: float = 0.0


class FrameUtilisation(NamedTuple):
    """The governing utilisation of every member at each frame
    (:class:`~tensegrity.design.utilisation.Utilisation`'s ``rod`` and ``tendon``)."""

    rod: np.ndarray  #: (F, R): the larger of yield and buckling
    tendon: np.ndarray  #: (F, S): yield
    high: float  #: top of the colour scale: ``max(1, largest utilisation of the run)``


class FrameContacts(NamedTuple):
    """A run's planes as drawn and its contact pairs' modes at each frame
    (:attr:`SimulationResult.planes <tensegrity.engine.result.SimulationResult.planes>`,
    ``contact_node``, ``contact_plane``, ``contact_mode``): ``P`` planes, ``CP`` pairs."""

    patch: np.ndarray  #: (P, 4, 3) corners [m] of each plane's patch, in turn around it
    normal: np.ndarray  #: (P, 3) each plane's unit normal
    cell: float  #: side [m] of the squares of the grid on the patches (lines at its multiples)
    node: np.ndarray  #: (CP,) the node of each contact pair
    plane: np.ndarray  #: (CP,) its plane, an index into ``patch``
    mode: np.ndarray  #: (F, CP) int8: its mode at each frame, 0 free, 1 slip, 2 stick

    def ends(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The nodes in contact at frame ``k``: those sticking (a pair of theirs sticks) and
        those slipping (else a pair slips), each ascending."""
        stick = np.unique(self.node[self.mode[k] == STICK])
        return stick, np.setdiff1d(self.node[self.mode[k] == SLIP], stick)

    def grid(self) -> np.ndarray:
        """The grid lines on the patches, every :attr:`cell` along each side, shape (L, 2, 3)
        [m]."""
        lines = []
        for c0, c1, _, c3 in self.patch:
            for side, other in ((c1 - c0, c3 - c0), (c3 - c0, c1 - c0)):
                count = max(1, round(float(np.linalg.norm(side)) / self.cell))
                start = c0 + np.outer(np.linspace(0.0, 1.0, count + 1), side)
                lines.append(np.stack([start, start + other], axis=1))
        return np.concatenate(lines) if lines else np.zeros((0, 2, 3))


@dataclasses.dataclass(frozen=True, eq=False)
class Frames:
    """Frames of a run (or of a structure at rest) to draw.

    Attributes
    ----------
    structure : Structure
        ``N`` nodes, ``R`` rods, ``S`` tendons.
    t : ndarray, shape (F,)
        Simulation time of each frame [s] (the time of the sample it shows).
    index : ndarray of int, shape (F,)
        The sample of the run each frame shows.
    node_position : ndarray, shape (F, N, 3)
        Node positions [m]; ``z = 0`` for a planar structure.
    tendon_tension : ndarray, shape (F, S)
        Tendon tensions [N].
    slack : ndarray of bool, shape (F, S)
        Slack tendons (tension ``<= 0``).
    energy : dict of str to ndarray, shape (F,)
        ``"total"`` (the conserved balance, ``SimulationResult.total_energy``), ``"kinetic"``,
        ``"elastic"`` [J]; empty for a structure at rest.
    tension_range : (float, float)
        Low and high ends of the tension colour map [N], over the taut tensions of every sample
        of the run; ``low < high``.
    bounds : ndarray, shape (2, 3)
        Lowest and highest x, y, z of any node in any frame [m].
    title : str
        A line naming the run (status message), or empty.
    utilisation : FrameUtilisation, optional
        The members' utilisation at each frame, for a run whose members have a design
        (:class:`MemberCheck`); None otherwise.
    contacts : FrameContacts, optional
        The planes and the contact pairs' modes at each frame, for a run with planes; None
        otherwise.
    """

    structure: Structure
    t: np.ndarray
    index: np.ndarray
    node_position: np.ndarray
    tendon_tension: np.ndarray
    slack: np.ndarray
    energy: dict[str, np.ndarray]
    tension_range: tuple[float, float]
    bounds: np.ndarray
    title: str = ""
    utilisation: FrameUtilisation | None = None
    contacts: FrameContacts | None = None

    @property
    def n_frames(self) -> int:
        """Number of frames ``F``."""
        return int(self.t.size)

    @property
    def joint_nodes(self) -> np.ndarray:
        """One node of each ball joint (the pair's first), shape (J,)."""
        joints = self.structure.joint_nodes
        return np.unique(joints[:, 0]) if joints.size else np.zeros(0, np.int64)

    @property
    def fixed_nodes(self) -> np.ndarray:
        """Fixed nodes (supports and anchors), shape (K,)."""
        return np.flatnonzero(self.structure.node_fixed)

    @property
    def point_mass_nodes(self) -> np.ndarray:
        """Nodes with a point mass, shape (M,)."""
        return self.structure.point_mass_nodes

    @property
    def scene_bounds(self) -> np.ndarray:
        """The lowest and highest x, y, z [m] of what is drawn, shape (2, 3), that is
        :attr:`bounds` and the corners of the planes' patches (:attr:`bounds` without
        planes)."""
        if self.contacts is None:
            return self.bounds
        corners = self.contacts.patch.reshape(-1, 3)
        return np.stack(
            [
                np.minimum(self.bounds[0], corners.min(axis=0)),
                np.maximum(self.bounds[1], corners.max(axis=0)),
            ]
        )

    def segments(self, k: int, pairs: np.ndarray) -> np.ndarray:
        """The line segments (K, 2, 3) [m] between node ``pairs`` (K, 2) at frame ``k``."""
        return self.node_position[k][pairs] if len(pairs) else np.zeros((0, 2, 3))


def playback_times(
    t_start: float,
    t_end: float,
    *,
    fps: float = 30.0,
    duration: float | None = None,
    speed: float | None = None,
) -> np.ndarray:
    """Simulation times [s] of a video's frames, evenly spaced from ``t_start`` to ``t_end``.

    Parameters
    ----------
    t_start, t_end : float
        The run's first and last sample times [s].
    fps : float
        Frames per second of the video, > 0.
    duration : float, optional
        Length of the video [s], > 0.  Give this or ``speed``, not both.
    speed : float, optional
        Simulated seconds per second of video, > 0 (1 is real time).  Default: real time for a
        run up to :data:`MAX_REAL_TIME` long, else whatever plays it in ``MAX_REAL_TIME``.

    Returns
    -------
    ndarray, shape (F,)
        ``F = max(1, round(duration * fps))`` times [s]; the first is ``t_start`` and the last
        ``t_end`` (one frame, at ``t_end``, if ``F = 1``).
    """
    for name, value in (("fps", fps), ("duration", duration), ("speed", speed)):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")
    if duration is not None and speed is not None:
        raise ValueError("duration, speed: give one of them, not both")
    span = max(float(t_end) - float(t_start), 0.0)
    if duration is None:
        duration = (span / speed) if speed is not None else min(span, MAX_REAL_TIME)
    count = max(1, round(duration * fps))
    if count == 1:
        return np.array([float(t_end)])
    return np.linspace(float(t_start), float(t_end), count)


def gif_delay(fps: float) -> int:
    """A GIF frame's delay [hundredths of a second] for ``fps`` (> 0) frames per second: GIF
    delays are whole hundredths, and browsers show delays under 2 as 10, so at least 2."""
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps: must be a finite number > 0, got {fps!r}")
    return max(2, round(100.0 / fps))


def frame_rate(path: PathLike, fps: float) -> float:
    """The frame rate [1/s] a video file at ``path`` is written at when ``fps`` is asked:
    ``fps``, except for a GIF (suffix ``.gif``), whose rate is ``100 / gif_delay(fps)`` (e.g.
    33.3 for 30, at most 50), so that it plays in the time its frames show: a GIF written at 30
    fps with delays of 3 hundredths would play 10% fast."""
    if str(path).lower().endswith(".gif"):
        return 100.0 / gif_delay(fps)
    return float(fps)


def frame_indices(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """For each time of ``times`` (F,), the last sample of ``t`` (T,) at or before it [s]
    (the first sample for a time before it), shape (F,)."""
    t = np.asarray(t, dtype=float)
    found = np.searchsorted(t, np.asarray(times, dtype=float), side="right") - 1
    return np.clip(found, 0, t.size - 1)


def decimated_indices(n_samples: int, max_frames: int) -> np.ndarray:
    """At most ``max_frames`` (>= 1) samples of ``n_samples``, evenly spread, the first and the
    last among them (the last alone if ``max_frames`` is 1), ascending, shape (F,)."""
    if max_frames < 1:
        raise ValueError(f"max_frames: must be >= 1, got {max_frames}")
    if n_samples <= max_frames:
        return np.arange(n_samples)
    if max_frames == 1:
        return np.array([n_samples - 1])
    return np.unique(np.round(np.linspace(0, n_samples - 1, max_frames)).astype(np.int64))


def _padded(structure: Structure, position: np.ndarray) -> np.ndarray:
    """Node positions (..., N, 3) [m]: a planar structure's (..., N, 2) with ``z = 0``."""
    position = np.asarray(position, dtype=float)
    if structure.dim == 3:
        return position
    return np.concatenate([position, np.zeros((*position.shape[:-1], 1))], axis=-1)


def _tension_range(tension: np.ndarray) -> tuple[float, float]:
    """The colour map's range [N] over the taut tensions of ``tension`` (any shape): from the
    lowest to the highest, widened to ``(v - 0.5, v + 0.5)`` [N] or by 1e-3 relative if they
    agree; ``(0, 1)`` without a taut tendon."""
    taut = tension[tension > 0]
    if not taut.size:
        return 0.0, 1.0
    low, high = float(taut.min()), float(taut.max())
    if high - low <= 1e-9 * high:
        widen = 0.5 if high < 500 else 1e-3 * high
        return max(low - widen, 0.0), high + widen
    return low, high


def make_frames(
    result: SimulationResult,
    indices: np.ndarray | None = None,
    *,
    check: MemberCheck | None = None,
) -> Frames:
    """The frames of ``result`` that show the samples ``indices`` (default: every sample).

    Parameters
    ----------
    result : SimulationResult
        A run in memory, or read with :func:`tensegrity.io.trajectory.read_trajectory` (its
        ``every=`` reads a long run's overview).
    indices : array_like of int, shape (F,), optional
        Samples to show, e.g. :func:`frame_indices` of :func:`playback_times` (a video) or
        :func:`decimated_indices` (the viewer).
    check : MemberCheck, optional
        The design of the run's members: the frames get their utilisation (rod forces at each
        frame shown, a solve each).

    Returns
    -------
    Frames
        Tension range and bounds over every sample of ``result`` (not only those shown).
    """
    frames = _frames(
        result.structure,
        result.t,
        result.node_position,
        result.tendon_tension,
        result.energy,
        indices,
        result.message,
        contact=_contact_of(result),
    )
    if check is None:
        return frames
    from tensegrity.design.utilisation import run_utilisation  # (the statics: loaded on use)

    u = run_utilisation(
        _sample_rows(result, frames.index),
        check.members,
        safety_factor=check.safety_factor,
        strength_factor=check.strength_factor,
        external_force=check.external_force,
    )
    high = max(1.0, check.largest, u.largest)
    return dataclasses.replace(
        frames, utilisation=FrameUtilisation(u.samples.rod, u.samples.tendon, high)
    )


class _Contact(NamedTuple):
    """A run's planes (``Plane.settings()`` each) and contact pairs (:class:`FrameContacts`'s
    ``node`` and ``plane``), and the pairs' modes at each of its T rows, (T, CP)."""

    planes: Sequence[Mapping[str, Any]]
    node: np.ndarray
    plane: np.ndarray
    mode: np.ndarray


def _contact_of(result: SimulationResult, mode: np.ndarray | None = None) -> _Contact | None:
    """The planes and contact pairs of ``result`` with ``mode`` (T, CP) (default its own
    ``contact_mode``), or None for a run without planes."""
    if not result.planes:
        return None
    mode = np.asarray(result.contact_mode if mode is None else mode, dtype=np.int8)
    return _Contact(result.planes, result.contact_node, result.contact_plane, mode)


def _sample_rows(result: SimulationResult, index: np.ndarray) -> SimulationResult:
    """The samples ``index`` (K,) of ``result``, as a run of K samples."""
    return dataclasses.replace(
        result,
        t=result.t[index],
        q=result.q[index],
        qdot=result.qdot[index],
        node_position=result.node_position[index],
        node_velocity=result.node_velocity[index],
        tendon_length=result.tendon_length[index],
        tendon_tension=result.tendon_tension[index],
        energy={name: values[index] for name, values in result.energy.items()},
        residual_acceleration=result.residual_acceleration[index],
    )


def frame_budget(
    structure: Structure,
    *,
    max_frames: int,
    max_bytes: int,
    utilisation: bool = False,
    planes: int = 0,
) -> int:
    """How many frames a page of ``structure`` holds: at most ``max_frames``, and at most
    ``max_bytes`` of Float32 positions ``(N, 3)`` and tensions ``(S,)`` (and, with
    ``utilisation``, the members' utilisation ``(R + S,)``; in a run with ``planes`` planes,
    the Int8 modes of its ``CP`` contact pairs ``(CP,)``) (at least one frame)."""
    if max_frames < 1 or max_bytes < 1:
        raise ValueError(f"max_frames, max_bytes: must be >= 1, got {max_frames}, {max_bytes}")
    from tensegrity.io.trajectory import contact_pairs

    members = structure.n_rods + structure.n_tendons if utilisation else 0
    per_frame = 4 * (3 * structure.n_nodes + structure.n_tendons + members)
    per_frame += contact_pairs(structure, planes)
    return max(1, min(max_frames, max_bytes // per_frame))


class FrameKeeper:
    """The viewer's frames of a run as its samples come (:func:`tensegrity.io.stream.
    simulate_to_file`'s ``observe``): at most ``max_frames`` evenly spread samples and the last,
    kept as they pass (the spacing doubles whenever twice that many are held; only the times,
    node positions, tensions, energies and, with planes, the contact pairs' modes), so that a
    long run's file need not be read again for them.  :meth:`frames` makes them."""

    def __init__(self, structure: Structure, *, t0: float, sample_dt: float, max_frames: int):
        self.structure, self.t0, self.sample_dt = structure, float(t0), float(sample_dt)
        self.max_frames, self.every = max(1, max_frames), 1
        #: kept rows (sample number divisible by ``every``): (number, t, position, tension,
        #: energy) arrays, one tuple per block
        self.kept: list[tuple[np.ndarray, ...]] = []
        self.last: tuple[np.ndarray, ...] | None = None

    def add(self, samples: Samples) -> None:
        """Keep what the frames need of ``samples`` (a block, in time order): positions and
        tensions as float32, what the page holds."""
        number = np.round((samples.t - self.t0) / self.sample_dt).astype(np.int64)
        last = np.arange(number.size) == number.size - 1
        self.last = self._columns(samples, number, last)
        self.kept.append(self._columns(samples, number, number % self.every == 0))
        while sum(k[0].size for k in self.kept) > 2 * self.max_frames:
            self.every *= 2
            self.kept = [_rows(k, k[0] % self.every == 0) for k in self.kept]

    @staticmethod
    def _columns(samples: Samples, number: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, ...]:
        """The rows ``keep`` of what a frame shows: sample number, time, positions, tensions
        (float32), energies and contact modes (int8, (K, CP))."""
        return (
            number[keep],
            samples.t[keep],
            samples.node_position[keep].astype(np.float32),
            samples.tendon_tension[keep].astype(np.float32),
            samples.energy[keep],
            samples.contact_mode[keep],
        )

    def frames(self, title: str = "", *, run: SimulationResult | None = None) -> Frames:
        """The frames kept (at most ``max_frames``, evenly spread, the first and last); for a
        run with planes, ``run`` is that run (any of its samples, e.g. read back from its file):
        its planes and contact pairs."""
        assert self.last is not None, "frames: no samples were kept"
        number, t, position, tension, energy, mode = (
            np.concatenate(column) for column in zip(*self.kept, self.last, strict=True)
        )
        if number.size > 1 and number[-2] == number[-1]:  # (the last sample was kept already)
            number, t, position, tension, energy, mode = (
                c[:-1] for c in (number, t, position, tension, energy, mode)
            )
        if mode.shape[1] and run is None:
            raise ValueError("run: the run of planes whose frames these are, needed")
        return _frames(
            self.structure,
            t,
            position,
            tension,
            {name: energy[:, k] for k, name in enumerate(ENERGY_NAMES)},
            decimated_indices(t.size, self.max_frames),
            title,
            number,
            contact=None if run is None else _contact_of(run, mode),
        )


def _rows(columns: tuple[np.ndarray, ...], keep: np.ndarray) -> tuple[np.ndarray, ...]:
    """The rows ``keep`` (a mask) of each of ``columns``."""
    return tuple(column[keep] for column in columns)


def read_frames(
    path: PathLike, *, max_frames: int, max_bytes: int, check: MemberCheck | None = None
) -> tuple[Frames, int]:
    """The frames of the trajectory file at ``path`` for the viewer (:func:`frame_budget` of
    them, evenly spread, the first and last samples among them) and
    its number of samples, reading only the datasets they show: a long run's whole file is
    several times larger (``q``, ``qdot``, velocities, lengths).  With ``check`` (the design
    of the run's members) the frames get their utilisation (:func:`make_frames`), from every
    dataset at those samples.  ``ValueError`` names the file and the problem
    (:mod:`tensegrity.io.trajectory`)."""
    from tensegrity.io.trajectory import read_dataset, read_trajectory

    ends = read_trajectory(path, every=2**62)  # the structure, the message: two samples
    n_samples = read_dataset(path, "t").size
    budget = frame_budget(
        ends.structure,
        max_frames=max_frames,
        max_bytes=max_bytes,
        utilisation=check is not None,
        planes=len(ends.planes),
    )
    every = max(1, -(-(n_samples - 1) // max(budget - 1, 1)))
    numbers = np.r_[np.arange(0, n_samples - 1, every), n_samples - 1]  # (as read_dataset reads)
    if check is not None:
        frames = make_frames(read_trajectory(path, every=every), check=check)
        return dataclasses.replace(frames, index=numbers), n_samples
    energy = read_dataset(path, "energy", every=every)
    frames = _frames(
        ends.structure,
        read_dataset(path, "t", every=every),
        read_dataset(path, "node_position", every=every),
        read_dataset(path, "tendon_tension", every=every),
        {name: energy[:, k] for k, name in enumerate(ENERGY_NAMES)},
        None,
        ends.message,
        numbers,
        contact=_contact_of(ends, read_dataset(path, "contact_mode", every=every).astype(np.int8))
        if ends.planes
        else None,
    )
    return frames, n_samples


def _frames(
    structure: Structure,
    t: np.ndarray,
    node_position: np.ndarray,
    tendon_tension: np.ndarray,
    energy: Mapping[str, np.ndarray] | None,
    indices: np.ndarray | None,
    title: str,
    numbers: np.ndarray | None = None,
    *,
    contact: _Contact | None = None,
) -> Frames:
    """:func:`make_frames` of a run's arrays (T rows each; ``energy`` by
    :data:`~tensegrity.engine.result.ENERGY_NAMES`, or ``None``: no energies, ``{}`` as
    :func:`structure_frames`); ``numbers`` (T,) the rows' sample numbers in the run (default:
    the rows are every sample); ``contact`` its planes and contact modes (T rows), if any."""
    T = t.size
    index = np.arange(T) if indices is None else np.asarray(indices, dtype=np.int64)
    if index.ndim != 1 or not index.size or index.min() < 0 or index.max() >= T:
        raise ValueError(f"indices: expected sample numbers in 0..{T - 1}, got {index!r}")
    position = _padded(structure, node_position[index])
    every = _padded(structure, node_position)
    tension = np.asarray(tendon_tension[index], dtype=float)
    energies = (
        {}
        if energy is None
        else {
            "total": total_energy(energy)[index],
            "kinetic": energy["kinetic"][index],
            "elastic": energy["elastic"][index],
        }
    )
    bounds = np.stack([every.min(axis=(0, 1)), every.max(axis=(0, 1))])
    return Frames(
        structure=structure,
        t=np.asarray(t[index], dtype=float),
        index=index if numbers is None else np.asarray(numbers, dtype=np.int64)[index],
        node_position=position,
        tendon_tension=tension,
        slack=tension <= 0,
        energy=energies,
        tension_range=_tension_range(np.asarray(tendon_tension)),
        bounds=bounds,
        title=title,
        contacts=None if contact is None else _frame_contacts(contact, every, index),
    )


def _frame_contacts(contact: _Contact, every: np.ndarray, index: np.ndarray) -> FrameContacts:
    """The :class:`FrameContacts` of the frames ``index`` of a run with planes, its patches
    around the nodes of every row, ``every`` (T, N, 3) [m]."""
    patch, normal, cell = plane_patches(contact.planes, every)
    return FrameContacts(
        patch=patch,
        normal=normal,
        cell=cell,
        node=np.asarray(contact.node, dtype=np.int64),
        plane=np.asarray(contact.plane, dtype=np.int64),
        mode=np.asarray(contact.mode[index], dtype=np.int8),
    )


def plane_patches(
    planes: Sequence[Mapping[str, Any]], node_position: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """The finite patches to draw of infinite planes: each the footprint of the nodes on the
    plane (projected along its normal) widened by :data:`PLANE_MARGIN` of the run's size, its
    sides on the grid of the returned ``cell``, which is fixed in space (so that rolling and
    sliding show against it).

    Parameters
    ----------
    planes : sequence of mappings
        Each plane's ``"point"`` (3,) [m] and ``"normal"`` (3,) (``Plane.settings()``, as
        :attr:`SimulationResult.planes <tensegrity.engine.result.SimulationResult.planes>`).
    node_position : array_like, shape (..., N, 3)
        Node positions [m], e.g. of every sample of a run.

    Returns
    -------
    patch : ndarray, shape (P, 4, 3)
        Each plane's patch, its corners [m] in turn around it.
    normal : ndarray, shape (P, 3)
        Each plane's unit normal.
    cell : float
        Side [m] of the grid's squares: 1, 2 or 5 times a power of ten, near an eighth of the
        run's size.
    """
    x = np.asarray(node_position, dtype=float).reshape(-1, 3)
    size = float(np.ptp(x, axis=0).max()) or 1.0
    step = size / 8
    power = 10.0 ** np.floor(np.log10(step))
    cell = float(power * min(m for m in (1, 2, 5, 10) if m * power >= step * (1 - 1e-12)))
    margin = PLANE_MARGIN * size
    patches, normals = [], []
    for plane in planes:
        n = np.asarray(plane["normal"], dtype=float)
        n = n / np.linalg.norm(n)
        point = np.asarray(plane["point"], dtype=float)
        origin = (point @ n) * n  # (the plane's point nearest the origin: the grid fixed)
        axis = np.eye(3)[np.argmin(np.abs(n))]  # (x on a ground plane)
        u = axis - (axis @ n) * n
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        a, b = (x - origin) @ u, (x - origin) @ v
        (a0, b0), (a1, b1) = (
            cell * np.floor((np.array([a.min(), b.min()]) - margin) / cell),
            cell * np.ceil((np.array([a.max(), b.max()]) + margin) / cell),
        )
        corners = [(a0, b0), (a1, b0), (a1, b1), (a0, b1)]
        patches.append([origin + s * u + t * v for s, t in corners])
        normals.append(n)
    return np.array(patches).reshape(-1, 4, 3), np.array(normals).reshape(-1, 3), cell


def motion_frames(
    structure: Structure,
    t: np.ndarray,
    node_position: np.ndarray,
    tendon_tension: np.ndarray,
    *,
    indices: np.ndarray | None = None,
    title: str = "",
) -> Frames:
    """Frames of a motion that is not a :class:`~tensegrity.engine.result.SimulationResult`
    (a mode's oscillation, a sequence of equilibria, a controlled run's states): every row
    a frame, no energies (``{}``, as :func:`structure_frames`).

    Parameters
    ----------
    structure : Structure
        ``N`` nodes, ``S`` tendons.
    t : array_like, shape (T,)
        Time of each frame [s], ascending.
    node_position : array_like, shape (T, N, dim)
        Node positions [m].
    tendon_tension : array_like, shape (T, S)
        Tendon tensions [N], e.g. :func:`tensegrity.physics.dynamics.tendon_tensions` of each
        configuration.
    indices : array_like of int, optional
        Rows to show (e.g. :func:`decimated_indices` of a long motion); default every row.
        The tension range and bounds are over every row.
    title : str
        A line naming the motion, or empty.
    """
    t = np.asarray(t, dtype=float)
    return _frames(
        structure,
        t,
        np.asarray(node_position, dtype=float),
        np.asarray(tendon_tension, dtype=float).reshape(t.size, structure.n_tendons),
        None,
        indices,
        title,
    )


def structure_frames(structure: Structure, position: np.ndarray | None = None) -> Frames:
    """One frame of ``structure`` at rest: at ``position`` (N, dim) [m] (default its
    ``node_position``), its tendons' tensions from their stretch, ``k max(l - L0, 0)`` [N]
    (:func:`~tensegrity.physics.dynamics.elastic_tensions`: a structure's view before any run;
    damping and control left out)."""
    p = _padded(structure, structure.node_position if position is None else position)[None]
    tension = elastic_tensions(structure, tendon_lengths(structure, p[0]))[None]
    return Frames(
        structure=structure,
        t=np.zeros(1),
        index=np.zeros(1, np.int64),
        node_position=p,
        tendon_tension=tension,
        slack=tension <= 0,
        energy={},
        tension_range=_tension_range(tension),
        bounds=np.stack([p[0].min(axis=0), p[0].max(axis=0)]),
        title="",
    )


def tension_colors(tension: np.ndarray, tension_range: tuple[float, float]) -> np.ndarray:
    """RGBA colours (..., 4) of tensions (...) [N] on the tension colour map over
    ``tension_range`` (clipped at its ends); the map of :mod:`tensegrity.plots.figures`."""
    from tensegrity.plots.figures import tension_colormap  # (matplotlib: loaded on use)

    low, high = tension_range
    scaled = np.clip((np.asarray(tension, dtype=float) - low) / (high - low), 0.0, 1.0)
    return tension_colormap()(scaled)
