"""Loads: tabulated nodal forces (a time table of forces as the callable
``simulate(external_force=...)``), forces on named nodes, constant or ramped in
(:class:`NodalLoad`, :func:`nodal_load_table`), and uniform gravity given as a number or a
vector.

A table gives the external force on every node at increasing times ``t_k``; between them the
force is interpolated linearly, and outside ``[t_0, t_last]`` it is held at the end values
(``outside="hold"``) or zero (``outside="zero"``).  Files: ``.npz`` with arrays ``time`` (T,) [s]
and ``force`` (T, N, 3) [N], or ``.csv`` with one row per time, ``t, f0x, f0y, f0z, f1x, ...``
(``1 + 3N`` numbers; lines starting with ``#`` are comments).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from tensegrity.model.structure import Structure


def gravity_vector(value: float | Sequence[float], dim: int) -> np.ndarray:
    """Uniform gravity [m/s^2] as a (dim,) vector.

    A number ``g`` points down the last axis (``(0, 0, -g)`` in 3-D, ``(0, -g)`` for a planar
    structure); a sequence of ``dim`` numbers is the vector itself.  ``ValueError`` naming
    ``gravity`` otherwise.
    """
    problem = ValueError(
        f"gravity: expected a finite number or {dim} finite components, got {value!r}"
    )
    try:
        vector = np.array(value, dtype=float, ndmin=1)
    except (TypeError, ValueError):
        raise problem from None
    if vector.shape == (1,):
        vector = np.concatenate([np.zeros(dim - 1), -vector])
    if vector.shape != (dim,) or not np.all(np.isfinite(vector)):
        raise problem
    return vector


class _Table:
    """Values at strictly increasing times, linear in between; outside ``[time[0], time[-1]]``
    held at the end rows (``outside="hold"``) or zero (``"zero"``).  Subclasses name their
    values (:attr:`values`, (T, ...)) and call :meth:`_validate` from ``__post_init__``."""

    time: np.ndarray
    outside: str
    _values_field = "values"

    @property
    def values(self) -> np.ndarray:
        """The table's rows (T, ...)."""
        return getattr(self, self._values_field)

    def _validate(self, row_shape: str, row_ndim: int) -> None:
        time = np.array(self.time, dtype=float)
        values = np.array(self.values, dtype=float)
        name = self._values_field
        if time.ndim != 1 or time.size == 0:
            raise ValueError(f"time: expected a non-empty 1-D array, got shape {time.shape}")
        if (
            values.ndim != 1 + row_ndim
            or values.shape[0] != time.size
            or (row_ndim == 2 and values.shape[2] != 3)
        ):
            raise ValueError(
                f"{name}: expected shape (T, {row_shape}) with T = {time.size} rows "
                f"like time, got {values.shape}"
            )
        for field, array in (("time", time), (name, values)):
            bad = np.argwhere(~np.isfinite(array))
            if bad.size:
                raise ValueError(f"{field}[{', '.join(map(str, bad[0]))}]: must be finite")
        step = np.flatnonzero(np.diff(time) <= 0)
        if step.size:
            k = step[0] + 1
            raise ValueError(
                f"time: must increase strictly, but time[{k}] = {float(time[k])!r} <= "
                f"time[{k - 1}] = {float(time[k - 1])!r}"
            )
        if self.outside not in ("hold", "zero"):
            raise ValueError(f"outside: expected 'hold' or 'zero', got {self.outside!r}")
        time.setflags(write=False)
        values.setflags(write=False)
        object.__setattr__(self, "time", time)
        object.__setattr__(self, name, values)

    def _segments(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per time: the row before, the fraction of the way to the next row, and whether the
        time is outside the table."""
        time = self.time
        t = np.atleast_1d(np.asarray(times, dtype=float))
        k = np.clip(np.searchsorted(time, t, side="right"), 1, max(time.size - 1, 1))
        lo = k - 1
        span = time[k] - time[lo] if time.size > 1 else np.ones_like(t)
        fraction = np.clip((t - time[lo]) / span, 0.0, 1.0) if time.size > 1 else np.zeros_like(t)
        return lo, fraction, (t < time[0]) | (t > time[-1])

    def at(self, times: np.ndarray) -> np.ndarray:
        """The rows (K, ...) at ``times`` (K,) [s]."""
        values = self.values
        lo, fraction, outside = self._segments(times)
        hi = np.minimum(lo + 1, values.shape[0] - 1)
        w = fraction.reshape(-1, *[1] * (values.ndim - 1))
        out = (1.0 - w) * values[lo] + w * values[hi]
        if self.outside == "zero":
            out[outside] = 0.0
        return out

    def slope(self, times: np.ndarray) -> np.ndarray:
        """The time derivative of the rows (K, ...) at ``times`` (zero outside the table)."""
        values, time = self.values, self.time
        lo, _, outside = self._segments(times)
        if time.size == 1:
            return np.zeros((lo.size, *values.shape[1:]))
        hi = lo + 1
        out = (values[hi] - values[lo]) / (time[hi] - time[lo]).reshape(
            -1, *[1] * (values.ndim - 1)
        )
        out[outside] = 0.0
        return out

    def __call__(self, t: float) -> np.ndarray:
        """The row at time ``t`` [s]."""
        return self.at(np.array([t]))[0]


@dataclasses.dataclass(frozen=True, eq=False)
class ForceTable(_Table):
    """External nodal forces from a time table, linear in between; call it as ``w(t)``.

    Parameters
    ----------
    time : array_like, shape (T,)
        Strictly increasing, finite times [s], ``T >= 1`` (one row: a constant force).
    force : array_like, shape (T, N, 3)
        Forces [N] on each node at each time.
    outside : ``"hold"`` or ``"zero"``
        The force before ``time[0]`` and after ``time[-1]``: the end rows, or zero.

    Raises
    ------
    ValueError
        Naming the field: ``time: must increase strictly, but time[3] = 0.2 <= time[2] = 0.2``,
        ``force: expected shape (T, N, 3) with T = 4 rows like time, got (3, 12, 3)``, ...
    """

    time: np.ndarray
    force: np.ndarray
    outside: str = "hold"
    _values_field = "force"

    def __post_init__(self) -> None:
        self._validate("N, 3", 2)

    @property
    def n_nodes(self) -> int:
        """Number of nodes ``N`` the table is for."""
        return self.force.shape[1]


@dataclasses.dataclass(frozen=True, eq=False)
class ControlTable(_Table):
    """Controls ``u`` (rest-length changes, ``Lbar = L0 - u``) from a time table, linear in
    between; call it as ``u(t)``.  The engine uses its slopes for the work of the control.

    Parameters
    ----------
    time : array_like, shape (T,)
        Strictly increasing, finite times [s].
    control : array_like, shape (T, S)
        Rest-length changes [m] of each tendon at each time.
    outside : ``"hold"`` or ``"zero"``
        The control before ``time[0]`` and after ``time[-1]``.
    """

    time: np.ndarray
    control: np.ndarray
    outside: str = "hold"
    _values_field = "control"

    def __post_init__(self) -> None:
        self._validate("S", 1)


@dataclasses.dataclass(frozen=True)
class NodalLoad:
    """A force on one node, constant or ramped in.

    Parameters
    ----------
    node : str or int
        The node: a name or a 0-based index (:meth:`Structure.node_index
        <tensegrity.model.structure.Structure.node_index>`: a name wins over an index).
    force : sequence of float, shape (3,)
        The force [N].
    ramp : float
        Time [s] over which the force grows linearly from 0 (at ``t = 0``), then held; 0: the
        whole force from the start.
    """

    node: str | int
    force: tuple[float, ...]
    ramp: float = 0.0


def nodal_load_table(structure: Structure, loads: Sequence[NodalLoad]) -> ForceTable:
    """The :class:`ForceTable` of ``loads`` on ``structure`` (forces on one node add up): rows
    at ``t = 0`` and at each ramp's end, linear in between, held after (and before ``t = 0``).

    Raises
    ------
    KeyError
        An unknown node (:meth:`Structure.node_index
        <tensegrity.model.structure.Structure.node_index>`).
    ValueError
        A force of the wrong length or not finite, a ramp negative or not finite (naming
        ``loads[k]``), no loads, or a planar structure (a table's forces are 3-D).
    """
    if not loads:
        raise ValueError("loads: expected at least one load")
    if structure.dim != 3:
        raise ValueError("loads: a force table holds 3-D forces; the structure is planar")
    dim = 3
    nodes, forces = [], []
    for k, load in enumerate(loads):
        force = np.array(load.force, dtype=float)
        if force.shape != (dim,) or not np.all(np.isfinite(force)):
            raise ValueError(f"loads[{k}].force: expected {dim} finite components [N], got {force}")
        if not (np.isfinite(load.ramp) and load.ramp >= 0):
            raise ValueError(f"loads[{k}].ramp: must be finite and >= 0 [s], got {load.ramp}")
        nodes.append(structure.node_index(load.node))
        forces.append(force)
    time = np.unique([0.0, *(load.ramp for load in loads)])
    table = np.zeros((time.size, structure.n_nodes, dim))
    for node, force, load in zip(nodes, forces, loads, strict=True):
        share = np.ones_like(time) if load.ramp == 0 else np.minimum(time / load.ramp, 1.0)
        table[:, node] += share[:, None] * force
    return ForceTable(time, table)


def add_force_tables(first: ForceTable, second: ForceTable) -> ForceTable:
    """The sum of two tables held outside their times (``outside="hold"``), exactly: rows at
    the times of both (both are linear between them and constant outside them).

    Raises
    ------
    ValueError
        Tables for different numbers of nodes, or one that is zero outside its times (the sum
        would jump there: not a table), naming the table.
    """
    for name, table in (("first", first), ("second", second)):
        if table.outside != "hold":
            raise ValueError(
                f"{name}: a table zero outside its times cannot be added to another (its sum "
                "jumps at its ends)"
            )
    if first.force.shape[1:] != second.force.shape[1:]:
        raise ValueError(
            f"second: forces of shape {second.force.shape[1:]}, the first table's are "
            f"{first.force.shape[1:]}"
        )
    time = np.union1d(first.time, second.time)
    return ForceTable(time, first.at(time) + second.at(time))
