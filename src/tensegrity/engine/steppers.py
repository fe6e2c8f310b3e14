"""Integrators behind one small protocol, as the run loop drives them (:class:`Stepper`):
``step(bound)`` takes one accepted step not past ``bound``, ``dense()`` interpolates inside it,
``retreat(to)`` discards it to head for a located switch at ``to``, ``resume()`` goes on at the
step size of before once there, ``restart(y)`` continues from a changed state (after a
projection or a controller's update), ``evaluation()`` is the data record of an evaluation at
the current state and ``step_span()`` the last step, for the events
(:mod:`tensegrity.engine.events`), and ``memory()`` is what a checkpoint must keep to continue
exactly (:class:`StepperMemory`).

The default method, DOP853, runs its whole loop compiled (:mod:`tensegrity.engine.dop853`); here
are the others:

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
from tensegrity.physics.records import Data

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

    def evaluation(self) -> Data:
        """The system's data record holding an evaluation at the current state (its tensions:
        :func:`tensegrity.engine.events.events_crossed`)."""

    def step_span(self) -> tuple[float, float, np.ndarray, np.ndarray]:
        """The last step's ``(t_old, t, F, y_old)`` for
        :func:`tensegrity.engine.events.locate_event` (``F``, ``y_old`` empty: the state inside
        it comes from :meth:`dense`)."""

    def memory(self) -> StepperMemory:
        """What a checkpoint keeps to continue from the current state exactly."""


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
        data = self.system.stage_inputs(np.array([t]))
        compiled.ode_rhs_entry(self.system.model, data, 0, np.ascontiguousarray(y), dy)
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

    def step_span(self) -> tuple[float, float, np.ndarray, np.ndarray]:
        return self.t_old, self.t, np.zeros((0, 0)), np.zeros(0)

    def memory(self) -> StepperMemory:
        """Nothing: a ``scipy`` solver restarts at every boundary of a run (checkpoints,
        controller updates) in any case, so ``(t, y)`` is all it needs."""
        return StepperMemory(np.zeros(0), 0.0, 0.0)

    def evaluation(self) -> Data:
        if not self._tensions_here:  # the solver's last evaluation need not be at its state
            self._rhs(self.t, self.y)
            self._nfev_before += 1
            self._tensions_here = True
        return self.system.data


class RK4:
    """Classical fixed-step RK4; the state is projected after every step.  The run loop keeps
    the time (``t``, set after each :meth:`advance`)."""

    def __init__(self, system: CompiledSystem, t0: float, y0: np.ndarray) -> None:
        self.system = system
        m = system.m
        #: a step's scratch (:func:`compiled.rk4_step`); ``first`` = ``f(t, y)`` at the start of
        #: the last step taken with ``keep_first``
        self.work_step = system.rk4_work()
        self.first = self.work_step[3]
        self.y_end = np.empty(m)
        self.t = float(t0)
        self.y = np.array(y0, dtype=float)
        self.nfev = 0
        #: why the last :meth:`advance` stopped with ``CHECK_INPUT`` (the inputs' ValueError)
        self.input_error = ""

    def advance(self, n_steps: int, h: float, *, keep_first: bool) -> tuple[int, int, float]:
        """Up to ``n_steps`` steps of ``h`` [s] from ``t``, each checked
        (:func:`compiled.check_state`, with the system's limits and monitor) and projected, in
        one compiled call (:func:`compiled.rk4_segment`; inputs that vary are made at each
        step's stage times, Python functions through the callback).  Returns ``(steps, check
        code, check value)``; ``self.y_end`` is the last step's end before projection.  Inputs
        that cannot be used (a rest length would be negative, or a function raised a
        ``ValueError``) stop it before that step with ``CHECK_INPUT``, the reason in
        :attr:`input_error`; another exception of a function is raised.  ``keep_first``:
        :attr:`first` receives ``f(t, y)`` at the start of each step."""
        system = self.system
        steps, code, value = compiled.rk4_segment(
            system.model,
            system.input_buffers(compiled.RK4_C.size),
            self.y,
            self.y_end,
            self.work_step,
            keep_first,
            self.t,
            h,
            n_steps,
        )
        self.nfev += 4 * steps
        if code == compiled.CHECK_INPUT:
            try:
                system.raise_input_error()
                system.inputs.rest_length(self.t + steps * h + compiled.RK4_C * h)
            except ValueError as exc:  # (the message names the tendon and time)
                self.input_error = str(exc)
        return steps, code, value

    def memory(self) -> StepperMemory:
        """Nothing: a step starts from ``(t, y)`` alone (the loop keeps the steps taken)."""
        return StepperMemory(np.zeros(0), 0.0, 0.0)
