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

import contextlib
import dataclasses
import json
import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.structure import Structure

if TYPE_CHECKING:
    from tensegrity.simulate import SimulationResult

PathLike = str | os.PathLike

#: ``format`` attribute of a trajectory file.
TRAJECTORY_FORMAT = "tensegrity-trajectory"
#: ``version`` attribute written; files of a higher version are refused.
TRAJECTORY_VERSION = 1
#: Energy columns in the order :func:`tensegrity.simulate.simulate` produces them [J].
ENERGY_COLUMNS = ("kinetic", "elastic", "gravity", "dissipated", "external_work", "control_work")

_ARRAY_DATASETS = (
    "time", "nodes", "velocities", "tendon_length", "tendon_tension", "energy", "q", "qdot",
    "residual_acceleration",
)
_COUNT_ATTRIBUTES = ("nfev", "nsteps", "nswitches", "nprojections")


# ------------------------------------------------------------------------- atomic writes
@contextlib.contextmanager
def atomic_path(path: PathLike, *, fsync: bool = True) -> Iterator[Path]:
    """Write a file atomically: yield a temporary path to write, then move it onto ``path``.

    The temporary file (``<name>.<random>.tmp``) is created empty in ``path``'s directory, so the
    final :func:`os.replace` is an atomic rename on the same file system.  If the ``with`` body
    completes, the temporary file is flushed to disk (``fsync``) and replaces ``path``; if it
    raises (any exception, ``KeyboardInterrupt`` included), the temporary file is removed and the
    exception propagates, leaving ``path`` as it was (absent, or the older file intact).

    The new file gets the permissions of the file it replaces, or the usual ``0o666 & ~umask``
    for a new file (rather than ``mkstemp``'s private ``0o600``).

    Parameters
    ----------
    path : str or os.PathLike
        Final file name.  Its directory must exist.
    fsync : bool
        Flush the data to disk before the rename (default True), so that after a system crash
        ``path`` holds either the old or the complete new content.

    Yields
    ------
    pathlib.Path
        The temporary file to write (it exists and is empty; writers may truncate or replace it).
        Note its suffix is ``.tmp``: tools that infer the format from the name (e.g. matplotlib's
        ``savefig``) need it given explicitly.

    Examples
    --------
    >>> with atomic_path("out.png") as tmp:               # doctest: +SKIP
    ...     figure.savefig(tmp, format="png")
    """
    final = Path(path)
    with tempfile.NamedTemporaryFile(
        dir=final.parent, prefix=f"{final.name}.", suffix=".tmp", delete=False
    ) as handle:
        tmp = Path(handle.name)
    try:
        yield tmp
        os.chmod(tmp, _new_file_mode(final))
        if fsync:
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    if fsync:
        _fsync_directory(final.parent)


def _new_file_mode(final: Path) -> int:
    """The permission bits ``final`` should get: those of the file it replaces, or the umask's."""
    try:
        return stat.S_IMODE(os.stat(final).st_mode)
    except OSError:
        pass
    return 0o666 & ~_umask()


def _umask() -> int:
    try:  # Linux: read it without changing it (os.umask is process-wide and not thread-safe)
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _fsync_directory(directory: Path) -> None:
    """Persist a rename (best effort; not possible on every platform)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _file_error(path: PathLike, problem: str) -> ValueError:
    """A one-line ``ValueError``: ``"<path>: <problem>"``."""
    return ValueError(f"{os.fspath(path)}: {' '.join(str(problem).split())}")


def _os_problem(exc: OSError) -> str:
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    if isinstance(exc, IsADirectoryError):
        return "is a directory, not a file"
    if isinstance(exc, PermissionError):
        return "permission denied"
    return f"cannot read: {exc.strerror or exc}"


# ------------------------------------------------------------------- staged output folders
def write_staged(out: Path, write: Callable[[Path], list[Path]]) -> list[Path]:
    """Write every output into a staging folder inside ``out``, then move them into ``out``.

    ``write(staging)`` writes the files and returns them in the order they are to be moved;
    a file in a subfolder of ``staging`` goes to the same subfolder of ``out`` (created if
    missing; files already there and not rewritten stay).  Either all files appear (each by an
    atomic rename) or, if any write fails, none does and the folders created for them are
    removed again.
    """
    out = Path(out)
    created = [folder for folder in (out, *out.parents) if not folder.exists()]
    out.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryDirectory(dir=out, prefix=".staging-") as staging:
            moved = []
            for path in write(Path(staging)):
                target = out / Path(path).relative_to(staging)
                if not target.parent.exists():
                    target.parent.mkdir(parents=True)
                    created.append(target.parent)
                os.replace(path, target)
                moved.append(target)
            return moved
    except BaseException:
        for folder in sorted(created, key=lambda f: len(f.parts), reverse=True):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only if empty
        raise


# ----------------------------------------------------------------------------- structures
def read_structure(path: PathLike) -> Structure:
    """Read a structure file (the JSON form of :meth:`Structure.to_dict`).

    Parameters
    ----------
    path : str or os.PathLike
        A UTF-8 JSON file: ``{"nodes": [[x, y, z], ...] (N, 3) [m], "velocities": (N, 3) [m/s],
        "rods": [{"nodes", "mass" [kg], "length" [m], "damping" [1/s]}, ...],
        "tendons": [{"name", "nodes", "stiffness" [N/m], "rest_length" [m],
        "damping" [N s/m]}, ...]}``.

    Returns
    -------
    Structure

    Raises
    ------
    ValueError
        One line starting with the file name: ``"s.json: no such file"``,
        ``"s.json: invalid JSON at line 3, column 5: Expecting ',' delimiter"``,
        ``"s.json: tendons[2] ('t3_1_1').stiffness: must be > 0, got -5.0"``, ...

    Notes
    -----
    A ``.yaml``, ``.yml``, ``.toml`` or ``.npz`` file is read by
    :func:`tensegrity.network.read_network` instead (docs/networks.md); any other name as JSON.
    """
    if Path(path).suffix.lower() in (".yaml", ".yml", ".toml", ".npz"):
        from tensegrity.network import read_network

        return read_network(path)
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except OSError as exc:
        raise _file_error(path, _os_problem(exc)) from exc
    except UnicodeDecodeError as exc:
        raise _file_error(path, f"not UTF-8 text (byte {exc.start})") from exc
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _file_error(
            path, f"invalid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}"
        ) from exc
    except RecursionError as exc:
        raise _file_error(path, "invalid JSON: nested too deeply") from exc
    return _structure_from_dict(data, path)


def _structure_from_dict(data: Any, path: PathLike) -> Structure:
    try:
        return Structure.from_dict(data)
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        # TypeError/KeyError/OverflowError: a malformed value that slipped past from_dict's own
        # checks (e.g. a string or a huge integer as a node index).
        raise _file_error(path, str(exc) or type(exc).__name__) from exc


def write_structure(path: PathLike, structure: Structure) -> Path:
    """Write ``structure`` as JSON (:meth:`Structure.to_dict`, indent 2), atomically.

    Floats are written with Python's shortest round-trip representation, so
    ``read_structure(path).to_dict() == structure.to_dict()`` exactly.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its directory must exist.  An existing file is replaced only once the new
        one is complete.
    structure : Structure

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    text = json.dumps(structure.to_dict(), indent=2, allow_nan=False) + "\n"
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


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
        The options of the run (as recorded by :func:`tensegrity.simulate.simulate`).
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


def _json_default(value: Any) -> Any:
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
        "settings": json.dumps(result.settings, default=_json_default),
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
        raise _file_error(path, "no such file") from exc
    except IsADirectoryError as exc:
        raise _file_error(path, "is a directory, not a file") from exc
    except PermissionError as exc:
        raise _file_error(path, "permission denied") from exc
    except OSError as exc:
        if not Path(path).exists():
            raise _file_error(path, "no such file") from exc
        raise _file_error(path, "not an HDF5 file (a tensegrity trajectory is HDF5)") from exc
    with handle as f:
        return _read_open_trajectory(f, path)


def _read_open_trajectory(f, path: PathLike) -> Trajectory:
    attrs = f.attrs
    fmt = _text(attrs.get("format"))
    if fmt != TRAJECTORY_FORMAT:
        found = "no 'format' attribute" if fmt is None else f"format {fmt!r}"
        raise _file_error(path, f"not a tensegrity trajectory file ({found}, expected "
                                f"{TRAJECTORY_FORMAT!r})")
    try:
        version = int(attrs.get("version"))
    except (TypeError, ValueError) as exc:
        raise _file_error(path, "missing or invalid 'version' attribute") from exc
    if version > TRAJECTORY_VERSION:
        raise _file_error(path, f"trajectory format version {version} is newer than this "
                                f"library reads ({TRAJECTORY_VERSION}); upgrade tensegrity")

    def attribute(name: str) -> Any:
        if name not in attrs:
            raise _file_error(path, f"missing attribute {name!r}")
        return attrs[name]

    def json_attribute(name: str) -> Any:
        try:
            return json.loads(_text(attribute(name)))
        except (TypeError, json.JSONDecodeError) as exc:
            raise _file_error(path, f"attribute {name!r}: invalid JSON ({exc})") from exc

    missing = [name for name in _ARRAY_DATASETS if not isinstance(f.get(name), _h5py_dataset())]
    if missing:
        raise _file_error(path, f"missing dataset {missing[0]!r} (not a complete tensegrity "
                                "trajectory)")
    arrays = {name: np.asarray(f[name][()]) for name in _ARRAY_DATASETS}
    columns = [_text(c) for c in f["energy"].attrs.get("columns", ENERGY_COLUMNS)]

    structure_data = json_attribute("structure")
    try:
        structure = Structure.from_dict(structure_data)
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        raise _file_error(path, f"attribute 'structure': {exc}") from exc
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
            raise _file_error(path, f"dataset {name!r}: expected shape {shape} for this "
                                    f"structure, got {arrays[name].shape}")
    try:
        counts = {name: int(attribute(name)) for name in _COUNT_ATTRIBUTES}
        status = int(attribute("status"))
        floats = {name: float(attribute(name)) for name in ("max_rod_length_error", "wall_time")}
        # Absent from files written before it was stored: unknown there, unless nothing can err.
        floats["max_constraint_error"] = float(f.attrs.get(
            "max_constraint_error", np.nan if structure.has_constraints else 0.0))
    except (TypeError, ValueError) as exc:
        raise _file_error(path, f"invalid attribute: {exc}") from exc
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
        message=_text(attribute("message")),
        **counts,
        **floats,
    )


def _h5py_dataset() -> type:
    import h5py

    return h5py.Dataset


def _text(value: Any) -> str | None:
    """An HDF5 string attribute as ``str`` (h5py may return ``bytes`` or a NumPy string)."""
    if value is None:
        return None
    if isinstance(value, bytes):
        return value.decode("utf-8")
    if isinstance(value, np.ndarray) and value.shape == ():
        return _text(value[()])
    return str(value)
