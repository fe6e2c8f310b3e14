"""Loads: tabulated nodal forces (a time table of forces as the callable
``simulate(external_force=...)``) and uniform gravity given as a number or a vector.

A table gives the external force on every node at increasing times ``t_k``; between them the
force is interpolated linearly, and outside ``[t_0, t_last]`` it is held at the end values
(``outside="hold"``) or zero (``outside="zero"``).  Files: ``.npz`` with arrays ``time`` (T,) [s]
and ``force`` (T, N, 3) [N], or ``.csv`` with one row per time, ``t, f0x, f0y, f0z, f1x, ...``
(``1 + 3N`` numbers; lines starting with ``#`` are comments).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np


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
