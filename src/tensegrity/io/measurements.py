"""Measurement files: the samples of a set of sensors (:mod:`tensegrity.engine.sensors`) as
CSV, and the sensor files that describe the sensors (JSON).

Two CSV files, UTF-8, a header row then one row per sample, numbers in Python's shortest
round-trip form (read back bit for bit), rows in time order:

- ``markers.csv``, the position sensors' markers: header ``time,marker,x,y,z``, one row per
  marker and sample time: the time [s], the marker (its node's name) and the measured position
  [m] (``z`` 0 for a planar structure).  The file a motion-capture system gives, the input of an
  identification.
- ``measurements.csv``, every channel: header ``time,channel,value``, one row per channel and
  sample time: the time [s], the channel's name (``position.n3.x``, ``tension.c_01``,
  ``contact.n4``: :mod:`tensegrity.engine.sensors`) and the value in the channel's SI unit.

Each channel (marker) has its own sample times, strictly increasing; lines starting with ``#``
and empty lines are skipped.  :func:`write_measurements` and :func:`write_markers` write them
atomically; :func:`read_measurements` and :func:`read_markers` read them back, with one-line
``ValueError``\\ s naming the file, the line and the column at fault.  An identification
(``tensegrity fit --data``) reads either file: :func:`csv_kind` tells them apart by the header,
:func:`fitted_channels` picks the markers, lengths and tensions of a measurements file.

A sensor file (``tensegrity simulate --sensors FILE.json``) is a JSON object ``{"seed": 0,
"sensors": [...]}`` (or the list alone: seed 0), each sensor an object of the fields of
:class:`~tensegrity.engine.sensors.Sensor`::

    {"seed": 7, "sensors": [
      {"kind": "position", "nodes": ["n0", "n1"], "noise": 0.001, "rate": 100},
      {"kind": "tension", "tendons": ["c_01"], "noise": 0.5, "bias": 2.0, "delay": 0.01},
      {"kind": "angular_rate", "rods": [0], "noise": 0.02, "rate": 200},
      {"kind": "contact", "rate": 50}]}

:func:`read_sensors` reads it, errors naming the file and the field (``sensors[1].noise``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tensegrity.engine.sensors import Measurements, Sensor
from tensegrity.io.files import PathLike, atomic_path, file_error, read_input

__all__ = [
    "MARKER_HEADER",
    "MEASUREMENT_HEADER",
    "ChannelSeries",
    "MarkerSeries",
    "SensorFile",
    "csv_kind",
    "fitted_channels",
    "read_markers",
    "read_measurements",
    "read_sensors",
    "write_markers",
    "write_measurements",
]

#: The header of a markers file.
MARKER_HEADER = ("time", "marker", "x", "y", "z")
#: The header of a measurements file.
MEASUREMENT_HEADER = ("time", "channel", "value")


class ChannelSeries(NamedTuple):
    """One channel of a measurements file: sample times ``t`` (K,) [s], ``value`` (K,)."""

    t: np.ndarray
    value: np.ndarray


class MarkerSeries(NamedTuple):
    """One marker of a markers file: sample times ``t`` (K,) [s], ``position`` (K, 3) [m]."""

    t: np.ndarray
    position: np.ndarray


class SensorFile(NamedTuple):
    """A sensor file's sensors and the seed of their noise."""

    sensors: tuple[Sensor, ...]
    seed: int


def _number(x: float) -> str:
    return repr(float(x))


def _write_rows(path: PathLike, header: Sequence[str], rows: list[tuple[float, str, str]]) -> Path:
    """Write ``header`` and ``rows`` (time, name, the rest of the line) in time order (stable:
    rows of one time stay in the order given), atomically."""
    for _, name, _ in rows:
        if "," in name or not name.isprintable():
            raise ValueError(
                f"measurements: the name {name!r:.60} has a comma or a control character"
            )
    rows.sort(key=lambda row: row[0])
    lines = [",".join(header), *(f"{_number(t)},{name},{rest}" for t, name, rest in rows)]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return Path(path)


def write_measurements(path: PathLike, measurements: Measurements) -> Path:
    """Write every channel of ``measurements`` as ``time,channel,value`` rows (module doc),
    atomically; returns the path."""
    rows = [
        (float(t), name, _number(value))
        for series in measurements.series
        for t, values in zip(series.t, series.value, strict=True)
        for name, value in zip(series.channel, values, strict=True)
    ]
    return _write_rows(path, MEASUREMENT_HEADER, rows)


def write_markers(path: PathLike, measurements: Measurements) -> Path:
    """Write the position sensors' samples of ``measurements`` as ``time,marker,x,y,z`` rows
    (module doc), atomically; returns the path.  ``ValueError`` naming ``measurements`` if it
    has no position sensor."""
    positions = [s for s in measurements.series if s.sensor.kind == "position"]
    if not positions:
        raise ValueError("measurements: no position sensor (markers are their nodes)")
    rows = []
    for series in positions:
        dim = len(series.channel) // len(series.items)
        for t, values in zip(series.t, series.value, strict=True):
            for k, marker in enumerate(series.items):
                xyz = [*values[k * dim : (k + 1) * dim], *([0.0] * (3 - dim))]
                rows.append((float(t), marker, ",".join(map(_number, xyz))))
    return _write_rows(path, MARKER_HEADER, rows)


def _rows(path: PathLike, header: Sequence[str]) -> list[tuple[int, list[str]]]:
    """The rows after ``header`` of the CSV file ``path`` (line number, cells), each of the
    header's length; ``ValueError`` without the file name otherwise."""
    raw = read_input(path)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 text (byte {exc.start})") from None
    lines = [
        (number, [cell.strip() for cell in line.split(",")])
        for number, line in enumerate(text.splitlines(), 1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines or lines[0][1] != list(header):
        got = ",".join(lines[0][1]) if lines else "nothing"
        where = lines[0][0] if lines else 1
        raise ValueError(f"line {where}: expected the header {','.join(header)!r}, got {got!r:.80}")
    for number, cells in lines[1:]:
        if len(cells) != len(header):
            raise ValueError(
                f"line {number}: expected {len(header)} values ({','.join(header)}), got "
                f"{len(cells)}"
            )
    return lines[1:]


def _value(cell: str, number: int, column: str) -> float:
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ValueError(
            f"line {number}, column {column}: expected a finite number, got {cell!r:.80}"
        )
    return value


def _series(
    path: PathLike, header: Sequence[str], what: str
) -> dict[str, tuple[list[float], list[list[float]]]]:
    """Each name's (column 2) times and values (the columns after it) of the file ``path``, in
    the order the names first appear; ``ValueError`` naming the file, line and column."""
    try:
        out: dict[str, tuple[list[float], list[list[float]]]] = {}
        for number, cells in _rows(path, header):
            t = _value(cells[0], number, header[0])
            name = cells[1]
            if not name:
                raise ValueError(f"line {number}, column {what}: empty")
            values = [_value(c, number, h) for c, h in zip(cells[2:], header[2:], strict=True)]
            times, rows = out.setdefault(name, ([], []))
            if times and t <= times[-1]:
                raise ValueError(
                    f"line {number}, column time: {t!r} is not after the {what}'s previous "
                    f"sample ({name!r:.60} at {times[-1]!r})"
                )
            times.append(t)
            rows.append(values)
    except ValueError as exc:
        raise file_error(path, str(exc)) from None
    return out


def read_measurements(path: PathLike) -> dict[str, ChannelSeries]:
    """Each channel of a measurements file (``time,channel,value``, module doc) by name.

    Raises
    ------
    ValueError
        One line starting with the file name, naming the line and column at fault.
    """
    return {
        name: ChannelSeries(np.array(t), np.array(v).reshape(-1))
        for name, (t, v) in _series(path, MEASUREMENT_HEADER, "channel").items()
    }


def read_markers(path: PathLike) -> dict[str, MarkerSeries]:
    """Each marker of a markers file (``time,marker,x,y,z``, module doc) by name.

    Raises
    ------
    ValueError
        One line starting with the file name, naming the line and column at fault.
    """
    return {
        name: MarkerSeries(np.array(t), np.array(p).reshape(-1, 3))
        for name, (t, p) in _series(path, MARKER_HEADER, "marker").items()
    }


def csv_kind(path: PathLike) -> str:
    """``"markers"`` or ``"measurements"``: which of the two CSV files ``path`` is, by its
    header (its first line that is neither empty nor a ``#`` comment).

    Raises
    ------
    ValueError
        One line starting with the file name when the header is neither.
    """
    try:
        text = read_input(path).decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise file_error(path, f"not UTF-8 text (byte {exc.start})") from None
    for line in text.splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            cells = tuple(cell.strip() for cell in line.split(","))
            if cells in (MARKER_HEADER, MEASUREMENT_HEADER):
                return "markers" if cells == MARKER_HEADER else "measurements"
            break
    raise file_error(
        path,
        f"expected the header {','.join(MARKER_HEADER)!r} (markers) or "
        f"{','.join(MEASUREMENT_HEADER)!r} (measurements)",
    )


def fitted_channels(
    channels: dict[str, ChannelSeries], dim: int
) -> dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """The channels of a measurements file an identification reads, by kind: ``markers``
    (node -> times (T,) [s], positions (T, dim) [m], from the channels ``position.NODE.x``,
    ``.y`` (and ``.z``) sampled together), ``lengths`` and ``tensions`` (tendon -> times,
    values [m] or [N], from ``length.TENDON`` and ``tension.TENDON``): the names
    :mod:`tensegrity.engine.sensors` gives them.

    Raises
    ------
    ValueError
        One line naming a channel of another kind, or a marker whose coordinates are missing or
        sampled at other times.
    """
    out: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {
        "markers": {},
        "lengths": {},
        "tensions": {},
    }
    axes = "xyz"[:dim]
    for name, series in channels.items():
        kind, _, item = name.partition(".")
        if kind in ("length", "tension") and item:
            out[kind + "s"][item] = (series.t, series.value)
        elif kind == "position" and "." in item:
            node, _, axis = item.rpartition(".")
            if axis not in axes:
                raise ValueError(
                    f"channel {name!r:.60}: a marker's coordinates are {', '.join(axes)} (a "
                    f"{dim}-D structure)"
                )
            if node in out["markers"]:
                continue
            found: list[ChannelSeries] = []
            for axis in axes:
                part = channels.get(f"position.{node}.{axis}")
                if part is None or (found and not np.array_equal(part.t, found[0].t)):
                    raise ValueError(
                        f"channel {f'position.{node}.{axis}'!r:.60}: "
                        + ("missing" if part is None else "sampled at other times than .x")
                        + f" (a marker needs {', '.join(axes)} at the same times)"
                    )
                found.append(part)
            out["markers"][node] = (found[0].t, np.stack([p.value for p in found], axis=1))
        else:
            raise ValueError(
                f"channel {name!r:.60}: not one an identification reads (position.NODE.x, "
                "length.TENDON, tension.TENDON)"
            )
    return out


def read_sensors(path: PathLike) -> SensorFile:
    """The sensors and seed of a sensor file (JSON, module doc).

    Raises
    ------
    ValueError
        One line starting with the file name, naming the field at fault (``sensors[2].rate:
        expected a finite number > 0, got 'fast'``).  Whether the nodes, tendons and rods
        named exist is the structure's to say (:class:`~tensegrity.engine.sensors.SensorReader`).
    """
    raw = read_input(path)
    try:
        try:
            document: Any = json.loads(raw.decode("utf-8-sig"))
        except UnicodeDecodeError as exc:
            raise ValueError(f"not UTF-8 text (byte {exc.start})") from None
        except json.JSONDecodeError as exc:
            raise ValueError(f"line {exc.lineno}, column {exc.colno}: {exc.msg}") from None
        return _sensor_file(document)
    except ValueError as exc:
        raise file_error(path, str(exc)) from None


def _sensor_file(document: Any) -> SensorFile:
    """The sensors and seed of a sensor file's JSON ``document`` (``ValueError`` naming the
    field, without the file name)."""
    seed: Any = 0
    if isinstance(document, dict):
        unknown = [key for key in document if key not in ("seed", "sensors")]
        if unknown:
            raise ValueError(f"{unknown[0]:.60}: unknown field (expected seed, sensors)")
        if "sensors" not in document:
            raise ValueError("sensors: missing (a list of sensors)")
        seed, document = document.get("seed", 0), document["sensors"]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: expected a whole number >= 0, got {seed!r:.60}")
    if not isinstance(document, list) or not document:
        raise ValueError("sensors: expected a non-empty list of sensors")
    sensors = []
    for j, fields in enumerate(document):
        try:
            sensors.append(Sensor.from_dict(fields))
        except (TypeError, ValueError) as exc:
            where = f"sensors[{j}]." if isinstance(fields, dict) else f"sensors[{j}]: "
            raise ValueError(f"{where}{exc}") from None
    return SensorFile(tuple(sensors), seed)
