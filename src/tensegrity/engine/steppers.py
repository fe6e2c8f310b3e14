"""Integrators behind one small protocol, as the run loop drives them (:class:`Stepper`):
``step(bound)`` takes one accepted step not past ``bound``, ``dense()`` interpolates inside it,
``retreat(to)`` discards it to head for a located switch at ``to``, ``resume()`` goes on at the
step size of before once there, ``restart(y)`` continues from a changed state (after a
projection or a controller's update), ``switch_distance(t, ...)`` tells how far tendons are
from changing taut/slack state at a time inside the last step, and ``memory()`` is what a
checkpoint must keep to continue exactly (:class:`StepperMemory`).

- :class:`DOP853` — the default: ``scipy.integrate.DOP853``'s method, coefficients, error norm
  and step-size law, its stages evaluated in compiled code (:mod:`tensegrity.engine.compiled`).
  The step size carries over a projection or a located switch (no restart from an initial
  guess).
- :class:`ScipyMethod` — any other ``scipy.integrate`` method (``Radau``, ``BDF``, ...) with the
  compiled right-hand side.
- :class:`RK4` — classical fixed-step RK4; :meth:`RK4.advance` runs many steps in one compiled
  call (projection and blow-up checks included) when the inputs are constant.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np

from tensegrity.engine import compiled
from tensegrity.engine.system import CompiledSystem

if TYPE_CHECKING:  # (imported when used: scipy.integrate costs 0.15 s of a start, measured)
    from scipy.integrate import OdeSolver


class IntegrationError(RuntimeError):
    """The integrator could not take a step (e.g. the step size fell below its minimum)."""


class StepperMemory(NamedTuple):
    """What an adaptive stepper carries from one step to the next besides ``(t, y)``: the first
    stage ``f(t, y)`` (m,) and the step sizes [s] (empty and zeros where a stepper keeps none)."""

    first_stage: np.ndarray
    step: float
    step_before: float


class Stepper(Protocol):
    """What the run loop needs of an adaptive integrator; ``t``, ``y`` the current time and
    state, ``t_old`` the start of the last step, ``nfev`` right-hand-side evaluations so far,
    ``provisional`` whether the last step is a rejected attempt kept to locate a switch in it."""

    t: float
    t_old: float
    y: np.ndarray
    provisional: bool

    @property
    def nfev(self) -> int:
        """Right-hand-side evaluations so far (an attribute, or a property: read only here)."""

    def step(self, bound: float, taut: np.ndarray | None = None) -> None:
        """One accepted step, ending at or before ``bound`` (see :meth:`DOP853.step`)."""

    def dense(self) -> Callable[[float], np.ndarray]:
        """``y(t)`` inside the last step."""

    def retreat(self, to: float) -> None:
        """Discard the last step (back to ``(t_old, y_old)``) and head for ``to``."""

    def resume(self) -> None:
        """Arrived at the time given to :meth:`retreat`: go on with the step size of before."""

    def accept(self) -> None:
        """The last step is kept: the next starts at its end."""

    def restart(self, y: np.ndarray) -> None:
        """Continue from ``y`` at the current time (after a projection)."""

    def tensions(self) -> np.ndarray:
        """Tensions (S,) [N] at the current state, kernel order (a view of the work buffer)."""

    def switch_distance(self, t: float, candidates: np.ndarray, was_taut: np.ndarray) -> np.ndarray:
        """How far each of ``candidates`` (kernel positions) is from leaving its state
        ``was_taut`` at ``t`` inside the last step (:func:`compiled.switch_distance`; ``<= 0``:
        it has switched)."""

    def memory(self) -> StepperMemory:
        """What a checkpoint keeps to continue from the current state exactly."""


def _rms(x: np.ndarray) -> float:
    return float(np.linalg.norm(x) / np.sqrt(x.size))


class DOP853:
    """Explicit Runge-Kutta of order 8(5,3), adaptive (``rtol``, ``atol``)."""

    SAFETY, MIN_FACTOR, MAX_FACTOR, EXPONENT = 0.9, 0.2, 10.0, -1.0 / 8.0

    def __init__(
        self,
        system: CompiledSystem,
        t0: float,
        y0: np.ndarray,
        *,
        rtol: float,
        atol: float,
        t_end: float,
        memory: StepperMemory | None = None,
    ) -> None:
        """Start at ``(t0, y0)`` with Hairer's initial step, or continue with ``memory`` (of a
        checkpoint) exactly as the stepper that made it would have."""
        self.system, self.rtol, self.atol = system, rtol, atol
        m = system.m
        self.K = np.zeros((compiled.DOP853_C.size, m))
        self._stage, self._F = np.empty(m), np.empty((compiled.DOP853_DENSE_ROWS, m))
        self._scratch = (np.empty(m), np.empty(system.structure.n_tendons))
        self.t = self.t_old = float(t0)
        self.y = np.array(y0, dtype=float)
        self.y_old = self.y.copy()
        self.nfev = 0
        self.provisional = False
        self._dense_ready = False
        if memory is None:
            self._h_before = 0.0
            self._evaluate_first_stage()
            self.h = self._initial_step(t_end)
        else:
            self.K[0] = memory.first_stage
            self.h, self._h_before = memory.step, memory.step_before

    def _inputs(self, t: float, h: float) -> tuple:
        return self.system.stage_inputs(t + compiled.DOP853_C * h)

    def _evaluate_first_stage(self) -> None:
        compiled.ode_rhs(
            self.y, self.K[0], 0, self.system.system, self._inputs(self.t, 0.0), self.system.work
        )
        self.nfev += 1

    def _initial_step(self, t_end: float) -> float:
        """Hairer, Norsett and Wanner's initial step (II.4), as ``scipy``'s."""
        y0, f0 = self.y, self.K[0].copy()
        scale = self.atol + np.abs(y0) * self.rtol
        d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, t_end - self.t)
        f1 = np.empty_like(y0)
        compiled.ode_rhs(
            y0 + h0 * f0,
            f1,
            0,
            self.system.system,
            self.system.stage_inputs(np.array([self.t + h0])),
            self.system.work,
        )
        self.nfev += 1
        compiled.ode_rhs(
            y0, self.K[0], 0, self.system.system, self._inputs(self.t, 0.0), self.system.work
        )  # leave the work buffers at the current state
        self.nfev += 1
        d2 = _rms((f1 - f0) / scale) / h0
        h1 = (
            max(1e-6, h0 * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1 / 8)
        )
        return min(100 * h0, h1, t_end - self.t)

    def step(self, bound: float, taut: np.ndarray | None = None) -> None:
        """One step not past ``bound``; with ``taut`` (kernel order), a rejected attempt whose
        end shows a tendon switched is returned as the step (:attr:`provisional` True): the loop
        then locates the switch on its dense output and retakes the step up to it, instead of
        shrinking the step until the kink falls out of it."""
        t, h = self.t, self.h
        self.provisional = False
        min_step = 10 * abs(np.nextafter(t, np.inf) - t)
        rejected = False
        y_new = np.empty_like(self.y)
        while True:
            h = max(min(h, bound - t), min_step)
            if t + h > bound or bound - (t + h) < min_step:
                h = bound - t
            error = compiled.dop853_attempt(
                self.y,
                h,
                self.K,
                y_new,
                self._stage,
                self.rtol,
                self.atol,
                self.system.system,
                self._inputs(t, h),
                self.system.work,
            )
            self.nfev += compiled.DOP853_STAGES
            if error < 1:
                break
            if (
                taut is not None
                and np.isfinite(error)
                and np.any((self.system.work[2] > 0) != taut)
            ):
                self.provisional = True
                break
            if not np.isfinite(error):
                factor = self.MIN_FACTOR
            else:
                factor = max(self.MIN_FACTOR, self.SAFETY * error**self.EXPONENT)
            h *= factor
            rejected = True
            if h < min_step:
                raise IntegrationError(
                    f"DOP853 failed at t = {t:.9g} s: required step size is "
                    "less than spacing between numbers"
                )
        if not self.provisional:
            factor = (
                self.MAX_FACTOR
                if error == 0
                else min(self.MAX_FACTOR, self.SAFETY * error**self.EXPONENT)
            )
            self.h = h * (min(1.0, factor) if rejected else factor)
        self.t_old, self.y_old = t, self.y
        self.t = bound if h == bound - t else t + h
        self.y = y_new
        self._dense_ready = False

    def accept(self) -> None:
        """Make the last step's end the first stage of the next (first same as last)."""
        self.K[0] = self.K[compiled.DOP853_STAGES]

    def dense(self) -> Callable[[float], np.ndarray]:
        if not self._dense_ready:
            h = self.t - self.t_old
            compiled.dop853_dense(
                self.y_old,
                self.y,
                h,
                self.K,
                self._F,
                self._stage,
                self.system.system,
                self._inputs(self.t_old, h),
                self.system.work,
            )
            self.nfev += 3
            self._dense_ready = True
        F, y_old, t_old, h = self._F, self.y_old, self.t_old, self.t - self.t_old

        def at(t: float) -> np.ndarray:
            out = np.empty_like(y_old)
            compiled.dop853_interpolate(F, y_old, (t - t_old) / h, out)
            return out

        return at

    def retreat(self, to: float) -> None:
        self.t, self.y = self.t_old, self.y_old
        self._dense_ready = False
        self._h_before, self.h = self.h, to - self.t

    def resume(self) -> None:
        self.h = max(self.h, self._h_before)

    def restart(self, y: np.ndarray) -> None:
        self.y = y
        self._evaluate_first_stage()

    def tensions(self) -> np.ndarray:
        return self.system.work[2]

    def switch_distance(self, t: float, candidates: np.ndarray, was_taut: np.ndarray) -> np.ndarray:
        self.dense()
        system, (y, indicator) = self.system, self._scratch
        out = np.empty(candidates.size)
        compiled.switch_distance(
            self._F,
            self.y_old,
            (t - self.t_old) / (self.t - self.t_old),
            y,
            system.system,
            system.rest_row(t),
            system.work,
            system.scratch_p,
            system.scratch_v,
            indicator,
            candidates,
            was_taut,
            out,
        )
        return out

    def memory(self) -> StepperMemory:
        return StepperMemory(self.K[0].copy(), self.h, self._h_before)


class ScipyMethod:
    """A ``scipy.integrate`` ``OdeSolver`` (``RK45``, ``Radau``, ``BDF``, ...) on the compiled
    right-hand side; restarted (a new initial step) after a projection or at a switch."""

    def __init__(
        self,
        system: CompiledSystem,
        t0: float,
        y0: np.ndarray,
        *,
        method: str,
        rtol: float,
        atol: float,
        t_end: float,
    ) -> None:
        from scipy import integrate

        self.system, self.rtol, self.atol = system, rtol, atol
        self.solver_class = getattr(integrate, method)
        self.name = method
        self.provisional = False
        self._nfev_before = 0  # of earlier solvers and of tension evaluations
        self._solver: OdeSolver = self._new_solver(t0, y0, t_end)

    def _rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        dy = np.empty_like(y)
        compiled.ode_rhs(
            np.ascontiguousarray(y),
            dy,
            0,
            self.system.system,
            self.system.stage_inputs(np.array([t])),
            self.system.work,
        )
        return dy

    def _new_solver(self, t0: float, y0: np.ndarray, bound: float) -> OdeSolver:
        """A solver from ``(t0, y0)`` towards ``bound``; the stepper's state set to its start."""
        solver = self.solver_class(self._rhs, t0, y0, bound, rtol=self.rtol, atol=self.atol)
        self._bound = bound
        self.t = self.t_old = float(t0)
        self.y = np.array(y0, dtype=float)
        self.y_old = self.y
        self._dense: Callable[[float], np.ndarray] | None = None
        self._tensions_here = False
        return solver

    def _start(self, t0: float, y0: np.ndarray, bound: float) -> None:
        """Start again from ``(t0, y0)`` towards ``bound`` with a new solver (the evaluations of
        the one before counted)."""
        self._nfev_before += self._solver.nfev
        self._solver = self._new_solver(t0, y0, bound)

    @property
    def nfev(self) -> int:
        return self._nfev_before + self._solver.nfev

    def step(self, bound: float, taut: np.ndarray | None = None) -> None:
        if bound != self._bound:
            self._start(self.t, self.y, bound)
        self.t_old, self.y_old = self.t, self.y
        message = self._solver.step()
        if self._solver.status == "failed":
            raise IntegrationError(f"{self.name} failed at t = {self._solver.t:.9g} s: {message}")
        self.t, self.y, self._dense = self._solver.t, self._solver.y, None
        self._tensions_here = False

    def accept(self) -> None:
        pass

    def dense(self) -> Callable[[float], np.ndarray]:
        dense = self._dense
        if dense is None:
            dense = self._dense = self._solver.dense_output()
        return dense

    def retreat(self, to: float) -> None:
        self._start(self.t_old, self.y_old, self._bound)

    def resume(self) -> None:
        pass

    def restart(self, y: np.ndarray) -> None:
        self._start(self.t, y, self._bound)

    def switch_distance(self, t: float, candidates: np.ndarray, was_taut: np.ndarray) -> np.ndarray:
        system = self.system
        indicator = np.empty(system.structure.n_tendons)
        compiled.switch_indicator(
            np.ascontiguousarray(self.dense()(t)),
            system.system,
            system.rest_row(t),
            system.work,
            system.scratch_p,
            system.scratch_v,
            indicator,
        )
        return np.where(was_taut[candidates], indicator[candidates], -indicator[candidates])

    def memory(self) -> StepperMemory:
        """Nothing: a ``scipy`` solver restarts at every boundary of a run (checkpoints,
        controller updates) in any case, so ``(t, y)`` is all it needs."""
        return StepperMemory(np.zeros(0), 0.0, 0.0)

    def tensions(self) -> np.ndarray:
        if not self._tensions_here:  # the solver's last evaluation need not be at its state
            self._rhs(self.t, self.y)
            self._nfev_before += 1
            self._tensions_here = True
        return self.system.work[2]


class RK4:
    """Classical fixed-step RK4; the state is projected after every step.  The run loop keeps
    the time (``t``, set after each :meth:`advance`)."""

    def __init__(self, system: CompiledSystem, t0: float, y0: np.ndarray) -> None:
        self.system = system
        m = system.m
        self.K, self._stage, self.y_end = np.zeros((4, m)), np.empty(m), np.empty(m)
        self.t = float(t0)
        self.y = np.array(y0, dtype=float)
        self.nfev = 0
        #: why the last :meth:`advance` stopped with ``CHECK_INPUT`` (the inputs' ValueError)
        self.input_error = ""

    def advance(
        self, n_steps: int, h: float, limits: tuple, monitor: np.ndarray
    ) -> tuple[int, int, float]:
        """Up to ``n_steps`` steps of ``h`` [s] from ``t``, each checked
        (:func:`compiled.check_state`) and projected.  Returns ``(steps, check code, check
        value)``; ``self.y_end`` is the last step's end before projection.  Constant or
        tabulated inputs: one compiled call; a Python callable among them: one per step, with
        the inputs at its stage times.  Inputs that cannot be used (a rest length would be
        negative) stop it before that step with ``CHECK_INPUT``, the reason in
        :attr:`input_error`."""
        system = self.system
        if system.inputs.constant or system.tables is not None:
            return self._stretch(n_steps, h, limits, monitor)
        steps, code, value = 0, compiled.CHECK_OK, 0.0
        while steps < n_steps and code == compiled.CHECK_OK:
            stages = self.t + steps * h + compiled.RK4_C * h
            try:
                inputs = system.stage_inputs(stages)
            except ValueError as exc:
                self.input_error = str(exc)
                code, value = compiled.CHECK_INPUT, np.nan
                break
            one, code, value = compiled.rk4_segment(
                self.y,
                self.t + steps * h,
                h,
                1,
                self.K,
                self._stage,
                self.y_end,
                system.system,
                inputs,
                None,
                system.work,
                limits,
                monitor,
            )
            steps += one
        self.nfev += 4 * steps
        return steps, code, value

    def _stretch(
        self, n_steps: int, h: float, limits: tuple, monitor: np.ndarray
    ) -> tuple[int, int, float]:
        """:meth:`advance` in one compiled call (the inputs constant or tabulated)."""
        system = self.system
        tables = system.tables
        stages = self.t + compiled.RK4_C * h
        steps, code, value = compiled.rk4_segment(
            self.y,
            self.t,
            h,
            n_steps,
            self.K,
            self._stage,
            self.y_end,
            system.system,
            system.stage_inputs(stages if tables is not None else stages[:1]),
            tables,
            system.work,
            limits,
            monitor,
        )
        self.nfev += 4 * steps
        if code == compiled.CHECK_INPUT:
            try:
                system.inputs.rest_length(self.t + steps * h + compiled.RK4_C * h)
            except ValueError as exc:  # (it raises: the message names the tendon and time)
                self.input_error = str(exc)
        return steps, code, value

    def memory(self) -> StepperMemory:
        """Nothing: a step starts from ``(t, y)`` alone (the loop keeps the steps taken)."""
        return StepperMemory(np.zeros(0), 0.0, 0.0)
