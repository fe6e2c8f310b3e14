"""Files: structures as JSON, simulation results as HDF5, and atomic writes.

A thin layer over :meth:`Structure.to_dict` / :meth:`Structure.from_dict` and ``h5py``.

- Every writer is atomic (:func:`atomic_path`): the data go to a temporary file in the target's
  directory that replaces the target only once it is complete, so a crash or an error never
  leaves a partial file under the final name, and an older file there stays intact.
- Every reader raises ``ValueError`` with a one-line message that starts with the file name and
  names the problem (missing file, invalid JSON with its line and column, the invalid element of
  the structure, a missing dataset, ...).

SI units throughout: m, kg, s, N, J.

The trajectory file (``format = "tensegrity-trajectory"``, ``version = 1``) holds, for ``T``
samples, ``N`` nodes, ``R`` rods and ``S`` tendons:

=========================  ===========  ===================================================
dataset                    shape        content
=========================  ===========  ===================================================
``time``                   (T,)         sample times [s]
``nodes``                  (T, N, 3)    node positions [m]
``velocities``             (T, N, 3)    node velocities [m/s]
``tendon_length``          (T, S)       tendon lengths [m]
``tendon_tension``         (T, S)       tendon tensions [N] (damping included; 0 when slack)
``energy``                 (T, 6)       energies and works [J]; attribute ``columns`` names them
``q``, ``qdot``            (T, 6R)      generalized coordinates [m] and rates [m/s]
``residual_acceleration``  (T,)         largest node acceleration [m/s^2]
=========================  ===========  ===================================================

and the root attributes ``format``, ``version``, ``structure`` (JSON form of the structure),
``settings`` (JSON), ``status``, ``message``, ``nfev``, ``nsteps``, ``nswitches``,
``nprojections``, ``max_rod_length_error``, ``max_constraint_error`` [m] (joints and supports;
0 without them), ``wall_time`` [s] and ``tendon_names``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.io.files import PathLike, atomic_path, file_error
from tensegrity.model.structure import Structure

if TYPE_CHECKING:
    from tensegrity.engine.simulate import SimulationResult


#: ``format`` attribute of a trajectory file.
TRAJECTORY_FORMAT = "tensegrity-trajectory"
#: ``version`` attribute written; files of a higher version are refused.
TRAJECTORY_VERSION = 1
#: Energy columns in the order :func:`tensegrity.engine.simulate.simulate` produces them [J].
ENERGY_COLUMNS = ("kinetic", "elastic", "gravity", "dissipated", "external_work", "control_work")

ARRAY_DATASETS = (
    "time", "nodes", "velocities", "tendon_length", "tendon_tension", "energy", "q", "qdot",
    "residual_acceleration",
)
_COUNT_ATTRIBUTES = ("nfev", "nsteps", "nswitches", "nprojections")






















# --------------------------------------------------------------------------- trajectories
@dataclasses.dataclass(frozen=True, eq=False)
class Trajectory:
    """A simulation read back from a trajectory file (:func:`read_trajectory`).

    ``T`` samples, ``N`` nodes, ``R`` rods, ``S`` tendons.

    Attributes
    ----------
    time : ndarray, shape (T,)
        Sample times [s].
    nodes, velocities : ndarray, shape (T, N, 3)
        Node positions [m] and velocities [m/s].
    tendon_length : ndarray, shape (T, S)
        Tendon lengths [m].
    tendon_tension : ndarray, shape (T, S)
        Tendon tensions [N]; ``<= 0`` means slack.
    energy : dict of str to ndarray, shape (T,)
        ``kinetic``, ``elastic``, ``gravity``, ``dissipated``, ``external_work``,
        ``control_work`` [J], in the file's column order.
    q, qdot : ndarray, shape (T, 6R)
        Generalized coordinates [m] and rates [m/s].
    residual_acceleration : ndarray, shape (T,)
        Largest node acceleration [m/s^2].
    structure : Structure
        The simulated structure.
    settings : dict
        The options of the run (as recorded by :func:`tensegrity.engine.simulate.simulate`).
    status : int
        ``1`` steady state, ``0`` end time reached, ``-1`` failed.
    message : str
    nfev, nsteps, nswitches, nprojections : int
        Right-hand-side evaluations, steps, located slack/taut switches, projections.
    max_rod_length_error : float
        Largest relative rod-length error seen.
    wall_time : float
        Run time [s].
    max_constraint_error : float
        Largest violation of the joints and supports seen [m] (0 for a structure without them;
        NaN when read from a file written before it was stored).
    """

    time: np.ndarray
    nodes: np.ndarray
    velocities: np.ndarray
    tendon_length: np.ndarray
    tendon_tension: np.ndarray
    energy: dict[str, np.ndarray]
    q: np.ndarray
    qdot: np.ndarray
    residual_acceleration: np.ndarray
    structure: Structure
    settings: dict[str, Any]
    status: int
    message: str
    nfev: int
    nsteps: int
    nswitches: int
    nprojections: int
    max_rod_length_error: float
    wall_time: float
    max_constraint_error: float = 0.0

    @property
    def success(self) -> bool:
        """True unless the run failed."""
        return self.status >= 0

    @property
    def tendon_names(self) -> tuple[str, ...]:
        """Tendon names, shape (S,)."""
        return self.structure.tendon_name


def json_default(value: Any) -> Any:
    """JSON for NumPy scalars and arrays in ``settings``; ``str`` for anything else."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    return str(value)


def write_trajectory(path: PathLike, result: SimulationResult) -> Path:
    """Write a simulation result to an HDF5 trajectory file, atomically.

    Arrays are stored exactly (float64, gzip level 4 with byte shuffle, ``h5py``'s automatic
    chunking); see the module docstring for the layout.  The file uses the HDF5 1.8 format, which
    allows attributes larger than 64 KiB (the structure of a large shell).

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
    """
    import h5py

    structure = result.structure
    energy_names = list(result.energy)
    arrays = {
        "time": result.t,
        "nodes": result.node_position,
        "velocities": result.node_velocity,
        "tendon_length": result.tendon_length,
        "tendon_tension": result.tendon_tension,
        "energy": np.column_stack([result.energy[name] for name in energy_names])
        if energy_names else np.zeros((len(result.t), 0)),
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
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w", libver=("v108", "v108")) as f:
            for name, value in attributes.items():
                f.attrs[name] = value
            for name, value in arrays.items():
                value = np.asarray(value, dtype=float)
                compress = {} if value.size == 0 else dict(
                    compression="gzip", compression_opts=4, shuffle=True, chunks=True
                )
                f.create_dataset(name, data=value, **compress)
            f["energy"].attrs["columns"] = np.array(energy_names, dtype=h5py.string_dtype())
    return Path(path)


def read_trajectory(path: PathLike) -> Trajectory:
    """Read a trajectory file written by :func:`write_trajectory`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Trajectory

    Raises
    ------
    ValueError
        One line starting with the file name, if the file is missing, is not HDF5, is not a
        tensegrity trajectory (``format`` attribute), is of a newer version, misses a dataset or
        an attribute, or holds arrays whose shapes do not fit its structure.
    """
    import h5py

    try:
        handle = h5py.File(path, "r")
    except FileNotFoundError as exc:
        raise file_error(path, "no such file") from exc
    except IsADirectoryError as exc:
        raise file_error(path, "is a directory, not a file") from exc
    except PermissionError as exc:
        raise file_error(path, "permission denied") from exc
    except OSError as exc:
        if not Path(path).exists():
            raise file_error(path, "no such file") from exc
        raise file_error(path, "not an HDF5 file (a tensegrity trajectory is HDF5)") from exc
    with handle as f:
        return _read_open_trajectory(f, path)


def _read_open_trajectory(f, path: PathLike) -> Trajectory:
    attrs = f.attrs
    fmt = text_attribute(attrs.get("format"))
    if fmt != TRAJECTORY_FORMAT:
        found = "no 'format' attribute" if fmt is None else f"format {fmt!r}"
        raise file_error(path, f"not a tensegrity trajectory file ({found}, expected "
                                f"{TRAJECTORY_FORMAT!r})")
    try:
        version = int(attrs.get("version"))
    except (TypeError, ValueError) as exc:
        raise file_error(path, "missing or invalid 'version' attribute") from exc
    if version > TRAJECTORY_VERSION:
        raise file_error(path, f"trajectory format version {version} is newer than this "
                                f"library reads ({TRAJECTORY_VERSION}); upgrade tensegrity")

    def attribute(name: str) -> Any:
        if name not in attrs:
            raise file_error(path, f"missing attribute {name!r}")
        return attrs[name]

    def json_attribute(name: str) -> Any:
        try:
            return json.loads(text_attribute(attribute(name)))
        except (TypeError, json.JSONDecodeError) as exc:
            raise file_error(path, f"attribute {name!r}: invalid JSON ({exc})") from exc

    missing = [name for name in ARRAY_DATASETS if not isinstance(f.get(name), _h5py_dataset())]
    if missing:
        raise file_error(path, f"missing dataset {missing[0]!r} (not a complete tensegrity "
                                "trajectory)")
    arrays = {name: np.asarray(f[name][()]) for name in ARRAY_DATASETS}
    columns = [text_attribute(c) for c in f["energy"].attrs.get("columns", ENERGY_COLUMNS)]

    structure_data = json_attribute("structure")
    try:
        structure = Structure.from_dict(structure_data)
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        raise file_error(path, f"attribute 'structure': {exc}") from exc
    settings = json_attribute("settings")

    T, N, S, n = (arrays["time"].shape[0] if arrays["time"].ndim == 1 else -1,
                  structure.n_nodes, structure.n_tendons, structure.n_coordinates)
    expected = {
        "time": (T,), "nodes": (T, N, structure.dim), "velocities": (T, N, structure.dim),
        "tendon_length": (T, S),
        "tendon_tension": (T, S), "energy": (T, len(columns)), "q": (T, n), "qdot": (T, n),
        "residual_acceleration": (T,),
    }
    for name, shape in expected.items():
        if arrays[name].shape != shape:
            raise file_error(path, f"dataset {name!r}: expected shape {shape} for this "
                                    f"structure, got {arrays[name].shape}")
    try:
        counts = {name: int(attribute(name)) for name in _COUNT_ATTRIBUTES}
        status = int(attribute("status"))
        floats = {name: float(attribute(name)) for name in ("max_rod_length_error", "wall_time")}
        # Absent from files written before it was stored: unknown there, unless nothing can err.
        floats["max_constraint_error"] = float(f.attrs.get(
            "max_constraint_error", np.nan if structure.has_constraints else 0.0))
    except (TypeError, ValueError) as exc:
        raise file_error(path, f"invalid attribute: {exc}") from exc
    return Trajectory(
        time=arrays["time"],
        nodes=arrays["nodes"],
        velocities=arrays["velocities"],
        tendon_length=arrays["tendon_length"],
        tendon_tension=arrays["tendon_tension"],
        energy={name: arrays["energy"][:, k] for k, name in enumerate(columns)},
        q=arrays["q"],
        qdot=arrays["qdot"],
        residual_acceleration=arrays["residual_acceleration"],
        structure=structure,
        settings=settings,
        status=status,
        message=text_attribute(attribute("message")),
        **counts,
        **floats,
    )


def _h5py_dataset() -> type:
    import h5py

    return h5py.Dataset


def text_attribute(value: Any) -> str | None:
    """An HDF5 string attribute as ``str`` (h5py may return ``bytes`` or a NumPy string)."""
    if value is None:
        return None
    if isinstance(value, bytes):
        return value.decode("utf-8")
    if isinstance(value, np.ndarray) and value.shape == ():
        return text_attribute(value[()])
    return str(value)
