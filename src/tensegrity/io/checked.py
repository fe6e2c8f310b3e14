"""Reading files that may be crafted: HDF5 datasets and attributes, and ``.npz`` arrays, each
checked against the documented layout and the limits (:mod:`tensegrity.io.files`) before any of
its data is read (docs/reliability.md).

An HDF5 dataset is read only if it is stored in the file itself: a hard link (not an external
or soft link, which may lead out of the file), its data in the file (not external raw storage,
which reads any local file, nor a virtual dataset, which maps other files), of the expected kind
of numbers (real floats where floats belong: no compound, complex, text or integer data), in
chunks no larger than :data:`MAX_CHUNK_BYTES` or one row, and within ``TENSEGRITY_MAX_ARRAY_BYTES``
(:func:`read_datasets`).  An attribute is read only if it has the expected type and shape.

Every problem is a ``ValueError`` with one line that starts with the file name and names the
dataset or attribute; :func:`npz_arrays` raises without the file name, which its callers add.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
import zlib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tensegrity.io.files import (
    MAX_ARRAY_BYTES,
    PathLike,
    byte_limit,
    byte_text,
    file_error,
    over_limit,
    regular_file,
    shown_path,
)

#: Largest chunk [bytes] of a dataset, unless one row of the dataset is larger: reading any
#: sample of a chunked dataset decompresses its whole chunk (the library writes chunks of at
#: most 1 MiB or one row).
MAX_CHUNK_BYTES = 64 * 2**20

#: NumPy dtype kinds: real floats; numbers (also integers and booleans).
FLOATS = "f"
NUMBERS = "biuf"
#: The kinds of an HDF5 dataset of text (:func:`hdf5_dataset`): strings, of any length.
TEXT = "text"


class ArrayKind(NamedTuple):
    """What an ``.npz`` array may hold (:func:`npz_arrays`): its NumPy dtype kinds, and what
    they are in words for the message that refuses others."""

    kinds: str  #: e.g. ``"iuf"``: integers or real floats
    words: str  #: e.g. ``"real numbers"``


def _within_limit(total: int, size: int, what: str) -> int:
    """``total + size``, the array bytes of one read so far, if within
    ``TENSEGRITY_MAX_ARRAY_BYTES``; else ``ValueError`` (without the file name) naming ``what``,
    the limit and how to raise it."""
    if total + size > byte_limit(MAX_ARRAY_BYTES):
        if total:
            what += " with the arrays before it"
        raise ValueError(over_limit(what, total + size, MAX_ARRAY_BYTES))
    return total + size


# ------------------------------------------------------------------------------------ HDF5
def open_hdf5(path: PathLike, why: str) -> Any:
    """The HDF5 file at ``path`` (a regular file only), open for reading; ``why`` says in the
    message of a file that is not HDF5 why it should be (``"a tensegrity trajectory is HDF5"``).

    Raises
    ------
    ValueError
        One line naming the file: missing, not a regular file, not HDF5, ...
    """
    import h5py

    regular_file(path)
    try:
        return h5py.File(path, "r")
    except FileNotFoundError as exc:
        raise file_error(path, "no such file") from exc
    except IsADirectoryError as exc:
        raise file_error(path, "is a directory, not a file") from exc
    except PermissionError as exc:
        raise file_error(path, "permission denied") from exc
    except OSError as exc:
        if not Path(path).exists():
            raise file_error(path, "no such file") from exc
        raise file_error(path, f"not an HDF5 file ({why})") from exc


def _name(group: Any, name: str) -> str:
    """``name`` inside ``group`` as a path in the file, without the leading ``/``."""
    parent = group.name.strip("/")
    return f"{parent}/{name}" if parent else name


#: What h5py raises reading a damaged file (e.g. copied while it was written).
_DAMAGED = (KeyError, OSError, RuntimeError)


def _damaged(path: PathLike, what: str, exc: BaseException) -> ValueError:
    """The one-line error for ``what`` failing on a damaged file, with h5py's reason."""
    problem = " ".join(str(exc).split()) or type(exc).__name__
    return file_error(path, f"{what}, the file is damaged ({problem})")


def _stored_object(group: Any, name: str, path: PathLike, kind: str) -> Any:
    """The object ``name`` of ``group`` if it is a hard link (in the file), else ``None`` if
    absent; ``ValueError`` for an external or soft link, or an object HDF5 cannot open (a
    damaged file, e.g. copied while it was written: h5py raises ``KeyError``)."""
    import h5py

    where = _name(group, name)
    try:
        link = group.get(name, getlink=True)
        if link is None or isinstance(link, h5py.HardLink):
            return None if link is None else group[name]
    except _DAMAGED as exc:
        raise _damaged(path, f"{kind} {where!r} cannot be opened", exc) from exc
    if isinstance(link, h5py.ExternalLink):
        target = f"{shown_path(link.filename)}:{shown_path(link.path)}"
        raise file_error(
            path, f"{kind} {where!r} is an external link (to {target}), not in the file"
        )
    if isinstance(link, h5py.SoftLink):
        raise file_error(
            path, f"{kind} {where!r} is a soft link (to {shown_path(link.path)}), not in place"
        )
    raise file_error(path, f"{kind} {where!r} is a {type(link).__name__}, not in the file")


def hdf5_names(group: Any, path: PathLike) -> list[str]:
    """The names of the links in ``group``.

    Raises
    ------
    ValueError
        One line naming the file and the group if HDF5 cannot list them (a damaged file, e.g.
        copied while it was written: h5py raises ``RuntimeError``).
    """
    try:
        return list(group)
    except _DAMAGED as exc:
        where = group.name.strip("/") or "/"
        raise _damaged(path, f"group {where!r} cannot be listed", exc) from exc


def hdf5_group(group: Any, name: str, path: PathLike) -> Any | None:
    """The subgroup ``name`` of ``group`` stored in the file, or ``None`` if there is none.

    Raises
    ------
    ValueError
        For a link out of the file, or an object that is not a group.
    """
    import h5py

    found = _stored_object(group, name, path, "group")
    if found is not None and not isinstance(found, h5py.Group):
        raise file_error(path, f"{_name(group, name)!r} is not a group")
    return found


def hdf5_dataset(group: Any, name: str, path: PathLike, *, kinds: str = FLOATS) -> Any | None:
    """The dataset ``name`` of ``group`` if its data are in the file and of the expected kind,
    ``None`` if there is none; nothing of its data is read.

    Parameters
    ----------
    group : h5py.Group
    name : str
    path : str or os.PathLike
        The file, for the messages.
    kinds : str
        The NumPy dtype kinds allowed: :data:`FLOATS` (default) or :data:`NUMBERS`; or
        :data:`TEXT` for strings.

    Raises
    ------
    ValueError
        One line naming the file and the dataset: an external or soft link, a group, external
        raw storage, a virtual dataset, data of another kind, chunks over :data:`MAX_CHUNK_BYTES`
        and one row.
    """
    import h5py

    found = _stored_object(group, name, path, "dataset")
    if found is None:
        return None
    where = _dataset_name(found) if isinstance(found, h5py.Dataset) else repr(_name(group, name))
    if not isinstance(found, h5py.Dataset):
        raise file_error(path, f"{where} is not a dataset ({type(found).__name__})")
    if found.is_virtual:
        raise file_error(path, f"{where} is a virtual dataset (its data are in other files)")
    if found.external:
        files = ", ".join(sorted({shown_path(entry[0]) for entry in found.external}))
        raise file_error(path, f"{where} has external storage (its data are in {files})")
    _check_kind(found.dtype, kinds, where, path)
    _check_chunks(found, where, path)
    return found


def _dtype_text(dtype: np.dtype) -> str:
    if dtype.names is not None:
        return f"compound data ({', '.join(dtype.names)})"
    if dtype.kind == "c":
        return f"complex numbers ({dtype})"
    if dtype.kind in "OSUa":
        return "text or objects"
    return f"{dtype}"


def _check_kind(dtype: np.dtype, kinds: str, where: str, path: PathLike) -> None:
    if kinds == TEXT:
        _check_text(dtype, where, path)
    elif dtype.names is not None or dtype.kind not in kinds:
        wanted = "real floating-point numbers" if kinds == FLOATS else "real numbers"
        raise file_error(path, f"{where}: expected {wanted}, got {_dtype_text(dtype)}")


def _check_chunks(dataset: Any, where: str, path: PathLike) -> None:
    if dataset.chunks is None:
        return
    itemsize = dataset.dtype.itemsize
    chunk = math.prod(dataset.chunks) * itemsize
    row = math.prod(dataset.shape[1:]) * itemsize
    if chunk > max(MAX_CHUNK_BYTES, row):
        raise file_error(
            path,
            f"{where}: chunks of {byte_text(chunk)}, larger than one row and "
            f"{byte_text(MAX_CHUNK_BYTES)} (reading one sample would decompress all of it)",
        )


def read_datasets(
    datasets: Mapping[str, Any],
    path: PathLike,
    *,
    every: int = 1,
    computed: Mapping[str, int] | None = None,
) -> dict[str, np.ndarray]:
    """Checked datasets (:func:`hdf5_dataset`) read as arrays: every ``every``-th row and the last
    row of each (all of it for ``every`` 1), float64 for floats; their sizes, and the bytes of
    the arrays the reader will compute from them (``computed``: bytes by a description of the
    array, e.g. ``"array 'node_position'"``), are counted against
    ``TENSEGRITY_MAX_ARRAY_BYTES`` before any is read.

    Raises
    ------
    ValueError
        Over the limit, or a dataset HDF5 cannot read (e.g. an unknown compression filter), or
        whose data fail their Fletcher-32 checksum (corrupted).
    """
    check_read_bytes(datasets.values(), path, every=every, computed=computed)
    return {name: _rows(dataset, every, path) for name, dataset in datasets.items()}


def check_read_bytes(
    datasets: Iterable[Any],
    path: PathLike,
    *,
    every: int = 1,
    computed: Mapping[str, int] | None = None,
) -> None:
    """``ValueError`` naming the file and the first dataset over ``TENSEGRITY_MAX_ARRAY_BYTES``,
    counted over ``datasets`` (every ``every``-th row and the last of each) as
    :func:`read_datasets` reads them, at least 8 bytes an element, then ``computed`` (bytes by
    a description of the array); nothing of them is read."""
    sizes = [
        (_dataset_name(d), math.prod(selected_shape(d.shape, every)) * max(8, d.dtype.itemsize))
        for d in datasets
    ]
    total = 0
    for what, size in [*sizes, *(computed or {}).items()]:
        try:
            total = _within_limit(total, size, what)
        except ValueError as exc:
            raise file_error(path, str(exc)) from None


def _dataset_name(dataset: Any) -> str:
    return f"dataset {dataset.name.lstrip('/')!r}"


def _rows(dataset: Any, every: int, path: PathLike) -> np.ndarray:
    dtype = float if dataset.dtype.kind == "f" else None
    try:
        if every == 1 or dataset.ndim == 0 or dataset.shape[0] <= 1:
            return np.asarray(dataset[()], dtype=dtype)
        rows = dataset[::every]
        if (dataset.shape[0] - 1) % every:
            rows = np.concatenate([rows, dataset[-1:]])
        return np.asarray(rows, dtype=dtype)
    except OSError as exc:
        if dataset.fletcher32 and "filter returned failure" in str(exc):
            raise file_error(
                path,
                f"{_dataset_name(dataset)}: corrupted (its data do not match their checksum: "
                "the file is damaged)",
            ) from exc
        raise file_error(path, f"{_dataset_name(dataset)}: cannot read ({exc})") from exc


def selected_shape(shape: tuple[int, ...], every: int) -> tuple[int, ...]:
    """The shape :func:`read_datasets` returns for a dataset of ``shape``."""
    if every == 1 or not shape or shape[0] <= 1:
        return shape
    rows = len(range(0, shape[0], every)) + (1 if (shape[0] - 1) % every else 0)
    return (rows, *shape[1:])


# ------------------------------------------------------------------------------ attributes
def _attribute_dtype(owner: Any, name: str, path: PathLike, shape: tuple[int, ...]) -> np.dtype:
    """The dtype of the attribute ``name`` (present) of ``owner`` if its shape is ``shape`` (a
    1-D ``(-1,)``: any length); nothing of its value is read."""
    where = _attribute_name(owner, name)
    ident = owner.attrs.get_id(name)
    if not (ident.shape == shape or (shape == (-1,) and len(ident.shape) == 1)):
        wanted = "a scalar" if shape == () else "a list"
        raise file_error(path, f"{where}: expected {wanted}, got an array of shape {ident.shape}")
    return _checked_attribute_dtype(ident, where, path)


def _checked_attribute_dtype(ident: Any, where: str, path: PathLike) -> np.dtype:
    """The dtype of the attribute ``ident`` if NumPy reads it and it is within
    ``TENSEGRITY_MAX_ARRAY_BYTES``."""
    try:
        dtype = ident.dtype
    except (TypeError, ValueError) as exc:
        raise file_error(path, f"{where}: a type NumPy does not read ({exc})") from exc
    size = math.prod(ident.shape) * dtype.itemsize
    if size > byte_limit(MAX_ARRAY_BYTES):
        raise file_error(path, over_limit(where, size, MAX_ARRAY_BYTES))
    return dtype


def check_attributes(owner: Any, path: PathLike) -> None:
    """``ValueError`` naming the file and the attribute unless every attribute of the HDF5 group
    or dataset ``owner`` is of a type NumPy reads and within ``TENSEGRITY_MAX_ARRAY_BYTES``
    (for a reader that reads all of them, as xarray does); nothing of their values is read."""
    for name in owner.attrs:
        _checked_attribute_dtype(owner.attrs.get_id(name), _attribute_name(owner, name), path)


def _attribute_name(owner: Any, name: str) -> str:
    place = owner.name.strip("/")
    return f"attribute {name!r}" + (f" of {place!r}" if place else "")


def _text_of(value: Any, where: str, path: PathLike) -> str:
    """An HDF5 string value as ``str`` (h5py gives ``str`` or ``bytes``); ``where`` names it in
    the message."""
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    if isinstance(value, bytes):
        try:
            return value.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise file_error(path, f"{where}: not UTF-8 text (byte {exc.start})") from exc
    if isinstance(value, str):
        return value
    raise file_error(path, f"{where}: expected text, got {type(value).__name__}")


def _check_text(dtype: np.dtype, where: str, path: PathLike, wanted: str = "text") -> None:
    import h5py

    if h5py.check_string_dtype(dtype) is None:
        raise file_error(path, f"{where}: expected {wanted}, got {_dtype_text(dtype)}")


def attribute_text(owner: Any, name: str, path: PathLike) -> str:
    """The scalar text attribute ``name`` (present) of the HDF5 group or dataset ``owner``."""
    where = _attribute_name(owner, name)
    _check_text(_attribute_dtype(owner, name, path, ()), where, path)
    return _text_of(owner.attrs[name], where, path)


def attribute_text_list(owner: Any, name: str, path: PathLike) -> list[str]:
    """The 1-D text attribute ``name`` (present) of ``owner``, as a list."""
    where = _attribute_name(owner, name)
    _check_text(_attribute_dtype(owner, name, path, (-1,)), where, path, "a list of text")
    return [_text_of(value, where, path) for value in owner.attrs[name]]


def attribute_number(owner: Any, name: str, path: PathLike, *, integer: bool = False) -> Any:
    """The scalar number attribute ``name`` (present) of ``owner``: ``int`` if ``integer`` (stored
    as an integer or a boolean), else ``float`` (any real number, NaN included)."""
    where = _attribute_name(owner, name)
    dtype = _attribute_dtype(owner, name, path, ())
    if dtype.names is not None or dtype.kind not in ("biu" if integer else NUMBERS):
        wanted = "an integer" if integer else "a real number"
        raise file_error(path, f"{where}: expected {wanted}, got {_dtype_text(dtype)}")
    value = owner.attrs[name]
    return int(value) if integer else float(value)


def attribute_json(owner: Any, name: str, path: PathLike) -> dict[str, Any]:
    """The scalar text attribute ``name`` (present) of ``owner``, parsed as a JSON object."""
    where = _attribute_name(owner, name)
    text = attribute_text(owner, name, path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise file_error(path, f"{where}: invalid JSON ({exc})") from exc
    except RecursionError as exc:
        raise file_error(path, f"{where}: invalid JSON (nested too deeply)") from exc
    except ValueError as exc:  # an integer of more digits than Python converts (4300)
        raise file_error(path, f"{where}: invalid JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise file_error(path, f"{where}: expected a JSON object, got {type(data).__name__}")
    return data


# -------------------------------------------------------------------------------------- npz
#: The first bytes of a ZIP archive (an ``.npz``; an empty one starts with its end record).
_ZIP_SIGNATURES = (b"PK\x03\x04", b"PK\x05\x06")
#: What reading a damaged or unusual ZIP member raises.
_ZIP_ERRORS = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
    NotImplementedError,  # an unknown compression method
    RuntimeError,  # an encrypted member
)


def open_npz(raw: bytes) -> Any:
    """The ``.npz`` archive in ``raw``, open and none of its arrays read (:func:`numpy.load`
    would read a bare ``.npy`` array at once, whatever its header asks for).

    Raises
    ------
    ValueError
        Not an ``.npz`` archive (without the file name, which the caller adds).
    """
    if not raw.startswith(_ZIP_SIGNATURES):
        raise ValueError("not a NumPy .npz archive (no ZIP signature)")
    try:
        return np.load(io.BytesIO(raw), allow_pickle=False)
    except (*_ZIP_ERRORS, ValueError) as exc:
        raise ValueError(f"not a NumPy .npz archive ({type(exc).__name__})") from exc


def npz_arrays(
    archive: Any,
    names: Iterable[str] | None = None,
    *,
    kinds: str | Mapping[str, ArrayKind] | None = None,
) -> dict[str, np.ndarray]:
    """The arrays ``names`` (default: all) of an open ``.npz`` archive (:func:`open_npz`), each
    read only after its header is checked: of the kind of data allowed, the data its header
    describes in the archive member (a crafted header asks for terabytes), and within
    ``TENSEGRITY_MAX_ARRAY_BYTES`` over all of them.

    Parameters
    ----------
    archive : numpy.lib.npyio.NpzFile
    names : iterable of str, optional
    kinds : str or mapping of str to ArrayKind, optional
        NumPy dtype kinds allowed, for every array (e.g. :data:`NUMBERS`) or per array name
        (an array not in the mapping: any kind but objects); any but objects if None.

    Raises
    ------
    ValueError
        One line without the file name (the caller adds it), naming the array.
    """
    total, arrays = 0, {}
    for name in archive.files if names is None else names:
        try:
            dtype, size, stored = _npy_header(archive.zip, name)
            _check_npy(name, dtype, size, stored, kinds)
            total = _within_limit(total, size, f"array {name!r}")
            arrays[name] = archive[name]
        except _ZIP_ERRORS as exc:
            raise ValueError(f"array {name!r}: cannot read ({type(exc).__name__}: {exc})") from exc
    return arrays


def _check_npy(
    name: str,
    dtype: np.dtype,
    size: int,
    stored: int,
    kinds: str | Mapping[str, ArrayKind] | None,
) -> None:
    allowed = ArrayKind(kinds, "numbers") if isinstance(kinds, str) else None
    if isinstance(kinds, Mapping):
        allowed = kinds.get(name)
    if dtype.hasobject or (
        allowed is not None and (dtype.names is not None or dtype.kind not in allowed.kinds)
    ):
        wanted = "numbers" if allowed is None else allowed.words
        raise ValueError(f"array {name!r}: expected {wanted}, got {_dtype_text(dtype)}")
    if size > stored:
        raise ValueError(
            f"array {name!r}: its header asks for {byte_text(size)}, but the archive holds "
            f"{byte_text(max(stored, 0))} of it"
        )


def _npy_header(zipped: Any, name: str) -> tuple[np.dtype, int, int]:
    """The dtype of the ``.npy`` member for ``name``, the bytes its header describes, and the
    bytes of data the member holds."""
    from numpy.lib import format as npy

    try:
        info = zipped.getinfo(f"{name}.npy")
    except KeyError as exc:
        raise ValueError(f"array {name!r}: not a .npy member of the archive") from exc
    with zipped.open(info) as member:
        try:
            version = npy.read_magic(member)
            read_header = {(1, 0): npy.read_array_header_1_0, (2, 0): npy.read_array_header_2_0}
            if version not in read_header:
                raise ValueError(f".npy format version {version} is not read")
            shape, _, dtype = read_header[version](member)
        except ValueError as exc:
            raise ValueError(f"array {name!r}: {exc}") from exc
        header = member.tell()
    return dtype, math.prod(shape) * dtype.itemsize, info.file_size - header
