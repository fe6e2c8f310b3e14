"""Rest-length actuators as hardware has them (:class:`Actuators`): which tendons a controller
drives, the bounds of their rest lengths, how fast they can change, the lag of the drive, and a
winch motor from which the rate and force limits follow (:class:`Winch`).

A controller (or a learning environment's action) *commands* a control ``u_cmd`` [m] per
actuated tendon (rest length ``L0 - u``, as everywhere in the package); the actuator moves the
applied control ``u`` toward it:

- the command is clipped so that the rest length stays in ``[min_rest_length,
  max_rest_length]`` (never below zero);
- ``u`` follows a first-order lag ``du/dt = (u_cmd - u) / time_constant`` (``time_constant`` 0:
  no lag), its rate clipped to ``max_rate`` [m/s] (infinite: no limit; with neither, ``u`` jumps
  to the command, a zero-order hold);
- ``max_tension`` [N] caps the tendon's tension (a motor that cannot hold more, as MuJoCo's
  ``forcerange``): ``T = min(k (l - Lbar) + c l', max_tension)``, its spring's potential growing
  linearly beyond ``k x = max_tension`` (``tensegrity.physics.kernel.capped_energy``).

Between two commands the applied control is a closed-form function of time (a ramp at the rate
limit, then the lag's exponential), so the engine needs no extra state for it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from tensegrity.model.structure import Structure

__all__ = ["Actuators", "Winch", "actuators"]


@dataclasses.dataclass(frozen=True)
class Winch:
    """A winch motor that reels a tendon in and out (SI units).

    Attributes
    ----------
    radius : float
        Drum radius [m] (> 0).
    max_speed : float
        Largest drum speed [rad/s] (> 0): the rate limit is ``radius * max_speed`` [m/s].
    max_torque : float, optional
        Largest torque [N m] (> 0): the tension cap is ``max_torque / radius`` [N] (None: no
        cap).
    """

    radius: float
    max_speed: float
    max_torque: float | None = None

    def __post_init__(self) -> None:
        for field in ("radius", "max_speed", "max_torque"):
            value = getattr(self, field)
            if field == "max_torque" and value is None:
                continue
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
                value, bool
            )
            if not (ok and math.isfinite(value) and value > 0):
                raise ValueError(f"winch.{field}: must be a finite number > 0, got {value!r}")

    @property
    def max_rate(self) -> float:
        """Largest rate of the rest length [m/s]."""
        return float(self.radius * self.max_speed)

    @property
    def max_tension(self) -> float:
        """Largest tension the motor holds [N] (inf without ``max_torque``)."""
        return math.inf if self.max_torque is None else float(self.max_torque / self.radius)


@dataclasses.dataclass(frozen=True, eq=False)
class Actuators:
    """The actuated tendons of a structure and their limits; ``A`` actuators, arrays (A,).

    Build it with :func:`actuators` (names, scalars broadcast, checks against the structure).

    Attributes
    ----------
    tendons : (A,) int array
        Indices of the actuated tendons (distinct).
    min_rest_length, max_rest_length : (A,) float arrays
        Bounds of their rest lengths [m], ``0 <= min <= max`` (max may be ``inf``).
    max_rate : (A,) float array
        Largest rate of the rest length [m/s] (``inf``: none).
    time_constant : (A,) float array
        The drive's first-order lag [s] (0: none).
    max_tension : (A,) float array
        Largest tension [N] (``inf``: none).
    """

    tendons: np.ndarray
    min_rest_length: np.ndarray
    max_rest_length: np.ndarray
    max_rate: np.ndarray
    time_constant: np.ndarray
    max_tension: np.ndarray

    @property
    def size(self) -> int:
        """``A``, the number of actuators."""
        return int(self.tendons.size)

    @property
    def dynamic(self) -> bool:
        """True if some actuator has a rate limit or a lag (its control moves continuously)."""
        return bool(np.any(np.isfinite(self.max_rate)) or np.any(self.time_constant > 0))

    def command_bounds(self, structure: Structure) -> tuple[np.ndarray, np.ndarray]:
        """The controls ``u`` (A,) [m] the bounds admit, ``(low, high)``: ``L0 - max`` and
        ``L0 - min`` of each actuated tendon."""
        rest0 = structure.tendon_rest_length[self.tendons]
        return rest0 - self.max_rest_length, rest0 - self.min_rest_length

    def settings(self, structure: Structure) -> dict[str, Any]:
        """The actuators as plain data (tendon names, limits; ``inf`` as None), for a run's
        settings record."""

        def listed(x: np.ndarray) -> list[float | None]:
            return [float(v) if math.isfinite(v) else None for v in x]

        return dict(
            tendons=[structure.tendon_name[s] for s in self.tendons],
            min_rest_length=listed(self.min_rest_length),
            max_rest_length=listed(self.max_rest_length),
            max_rate=listed(self.max_rate),
            time_constant=listed(self.time_constant),
            max_tension=listed(self.max_tension),
        )


def _per_actuator(
    value: Any, A: int, name: str, *, low: float, allow_inf: bool, strict: bool = False
) -> np.ndarray:
    """``value`` (a number or A numbers) as (A,) floats ``>= low`` (``> low`` if ``strict``);
    ``ValueError`` naming it."""
    try:
        x = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number or {A} numbers, got {value!r:.60}") from None
    if x.ndim == 0:
        x = np.full(A, float(x))
    if x.shape != (A,):
        raise ValueError(f"{name}: expected a number or {A} numbers, got shape {x.shape}")
    bad = np.isnan(x) | ((x <= low) if strict else (x < low)) | (~allow_inf & np.isinf(x))
    if np.any(bad):
        i = int(np.argmax(bad))
        bound = (f"> {low:g}" if strict else f">= {low:g}") + ("" if allow_inf else ", finite")
        raise ValueError(f"{name}[{i}]: must be {bound}, got {x[i]!r}")
    return x


def actuators(
    structure: Structure,
    tendons: Sequence[str | int] | None = None,
    *,
    min_rest_length: Any = 0.0,
    max_rest_length: Any = math.inf,
    max_rate: Any = math.inf,
    time_constant: Any = 0.0,
    max_tension: Any = math.inf,
    winch: Winch | None = None,
) -> Actuators:
    """Actuators on ``tendons`` of ``structure`` (names or indices; None: every tendon).

    Each limit is a number for all or one per actuator, in SI units (see :class:`Actuators`).
    A ``winch`` sets ``max_rate`` and ``max_tension`` (then not given separately).  The
    tendons' rest lengths must lie within the bounds.

    Raises
    ------
    ValueError
        Naming the argument (and the actuator) that is out of range, or a tendon twice.
    KeyError
        For a tendon name the structure does not have.
    """
    S = structure.n_tendons
    if tendons is None:
        index = np.arange(S)
    else:
        index = np.array(
            [
                t if isinstance(t, (int, np.integer)) else structure.tendon_index(str(t))
                for t in tendons
            ],
            dtype=np.int64,
        )
        if index.size == 0:
            raise ValueError("tendons: need at least one actuated tendon")
        if np.any((index < 0) | (index >= S)):
            raise ValueError(f"tendons: indices must be in [0, {S}), got {index.tolist()}")
        if np.unique(index).size != index.size:
            raise ValueError("tendons: a tendon is listed twice")
    A = index.size
    if winch is not None:
        if not (
            np.all(np.isinf(np.asarray(max_rate, dtype=float)))
            and np.all(np.isinf(np.asarray(max_tension, dtype=float)))
        ):
            raise ValueError("winch: gives max_rate and max_tension; do not set them as well")
        max_rate, max_tension = winch.max_rate, winch.max_tension
    low = _per_actuator(min_rest_length, A, "min_rest_length", low=0.0, allow_inf=False)
    high = _per_actuator(max_rest_length, A, "max_rest_length", low=0.0, allow_inf=True)
    if np.any(high < low):
        i = int(np.argmax(high < low))
        raise ValueError(
            f"max_rest_length[{i}]: {high[i]:g} m is below min_rest_length {low[i]:g} m"
        )
    rest0 = structure.tendon_rest_length[index]
    outside = (rest0 < low) | (rest0 > high)
    if np.any(outside):
        i = int(np.argmax(outside))
        raise ValueError(
            f"tendons[{i}]: rest length {rest0[i]:g} m of tendon "
            f"{structure.tendon_name[index[i]]!r} is outside [{low[i]:g}, {high[i]:g}] m"
        )
    return Actuators(
        tendons=index,
        min_rest_length=low,
        max_rest_length=high,
        max_rate=_per_actuator(max_rate, A, "max_rate", low=0.0, allow_inf=True, strict=True),
        time_constant=_per_actuator(time_constant, A, "time_constant", low=0.0, allow_inf=False),
        max_tension=_per_actuator(
            max_tension, A, "max_tension", low=0.0, allow_inf=True, strict=True
        ),
    )
