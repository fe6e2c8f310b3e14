"""Force tables read from files: :func:`read_force_table` (``.npz`` or ``.csv``) into a
:class:`~tensegrity.model.loads.ForceTable`."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from tensegrity.io.checked import NUMBERS, npz_arrays, open_npz
from tensegrity.io.files import PathLike, file_error, read_input
from tensegrity.model.loads import ForceTable


def read_force_table(path: PathLike, *, outside: str = "hold") -> ForceTable:
    """Read a force table from ``.npz`` (``time``, ``force``) or ``.csv`` (see the module doc).

    The file is read whole (a regular file of at most ``TENSEGRITY_MAX_INPUT_BYTES``), and the
    arrays of an ``.npz`` only after their headers are checked (``TENSEGRITY_MAX_ARRAY_BYTES``,
    :func:`tensegrity.io.checked.npz_arrays`).

    Raises
    ------
    ValueError
        One line starting with the file name.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise file_error(path, f"unknown force table suffix {suffix!r} (expected .npz or .csv)")
    raw = read_input(path)
    try:
        if suffix == ".npz":
            return _npz_table(raw, outside)
        rows = np.loadtxt(io.StringIO(raw.decode("utf-8")), delimiter=",", comments="#", ndmin=2)
        if (rows.shape[1] - 1) % 3 or rows.shape[1] < 4:
            raise ValueError(
                f"expected rows of 1 + 3N numbers (t, f0x, f0y, f0z, ...), got {rows.shape[1]}"
            )
        return ForceTable(rows[:, 0], rows[:, 1:].reshape(rows.shape[0], -1, 3), outside)
    except ValueError as exc:
        raise file_error(path, str(exc)) from exc


def _npz_table(raw: bytes, outside: str) -> ForceTable:
    """The force table in the bytes of an ``.npz`` (``ValueError`` without the file name)."""
    with open_npz(raw) as archive:
        missing = [name for name in ("time", "force") if name not in archive.files]
        if missing:
            raise ValueError(f"missing array {missing[0]!r} (expected time (T,), force (T, N, 3))")
        arrays = npz_arrays(archive, ("time", "force"), kinds=NUMBERS)
    return ForceTable(arrays["time"], arrays["force"], outside)
