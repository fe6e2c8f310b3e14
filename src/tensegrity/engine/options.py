"""The options of a run, defined once: ``simulate``, the CLI, streamed runs and sweeps take them
from here (:class:`Options`), and a run's ``settings`` record is made from them."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

#: Adaptive methods the engine integrates in compiled code (the default first).
COMPILED_ADAPTIVE_METHODS = ("DOP853",)
#: ``scipy.integrate`` methods still accepted, stepped through ``scipy`` with the compiled
#: right-hand side (implicit ones, for stiff problems).
SCIPY_METHODS = ("RK45", "RK23", "Radau", "BDF", "LSODA")
ADAPTIVE_METHODS = COMPILED_ADAPTIVE_METHODS + SCIPY_METHODS
FIXED_STEP_METHODS = ("rk4",)


@dataclasses.dataclass(frozen=True)
class Options:
    """How to integrate, sample and check a run (SI units).

    Attributes
    ----------
    method : ``"DOP853"`` (adaptive, order 8, the default), another ``scipy.integrate`` method
        (``"RK45"``, ``"Radau"``, ...) or ``"rk4"`` (classical fixed-step, needs ``dt``).
    rtol, atol : adaptive methods' relative and absolute tolerances.
    dt : fixed step [s] (``"rk4"`` only).
    sample_dt : output spacing [s]; None: a thousandth of the span.
    locate_switches : adaptive methods: find each slack/taut switch of a tendon inside a step
        and end a step there, so that no step straddles a kink of the tension law.
    steady_state : stop at the first sample where every node's speed is below ``velocity_tol``
        [m/s] and its acceleration below ``acceleration_tol`` [m/s^2].
    projection_tol : adaptive methods project onto the rod, joint and support constraints when
        a relative rod-length error, or a constraint violation in metres, exceeds it; ``"rk4"``
        projects after every step.
    max_rod_length_error, max_energy_growth : blow-up detection: the run fails when, at the end
        of a step, the state is not finite, a relative rod-length error exceeds
        ``max_rod_length_error`` (joints and supports: that times the longest rod, at least 1
        m), or the energy balance has grown by more than ``max_energy_growth`` times the largest
        energy magnitude seen.
    """

    method: str = "DOP853"
    rtol: float = 1e-9
    atol: float = 1e-12
    dt: float | None = None
    sample_dt: float | None = None
    locate_switches: bool = True
    steady_state: bool = False
    velocity_tol: float = 1e-6
    acceleration_tol: float = 1e-6
    projection_tol: float = 1e-12
    max_rod_length_error: float = 1e-3
    max_energy_growth: float = 0.1

    def __post_init__(self) -> None:
        if self.method not in ADAPTIVE_METHODS + FIXED_STEP_METHODS:
            raise ValueError(
                f"method: unknown method {self.method!r}; choose one of "
                f"{', '.join(ADAPTIVE_METHODS + FIXED_STEP_METHODS)}"
            )
        if self.fixed_step and self.dt is None:
            raise ValueError(f"dt: method {self.method!r} is fixed-step and needs a step dt")
        if self.dt is not None and not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt: must be > 0, got {self.dt!r}")
        if self.sample_dt is not None and not (
            math.isfinite(self.sample_dt) and self.sample_dt > 0
        ):
            raise ValueError(f"sample_dt: must be > 0, got {self.sample_dt!r}")
        for field in (
            "rtol",
            "atol",
            "velocity_tol",
            "acceleration_tol",
            "projection_tol",
            "max_rod_length_error",
            "max_energy_growth",
        ):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and value > 0):
                raise ValueError(f"{field}: must be > 0, got {value!r}")

    @property
    def fixed_step(self) -> bool:
        """True for a fixed-step method."""
        return self.method in FIXED_STEP_METHODS

    def sample_spacing(self, t0: float, t_end: float) -> float:
        """``sample_dt``, or a thousandth of ``t_end - t0`` [s]."""
        return (t_end - t0) / 1000 if self.sample_dt is None else float(self.sample_dt)

    def settings(self, t0: float, t_end: float, **inputs: Any) -> dict[str, Any]:
        """The JSON-friendly record of a run (``SimulationResult.settings``): ``t_span``, the
        options a result depends on, and what ``inputs`` were given (see
        :meth:`tensegrity.engine.inputs.Inputs.settings`)."""
        return dict(
            t_span=[t0, t_end],
            method=self.method,
            rtol=self.rtol,
            atol=self.atol,
            dt=self.dt,
            sample_dt=self.sample_spacing(t0, t_end),
            locate_switches=self.locate_switches,
            steady_state=self.steady_state,
            velocity_tol=self.velocity_tol,
            acceleration_tol=self.acceleration_tol,
            **inputs,
        )
