"""Time integrators behind one small protocol: start, step, interpolate within the last step.

``simulate`` drives an :class:`Integrator` one step at a time so that it can locate slack/taut
switches, project onto the rod constraints and stop on steady state or blow-up between steps.

- :class:`AdaptiveIntegrator` wraps ``scipy.integrate``'s ``OdeSolver`` classes (``RK45``,
  ``DOP853``, ``RK23``, ``Radau``, ``BDF``, ``LSODA``) with their error control and dense output.
- :class:`RK4` is the classical fixed-step fourth-order Runge-Kutta method, with cubic Hermite
  interpolation inside a step.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np
from scipy import integrate

RightHandSide = Callable[[float, np.ndarray], np.ndarray]

ADAPTIVE_METHODS: dict[str, type[integrate.OdeSolver]] = {
    "RK45": integrate.RK45,
    "RK23": integrate.RK23,
    "DOP853": integrate.DOP853,
    "Radau": integrate.Radau,
    "BDF": integrate.BDF,
    "LSODA": integrate.LSODA,
}
FIXED_STEP_METHODS = ("rk4",)


class IntegrationError(RuntimeError):
    """The integrator could not take a step (e.g. the step size fell below its minimum)."""


class Integrator(Protocol):
    """What ``simulate`` needs of an integrator.

    Attributes ``t``, ``y`` are the current time and state; ``t_old`` the time at the start of
    the last step; ``total_nfev`` counts right-hand-side evaluations over all (re)starts.
    """

    name: str
    adaptive: bool
    t: float
    t_old: float
    y: np.ndarray
    total_nfev: int

    def start(self, fun: RightHandSide, t0: float, y0: np.ndarray, t_bound: float) -> None:
        """(Re)start at ``(t0, y0)``, integrating toward ``t_bound``."""

    def step(self) -> None:
        """Advance one step (never past ``t_bound``)."""

    def interpolate(self, t: float | np.ndarray) -> np.ndarray:
        """State at ``t`` within the last step, shape (n,) or (n, len(t))."""


class AdaptiveIntegrator:
    """An adaptive ``scipy.integrate`` method with relative/absolute tolerances ``rtol``, ``atol``."""

    adaptive = True

    def __init__(
        self, method: str = "DOP853", *, rtol: float = 1e-9, atol: float = 1e-12,
        max_step: float = np.inf,
    ) -> None:
        if method not in ADAPTIVE_METHODS:
            raise ValueError(
                f"method: unknown method {method!r}; choose one of "
                f"{', '.join([*ADAPTIVE_METHODS, *FIXED_STEP_METHODS])}"
            )
        for field, value in (("rtol", rtol), ("atol", atol), ("max_step", max_step)):
            if not value > 0:
                raise ValueError(f"{field}: must be > 0, got {value!r}")
        self.name, self.rtol, self.atol, self.max_step = method, rtol, atol, max_step
        self._nfev_before_restart = 0
        self._solver: integrate.OdeSolver | None = None
        self._dense = None

    def start(self, fun: RightHandSide, t0: float, y0: np.ndarray, t_bound: float) -> None:
        if self._solver is not None:
            self._nfev_before_restart += self._solver.nfev
        self._solver = ADAPTIVE_METHODS[self.name](
            fun, t0, y0, t_bound, rtol=self.rtol, atol=self.atol, max_step=self.max_step
        )
        self._dense = None
        self.t_old = self.t = float(t0)

    def step(self) -> None:
        self.t_old = self._solver.t
        self._dense = None
        message = self._solver.step()
        if self._solver.status == "failed":
            raise IntegrationError(f"{self.name} failed at t = {self._solver.t:.9g} s: {message}")
        self.t = self._solver.t

    @property
    def y(self) -> np.ndarray:
        return self._solver.y

    @property
    def total_nfev(self) -> int:
        """Right-hand-side evaluations over all restarts."""
        return self._nfev_before_restart + (self._solver.nfev if self._solver is not None else 0)

    def interpolate(self, t: float | np.ndarray) -> np.ndarray:
        if self._dense is None:  # built once per step: it may cost extra evaluations
            self._dense = self._solver.dense_output()
        return self._dense(t)


class RK4:
    """Classical fixed-step Runge-Kutta of order 4 with step ``dt`` [s] (the last step may be
    shorter, to land on ``t_bound``)."""

    adaptive = False
    name = "rk4"

    def __init__(self, *, dt: float) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt: must be > 0, got {dt!r}")
        self.dt = float(dt)
        self.total_nfev = 0

    def start(self, fun: RightHandSide, t0: float, y0: np.ndarray, t_bound: float) -> None:
        self._fun, self.t_bound = fun, float(t_bound)
        self.t_old = self.t = float(t0)
        self.y = np.array(y0, dtype=float)
        self._f: np.ndarray | None = None  # f(t, y), computed when first needed
        self._previous: tuple[np.ndarray, np.ndarray] | None = None  # (y_old, f_old)

    def _eval(self, t: float, y: np.ndarray) -> np.ndarray:
        self.total_nfev += 1
        return self._fun(t, y)

    def step(self) -> None:
        t, y = self.t, self.y
        h = min(self.dt, self.t_bound - t)
        # Land exactly on t_bound rather than leave a sliver of a step.
        if self.t_bound - (t + h) < 1e-9 * self.dt:
            h = self.t_bound - t
        k1 = self._f if self._f is not None else self._eval(t, y)
        k2 = self._eval(t + h / 2, y + h / 2 * k1)
        k3 = self._eval(t + h / 2, y + h / 2 * k2)
        k4 = self._eval(t + h, y + h * k3)
        self._previous = (y, k1)
        self.y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        self.t_old, self.t = t, (self.t_bound if t + h >= self.t_bound else t + h)
        self._f = None

    def interpolate(self, t: float | np.ndarray) -> np.ndarray:
        """Cubic Hermite interpolation from the values and slopes at both ends of the step."""
        if self._f is None:
            self._f = self._eval(self.t, self.y)
        y0, f0 = self._previous
        y1, f1 = self.y, self._f
        h = self.t - self.t_old
        s = (np.asarray(t, dtype=float) - self.t_old) / h
        s2, s3 = s * s, s * s * s
        h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
        if np.ndim(s):
            return np.outer(y0, h00) + np.outer(h * f0, h10) + np.outer(y1, h01) + np.outer(h * f1, h11)
        return h00 * y0 + h10 * h * f0 + h01 * y1 + h11 * h * f1


def make_integrator(
    method: str = "DOP853", *, rtol: float = 1e-9, atol: float = 1e-12, dt: float | None = None
) -> AdaptiveIntegrator | RK4:
    """The integrator called ``method``: an adaptive scipy method, or ``"rk4"`` (needs ``dt``)."""
    if method in FIXED_STEP_METHODS:
        if dt is None:
            raise ValueError(f"dt: method {method!r} is fixed-step and needs a step dt")
        return RK4(dt=dt)
    return AdaptiveIntegrator(method, rtol=rtol, atol=atol)
