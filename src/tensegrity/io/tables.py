"""Time tables read from files, linear in between (``.npz`` or ``.csv``):
:func:`read_force_table` into a :class:`~tensegrity.model.loads.ForceTable` (external nodal
forces [N]), :func:`read_control_table` into a :class:`~tensegrity.model.loads.ControlTable`
(the tendons' rest-length changes ``u`` [m], ``Lbar = L0 - u``).

A force table's ``.csv`` has a row of numbers per time: ``t`` [s] and the force [N] on every
node, ``f0x, f0y, f0z, f1x, ...``; a first row of column names (``t,f0x,f0y,f0z,...``) may come
before them and is skipped.  Its ``.npz`` has ``time (T,)`` and ``force (T, N, 3)``.

A control table's ``.csv`` has a header row, ``t`` and then tendon names (the structure's
``tendon_name``), and a row of numbers per time: ``t`` [s] and ``u`` [m] of each tendon named;
a tendon not named has ``u = 0``.  Its ``.npz`` has ``time (T,)`` and ``control (T, S)`` (every
tendon, in the structure's order), or ``time (T,)``, ``names (K,)`` and ``control (T, K)``.
Lines starting with ``#`` and empty lines of a ``.csv`` are skipped.
:func:`write_control_table` writes that ``.csv``.
"""

from __future__ import annotations

import csv
import difflib
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from tensegrity.io.checked import NUMBERS, ArrayKind, npz_arrays, open_npz
from tensegrity.io.files import PathLike, atomic_path, file_error, read_input
from tensegrity.model.loads import ControlTable, ForceTable
from tensegrity.model.structure import Structure


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
    raw = _table_bytes(path, "force")
    try:
        if Path(path).suffix.lower() == ".npz":
            return _npz_table(raw, outside)
        lines = [line for _, line in _csv_lines(raw)]
        first = lines[0].split(",")[0].strip() if lines else ""
        if first[:1].isalpha() and not _number(first):
            lines = lines[1:]  # (the column names: t, f0x, ...)
        if not lines:
            raise ValueError("no rows of numbers (expected rows t, f0x, f0y, f0z, ...)")
        rows = np.loadtxt(lines, delimiter=",", ndmin=2)
        if (rows.shape[1] - 1) % 3 or rows.shape[1] < 4:
            raise ValueError(
                f"expected rows of 1 + 3N numbers (t, f0x, f0y, f0z, ...), got {rows.shape[1]}"
            )
        return ForceTable(rows[:, 0], rows[:, 1:].reshape(rows.shape[0], -1, 3), outside)
    except ValueError as exc:
        raise file_error(path, str(exc)) from exc


def _csv_lines(raw: bytes) -> list[tuple[int, str]]:
    """The lines of a table's ``.csv`` (UTF-8, a byte-order mark allowed) with their numbers
    (from 1), empty lines and ``#`` comments left out (``ValueError`` without the file name)."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 text (byte {exc.start})") from exc
    return [
        (number, line)
        for number, line in enumerate(text.splitlines(), 1)
        if line.strip() and not line.lstrip().startswith("#")
    ]


def _number(text: str) -> bool:
    """Whether ``text`` reads as a number."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def _npz_table(raw: bytes, outside: str) -> ForceTable:
    """The force table in the bytes of an ``.npz`` (``ValueError`` without the file name)."""
    with open_npz(raw) as archive:
        missing = [name for name in ("time", "force") if name not in archive.files]
        if missing:
            raise ValueError(f"missing array {missing[0]!r} (expected time (T,), force (T, N, 3))")
        arrays = npz_arrays(archive, ("time", "force"), kinds=NUMBERS)
    return ForceTable(arrays["time"], arrays["force"], outside)


def _table_bytes(path: PathLike, what: str) -> bytes:
    """The content of the table file ``path`` (``.npz`` or ``.csv``) of ``what`` (``"force"``,
    ``"control"``), read whole within the limits; a one-line ``ValueError`` otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise file_error(path, f"unknown {what} table suffix {suffix!r} (expected .npz or .csv)")
    return read_input(path)


def read_control_table(
    path: PathLike, structure: Structure, *, outside: str = "hold"
) -> ControlTable:
    """Read the rest-length changes ``u(t)`` [m] of ``structure``'s tendons from ``.csv`` or
    ``.npz`` (see the module doc): ``simulate(structure, t_span, control=table)``.

    Parameters
    ----------
    path : str or os.PathLike
        The table: rows at strictly increasing times [s], linear in between.
    structure : Structure
        Its ``tendon_name`` are the names the table's columns may use.
    outside : ``"hold"`` or ``"zero"``
        ``u`` before the first row and after the last: those rows (default), or zero.

    Returns
    -------
    ControlTable
        ``control`` (T, S): ``u`` of every tendon, 0 for those the table does not name.

    Raises
    ------
    ValueError
        One line starting with the file name, naming the column, row or array at fault:
        ``"u.csv: column 3 'c_O1': no tendon named so (close: 'c_01', 'c_10')"``, ``"u.csv:
        line 5, column 'c_01': expected a number, got 'x'"``, ...
    """
    raw = _table_bytes(path, "control")
    names = structure.tendon_name
    try:
        if Path(path).suffix.lower() == ".npz":
            time, columns, control = _npz_control(raw, names)
        else:
            time, columns, control = _csv_control(raw, names)
        full = np.zeros((control.shape[0], len(names)))
        full[:, columns] = control
        return ControlTable(time, full, outside)
    except ValueError as exc:
        raise file_error(path, str(exc)) from exc


def write_control_table(path: PathLike, table: ControlTable, structure: Structure) -> Path:
    """Write ``table`` as the ``.csv`` :func:`read_control_table` reads (module doc), atomically:
    the columns of ``structure``'s tendons whose ``u`` is not zero throughout, numbers in
    Python's shortest round-trip form.

    ``ValueError`` naming ``table`` if its column count is not ``structure``'s tendon count.
    """
    names = structure.tendon_name
    if table.control.shape[1] != len(names):
        raise ValueError(
            f"table: has {table.control.shape[1]} columns, the structure {len(names)} tendons"
        )
    used = [s for s in range(len(names)) if np.any(table.control[:, s] != 0.0)]
    lines = [",".join(["t", *(names[s] for s in used)])]
    lines += [
        ",".join(repr(float(v)) for v in (t, *row[used]))
        for t, row in zip(table.time, table.control, strict=True)
    ]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return Path(path)


def _tendon_columns(
    header: Sequence[str], names: Sequence[str], where: Callable[[int], str]
) -> list[int]:
    """The tendon index of each name of ``header``; ``ValueError`` naming the first unknown
    (with the close matches) or repeated one (``where(k)`` says which column ``k`` is)."""
    index = {name: k for k, name in enumerate(names)}
    columns: list[int] = []
    for k, name in enumerate(header):
        if name not in index:
            close = difflib.get_close_matches(name, names, n=3)
            hint = (
                f"close: {', '.join(map(repr, close))}"
                if close
                else f"the structure's tendons: {', '.join(map(repr, names[:8]))}"
                + (", ..." if len(names) > 8 else "")
            )
            raise ValueError(f"{where(k)} {name!r:.80}: no tendon named so ({hint})")
        if index[name] in columns:
            raise ValueError(f"{where(k)} {name!r:.80}: named twice")
        columns.append(index[name])
    return columns


def _csv_control(raw: bytes, names: Sequence[str]) -> tuple[np.ndarray, list[int], np.ndarray]:
    """Times (T,), the tendons of the columns (K) and their ``u`` (T, K) of a ``.csv`` control
    table (``ValueError`` without the file name)."""
    lines = _csv_lines(raw)
    if not lines:
        raise ValueError("no header row (expected t, then tendon names)")
    (_, head), *rows = [(number, next(csv.reader([line]))) for number, line in lines]
    header = [cell.strip() for cell in head]
    if header[0] != "t":
        raise ValueError(f"column 1 of the header: expected 't', got {header[0]!r:.80}")
    columns = _tendon_columns(header[1:], names, lambda k: f"column {k + 2}")
    if not rows:
        raise ValueError("no rows of numbers after the header")
    values = np.empty((len(rows), len(header)))
    for r, (number, cells) in enumerate(rows):
        if len(cells) != len(header):
            raise ValueError(
                f"line {number}: expected {len(header)} values (t and {len(header) - 1} "
                f"tendons, as the header), got {len(cells)}"
            )
        for c, cell in enumerate(cells):
            try:
                values[r, c] = float(cell)
            except ValueError:
                values[r, c] = math.nan
            if not math.isfinite(values[r, c]):
                raise ValueError(
                    f"line {number}, column {header[c]!r:.80}: expected a finite number, got "
                    f"{cell.strip()!r:.80}"
                )
    return values[:, 0], columns, values[:, 1:]


def _npz_control(raw: bytes, names: Sequence[str]) -> tuple[np.ndarray, list[int], np.ndarray]:
    """Times (T,), the tendons of the columns (K) and their ``u`` (T, K) of an ``.npz`` control
    table (``ValueError`` without the file name)."""
    with open_npz(raw) as archive:
        expected = "time (T,) and control (T, S), or time, names (K,) and control (T, K)"
        unknown = sorted(set(archive.files) - {"time", "control", "names"})
        if unknown:
            raise ValueError(f"unknown array {unknown[0]!r} (expected {expected})")
        missing = [name for name in ("time", "control") if name not in archive.files]
        if missing:
            raise ValueError(f"missing array {missing[0]!r} (expected {expected})")
        kinds = {
            "time": ArrayKind("iuf", "real numbers"),
            "control": ArrayKind("iuf", "real numbers"),
            "names": ArrayKind("U", "text"),
        }
        arrays = npz_arrays(archive, kinds=kinds)
    time, control = arrays["time"], arrays["control"]
    if "names" in arrays:
        header = [str(name) for name in np.atleast_1d(arrays["names"])]
        if arrays["names"].ndim != 1:
            raise ValueError(f"array 'names': expected shape (K,), got {arrays['names'].shape}")
        columns = _tendon_columns(header, names, lambda k: f"names[{k}]")
    else:
        columns = list(range(len(names)))
    if control.ndim != 2 or control.shape[1] != len(columns):
        what = "names" if "names" in arrays else f"the structure's {len(names)} tendons"
        raise ValueError(
            f"array 'control': expected shape (T, {len(columns)}) (one column per tendon of "
            f"{what}), got {control.shape}"
        )
    return np.asarray(time, dtype=float), columns, np.asarray(control, dtype=float)
