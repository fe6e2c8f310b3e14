"""The trajectory file: a :class:`~tensegrity.engine.result.SimulationResult` as HDF5
(:func:`write_trajectory`, atomic) and back (:func:`read_trajectory`, the same type with the
same names, shapes and units).  The layout below is defined here once; the streamed writer
(:mod:`tensegrity.io.stream`) writes the same datasets.

Every reader raises ``ValueError`` with a one-line message that starts with the file name and
names the problem (missing file, not HDF5, not a trajectory, a missing dataset, a shape that
does not fit the structure, ...).

SI units throughout: m, kg, s, N, J.

The trajectory file (``format = "tensegrity-trajectory"``, ``version = 1``) holds, for ``T``
samples, ``N`` nodes, ``R`` rods and ``S`` tendons:

=========================  ===========  ============================  ========================
dataset                    shape        content                       ``SimulationResult``
=========================  ===========  ============================  ========================
``time``                   (T,)         sample times [s]              ``t``
``nodes``                  (T, N, 3)    node positions [m]            ``node_position``
``velocities``             (T, N, 3)    node velocities [m/s]         ``node_velocity``
``tendon_length``          (T, S)       tendon lengths [m]            ``tendon_length``
``tendon_tension``         (T, S)       tensions [N] (damping         ``tendon_tension``
                                        included; 0 when slack)
``energy``                 (T, 6)       energies and works [J];       ``energy`` (a dict by
                                        attribute ``columns`` names   column name)
                                        the columns
``q``, ``qdot``            (T, 6R)      coordinates [m], rates [m/s]  ``q``, ``qdot``
``residual_acceleration``  (T,)         largest node acceleration     ``residual_acceleration``
                                        [m/s^2]
=========================  ===========  ============================  ========================

(``(T, N, 2)`` node arrays for a planar structure; point masses add 3 coordinates each to
``q``.) and the root attributes ``format``, ``version``, ``structure`` (JSON form of the structure),
``settings`` (JSON), ``status``, ``message``, ``nfev``, ``nsteps``, ``nswitches``,
``nprojections``, ``max_rod_length_error``, ``max_constraint_error`` [m] (joints and supports;
0 without them), ``wall_time`` [s] and ``tendon_names``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from tensegrity.engine.result import ENERGY_NAMES, SimulationResult
from tensegrity.io.checked import (
    attribute_json,
    attribute_number,
    attribute_text,
    attribute_text_list,
    hdf5_dataset,
    open_hdf5,
    read_datasets,
)
from tensegrity.io.files import PathLike, atomic_path, file_error
from tensegrity.model.structure import Structure

#: ``format`` attribute of a trajectory file.
TRAJECTORY_FORMAT = "tensegrity-trajectory"
#: ``version`` attribute written; files of a higher version are refused.
TRAJECTORY_VERSION = 1
#: Energy columns in the order :func:`tensegrity.engine.simulate.simulate` produces them [J].
ENERGY_COLUMNS = ENERGY_NAMES

ARRAY_DATASETS = (
    "time",
    "nodes",
    "velocities",
    "tendon_length",
    "tendon_tension",
    "energy",
    "q",
    "qdot",
    "residual_acceleration",
)
_COUNT_ATTRIBUTES = ("nfev", "nsteps", "nswitches", "nprojections")


# --------------------------------------------------------------------------- trajectories
def json_default(value: Any) -> Any:
    """JSON for NumPy scalars and arrays in ``settings``; ``str`` for anything else."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    return str(value)


def write_trajectory(path: PathLike, result: SimulationResult) -> Path:
    """Write a simulation result to an HDF5 trajectory file, atomically.

    Arrays are stored exactly (float64, gzip level 4 with byte shuffle, ``h5py``'s automatic
    chunking) with a Fletcher-32 checksum per chunk, so that a damaged file is an error when
    read rather than wrong numbers; see the module docstring for the layout.  The file uses
    the HDF5 1.8 format, which allows attributes larger than 64 KiB (the structure of a large
    shell).

    Parameters
    ----------
    path : str or os.PathLike
        Output file, conventionally ``*.h5``; its directory must exist.  An existing file is
        replaced only once the new one is complete; on any error nothing is left at ``path``
        (or the older file stays).
    result : SimulationResult
        ``T`` samples of a structure with ``N`` nodes, ``R`` rods and ``S`` tendons.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    TypeError
        ``result`` is not a :class:`SimulationResult`.
    """
    import h5py

    if not isinstance(result, SimulationResult):
        raise TypeError(
            f"result: expected a SimulationResult (what simulate returns), got "
            f"{type(result).__name__}"
        )
    structure = result.structure
    energy_names = list(result.energy)
    arrays = {
        "time": result.t,
        "nodes": result.node_position,
        "velocities": result.node_velocity,
        "tendon_length": result.tendon_length,
        "tendon_tension": result.tendon_tension,
        "energy": np.column_stack([result.energy[name] for name in energy_names])
        if energy_names
        else np.zeros((len(result.t), 0)),
        "q": result.q,
        "qdot": result.qdot,
        "residual_acceleration": result.residual_acceleration,
    }
    attributes = {
        "format": TRAJECTORY_FORMAT,
        "version": TRAJECTORY_VERSION,
        "structure": json.dumps(structure.to_dict(), allow_nan=False),
        "settings": json.dumps(result.settings, default=json_default),
        "status": int(result.status),
        "message": str(result.message),
        **{name: int(getattr(result, name)) for name in _COUNT_ATTRIBUTES},
        "max_rod_length_error": float(result.max_rod_length_error),
        "max_constraint_error": float(result.max_constraint_error),
        "wall_time": float(result.wall_time),
        "tendon_names": np.array(structure.tendon_name, dtype=h5py.string_dtype()),
    }
    with atomic_path(path) as tmp, h5py.File(tmp, "w", libver=("v108", "v108")) as f:
        for name, value in attributes.items():
            f.attrs[name] = value
        for name, value in arrays.items():
            value = np.asarray(value, dtype=float)
            compress = (
                {}
                if value.size == 0
                else dict(
                    compression="gzip",
                    compression_opts=4,
                    shuffle=True,
                    chunks=True,
                    fletcher32=True,
                )
            )
            f.create_dataset(name, data=value, **compress)
        f["energy"].attrs["columns"] = np.array(energy_names, dtype=h5py.string_dtype())
    return Path(path)


def read_trajectory(path: PathLike, *, every: int = 1) -> SimulationResult:
    """Read a trajectory file written by :func:`write_trajectory`.

    Parameters
    ----------
    path : str or os.PathLike
    every : int
        Read one sample in ``every`` (the first, every ``every``-th, and always the last): a
        long run's overview without its whole size in memory.

    Returns
    -------
    SimulationResult
        The same type, names, shapes and units as the result in memory that was written
        (``switch_times``, not stored, is empty).

    Raises
    ------
    ValueError
        One line starting with the file name, if the file is missing, is not HDF5, is not a
        tensegrity trajectory (``format`` attribute), is of a newer version, misses a dataset or
        an attribute, holds no samples, or holds arrays whose shapes do not fit its structure.
    """
    _check_every(every)
    with _open(path) as f:
        return _read_open_trajectory(f, path, every)


def read_dataset(path: PathLike, name: str, *, every: int = 1) -> np.ndarray:
    """One dataset of a trajectory file (a name of the layout above, e.g. ``"tendon_length"``),
    one sample in ``every`` and the last as in :func:`read_trajectory`: a long run's series
    without the rest of the file in memory.  ``ValueError`` names the file and the problem."""
    _check_every(every)
    if name not in ARRAY_DATASETS:
        raise ValueError(f"name: expected one of {', '.join(ARRAY_DATASETS)}, got {name!r}")
    with _open(path) as f:
        _check_format(f, path)
        return read_datasets({name: _dataset(f, name, path)}, path, every=every)[name]


def _check_every(every: int) -> None:
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ValueError(f"every: must be an integer >= 1, got {every!r}")


def _open(path: PathLike) -> Any:
    """The HDF5 file at ``path``, open for reading (one-line errors naming the file); a regular
    file only."""
    return open_hdf5(path, "a tensegrity trajectory is HDF5")


def _check_format(f: Any, path: PathLike) -> None:
    """``ValueError`` unless ``f`` is a tensegrity trajectory this library reads."""
    fmt = attribute_text(f, "format", path) if "format" in f.attrs else None
    if fmt != TRAJECTORY_FORMAT:
        found = "no 'format' attribute" if fmt is None else f"format {fmt!r}"
        raise file_error(
            path, f"not a tensegrity trajectory file ({found}, expected {TRAJECTORY_FORMAT!r})"
        )
    version = _Attributes(f, path).integer("version")
    if version > TRAJECTORY_VERSION:
        raise file_error(
            path,
            f"trajectory format version {version} is newer than this "
            f"library reads ({TRAJECTORY_VERSION}); upgrade tensegrity",
        )


def _dataset(f: Any, name: str, path: PathLike) -> Any:
    """The dataset ``name`` of the trajectory, checked to be stored in the file as floats."""
    dataset = hdf5_dataset(f, name, path)
    if dataset is None:
        raise file_error(path, f"missing dataset {name!r} (not a complete tensegrity trajectory)")
    return dataset


def _read_open_trajectory(f: Any, path: PathLike, every: int = 1) -> SimulationResult:
    """The trajectory in the open file ``f``: its layout, attributes and shapes are checked
    before any array is read."""
    _check_format(f, path)
    datasets = {name: _dataset(f, name, path) for name in ARRAY_DATASETS}
    attrs = _Attributes(f, path)
    structure_data = attrs.json("structure")
    try:
        structure = Structure.from_dict(structure_data)
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        raise file_error(path, f"attribute 'structure': {exc}") from exc
    settings = attrs.json("settings")
    figures, message = attrs.run_figures(structure), attrs.text("message")
    energy = datasets["energy"]
    columns = (
        attribute_text_list(energy, "columns", path)
        if "columns" in energy.attrs
        else list(ENERGY_COLUMNS)
    )
    _check_shapes({name: d.shape for name, d in datasets.items()}, structure, len(columns), path)
    arrays = read_datasets(datasets, path, every=every)
    return SimulationResult(
        t=arrays["time"],
        node_position=arrays["nodes"],
        node_velocity=arrays["velocities"],
        tendon_length=arrays["tendon_length"],
        tendon_tension=arrays["tendon_tension"],
        energy={name: arrays["energy"][:, k] for k, name in enumerate(columns)},
        q=arrays["q"],
        qdot=arrays["qdot"],
        residual_acceleration=arrays["residual_acceleration"],
        structure=structure,
        settings=settings,
        **figures,
        message=message,
    )


class _Attributes:
    """A trajectory file's root attributes, each checked for its type and shape before it is
    read, with one-line errors naming the file and the attribute."""

    def __init__(self, f: Any, path: PathLike) -> None:
        self.f, self.path = f, path

    def _present(self, name: str) -> str:
        if name not in self.f.attrs:
            raise file_error(self.path, f"missing attribute {name!r}")
        return name

    def json(self, name: str) -> dict[str, Any]:
        return attribute_json(self.f, self._present(name), self.path)

    def text(self, name: str) -> str:
        return attribute_text(self.f, self._present(name), self.path)

    def integer(self, name: str) -> int:
        return int(attribute_number(self.f, self._present(name), self.path, integer=True))

    def number(self, name: str) -> float:
        return float(attribute_number(self.f, self._present(name), self.path))

    def run_figures(self, structure: Structure) -> dict[str, Any]:
        """``status``, the counts and the errors of the run, as :class:`SimulationResult`
        takes them."""
        figures: dict[str, Any] = {name: self.integer(name) for name in _COUNT_ATTRIBUTES}
        figures["status"] = self.integer("status")
        figures["max_rod_length_error"] = self.number("max_rod_length_error")
        figures["wall_time"] = self.number("wall_time")
        # Absent from files written before it was stored: unknown there, unless nothing can err.
        figures["max_constraint_error"] = (
            self.number("max_constraint_error")
            if "max_constraint_error" in self.f.attrs
            else (np.nan if structure.has_constraints else 0.0)
        )
        return figures


def _check_shapes(
    shapes: dict[str, tuple[int, ...]], structure: Structure, n_energy: int, path: PathLike
) -> None:
    """``ValueError`` naming the first dataset whose shape does not fit ``structure``, or if
    the file holds no sample (a run has at least its initial one)."""
    T = shapes["time"][0] if len(shapes["time"]) == 1 else -1
    if T == 0:
        raise file_error(path, "holds no samples (a trajectory has at least its first state)")
    N, S, n, d = structure.n_nodes, structure.n_tendons, structure.n_coordinates, structure.dim
    expected = {
        "time": (T,),
        "nodes": (T, N, d),
        "velocities": (T, N, d),
        "tendon_length": (T, S),
        "tendon_tension": (T, S),
        "energy": (T, n_energy),
        "q": (T, n),
        "qdot": (T, n),
        "residual_acceleration": (T,),
    }
    for name, shape in expected.items():
        if shapes[name] != shape:
            raise file_error(
                path,
                f"dataset {name!r}: expected shape {shape} for this structure, got {shapes[name]}",
            )


def text_attribute(value: Any) -> str | None:
    """An HDF5 string attribute as ``str`` (h5py may return ``bytes`` or a NumPy string)."""
    if value is None:
        return None
    if isinstance(value, bytes):
        return value.decode("utf-8")
    if isinstance(value, np.ndarray) and value.shape == ():
        return text_attribute(value[()])
    return str(value)


def required_text(value: Any) -> str:
    """:func:`text_attribute` of an attribute that is present: a ``str``, never ``None`` (h5py
    reads no attribute as ``None``; ``TypeError`` if given one, as ``json.loads(None)`` raises)."""
    text = text_attribute(value)
    if text is None:
        raise TypeError("expected a text attribute, got None")
    return text
