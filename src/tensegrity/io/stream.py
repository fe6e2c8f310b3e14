"""Long simulations streamed to an HDF5 trajectory file in segments, resumable after interruption.

:func:`simulate_to_file` cuts ``t_span`` into segments on a fixed grid of boundaries and runs
:func:`tensegrity.engine.simulate.simulate` once per segment, each starting from the last state of
the one before.  After every segment its samples are appended to resizable, chunked datasets and a
checkpoint is stored in the same file, so that

- memory is that of one segment, whatever the length of the run;
- an interrupted run (Ctrl-C, an exception, a killed process) is resumed from its last finished
  segment by calling :func:`simulate_to_file` again with the same arguments, and produces exactly
  the samples an uninterrupted run with the same segments produces (the checkpoint holds the
  state bit for bit), with no sample lost or repeated.

Segment grid
------------
With sample spacing ``sample_dt`` and ``K = max(1, round(segment / sample_dt))`` samples per
segment, segment ``k`` spans ``[t0 + k K sample_dt, t0 + (k+1) K sample_dt]``, the last one ending
at ``t_end``.  Each segment's first sample is the previous segment's last, and is not stored
again.  The integrator restarts at every boundary (an adaptive method chooses its first step
again, ``rk4`` may take one shorter step to land on the boundary, the state is projected onto the
rod constraints), so a segmented run agrees with one :func:`simulate` call over the whole span only
to the integration tolerance, but bit for bit with any other run on the same grid.  Blow-up
detection (``max_energy_growth``) compares the energy balance with its value at the start of each
segment rather than of the run.

Energy bookkeeping is continuous: ``dissipated``, ``external_work`` and ``control_work`` restart at
zero in every :func:`simulate` call and are offset here by their values at the segment start, so
the stored columns are those of one run.

The file and how an incomplete one shows
----------------------------------------
While the run goes on, the data live in ``path + ".partial"`` (:data:`PARTIAL_SUFFIX`), whose
``format`` attribute is ``"tensegrity-trajectory-partial"`` (:data:`PARTIAL_FORMAT`) and whose
``complete`` attribute is false; :func:`tensegrity.io.trajectory.read_trajectory` refuses it ("not a
tensegrity trajectory file").  When the run ends (end time reached, steady state, or a failed,
unstable segment) the attributes are set to those of a finished trajectory (``format =
"tensegrity-trajectory"``, ``complete = True``, ``status``, ``message``), the file is flushed to
disk and renamed onto ``path`` (an atomic :func:`os.replace`).  So a file under ``path`` is always
complete, and :func:`tensegrity.io.trajectory.read_trajectory` reads it: the datasets have the names
and layout of :func:`tensegrity.io.trajectory.write_trajectory` (module docstring of
:mod:`tensegrity.io.trajectory`), stored exactly (float64, uncompressed: trajectories of moving
structures shrink by ~10% under gzip, which cost 60 times the write time, measured on a (10,10)
segment) in chunks of about 1 MiB, each with a Fletcher-32 checksum (a damaged file is an error
when read, not wrong numbers; 4 bytes a chunk, and about half the time of an uncompressed write
more: 44 -> 68 ms for 48 MB, h5py alone on a 2-core machine).  The file's ``settings`` is the
run's record (``SimulationResult.settings``, written when the file is created) with the segment
grid under ``stream``; ``switch_times`` is written when the run ends, and so is the members'
design (``material_form``: the attribute ``structure_material``), the finishing call's.  Extra
root attributes: ``complete``, ``stream_settings`` (JSON: what a resumed run must match) and
``stream_settings_hash``; an extra group ``checkpoint`` (see :class:`Checkpoint`).

A segment is stored in this order: its rows are appended to every dataset; the new checkpoint is
written into whichever of the two slots ``checkpoint/a``, ``checkpoint/b`` is not current; one
attribute write, ``checkpoint.attrs["current"]`` (0 or 1), then commits it.  An interruption
anywhere before that write leaves the previous checkpoint current, and its ``n_samples`` tells how
many rows count.

The partial file is open only while a segment's samples and the checkpoint are written (the
simulation itself runs with the file closed), then closed and ``fsync``-ed.  An interruption raised
as a Python exception (``KeyboardInterrupt`` included) at any moment leaves it consistent: rows
written after the last checkpoint are dropped on resume.  HDF5 has no journal, so a process killed
hard (``SIGKILL``, power loss) during that short write can leave the partial file unreadable;
:func:`simulate_to_file` then says so, and ``resume=False`` starts again.

Resuming
--------
``resume=True`` (the default) continues ``path + ".partial"`` if it exists, after checking that
the structure and every setting (``t_span``, ``sample_dt``, the segment grid and all
:func:`simulate` options, defaults filled in) are those of the checkpoint: otherwise it raises
``ValueError`` naming what differs.  Arrays (``initial``, ``control``, ``external_force``,
``gravity``) and tables (a :class:`~tensegrity.model.loads.ControlTable` or
:class:`~tensegrity.model.loads.ForceTable` as ``control`` or ``external_force``: their times
and rows, so a table file changed between the two runs is detected) are compared through a
SHA-256 of their bytes; any other callable ``control`` or ``external_force`` only through its
module and qualified name, so a changed function body under the same name is not detected.
If ``path`` already holds a finished streamed run with the same settings, nothing is run and
its summary is returned.  A finished file with other settings is replaced (atomically, at the
end of the new run), as every writer of :mod:`tensegrity.io.trajectory` does.  ``resume=False``
discards a partial file and starts again.

SI units throughout: m, kg, s, N, J.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tensegrity.engine.actuation import controlled_actuators
from tensegrity.engine.feedback import LinearFeedback
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.loop import Checkpointing, LoopState, StopCondition, run
from tensegrity.engine.options import OPTION_FIELDS, Options, sample_count, sample_time
from tensegrity.engine.result import RunSummary, Samples
from tensegrity.engine.simulate import STATUS_END, options_and_inputs
from tensegrity.io import trajectory as tio
from tensegrity.io.checked import (
    FLOATS,
    NUMBERS,
    attribute_json,
    attribute_number,
    attribute_text,
    hdf5_dataset,
    hdf5_group,
    hdf5_names,
    read_datasets,
)
from tensegrity.io.files import (
    PathLike,
    atomic_path,
    file_error,
    fsync_directory,
    new_file_mode,
    regular_file,
    reserve_space,
)
from tensegrity.model.actuators import Actuators
from tensegrity.model.ground import planes_of
from tensegrity.model.loads import ControlTable, ForceTable
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import State

#: Suffix of the file a run writes into until it ends.
PARTIAL_SUFFIX = ".partial"
#: ``format`` attribute of an unfinished streamed file
#: (:func:`tensegrity.io.trajectory.read_trajectory` refuses it).
PARTIAL_FORMAT = "tensegrity-trajectory-partial"
#: Version of the checkpoint layout and of the settings hash.
STREAM_VERSION = 3
#: Default budget [bytes] for the samples of one segment when ``segment`` is not given.
DEFAULT_SEGMENT_BYTES = 64 * 2**20
#: Most samples per segment when ``segment`` is not given.
DEFAULT_SEGMENT_SAMPLES = 1000
#: Target size [bytes] of one HDF5 chunk.
CHUNK_BYTES = 2**20

#: A run's inputs beside its options (keywords of :func:`tensegrity.engine.simulate.simulate`),
#: none by default.
_INPUTS = (
    "initial",
    "control",
    "external_force",
    "gravity",
    "ground",
    "contact_radius",
    "controller",
    "actuators",
    "stop",
)
#: The options a streamed run takes and their defaults: its inputs and the fields of
#: :class:`~tensegrity.engine.options.Options`.
_SIMULATE_PARAMETERS = {
    **dict.fromkeys(_INPUTS),
    **{name: field.default for name, field in OPTION_FIELDS.items()},
}
#: ``simulate`` options handled here rather than passed through.
_OWN_OPTIONS = ("sample_dt", "progress")
#: ``simulate`` options left out of the settings a resumed run must match: a budget (a run
#: may be resumed with more time).
_BUDGETS = ("max_wall_time",)
_COUNTERS = tio.COUNT_ATTRIBUTES


# ----------------------------------------------------------------------------- results
class OutOfTimeError(RuntimeError):
    """A streamed run stopped by ``max_wall_time``; ``partial`` [path] holds it up to its last
    checkpoint, to be resumed (:func:`simulate_to_file` with ``resume=True``)."""

    def __init__(self, message: str, partial: Path) -> None:
        super().__init__(message)
        self.partial = partial


@dataclasses.dataclass(frozen=True)
class StreamProgress:
    """What a ``progress`` callback of :func:`simulate_to_file` receives after each segment.

    Attributes
    ----------
    segment : int
        Segments finished so far (all sessions), ``1..n_segments``.
    n_segments : int
        Segments of the whole run.
    t : float
        Time of the last stored sample [s].
    n_samples : int
        Samples stored so far.
    wall_time : float
        Wall time of the run so far, all sessions [s].
    """

    segment: int
    n_segments: int
    t: float
    n_samples: int
    wall_time: float


@dataclasses.dataclass(frozen=True)
class Checkpoint:
    """The resumable state stored in an (unfinished or finished) streamed file.

    Stored in the file as the current slot (``checkpoint/a`` or ``checkpoint/b``, named by the
    attribute ``current`` of the group ``checkpoint``): datasets ``q``, ``qdot`` (6R,), a group
    ``loop`` with the arrays of :meth:`LoopState.to_arrays`, and the other fields as
    attributes.

    Attributes
    ----------
    next_segment : int
        Index of the first segment not yet stored (``n_segments`` when all are).
    n_segments : int
    n_samples : int
        Rows of every dataset that belong to the run; rows past them (an interrupted write) are
        dropped on resume.
    state : State
        The last stored sample (``t`` [s], ``q`` [m], ``qdot`` [m/s]): the end of the last
        stored segment.
    loop : LoopState or None
        The engine's state there, from which the run continues exactly
        (:class:`tensegrity.engine.loop.LoopState`); None before the first segment.
    counts : dict of str to int
        ``nfev``, ``nsteps``, ``nswitches``, ``nprojections`` up to there.
    max_rod_length_error : float
    wall_time : float
        Wall time of the stored segments, all sessions [s].
    settings_hash : str
        SHA-256 of the structure and settings of the run.
    ended : bool
        The run has ended (end time, steady state or failure): a resume only finishes the file.
    status : int
        ``1`` steady state, ``0`` end time reached or still running, ``-1`` failed.
    message : str
    max_constraint_error : float
        Largest violation of the joints and supports over the stored segments [m].
    """

    next_segment: int
    n_segments: int
    n_samples: int
    state: State
    loop: LoopState | None
    counts: dict[str, int]
    max_rod_length_error: float
    wall_time: float
    settings_hash: str
    ended: bool = False
    status: int = STATUS_END
    message: str = "running"
    max_constraint_error: float = 0.0


@dataclasses.dataclass(frozen=True)
class StreamSummary:
    """How a streamed run ended (:func:`simulate_to_file`).

    Attributes
    ----------
    path : pathlib.Path
        The finished trajectory file (readable with
        :func:`tensegrity.io.trajectory.read_trajectory`).
    status : int
        ``1`` steady state reached, ``0`` end time reached, ``-1`` a segment failed (unstable);
        the samples up to the failure are stored.
    message : str
    n_samples : int
        Samples stored.
    t_first, t_last : float
        Times of the first and last samples [s].
    n_segments : int
        Segments of the grid.
    segments_stored : int
        Segments stored (fewer than ``n_segments`` after a steady state or a failure).
    segments_run : int
        Segments simulated by this call (0 if the file was already finished).
    resumed_from : int or None
        Segment this call resumed from, or None for a fresh run.
    samples_per_segment : int
        ``K``: segments are ``K sample_dt`` long.
    nfev, nsteps, nswitches, nprojections : int
        Summed over all segments.
    max_rod_length_error : float
    max_constraint_error : float
        Largest violation of the joints and supports [m] (0 without them).
    wall_time : float
        Over all sessions [s].
    settings_hash : str
    """

    path: Path
    status: int
    message: str
    n_samples: int
    t_first: float
    t_last: float
    n_segments: int
    segments_stored: int
    segments_run: int
    resumed_from: int | None
    samples_per_segment: int
    nfev: int
    nsteps: int
    nswitches: int
    nprojections: int
    max_rod_length_error: float
    max_constraint_error: float
    wall_time: float
    settings_hash: str

    @property
    def success(self) -> bool:
        """True unless a segment failed."""
        return self.status >= 0


# ----------------------------------------------------------------------------- settings
def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _array_token(value: Any) -> dict[str, Any]:
    array = np.ascontiguousarray(np.asarray(value, dtype=float))
    return {"shape": list(array.shape), "sha256": _digest(array.tobytes())}


def _option_token(name: str, value: Any) -> Any:
    """A JSON-able, comparable form of one ``simulate`` option."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if name == "initial":
        if not isinstance(value, State):
            raise TypeError(f"initial: expected a State, got {type(value).__name__}")
        return {"q": _array_token(value.q), "qdot": _array_token(value.qdot)}
    if name == "ground":  # (a Plane or planes: their fields)
        return {"planes": [plane.settings() for plane in planes_of(value)]}
    if isinstance(value, LinearFeedback):  # (compared by content)
        return {
            "linear_feedback": {
                "K": _array_token(value.K),
                "y_ref": _array_token(value.y_ref),
                "u_ref": _array_token(value.u_ref),
                "period": value.period,
                "outputs": list(value.outputs),
                "tendons": None if value.tendons is None else [str(t) for t in value.tendons],
            }
        }
    if isinstance(value, Actuators):
        return {
            "actuators": {
                field.name: _array_token(getattr(value, field.name))
                for field in dataclasses.fields(value)
            }
        }
    if isinstance(value, (ControlTable, ForceTable)):  # (callable, but compared by content)
        return {
            "table": type(value).__name__,
            "time": _array_token(value.time),
            "values": _array_token(value.values),
            "outside": value.outside,
        }
    if callable(value):
        module = getattr(value, "__module__", None) or "?"
        qualname = getattr(value, "__qualname__", None) or type(value).__qualname__
        return {"callable": f"{module}.{qualname}"}
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    return {"array": _array_token(value)}


def _stream_settings(
    structure: Structure,
    t0: float,
    t1: float,
    sample_dt: float,
    samples_per_segment: int,
    options: Mapping[str, Any],
) -> dict[str, Any]:
    """The canonical settings of a run; every simulate option appears, defaults filled in."""
    filled = {
        name: options.get(name, default)
        for name, default in _SIMULATE_PARAMETERS.items()
        if name not in _OWN_OPTIONS + _BUDGETS
    }
    return {
        "stream_version": STREAM_VERSION,
        "structure": _structure_digest(structure.to_dict()),
        "t_span": [t0, t1],
        "sample_dt": sample_dt,
        "samples_per_segment": samples_per_segment,
        "options": {name: _option_token(name, value) for name, value in sorted(filled.items())},
    }


def _structure_digest(data: Mapping[str, Any]) -> str:
    """SHA-256 of a structure's dict form (:meth:`Structure.to_dict`), keys sorted."""
    return _digest(json.dumps(data, allow_nan=False, sort_keys=True).encode())


def _settings_json(settings: Mapping[str, Any]) -> str:
    return json.dumps(settings, sort_keys=True, allow_nan=False)


def _differences(
    stored: Mapping[str, Any], wanted: Mapping[str, Any], prefix: str = ""
) -> list[str]:
    """Human-readable differences between two settings dicts."""
    out = []
    for key in sorted(set(stored) | set(wanted)):
        a, b = stored.get(key, "<absent>"), wanted.get(key, "<absent>")
        if isinstance(a, Mapping) and isinstance(b, Mapping) and key != "structure":
            out += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            if key == "structure":
                out.append("structure (a different structure or parameters)")
            else:
                out.append(
                    f"{prefix}{key}: checkpoint has {json.dumps(a)}, this call {json.dumps(b)}"
                )
    return out


# ----------------------------------------------------------------------------- grid
def segment_grid(
    t_span: tuple[float, float], sample_dt: float, samples_per_segment: int
) -> np.ndarray:
    """Segment boundaries [s]: the times of samples ``0, K, 2K, ..`` of the run, then ``t_end``.

    The run's samples are those of the engine (:func:`tensegrity.engine.options.sample_count`,
    a last one within ``1e-9 sample_dt`` of ``t_end`` taken as ``t_end``), ``K`` to a segment.

    Returns
    -------
    ndarray, shape (n_segments + 1,)
    """
    t0, t1 = (float(x) for x in t_span)
    n_segments = segments_of(sample_count(t0, t1, sample_dt), samples_per_segment)
    index = np.arange(n_segments) * samples_per_segment
    return np.array([*(sample_time(t0, t1, sample_dt, int(k)) for k in index), t1])


def segments_of(n_samples: int, samples_per_segment: int) -> int:
    """Segments of a run of ``n_samples`` samples, ``samples_per_segment`` to a segment (each
    segment's first sample the last of the one before; a last one may be shorter)."""
    return max(1, math.ceil((n_samples - 1) / samples_per_segment))


def sample_bytes(structure: Structure, *, held: bool = False, planes: int = 0) -> int:
    """Bytes of one sample of ``structure`` in a trajectory file (its datasets' rows, float64),
    or with ``held`` as a segment holds it in memory (a row of
    :class:`~tensegrity.engine.result.Samples`: the arrays computed on read too), in a run with
    ``planes`` planes (the contact pairs' columns; none without)."""
    pairs = tio.contact_pairs(structure, planes)
    if held:
        return Samples.row_bytes(structure, pairs)
    return 8 * sum(math.prod(shape) for shape in tio.sample_rows(structure, pairs).values())


def samples_per_segment(
    structure: Structure, segment: float | None, sample_dt: float, *, planes: int = 0
) -> int:
    """Samples of one segment: ``segment`` [s] in samples, or by default as many as fit
    :data:`DEFAULT_SEGMENT_BYTES` (held twice while a segment is written; a run with ``planes``
    planes holds its contact columns too), at most :data:`DEFAULT_SEGMENT_SAMPLES`."""
    if segment is None:
        row_bytes = sample_bytes(structure, held=True, planes=planes)
        return int(max(1, min(DEFAULT_SEGMENT_SAMPLES, DEFAULT_SEGMENT_BYTES // (2 * row_bytes))))
    segment = float(segment)
    if not (math.isfinite(segment) and segment > 0):
        raise ValueError(f"segment: must be a duration > 0 in s, got {segment!r}")
    return max(1, round(segment / sample_dt))


# ----------------------------------------------------------------------------- HDF5
def _chunk_rows(row_shape: tuple[int, ...], samples_per_segment: int) -> int:
    row_bytes = 8 * max(1, math.prod(row_shape))
    return int(max(1, min(samples_per_segment + 1, CHUNK_BYTES // row_bytes)))


def _create_partial(
    partial: Path,
    structure: Structure,
    plan: _Plan,
) -> None:
    """Create the partial file (atomically: it appears only once it holds its empty layout)."""
    import h5py

    text = json.dumps(structure.to_dict(), allow_nan=False)
    with atomic_path(partial) as tmp:
        reserve_space(tmp, METADATA_BYTES + 4 * len(text) + 64 * structure.n_coordinates)
        with h5py.File(tmp, "w", libver=("v108", "v108")) as f:
            _write_layout(f, structure, text, plan)


def _write_layout(f, structure: Structure, structure_text: str, plan: _Plan) -> None:
    """The attributes, empty datasets and first checkpoint of a new partial file ``f``."""
    import h5py

    f.attrs["format"] = PARTIAL_FORMAT
    f.attrs["complete"] = False
    tio.write_layout_attributes(f, structure, structure_text)
    f.attrs["settings"] = tio.settings_json(plan.record)
    f.attrs["stream_settings"] = _settings_json(plan.settings)
    f.attrs["stream_settings_hash"] = plan.settings_hash
    n = structure.n_coordinates
    first = Checkpoint(
        next_segment=0,
        n_segments=plan.n_segments,
        n_samples=0,
        state=State(t=math.nan, q=np.zeros(n), qdot=np.zeros(n)),
        loop=None,
        counts=dict.fromkeys(_COUNTERS, 0),
        max_rod_length_error=0.0,
        wall_time=0.0,
        settings_hash=plan.settings_hash,
    )
    _write_run_attributes(f, first)
    pairs = tio.contact_pairs(structure, len(plan.record.get("ground", ())))
    actuated = len(plan.record.get("actuators", {}).get("tendons", ()))
    rows = tio.sample_rows(structure, pairs) | tio.event_rows(pairs, actuated)
    for name, shape in rows.items():
        f.create_dataset(
            name,
            shape=(0, *shape),
            dtype="f8",
            maxshape=(None, *(d if d > 0 else None for d in shape)),
            chunks=(_chunk_rows(shape, plan.K), *(max(d, 1) for d in shape)),
            fletcher32=True,
        )
    f["energy"].attrs["columns"] = np.array(tio.ENERGY_COLUMNS, dtype=h5py.string_dtype())
    group = f.create_group("checkpoint")
    group.attrs["version"] = STREAM_VERSION
    for slot in _SLOTS:
        group.create_group(slot)
    _write_checkpoint(group["a"], first)
    group.attrs["current"] = np.int64(0)


def _write_run_attributes(f, checkpoint: Checkpoint) -> None:
    """The root attributes of how the run ended (so far), from ``checkpoint``."""
    tio.write_run_attributes(
        f,
        status=checkpoint.status,
        message=checkpoint.message,
        counts=checkpoint.counts,
        max_rod_length_error=checkpoint.max_rod_length_error,
        max_constraint_error=checkpoint.max_constraint_error,
        wall_time=checkpoint.wall_time,
    )


#: The two checkpoint slots; the group attribute ``current`` (0 or 1) names the valid one.
_SLOTS = ("a", "b")


def _store_checkpoint(f, checkpoint: Checkpoint) -> None:
    """Write ``checkpoint`` into the slot that is not current, then make it current (the commit)."""
    group = f["checkpoint"]
    spare = 1 - int(group.attrs["current"])
    _write_checkpoint(group[_SLOTS[spare]], checkpoint)
    # One in-place write of an existing scalar attribute (a single HDF5 call, where assigning
    # attrs[...] would delete and re-create it): the commit point.
    group.attrs.modify("current", np.int64(spare))


def _write_checkpoint(slot, checkpoint: Checkpoint) -> None:
    """Fill one checkpoint slot (a group, emptied first)."""
    for name in list(slot):
        del slot[name]
    slot.create_dataset("q", data=np.asarray(checkpoint.state.q, dtype=float))
    slot.create_dataset("qdot", data=np.asarray(checkpoint.state.qdot, dtype=float))
    if checkpoint.loop is not None:
        loop = slot.create_group("loop")
        for name, value in checkpoint.loop.to_arrays().items():
            loop.create_dataset(name, data=value)
    a = slot.attrs
    a["next_segment"] = checkpoint.next_segment
    a["n_segments"] = checkpoint.n_segments
    a["n_samples"] = checkpoint.n_samples
    a["t"] = float(checkpoint.state.t)
    for name, count in checkpoint.counts.items():
        a[name] = int(count)
    a["max_rod_length_error"] = float(checkpoint.max_rod_length_error)
    a["max_constraint_error"] = float(checkpoint.max_constraint_error)
    a["wall_time"] = float(checkpoint.wall_time)
    a["settings_hash"] = checkpoint.settings_hash
    a["ended"] = bool(checkpoint.ended)
    a["status"] = int(checkpoint.status)
    a["message"] = str(checkpoint.message)


def _read_checkpoint_open(f, path: PathLike) -> Checkpoint:
    """The current checkpoint of the open streamed file ``f``; each group, attribute and dataset
    is checked (:mod:`tensegrity.io.checked`) before it is read."""
    group = hdf5_group(f, "checkpoint", path)
    if group is None or "current" not in group.attrs:
        raise file_error(path, "no checkpoint (not written by tensegrity.io.stream)")
    current = attribute_number(group, "current", path, integer=True)
    if current not in (0, 1):
        raise file_error(
            path, f"attribute 'current' of 'checkpoint': expected 0 or 1, got {current}"
        )
    version = (
        attribute_number(group, "version", path, integer=True) if "version" in group.attrs else 0
    )
    if version > STREAM_VERSION:
        raise file_error(
            path,
            f"checkpoint version {version} is newer than this library "
            f"reads ({STREAM_VERSION}); upgrade tensegrity",
        )
    slot = hdf5_group(group, _SLOTS[current], path)
    if slot is None:
        raise file_error(path, f"checkpoint: missing group 'checkpoint/{_SLOTS[current]}'")
    try:
        return _checkpoint_in(slot, path)
    except KeyError as exc:
        raise file_error(path, f"checkpoint: missing attribute or dataset {exc}") from exc


def _checkpoint_in(slot, path: PathLike) -> Checkpoint:
    """The checkpoint stored in ``slot`` (``KeyError`` names what is missing)."""

    def number(name: str, integer: bool = False) -> Any:
        if name not in slot.attrs:
            raise KeyError(name)
        return attribute_number(slot, name, path, integer=integer)

    datasets = {name: _slot_dataset(slot, name, path) for name in ("q", "qdot")}
    loop = hdf5_group(slot, "loop", path)
    if loop is not None:
        datasets |= {
            f"loop/{name}": _slot_dataset(loop, name, path, NUMBERS)
            for name in hdf5_names(loop, path)
        }
    arrays = read_datasets(datasets, path)
    if not (arrays["q"].ndim == 1 and arrays["q"].shape == arrays["qdot"].shape):
        raise file_error(
            path,
            f"checkpoint: expected q and qdot of one shape (n,), got {arrays['q'].shape} and "
            f"{arrays['qdot'].shape}",
        )
    segments = {name: number(name, integer=True) for name in ("next_segment", "n_segments")}
    n_samples = number("n_samples", integer=True)
    if not (n_samples >= 0 and 0 <= segments["next_segment"] <= segments["n_segments"]):
        raise file_error(
            path, f"checkpoint: inconsistent counts ({n_samples} samples, segments {segments})"
        )
    for name in ("settings_hash", "message"):
        if name not in slot.attrs:
            raise KeyError(name)
    return Checkpoint(
        **segments,
        n_samples=n_samples,
        state=State(t=number("t"), q=arrays["q"], qdot=arrays["qdot"]),
        loop=None if loop is None else _loop_state(arrays, path),
        counts={name: number(name, integer=True) for name in _COUNTERS},
        max_rod_length_error=number("max_rod_length_error"),
        wall_time=number("wall_time"),
        settings_hash=attribute_text(slot, "settings_hash", path),
        ended=bool(number("ended", integer=True)),
        status=number("status", integer=True),
        message=attribute_text(slot, "message", path),
        # absent from checkpoints written before it was kept: unknown
        max_constraint_error=(
            number("max_constraint_error") if "max_constraint_error" in slot.attrs else np.nan
        ),
    )


def _loop_state(arrays: dict[str, np.ndarray], path: PathLike) -> LoopState:
    """The engine's state from the arrays ``loop/<name>`` of a checkpoint."""
    try:
        return LoopState.from_arrays(
            {name[5:]: value for name, value in arrays.items() if name.startswith("loop/")}
        )
    except (TypeError, ValueError, OverflowError) as exc:
        raise file_error(path, f"checkpoint: group 'loop': {exc}") from exc


def _slot_dataset(group, name: str, path: PathLike, kinds: str = FLOATS):
    dataset = hdf5_dataset(group, name, path, kinds=kinds)
    if dataset is None:
        raise KeyError(name)
    return dataset


def _open_h5(path: Path, mode: str):
    import h5py

    try:
        return h5py.File(path, mode, libver=("v108", "v108"))
    except OSError as exc:
        raise file_error(
            path,
            f"cannot open as HDF5 ({exc}); if the run was killed while writing, start "
            "again with resume=False (run without --resume)",
        ) from exc


def read_checkpoint(path: PathLike) -> Checkpoint:
    """The checkpoint of a streamed file: ``path`` itself, or ``path + ".partial"`` if only that
    exists.

    Raises
    ------
    ValueError
        One line starting with the file name if neither file exists, or it holds no checkpoint.
    """
    path = Path(path)
    target = path if path.exists() else Path(str(path) + PARTIAL_SUFFIX)
    if not target.exists():
        raise file_error(path, f"no such file (nor {target.name})")
    regular_file(target)
    with _open_h5(target, "r") as f:
        return _read_checkpoint_open(f, target)


def _append(f, arrays: Mapping[str, np.ndarray], start: int) -> int:
    """Write ``arrays`` (rows ``start ..``) into the resizable datasets; return the new length."""
    count = len(next(iter(arrays.values())))
    for name, value in arrays.items():
        dataset = f[name]
        dataset.resize(start + count, axis=0)
        if count:
            dataset[start : start + count] = value
    return start + count


#: Bytes reserved for HDF5's own records (object headers, chunk indexes, attributes) in a write
#: to a streamed file.
METADATA_BYTES = 2**20


def _write_bytes(
    arrays: Mapping[str, np.ndarray], start: int, samples_per_segment: int, checkpoint: Checkpoint
) -> int:
    """At most the bytes HDF5 adds to a streamed file when it appends ``arrays`` at row
    ``start`` and stores ``checkpoint``: each chunk the rows touch, twice (a rewritten chunk
    with its checksum may move), the checkpoint's arrays twice, and :data:`METADATA_BYTES`."""
    total = METADATA_BYTES + 16 * (checkpoint.state.q.size + checkpoint.state.qdot.size)
    if checkpoint.loop is not None:
        total += 2 * sum(np.asarray(a).nbytes for a in checkpoint.loop.to_arrays().values())
    for value in arrays.values():
        if len(value):
            rows = _chunk_rows(value.shape[1:], samples_per_segment)
            chunks = (start + len(value) - 1) // rows - start // rows + 1
            total += 2 * chunks * rows * 8 * max(1, math.prod(value.shape[1:]))
    return total


def _truncate(f, n_samples: int, path: Path) -> None:
    for name in tio.SAMPLE_DATASETS:
        if name not in f:
            raise file_error(path, f"missing dataset {name!r}")
        rows = f[name].shape[0]
        if rows < n_samples:
            raise file_error(
                path,
                f"dataset {name!r} has {rows} rows, fewer than the {n_samples} of its checkpoint",
            )
        if rows > n_samples:
            f[name].resize(n_samples, axis=0)


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _summary(
    path: Path,
    f,
    checkpoint: Checkpoint,
    samples_per_segment: int,
    segments_run: int,
    resumed_from: int | None,
) -> StreamSummary:
    time_ = hdf5_dataset(f, "t", path)
    if time_ is None or time_.ndim != 1:
        raise file_error(path, "missing dataset 't' (or not of shape (T,))")
    n = time_.shape[0]
    return StreamSummary(
        path=path,
        status=attribute_number(f, "status", path, integer=True),
        message=attribute_text(f, "message", path),
        n_samples=n,
        t_first=float(time_[0]) if n else math.nan,
        t_last=float(time_[n - 1]) if n else math.nan,
        n_segments=checkpoint.n_segments,
        segments_stored=checkpoint.next_segment,
        segments_run=segments_run,
        resumed_from=resumed_from,
        samples_per_segment=samples_per_segment,
        **checkpoint.counts,
        max_rod_length_error=checkpoint.max_rod_length_error,
        max_constraint_error=checkpoint.max_constraint_error,
        wall_time=checkpoint.wall_time,
        settings_hash=checkpoint.settings_hash,
    )


def _finished_summary(
    path: Path, settings_hash: str, samples_per_segment: int
) -> StreamSummary | None:
    """The summary of a finished streamed file at ``path`` with these settings, else None (an
    unreadable file, or not a regular file, is no finished run: the run replaces it)."""
    import h5py

    try:
        regular_file(path)
        f = h5py.File(path, "r")
    except (OSError, ValueError):
        return None
    with f:
        if not (
            _has_text(f, "format", tio.TRAJECTORY_FORMAT)
            and _has_text(f, "stream_settings_hash", settings_hash)
            and "complete" in f.attrs
            and attribute_number(f, "complete", path, integer=True)
        ):
            return None
        checkpoint = _read_checkpoint_open(f, path)
        return _summary(path, f, checkpoint, samples_per_segment, 0, None)


def _has_text(f, name: str, expected: str) -> bool:
    """Whether ``f`` has the text attribute ``name`` and it is ``expected``."""
    try:
        return name in f.attrs and attribute_text(f, name, f.filename) == expected
    except ValueError:
        return False


# ----------------------------------------------------------------------------- the sink
class FileSink:
    """The engine's sink for a streamed run: samples are kept in memory for one segment, then
    appended to the partial file together with the checkpoint the engine hands over
    (:meth:`save`, a :class:`tensegrity.engine.loop.Checkpointing` callback); :meth:`finish`
    stores the rest and gives the file its final name."""

    def __init__(
        self,
        partial: Path,
        checkpoint: Checkpoint,
        *,
        samples_per_segment: int,
        progress: Callable[[StreamProgress], None] | None,
        observe: Callable[[Samples], None] | None = None,
    ) -> None:
        self.partial, self.checkpoint = partial, checkpoint
        self.K, self.progress, self.observe = samples_per_segment, progress, observe
        self.blocks: list[Samples] = []
        self.segments_run = 0

    def add(self, samples: Samples) -> None:
        self.blocks.append(samples)
        if self.observe is not None:
            self.observe(samples)

    def save(self, loop: LoopState) -> None:
        """Store the segment's samples and ``loop`` as the new checkpoint (then fsync)."""
        self._store(
            self._next_checkpoint(
                loop=loop,
                ended=False,
                status=STATUS_END,
                message="running",
                counts=loop.counts,
                max_rod_length_error=float(loop.monitor[2]),
                max_constraint_error=float(loop.monitor[3]),
                wall_time=loop.wall_time,
            )
        )
        if self.progress is not None:
            c = self.checkpoint
            self.progress(
                StreamProgress(
                    segment=c.next_segment,
                    n_segments=c.n_segments,
                    t=c.state.t,
                    n_samples=c.n_samples,
                    wall_time=c.wall_time,
                )
            )

    def finish(self, run: RunSummary) -> None:
        """Store the last samples and the run's end as the (ended) checkpoint."""
        checkpoint = self._next_checkpoint(
            loop=self.checkpoint.loop,
            ended=True,
            status=run.status,
            message=run.message,
            counts={name: getattr(run, name) for name in _COUNTERS},
            max_rod_length_error=run.max_rod_length_error,
            max_constraint_error=run.max_constraint_error,
            wall_time=run.wall_time,
        )
        self._store(checkpoint, events=tio.event_columns(run))

    def _next_checkpoint(self, *, ended: bool, message: str, **fields: Any) -> Checkpoint:
        """The checkpoint after the samples held now: their count, the last of them, the
        segments stored (a run that ended stores its last, shorter segment too)."""
        c, blocks = self.checkpoint, self.blocks
        n_samples = c.n_samples + sum(len(block.t) for block in blocks)
        segments = (n_samples - 1) // self.K
        if ended:
            segments = max(c.next_segment + 1, segments_of(n_samples, self.K))
        else:
            message = f"running: {segments} of {c.n_segments} segments"
        return Checkpoint(
            next_segment=segments,
            n_segments=c.n_segments,
            n_samples=n_samples,
            state=c.state if not blocks else _last_state(blocks[-1]),
            settings_hash=c.settings_hash,
            ended=ended,
            message=message,
            **fields,
        )

    def _store(
        self, checkpoint: Checkpoint, *, events: Mapping[str, np.ndarray] | None = None
    ) -> None:
        """Append the samples held to the file and make ``checkpoint`` its current one (the
        disk space for it reserved first: a full disk leaves the file at its last checkpoint);
        at the run's end, the run's ``events`` (:func:`tensegrity.io.trajectory.event_columns`)
        with them."""
        columns = _columns(self.blocks)
        reserve_space(
            self.partial, _write_bytes(columns, self.checkpoint.n_samples, self.K, checkpoint)
        )
        with _open_h5(self.partial, "a") as f:
            _append(f, columns, self.checkpoint.n_samples)
            _store_checkpoint(f, checkpoint)
            _write_run_attributes(f, checkpoint)
            for name, rows in (events or {}).items():
                _append(f, {name: rows}, 0)
            f.flush()
        _fsync(self.partial)
        self.blocks, self.checkpoint = [], checkpoint
        self.segments_run += 1


def _last_state(samples: Samples) -> State:
    """The state of the last of ``samples``."""
    return State(t=float(samples.t[-1]), q=samples.q[-1].copy(), qdot=samples.qdot[-1].copy())


def _columns(blocks: list[Samples]) -> dict[str, np.ndarray]:
    """The samples as the file's datasets (:func:`tensegrity.io.trajectory.sample_columns`)."""
    if not blocks:  # (nothing to append)
        return {"t": np.zeros(0)}
    return tio.sample_columns(Samples.join(blocks))


# ----------------------------------------------------------------------------- the run
def simulate_to_file(
    structure: Structure,
    t_span: tuple[float, float],
    path: PathLike,
    *,
    segment: float | None = None,
    resume: bool = True,
    progress: bool | Callable[[StreamProgress], None] = False,
    observe: Callable[[Samples], None] | None = None,
    stop: StopCondition | None = None,
    material_form: Mapping[str, Any] | None = None,
    **simulate_options: Any,
) -> StreamSummary:
    """Simulate ``structure`` over ``t_span = (t0, t_end)`` [s], streaming samples to ``path``.

    One run of the engine (:func:`tensegrity.engine.loop.run`) with this module's sink: see the
    module docstring for the segments, the file and resuming.

    Parameters
    ----------
    structure : Structure
    t_span : (float, float)
        ``(t0, t_end)`` [s], ``t0 < t_end``.
    path : str or os.PathLike
        The finished trajectory file (conventionally ``*.h5``); its directory must exist.  Until
        the run ends the data are in ``path + ".partial"``.
    segment : float, optional
        Time between checkpoints [s], rounded to a whole number ``K >= 1`` of sample intervals.
        Default: at most 1000 samples, and few enough that one segment's samples take about 64
        MiB (one sample of a (100, 100) shell takes about 5 MB).  Memory use is about twice one
        segment's samples, independent of the length of the run.
    resume : bool
        Continue ``path + ".partial"`` from its checkpoint if it exists (default), after checking
        that it was started with the same structure and settings; return at once if ``path`` is
        a finished run with the same settings.  False: start again.
    progress : bool or callable
        True: a ``tqdm`` bar over segments on stderr.  A callable is called with a
        :class:`StreamProgress` after each stored segment (once its checkpoint is on disk); an
        exception it raises (``KeyboardInterrupt`` included) stops the run, which can be resumed.
    observe : callable, optional
        Called with each block of samples this call makes
        (:class:`~tensegrity.engine.result.Samples`, in time order, a resumed call's from where
        it resumed) as the file gets them: what a caller wants of them without reading the file
        again (the CLI's viewer frames).
    stop : StopCondition, optional
        Ends the run at a sample (:func:`tensegrity.engine.simulate.simulate`'s ``stop``); the
        file is finished there, with status 2.  Not part of the settings a resume must match.
    material_form : mapping, optional
        The members' design: ``structure`` in the material form, stored in the finished file as
        :func:`tensegrity.io.trajectory.write_trajectory` stores its ``material_form``.  Not
        part of the settings a resume must match: the call that finishes the file writes its
        own.
    **simulate_options
        The options of :func:`tensegrity.engine.simulate.simulate`: ``sample_dt`` [s] (default
        ``(t_end - t0) / 1000``), ``initial``, ``control``, ``external_force``, ``gravity``,
        ``ground``, ``contact_radius``, ``method``, ``rtol``, ``atol``, ``dt``,
        ``locate_switches``, ``steady_state``,
        ``velocity_tol``, ``acceleration_tol``, ``projection_tol``, ``max_rod_length_error``,
        ``max_energy_growth``, ``max_steps``, ``max_samples``, ``max_wall_time`` (a budget for
        this call: see :class:`OutOfTimeError`).  Controls and forces given as functions receive the
        absolute time.  (``progress`` is this function's: it reports segments.)

    Returns
    -------
    StreamSummary
        ``status`` ``1`` (steady state: the run stops at the first steady sample), ``2`` (stopped
        by ``stop``), ``0`` (end time reached) or ``-1`` (the run went unstable: its samples up
        to the failure are stored, ``message`` says why; the file is finished all the same).

    Raises
    ------
    ValueError
        Invalid arguments, or a partial file whose checkpoint does not match this call (the
        message lists the differing settings), or an unreadable partial file.
    OutOfTimeError
        This call used up ``max_wall_time``: the partial file keeps every finished segment and
        the run resumes from there (a budget per session, for batch queues).
    KeyboardInterrupt, Exception
        Whatever interrupts the run propagates; the partial file keeps every finished segment
        and the run resumes from there.
    """
    plan = _plan(structure, t_span, segment, simulate_options)
    design = tio.material_form_json(material_form)
    final = Path(path)
    partial = Path(str(final) + PARTIAL_SUFFIX)
    if not final.parent.is_dir():
        raise file_error(final, "its directory does not exist")
    if resume and final.exists() and not partial.exists():
        done = _finished_summary(final, plan.settings_hash, plan.K)
        if done is not None:
            return done
    if not resume and partial.exists():
        partial.unlink()
    resumed_from = None
    if partial.exists():
        checkpoint = _resumable_checkpoint(partial, plan.settings, plan.settings_hash)
        resumed_from = checkpoint.next_segment
    else:
        _create_partial(partial, structure, plan)
        with _open_h5(partial, "r") as f:
            checkpoint = _read_checkpoint_open(f, partial)
    report, close = _reporter(progress, plan.n_segments, checkpoint.next_segment)
    sink = FileSink(
        partial, checkpoint, samples_per_segment=plan.K, progress=report, observe=observe
    )
    try:
        if not checkpoint.ended:  # (ended: interrupted between the end and the rename)
            summary = run(
                structure,
                plan.t_span,
                initial=plan.initial,
                inputs=plan.inputs,
                options=plan.options,
                sink=sink,
                checkpoint=Checkpointing(every=plan.K, save=sink.save),
                resume=checkpoint.loop,
                stop=stop,
                controller=plan.controller,
            )
            if summary.stopped_for_time:
                raise OutOfTimeError(summary.message, partial)
            sink.finish(summary)
    finally:
        close()
    return _rename_finished(final, partial, sink.segments_run, resumed_from, design)


class _Plan(NamedTuple):
    """A streamed run's arguments, checked: the engine's options and inputs, the segment grid
    (``K`` samples per segment) and the settings a checkpoint must match."""

    t_span: tuple[float, float]
    initial: State | None
    options: Options
    inputs: Inputs
    K: int
    n_segments: int
    settings: dict[str, Any]
    settings_hash: str
    record: dict[str, Any]
    controller: Any  #: a Controller or a LinearFeedback, or None


def _plan(
    structure: Structure,
    t_span: tuple[float, float],
    segment: float | None,
    simulate_options: dict[str, Any],
) -> _Plan:
    t0, t1 = (float(x) for x in t_span)
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise ValueError(f"t_span: need finite t0 < t_end, got {t_span!r}")
    unknown = sorted(set(simulate_options) - set(_SIMULATE_PARAMETERS))
    if unknown:
        raise TypeError(f"simulate_to_file: unknown option {unknown[0]!r}")
    options = dict(simulate_options)
    sample_dt = options.pop("sample_dt", None)
    sample_dt = (t1 - t0) / 1000 if sample_dt is None else float(sample_dt)
    if not (math.isfinite(sample_dt) and sample_dt > 0):
        raise ValueError(f"sample_dt: must be > 0, got {sample_dt!r}")
    initial = options.pop("initial", None)
    controller = options.pop("controller", None)
    run_options, inputs = options_and_inputs(structure, sample_dt=sample_dt, **options)
    K = samples_per_segment(structure, segment, sample_dt, planes=len(inputs.ground))
    settings = _stream_settings(
        structure, t0, t1, sample_dt, K, {**options, "initial": initial, "controller": controller}
    )
    n_segments = len(segment_grid((t0, t1), sample_dt, K)) - 1
    law = controller if isinstance(controller, LinearFeedback) else None
    driven = controlled_actuators(
        structure, inputs.actuators, feedback=law, controlled=controller is not None
    )
    actuated = {} if driven is None else {"actuators": driven.settings(structure)}
    stream = dict(segment=K * sample_dt, samples_per_segment=K, n_segments=n_segments)
    return _Plan(
        (t0, t1),
        initial,
        run_options,
        inputs,
        K,
        n_segments,
        settings,
        _digest(_settings_json(settings).encode()),
        {**run_options.settings(t0, t1, **inputs.settings()), **actuated, "stream": stream},
        controller,
    )


def _reporter(
    progress: bool | Callable[[StreamProgress], None], n_segments: int, done: int
) -> tuple[Callable[[StreamProgress], None], Callable[[], None]]:
    """The sink's progress callback (a ``tqdm`` bar for ``progress=True``, the user's callable
    otherwise) and what closes it."""
    bar = None
    if progress is True:
        from tqdm import tqdm

        bar = tqdm(total=n_segments, initial=done, unit="segment", desc="simulating", leave=False)
    callback = progress if callable(progress) else None

    def report(info: StreamProgress) -> None:
        if bar is not None:
            bar.update(info.segment - bar.n)
        if callback is not None:
            callback(info)

    return report, (bar.close if bar is not None else lambda: None)


def _resumable_checkpoint(
    partial: Path, settings: dict[str, Any], settings_hash: str
) -> Checkpoint:
    """The checkpoint of ``partial`` if it was made with these settings (rows past it dropped);
    ``ValueError`` naming the differing settings, or what in the file is not the layout the run
    appends to, otherwise."""
    regular_file(partial)
    reserve_space(partial, METADATA_BYTES)
    with _open_h5(partial, "a") as f:
        if not _has_text(f, "format", PARTIAL_FORMAT):
            raise file_error(
                partial, f"not a partial streamed trajectory (format is not {PARTIAL_FORMAT!r})"
            )
        checkpoint = _read_checkpoint_open(f, partial)
        if checkpoint.settings_hash != settings_hash:
            try:
                stored = attribute_json(f, "stream_settings", partial)
            except (KeyError, ValueError):
                stored = {}
            diff = _differences(stored, settings) or ["settings hash"]
            raise file_error(
                partial,
                "cannot resume: the checkpoint was made with other settings ("
                + "; ".join(diff)
                + "); start again with resume=False (run without --resume)",
            )
        _check_partial_layout(f, partial, settings["structure"], checkpoint)
        _truncate(f, checkpoint.n_samples, partial)
    return checkpoint


def _check_partial_layout(f, path: Path, structure_digest: str, checkpoint: Checkpoint) -> None:
    """``ValueError`` unless the partial file holds the run's structure, datasets in the file
    that rows of that structure can be appended to, and a checkpoint state that fits it."""
    if "structure" not in f.attrs:
        raise file_error(path, "missing attribute 'structure'")
    data = attribute_json(f, "structure", path)
    if _structure_digest(data) != structure_digest:
        raise file_error(path, "attribute 'structure': not the structure of this run")
    try:
        structure = Structure.from_dict(data)
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        raise file_error(path, f"attribute 'structure': {exc}") from exc
    for name, row in tio.sample_rows(structure).items():
        dataset = hdf5_dataset(f, name, path)
        if dataset is None:
            raise file_error(path, f"missing dataset {name!r}")
        if (
            dataset.ndim != 1 + len(row)
            or dataset.shape[1:] != row
            or dataset.maxshape[0] is not None
        ):
            raise file_error(
                path,
                f"dataset {name!r}: expected a resizable dataset of rows {row}, got shape "
                f"{dataset.shape} (at most {dataset.maxshape})",
            )
    n = structure.n_coordinates
    if checkpoint.state.q.shape != (n,):
        raise file_error(
            path, f"checkpoint: expected q of shape ({n},), got {checkpoint.state.q.shape}"
        )


def _rename_finished(
    final: Path, partial: Path, segments_run: int, resumed_from: int | None, design: str | None
) -> StreamSummary:
    """Give the ended partial file the attributes of a complete trajectory (the members'
    ``design``, :func:`tensegrity.io.trajectory.material_form_json`, if any), then its final
    name (an atomic rename)."""
    reserve_space(partial, METADATA_BYTES + 4 * len(design or ""))
    with _open_h5(partial, "a") as f:
        checkpoint = _read_checkpoint_open(f, partial)
        f.attrs["status"] = int(checkpoint.status)
        f.attrs["message"] = checkpoint.message
        tio.write_material_form(f, design)
        f.attrs["complete"] = True
        f.attrs["format"] = tio.TRAJECTORY_FORMAT
        f.flush()
        K = json.loads(tio.required_text(f.attrs["stream_settings"]))["samples_per_segment"]
        summary = _summary(final, f, checkpoint, K, segments_run, resumed_from)
    _fsync(partial)
    os.chmod(partial, new_file_mode(final))
    os.replace(partial, final)
    fsync_directory(final.parent)
    return summary


__all__ = [
    "PARTIAL_FORMAT",
    "PARTIAL_SUFFIX",
    "Checkpoint",
    "FileSink",
    "OutOfTimeError",
    "StreamProgress",
    "StreamSummary",
    "read_checkpoint",
    "segment_grid",
    "segments_of",
    "simulate_to_file",
]
