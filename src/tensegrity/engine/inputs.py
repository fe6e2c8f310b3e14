"""The inputs of a run: control ``u`` (rest-length changes, ``Lbar = L0 - u``), external nodal
forces ``w`` and gravity, evaluated at the stage times of a step.

Each of ``u`` and ``w`` is None, a constant array, a table
(:class:`tensegrity.model.loads.ForceTable`, :class:`tensegrity.model.loads.ControlTable`: linear
between rows, evaluated for all stages of a step at once) or a Python callable of time, called
once per stage.  The control's rate ``du/dt`` (for the work of the control) is the table's
slope, or for a callable a central difference (two more calls per stage).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tensegrity.model.actuators import Actuators
from tensegrity.model.ground import planes_of
from tensegrity.model.loads import ControlTable, ForceTable
from tensegrity.model.structure import Structure


def _check(
    value: np.ndarray, shape: tuple[int, ...], field: str, t: float | None = None
) -> np.ndarray:
    at = "" if t is None else f" at t = {t}"
    if value.shape != shape:
        raise ValueError(f"{field}: expected shape {shape}{at}, got {value.shape}")
    if not np.all(np.isfinite(value)):
        raise ValueError(f"{field}: must be finite{at}")
    return value


def _numbers(value: Any, field: str, expected: str) -> np.ndarray:
    """``value`` as a float array; ``ValueError`` naming ``field`` and what was ``expected``
    if it is not numbers."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(
            f"{field}: expected {expected}, got {type(value).__name__} {value!r:.60}"
        ) from None


class _Signal:
    """One input, ``None``, a constant, a table or a callable, evaluated at many times."""

    def __init__(self, value: Any, shape: tuple[int, ...], field: str) -> None:
        self.shape, self.field, self.value = shape, field, value
        if value is None or isinstance(value, (ForceTable, ControlTable)):
            self.kind = "none" if value is None else "table"
            if value is not None:
                _check(np.asarray(value.values[0]), shape, field)
        elif callable(value):
            self.kind = "function"
        else:
            self.kind = "constant"
            expected = f"numbers of shape {shape}, a table or a function of time"
            self.value = _check(_numbers(value, field, expected), shape, field)
            self.value.setflags(write=False)

    @property
    def constant(self) -> bool:
        return self.kind in ("none", "constant")

    def at(self, times: np.ndarray) -> np.ndarray | None:
        """Values (K, *shape) at ``times`` (K,), or None."""
        if self.kind == "none":
            return None
        if self.kind == "constant":
            return self.value[None]
        if self.kind == "table":
            return self.value.at(times)
        return self._calls(times)

    def _calls(self, times: np.ndarray) -> np.ndarray:
        """Values (K, *shape) of the callable at ``times`` (K,), one call each, checked."""
        return np.stack(
            [
                _check(
                    np.asarray(self.value(float(t)), dtype=float), self.shape, self.field, float(t)
                )
                for t in times
            ]
        )

    def rate(self, times: np.ndarray) -> np.ndarray | None:
        """Time derivatives (K, *shape) at ``times``, or None if constant."""
        if self.constant:
            return None
        if self.kind == "table":
            return self.value.slope(times)
        h = 1e-6 * np.maximum(1.0, np.abs(times))
        return (self._calls(times + h) - self._calls(times - h)) / (2 * h)[:, None]

    def setting(self) -> Any:
        """How the run's settings record this input."""
        return (
            "function"
            if self.kind == "function"
            else ("table" if self.kind == "table" else self.kind == "constant")
        )


class Inputs:
    """Control, external force, gravity and ground of a run on ``structure``, validated.

    Attributes ``constant`` (all inputs constant in time), ``gravity`` ((dim,) or None),
    ``ground`` (a tuple of :class:`~tensegrity.model.ground.Plane`, empty: none) and
    ``contact_radius`` (the radius [m] of the rods' ends as contact points).
    """

    def __init__(
        self,
        structure: Structure,
        *,
        control: Any = None,
        external_force: Any = None,
        gravity: Any = None,
        ground: Any = None,
        contact_radius: Any = 0.0,
        actuators: Actuators | None = None,
    ) -> None:
        self.structure = structure
        self.control = _Signal(control, (structure.n_tendons,), "control")
        self.external_force = _Signal(
            external_force, (structure.n_nodes, structure.dim), "external_force"
        )
        if gravity is not None:
            gravity = _numbers(gravity, "gravity", f"{structure.dim} numbers [m/s^2]")
            if gravity.shape != (structure.dim,) or not np.all(np.isfinite(gravity)):
                shown = np.array2string(gravity.ravel()[:6], separator=", ")
                raise ValueError(
                    f"gravity: expected {structure.dim} finite numbers [m/s^2], got shape "
                    f"{gravity.shape}: {shown}"
                )
        self.gravity = gravity
        self.ground = () if ground is None else planes_of(ground)
        radius = _numbers(contact_radius, "contact_radius", "a number >= 0 [m]")
        if radius.shape != () or not (np.isfinite(radius) and radius >= 0):
            raise ValueError(f"contact_radius: must be a number >= 0 [m], got {contact_radius!r}")
        self.contact_radius = float(radius)
        if self.ground and structure.dim != 3:
            raise ValueError("ground: contact is for 3-D structures (this one is planar)")
        if actuators is not None:
            if not isinstance(actuators, Actuators):
                raise TypeError(
                    "actuators: expected a tensegrity.model.actuators.Actuators (made by "
                    f"actuators(structure, ...)), got {type(actuators).__name__}"
                )
            if actuators.tendons.size and actuators.tendons.max() >= structure.n_tendons:
                raise ValueError("actuators: made for another structure (a tendon out of range)")
            if self.control.kind != "none":
                raise ValueError(
                    "control: the actuated tendons follow their commands (a controller's); give "
                    "actuators or a control, not both"
                )
        self.actuators = actuators
        self.constant = self.control.constant and self.external_force.constant and actuators is None

    def rest_length(self, times: np.ndarray) -> np.ndarray:
        """``Lbar = L0 - u`` (K, S) [m] at ``times``; raises ``ValueError`` naming the first
        tendon whose rest length would be negative."""
        u = self.control.at(times)
        rest = (
            self.structure.tendon_rest_length[None]
            if u is None
            else (self.structure.tendon_rest_length - u)
        )
        if u is not None and np.any(rest < 0):
            k, s = np.argwhere(rest < 0)[0]
            raise ValueError(
                f"{self.control.field}[{s}]: rest length "
                f"{self.structure.tendon_rest_length[s]:g} - {u[k, s]:g} is negative at "
                f"t = {times[min(k, len(times) - 1)]:g} s"
            )
        return rest

    def settings(self) -> dict[str, Any]:
        """``control``, ``external_force`` (False, True, ``"table"``, ``"function"``) and
        ``gravity`` (a list or None), for a run's settings record; with planes, ``ground`` (each
        plane's fields) and ``contact_radius``."""
        settings: dict[str, Any] = dict(
            gravity=None if self.gravity is None else self.gravity.tolist(),
            control=self.control.setting(),
            external_force=self.external_force.setting(),
        )
        if self.ground:
            settings["ground"] = [plane.settings() for plane in self.ground]
            settings["contact_radius"] = self.contact_radius
        if self.actuators is not None:
            settings["actuators"] = self.actuators.settings(self.structure)
        return settings
