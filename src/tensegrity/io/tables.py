"""Force tables read from files: :func:`read_force_table` (``.npz`` or ``.csv``) into a
:class:`~tensegrity.model.loads.ForceTable`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tensegrity.io.files import PathLike, file_error, os_problem
from tensegrity.model.loads import ForceTable


def read_force_table(path: PathLike, *, outside: str = "hold") -> ForceTable:
    """Read a force table from ``.npz`` (``time``, ``force``) or ``.csv`` (see the module doc).

    Raises
    ------
    ValueError
        One line starting with the file name.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise file_error(path, f"unknown force table suffix {suffix!r} (expected .npz or .csv)")
    try:
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as archive:
                missing = [name for name in ("time", "force") if name not in archive.files]
                if missing:
                    raise ValueError(
                        f"missing array {missing[0]!r} (expected time (T,), force (T, N, 3))"
                    )
                return ForceTable(archive["time"], archive["force"], outside)
        rows = np.loadtxt(path, delimiter=",", comments="#", ndmin=2)
        if (rows.shape[1] - 1) % 3 or rows.shape[1] < 4:
            raise ValueError(
                f"expected rows of 1 + 3N numbers (t, f0x, f0y, f0z, ...), got {rows.shape[1]}"
            )
        return ForceTable(rows[:, 0], rows[:, 1:].reshape(rows.shape[0], -1, 3), outside)
    except OSError as exc:
        raise file_error(path, os_problem(exc)) from exc
    except ValueError as exc:
        raise file_error(path, str(exc)) from exc
