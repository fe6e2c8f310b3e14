"""The trajectory file: a :class:`~tensegrity.engine.result.SimulationResult` as HDF5
(:func:`write_trajectory`, atomic) and back (:func:`read_trajectory`, the same type with the
same names, shapes and units).  The layout below is defined here once (:func:`sample_rows`,
:func:`sample_columns`, :data:`DERIVED`); the streamed writer (:mod:`tensegrity.io.stream`)
writes the same datasets.

Every reader raises ``ValueError`` with a one-line message that starts with the file name and
names the problem (missing file, not HDF5, not a trajectory, a missing dataset, a shape that
does not fit the structure, ...).

SI units throughout: m, kg, s, N, J.

The trajectory file (``format = "tensegrity-trajectory"``, ``version = 3``) holds, for ``T``
samples, ``n`` coordinates, ``S`` tendons and ``k`` switches, one dataset per sampled array of
:class:`SimulationResult`, under its name there:

=========================  ===========  ==============================================
dataset                    shape        content
=========================  ===========  ==============================================
``t``                      (T,)         sample times [s]
``q``, ``qdot``            (T, n)       coordinates [m], rates [m/s]
``tendon_tension``         (T, S)       tensions [N] (damping included; 0 when slack)
``energy``                 (T, 6)       energies and works [J]; its attribute
                                        ``columns`` names the columns (the keys of the
                                        result's ``energy`` dict)
``residual_acceleration``  (T,)         largest node acceleration [m/s^2]
``switch_times``           (k,)         times of the located events [s]
=========================  ===========  ==============================================

A run with planes (``settings["ground"]``; ``CP`` = (2 R + M) x planes contact pairs, M the
point masses) also stores ``contact_normal_force`` (T, CP) [N], ``contact_friction_force``
(T, CP, 3) [N], ``contact_mode`` (T, CP) (0 free, 1 slip, 2 stick, as float64) and
``contact_events`` (E, 4): each change of a pair's mode (time [s], pair, mode before, mode
after); files without them read as runs without contact.  A controlled run
(``settings["actuators"]``, A actuators) stores ``control_updates`` (U, 1 + 2 A): each update's
time [s], the commands held [m] and the controls applied then [m].

``node_position`` and ``node_velocity`` (T, N, dim) and ``tendon_length`` (T, S) are not
stored: they are ``P q``, ``P q'`` (:func:`tensegrity.physics.coordinates.nodes_from_coordinates`)
and the distances between a tendon's nodes (:func:`tensegrity.physics.dynamics.tendon_lengths`),
computed on read from ``q`` and ``qdot`` (:data:`DERIVED`), bit for bit the arrays the engine
records.  The file is then half the size it would be with them (a (10,10) shell: 3,388 of 6,768
numbers a sample).  The root
attributes are ``format``, ``version``, ``structure`` (JSON form of the structure), ``settings``
(JSON: the result's ``settings``), ``status``, ``message``, ``nfev``, ``nsteps``,
``nswitches``, ``nprojections``, ``max_rod_length_error``, ``max_constraint_error`` [m]
(joints and supports; 0 without them), ``wall_time`` [s] and ``tendon_name``.  A run whose
members have a design also stores ``structure_material`` (:data:`MATERIAL_FORM`): its structure
in the material form, as JSON (the document of
:func:`tensegrity.design.files.design_to_dict`: the members' materials and sections, the
factors of their utilisation, ``tendon_mass``; ``tensegrity simulate`` writes the same as
``structure-material.json``), which :func:`read_trajectory_structure` gives back and
:func:`tensegrity.design.files.trajectory_design` reads as the members' design; files without it
are runs without a design.  It is optional, as the contact datasets are: the version stays 3.

Files of earlier versions still read: version 2 stored ``tendon_length``; version 1 too, and
``time``, ``nodes`` and ``velocities`` for ``t``, ``node_position`` and ``node_velocity``
(:data:`VERSION1_NAMES`), and no switch times (read as none).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tensegrity.engine.result import (
    ENERGY_NAMES,
    SimulationResult,
    contact_event_arrays,
    control_arrays,
)
from tensegrity.io.checked import (
    attribute_json,
    attribute_number,
    attribute_text,
    attribute_text_list,
    hdf5_dataset,
    open_hdf5,
    read_datasets,
    selected_shape,
)
from tensegrity.io.files import PathLike, atomic_path, file_error
from tensegrity.model.structure import Structure
from tensegrity.physics.coordinates import nodes_from_coordinates
from tensegrity.physics.dynamics import tendon_lengths

#: ``format`` attribute of a trajectory file.
TRAJECTORY_FORMAT = "tensegrity-trajectory"
#: ``version`` attribute written; files of a higher version are refused.
TRAJECTORY_VERSION = 3
#: Energy columns in the order :func:`tensegrity.engine.simulate.simulate` produces them [J].
ENERGY_COLUMNS = ENERGY_NAMES

#: The sampled datasets a file stores, one row per sample, by their names in
#: :class:`SimulationResult` (and :class:`tensegrity.engine.result.Samples`).
SAMPLE_DATASETS = (
    "t",
    "q",
    "qdot",
    "tendon_tension",
    "energy",
    "residual_acceleration",
)
#: The sampled datasets of a run with planes, (T, CP, ...), CP its contact pairs.
CONTACT_DATASETS = ("contact_normal_force", "contact_friction_force", "contact_mode")
#: The sampled arrays of a result computed on read rather than stored: name -> (the stored
#: dataset it is computed from, the first file version that does not store it).
DERIVED = {"node_position": ("q", 2), "node_velocity": ("qdot", 2), "tendon_length": ("q", 3)}
#: Every sampled array a file gives (:func:`read_dataset`; the contact ones: a run with planes).
SAMPLE_NAMES = (*SAMPLE_DATASETS, *DERIVED, *CONTACT_DATASETS)
#: The result's names stored under other names in files of version 1, read only.
VERSION1_NAMES = {"t": "time", "node_position": "nodes", "node_velocity": "velocities"}
#: The run's counts, as root attributes: evaluations, steps, switches, projections.
COUNT_ATTRIBUTES = ("nfev", "nsteps", "nswitches", "nprojections")
#: The root attribute of a run whose members have a design: its structure in the material form
#: (JSON text), absent otherwise.
MATERIAL_FORM = "structure_material"


# --------------------------------------------------------------------------- the layout
def sample_rows(structure: Structure, pairs: int = 0) -> dict[str, tuple[int, ...]]:
    """The shape of one row (one sample) of each of :data:`SAMPLE_DATASETS` for ``structure``,
    and of :data:`CONTACT_DATASETS` for ``pairs`` > 0 contact pairs."""
    n, S = structure.n_coordinates, structure.n_tendons
    rows: dict[str, tuple[int, ...]] = {
        "t": (),
        "q": (n,),
        "qdot": (n,),
        "tendon_tension": (S,),
        "energy": (len(ENERGY_COLUMNS),),
        "residual_acceleration": (),
    }
    if pairs:
        rows |= {
            "contact_normal_force": (pairs,),
            "contact_friction_force": (pairs, 3),
            "contact_mode": (pairs,),
        }
    return rows


def contact_pairs(structure: Structure, planes: int) -> int:
    """The contact pairs of a run of ``structure`` with ``planes`` planes (``len`` of its
    settings' ``"ground"``): the rods' ends and the point masses, against each plane."""
    return (2 * structure.n_rods + structure.point_mass_nodes.size) * planes


def event_rows(pairs: int, actuated: int = 0) -> dict[str, tuple[int, ...]]:
    """The shape of one row of the datasets of events a run appends as it goes:
    ``switch_times``, ``contact_events`` with ``pairs`` > 0, ``control_updates`` with
    ``actuated`` > 0 actuators."""
    rows: dict[str, tuple[int, ...]] = {"switch_times": ()}
    if pairs:
        rows["contact_events"] = (4,)
    if actuated:
        rows["control_updates"] = (1 + 2 * actuated,)
    return rows


def event_columns(run: Any) -> dict[str, np.ndarray]:
    """The events of ``run`` (a :class:`SimulationResult` or a ``RunSummary``) as the datasets
    of :func:`event_rows`."""
    columns = {"switch_times": np.asarray(run.switch_times, dtype=float)}
    if isinstance(run, SimulationResult):
        if run.contact_mode.shape[1]:
            columns["contact_events"] = np.column_stack(
                [run.contact_event_time, run.contact_event_pair, run.contact_event_mode]
            ).reshape(-1, 4)
    elif len(run.settings.get("ground", ())):
        columns["contact_events"] = np.asarray(run.contact_events, dtype=float).reshape(-1, 4)
    actuated = len(run.settings.get("actuators", {}).get("tendons", ()))
    if actuated:
        updates = (
            np.column_stack([run.control_time, run.control_command, run.control_applied])
            if isinstance(run, SimulationResult)
            else run.control_updates
        )
        columns["control_updates"] = np.asarray(updates, dtype=float).reshape(-1, 1 + 2 * actuated)
    return columns


def derived_rows(structure: Structure) -> dict[str, tuple[int, ...]]:
    """The shape of one row of each of :data:`DERIVED` for ``structure``."""
    nodes = (structure.n_nodes, structure.dim)
    return {"node_position": nodes, "node_velocity": nodes, "tendon_length": (structure.n_tendons,)}


def derived_in(version: int) -> tuple[str, ...]:
    """The arrays of :data:`DERIVED` a file of ``version`` does not store."""
    return tuple(name for name, (_, since) in DERIVED.items() if version >= since)


def sample_columns(samples: Any) -> dict[str, np.ndarray]:
    """The rows of :data:`SAMPLE_DATASETS` that ``samples`` hold: a :class:`SimulationResult`
    or a block of :class:`tensegrity.engine.result.Samples`, which have these names.  Energy is
    the (T, 6) array of the block, or the result's ``energy`` dict as columns in its order."""
    energy = samples.energy
    if isinstance(energy, Mapping):
        energy = (
            np.column_stack([energy[name] for name in energy])
            if energy
            else np.zeros((len(samples.t), 0))
        )
    names = SAMPLE_DATASETS + (CONTACT_DATASETS if samples.contact_mode.shape[1] else ())
    return {name: energy if name == "energy" else getattr(samples, name) for name in names}


def derived(structure: Structure, name: str, source: np.ndarray) -> np.ndarray:
    """The derived array ``name`` of :data:`DERIVED` from its stored ``source`` (T, n)."""
    nodes = nodes_from_coordinates(structure, source, rates=name == "node_velocity")
    return tendon_lengths(structure, nodes) if name == "tendon_length" else nodes


def _derived_bytes(
    structure: Structure, names: Iterable[str], n_samples: int, every: int
) -> dict[str, int]:
    """The bytes of the derived arrays ``names`` of ``n_samples`` samples read one in
    ``every`` (:func:`tensegrity.io.checked.read_datasets`' ``computed``)."""
    rows = derived_rows(structure)
    return {
        f"array {name!r} (computed from {DERIVED[name][0]!r})": 8
        * math.prod(selected_shape((n_samples, *rows[name]), every))
        for name in names
    }


def json_default(value: Any) -> Any:
    """JSON for NumPy scalars and arrays in ``settings``; ``str`` for anything else."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    return str(value)


def settings_json(settings: Mapping[str, Any]) -> str:
    """The ``settings`` attribute of a file: a run's settings record as JSON, whatever writes
    it."""
    return json.dumps(settings, default=json_default)


def material_form_json(material_form: Mapping[str, Any] | None) -> str | None:
    """The :data:`MATERIAL_FORM` attribute of a file for ``material_form`` (a structure in the
    material form, :func:`tensegrity.design.files.design_to_dict`), as JSON text; None for
    None (the attribute is not written).

    Raises
    ------
    TypeError
        ``material_form`` is not a mapping, or holds what JSON cannot (naming the argument).
    ValueError
        It holds a NaN or an infinity.
    """
    if material_form is None:
        return None
    if not isinstance(material_form, Mapping):
        raise TypeError(
            "material_form: expected a mapping (the structure in the material form, "
            f"tensegrity.design.files.design_to_dict), got {type(material_form).__name__}"
        )
    try:
        return json.dumps(dict(material_form), allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"material_form: {exc}") from None


def write_material_form(f: Any, text: str | None) -> None:
    """Store ``text`` (:func:`material_form_json`) as the attribute :data:`MATERIAL_FORM` of
    the open file ``f``; for None, no such attribute."""
    if text is not None:
        f.attrs[MATERIAL_FORM] = text
    elif MATERIAL_FORM in f.attrs:
        del f.attrs[MATERIAL_FORM]


def write_layout_attributes(f: Any, structure: Structure, structure_json: str) -> None:
    """The attributes every trajectory file has from its start: ``version``, ``structure``
    (``structure_json``, the JSON text of ``structure``) and ``tendon_name``."""
    import h5py

    f.attrs["version"] = TRAJECTORY_VERSION
    f.attrs["structure"] = structure_json
    f.attrs["tendon_name"] = np.array(structure.tendon_name, dtype=h5py.string_dtype())


# --------------------------------------------------------------------------- trajectories
def write_trajectory(
    path: PathLike, result: SimulationResult, *, material_form: Mapping[str, Any] | None = None
) -> Path:
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
    material_form : mapping, optional
        The members' design: ``result.structure`` in the material form,
        ``tensegrity.design.files.design_to_dict(result.structure, design, keep_joints=True)``
        (its nodes the structure's own); stored as the attribute :data:`MATERIAL_FORM`, so that
        :func:`tensegrity.design.files.trajectory_design` and ``tensegrity view`` find the
        design in the file.  Default: none.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    TypeError
        ``result`` is not a :class:`SimulationResult`, or ``material_form`` not a mapping.
    """
    import h5py

    if not isinstance(result, SimulationResult):
        raise TypeError(
            f"result: expected a SimulationResult (what simulate returns), got "
            f"{type(result).__name__}"
        )
    design = material_form_json(material_form)
    arrays = sample_columns(result) | event_columns(result)
    with atomic_path(path) as tmp, h5py.File(tmp, "w", libver=("v108", "v108")) as f:
        f.attrs["format"] = TRAJECTORY_FORMAT
        structure = result.structure
        write_layout_attributes(f, structure, json.dumps(structure.to_dict(), allow_nan=False))
        f.attrs["settings"] = settings_json(result.settings)
        write_material_form(f, design)
        write_run_attributes(
            f,
            status=result.status,
            message=result.message,
            counts={name: getattr(result, name) for name in COUNT_ATTRIBUTES},
            max_rod_length_error=result.max_rod_length_error,
            max_constraint_error=result.max_constraint_error,
            wall_time=result.wall_time,
        )
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
        f["energy"].attrs["columns"] = np.array(list(result.energy), dtype=h5py.string_dtype())
    return Path(path)


def write_run_attributes(
    f: Any,
    *,
    status: int,
    message: str,
    counts: Mapping[str, int],
    max_rod_length_error: float,
    max_constraint_error: float,
    wall_time: float,
) -> None:
    """The attributes of how the run ended (so far): ``status``, ``message``, the counts of
    :data:`COUNT_ATTRIBUTES` (``counts``), the largest relative rod-length error, the largest
    constraint violation [m] and the wall time [s]."""
    f.attrs["status"] = int(status)
    f.attrs["message"] = str(message)
    for name in COUNT_ATTRIBUTES:
        f.attrs[name] = int(counts[name])
    f.attrs["max_rod_length_error"] = float(max_rod_length_error)
    f.attrs["max_constraint_error"] = float(max_constraint_error)
    f.attrs["wall_time"] = float(wall_time)


def read_trajectory(path: PathLike, *, every: int = 1) -> SimulationResult:
    """Read a trajectory file written by :func:`write_trajectory` or the streamed writer.

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
        (``switch_times`` empty for a file of version 1, which did not store them).

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


def read_trajectory_structure(path: PathLike) -> tuple[Structure, dict[str, Any] | None]:
    """The structure of a trajectory file and, if the file stores one (a run whose members have
    a design), that structure in the material form (the document of the attribute
    :data:`MATERIAL_FORM`; :func:`tensegrity.design.files.trajectory_design` reads it), else
    None; no sample is read.  ``ValueError`` names the file and the problem, as
    :func:`read_trajectory`'s."""
    with _open(path) as f:
        _check_format(f, path)
        structure = _structure(f, path)
        form = _Attributes(f, path).json(MATERIAL_FORM) if MATERIAL_FORM in f.attrs else None
    return structure, form


def read_dataset(path: PathLike, name: str, *, every: int = 1) -> np.ndarray:
    """One sampled array of a trajectory file by its name in :class:`SimulationResult` (one of
    :data:`SAMPLE_NAMES`, e.g. ``"tendon_length"``; ``energy`` as its (T, 6) dataset), one
    sample in ``every`` and the last as in :func:`read_trajectory`: a long run's series without
    the rest of the file in memory.  ``ValueError`` names the file and the problem."""
    _check_every(every)
    if name not in SAMPLE_NAMES:
        raise ValueError(f"name: expected one of {', '.join(SAMPLE_NAMES)}, got {name!r}")
    with _open(path) as f:
        version = _check_format(f, path)
        if name in derived_in(version):
            source = DERIVED[name][0]
            structure = _structure(f, path)
            dataset = _dataset(f, source, path)
            _check_shapes({source: dataset.shape}, structure, len(ENERGY_COLUMNS), path)
            computed = _derived_bytes(structure, [name], dataset.shape[0], every)
            rows = read_datasets({source: dataset}, path, every=every, computed=computed)
            return derived(structure, name, rows[source])
        stored = _stored_name(name, version)
        return read_datasets({stored: _dataset(f, stored, path)}, path, every=every)[stored]


def _stored_name(name: str, version: int) -> str:
    """The dataset that holds the result's array ``name`` in a file of ``version``."""
    return VERSION1_NAMES.get(name, name) if version < 2 else name


def _check_every(every: int) -> None:
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ValueError(f"every: must be an integer >= 1, got {every!r}")


def _open(path: PathLike) -> Any:
    """The HDF5 file at ``path``, open for reading (one-line errors naming the file); a regular
    file only."""
    return open_hdf5(path, "a tensegrity trajectory is HDF5")


def _check_format(f: Any, path: PathLike) -> int:
    """The version of ``f``; ``ValueError`` unless it is a tensegrity trajectory this library
    reads."""
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
    return version


def _dataset(f: Any, name: str, path: PathLike) -> Any:
    """The dataset ``name`` of the trajectory, checked to be stored in the file as floats."""
    dataset = hdf5_dataset(f, name, path)
    if dataset is None:
        raise file_error(path, f"missing dataset {name!r} (not a complete tensegrity trajectory)")
    return dataset


def _structure(f: Any, path: PathLike) -> Structure:
    """The structure of the trajectory in ``f``."""
    data = _Attributes(f, path).json("structure")
    try:
        return Structure.from_dict(data)
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        raise file_error(path, f"attribute 'structure': {exc}") from exc


def _read_open_trajectory(f: Any, path: PathLike, every: int = 1) -> SimulationResult:
    """The trajectory in the open file ``f``: its layout, attributes and shapes are checked
    before any array is read."""
    version = _check_format(f, path)
    computing = derived_in(version)
    names = (*SAMPLE_DATASETS, *(name for name in DERIVED if name not in computing))
    datasets = {name: _dataset(f, _stored_name(name, version), path) for name in names}
    attrs = _Attributes(f, path)
    structure = _structure(f, path)
    settings = attrs.json("settings")
    figures, message = attrs.run_figures(structure), attrs.text("message")
    energy = datasets["energy"]
    columns = (
        attribute_text_list(energy, "columns", path)
        if "columns" in energy.attrs
        else list(ENERGY_COLUMNS)
    )
    shapes = {name: d.shape for name, d in datasets.items()}
    _check_shapes(shapes, structure, len(columns), path, version)
    switch_times = _switch_times(f, path, version)
    contact = _contact_datasets(f, path, structure, settings, shapes["t"][0])
    computed = _derived_bytes(structure, computing, shapes["t"][0], every)
    arrays = read_datasets(datasets | contact, path, every=every, computed=computed)
    for name in computing:
        arrays[name] = derived(structure, name, arrays[DERIVED[name][0]])
    if contact:
        arrays["contact_mode"] = arrays["contact_mode"].astype(np.int8)
        arrays |= contact_event_arrays(
            read_datasets({"e": _dataset(f, "contact_events", path)}, path)["e"]
        )
    controls = _control_updates(f, path, settings)
    result = SimulationResult(
        t=arrays["t"],
        q=arrays["q"],
        qdot=arrays["qdot"],
        node_position=arrays["node_position"],
        node_velocity=arrays["node_velocity"],
        tendon_length=arrays["tendon_length"],
        tendon_tension=arrays["tendon_tension"],
        residual_acceleration=arrays["residual_acceleration"],
        energy={name: arrays["energy"][:, k] for k, name in enumerate(columns)},
        switch_times=switch_times,
        structure=structure,
        settings=settings,
        **figures,
        message=message,
    )
    contact = {name: arrays[name] for name in arrays if name.startswith("contact_")}
    return dataclasses.replace(result, **contact, **controls) if contact or controls else result


def _control_updates(f: Any, path: PathLike, settings: Mapping[str, Any]) -> dict[str, Any]:
    """The result's ``control_time``, ``control_command`` and ``control_applied`` from the
    dataset ``control_updates`` of a run with actuators (none in a file without)."""
    actuated = len(settings.get("actuators", {}).get("tendons", ()))
    if not actuated or "control_updates" not in f:
        return {}
    updates = _dataset(f, "control_updates", path)
    if updates.ndim != 2 or updates.shape[1] != 1 + 2 * actuated:
        raise file_error(
            path,
            f"dataset 'control_updates': expected shape (U, {1 + 2 * actuated}), got "
            f"{updates.shape}",
        )
    return control_arrays(read_datasets({"u": updates}, path)["u"])


def _contact_datasets(
    f: Any, path: PathLike, structure: Structure, settings: Mapping[str, Any], T: int
) -> dict[str, Any]:
    """The contact datasets of a run with planes (checked shapes), or none."""
    pairs = contact_pairs(structure, len(settings.get("ground", ())))
    if not pairs:
        return {}
    rows = sample_rows(structure, pairs)
    datasets = {name: _dataset(f, name, path) for name in CONTACT_DATASETS}
    for name, dataset in datasets.items():
        if dataset.shape != (T, *rows[name]):
            raise file_error(
                path,
                f"dataset {name!r}: expected shape {(T, *rows[name])} for this structure and "
                f"its {pairs} contact pairs, got {dataset.shape}",
            )
    events = _dataset(f, "contact_events", path)
    if events.ndim != 2 or events.shape[1] != 4:
        raise file_error(
            path, f"dataset 'contact_events': expected shape (E, 4), got {events.shape}"
        )
    return datasets


def _switch_times(f: Any, path: PathLike, version: int) -> np.ndarray:
    """The times of the run's located switches [s] (k,): none in a file of version 1, which did
    not store them."""
    if version < 2:
        return np.zeros(0)
    dataset = _dataset(f, "switch_times", path)
    if dataset.ndim != 1:
        raise file_error(path, f"dataset 'switch_times': expected shape (k,), got {dataset.shape}")
    return read_datasets({"switch_times": dataset}, path)["switch_times"]


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
        figures: dict[str, Any] = {name: self.integer(name) for name in COUNT_ATTRIBUTES}
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
    shapes: dict[str, tuple[int, ...]],
    structure: Structure,
    n_energy: int,
    path: PathLike,
    version: int = TRAJECTORY_VERSION,
) -> None:
    """``ValueError`` naming the first dataset of ``shapes`` (by the result's names, of a file
    of ``version``) whose shape does not fit ``structure``, or if the file holds no sample (a
    run has at least its initial one)."""
    rows = sample_rows(structure) | derived_rows(structure)
    rows["energy"] = (n_energy,)
    lead = "t" if "t" in shapes else next(iter(shapes))  # (the samples' count)
    T = shapes[lead][0] if len(shapes[lead]) == 1 + len(rows[lead]) else -1
    if T == 0:
        raise file_error(path, "holds no samples (a trajectory has at least its first state)")
    for name, shape in shapes.items():
        expected = (T, *rows[name])
        if shape != expected:
            raise file_error(
                path,
                f"dataset {_stored_name(name, version)!r}: expected shape {expected} for this "
                f"structure, got {shape}",
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
