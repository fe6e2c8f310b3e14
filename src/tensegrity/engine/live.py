"""A run advanced by its caller (:class:`Live`), for a loop closed outside the engine: a
learning environment, or a controller of your own that decides the next control from the state
the last stretch ended in.

The structure, its gravity, ground and contact radius are packed once
(:class:`~tensegrity.engine.system.CompiledSystem`) and the default method's compiled stepper
(:class:`~tensegrity.engine.dop853.DOP853`) is kept between calls: :meth:`Live.advance` holds a
command of the actuators (:mod:`tensegrity.model.actuators`: rest-length bounds, rate limits,
lags; default: every tendon, a control ``u`` (S,) [m] held at once) over a stretch of time and
returns the state at its end, the events (slack/taut, contact, stick/slip) located and the
blow-up checks made as in :func:`~tensegrity.engine.simulate.simulate`.  A stretch is what the
run loop (:mod:`tensegrity.engine.loop`) does between two updates of a controller: the state at
its end equals ``simulate(..., controller=...)`` with the same controls at the same times, and one
stretch equals ``simulate(..., control=u)`` over the same span.  No samples are recorded.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tensegrity.engine import dop853
from tensegrity.engine.dop853 import DOP853
from tensegrity.engine.events import event_work, start_contacts_entry
from tensegrity.engine.loop import (
    actuator_command,
    blow_up_limits,
    check_initial,
    failure_message,
)
from tensegrity.engine.options import DEFAULT_MAX_STEPS
from tensegrity.engine.simulate import options_and_inputs
from tensegrity.engine.system import CompiledSystem
from tensegrity.model.actuators import Actuators
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import State

__all__ = ["EngineError", "Live"]


class EngineError(RuntimeError):
    """A live run failed at time ``t`` [s]: a blow-up check (the message says which), the step
    size, or ``max_steps`` steps in one stretch.  The run needs a :meth:`Live.reset`."""

    def __init__(self, message: str, t: float) -> None:
        super().__init__(message)
        self.t = t


class Live:
    """``structure`` simulated stretch by stretch by DOP853, its caller choosing each stretch's
    control (module doc).

    Parameters
    ----------
    structure : Structure
    actuators : Actuators, optional
        The actuated tendons whose commands :meth:`advance` takes (default: every tendon,
        without limits: the command is the control ``u`` (S,) [m]).
    gravity, ground, contact_radius
        As :func:`~tensegrity.engine.simulate.simulate`'s: gravity (dim,) [m/s^2], planes
        (:class:`~tensegrity.model.ground.Plane`), the rods' ends' radius [m].
    rtol, atol, projection_tol, max_rod_length_error, max_energy_growth : float
        As :func:`~tensegrity.engine.simulate.simulate`'s (defaults the same).
    max_steps : int
        Steps one :meth:`advance` may take before it fails.

    Attributes
    ----------
    t : float
        The time reached [s].
    control : (A,) array
        The command held over the last stretch [m] (after the actuators' bounds).
    nfev, nsteps, nswitches : int
        Right-hand-side evaluations, steps and located events since the last :meth:`reset`.
    """

    def __init__(
        self,
        structure: Structure,
        *,
        actuators: Actuators | None = None,
        gravity: Any = None,
        ground: Any = None,
        contact_radius: Any = 0.0,
        rtol: float = 1e-9,
        atol: float = 1e-12,
        projection_tol: float = 1e-12,
        max_rod_length_error: float = 1e-3,
        max_energy_growth: float = 0.1,
        max_steps: int = DEFAULT_MAX_STEPS,
    ) -> None:
        self.options, inputs = options_and_inputs(
            structure,
            gravity=gravity,
            ground=ground,
            contact_radius=contact_radius,
            actuators=actuators,
            rtol=rtol,
            atol=atol,
            projection_tol=projection_tol,
            max_rod_length_error=max_rod_length_error,
            max_energy_growth=max_energy_growth,
            max_steps=max_steps,
        )
        self.structure = structure
        self.system = CompiledSystem(
            structure, inputs, limits=blow_up_limits(structure, self.options), controlled=True
        )
        self.t = math.nan
        self.control = np.zeros(self.system.actuation.position.size)
        self.nfev = self.nsteps = self.nswitches = 0
        self._y = np.zeros(self.system.m)  # the state until the stepper is made
        self._stepper: DOP853 | None = None
        self._failure: str | None = "no state yet: call reset(state) first"

    def reset(self, state: State) -> None:
        """Start again from ``state`` (:class:`~tensegrity.physics.dynamics.State`, projected
        onto the rod constraints), the actuators' command and control zero.
        ``TypeError``/``ValueError`` naming ``initial`` for a state that is not one of this
        structure, ``ValueError`` naming ``ground`` for a contact point below a plane."""
        check_initial(self.structure, state)
        y = self.system.state_vector(state)
        self.system.check_contacts(y)
        self.t, self._y, self._stepper, self._failure = float(state.t), y, None, None
        self.control = np.zeros_like(self.control)
        self.system.reset_actuation()
        self.system.monitor[:] = (np.nan, 0.0, 0.0, 0.0)  # (made by the stepper's first call)
        self.nfev = self.nsteps = self.nswitches = 0

    @property
    def y(self) -> np.ndarray:
        """The engine's state ``[q, q', E_d, W_w, W_u]`` (m,) at :attr:`t` (a copy)."""
        return (self._y if self._stepper is None else self._stepper.y).copy()

    def state(self) -> State:
        """The state at :attr:`t`: coordinates [m] and rates [m/s] in the structure's order."""
        q, qdot = self.system.coordinates(self._y if self._stepper is None else self._stepper.y)
        return State(t=self.t, q=q, qdot=qdot)

    def advance(self, control: Any, duration: float) -> State:
        """Hold the actuators' command ``control`` (A,) [m] (rest lengths ``L0 - u``; clipped
        to their bounds) for ``duration`` [s] and return the state at the end.

        Raises
        ------
        ValueError
            Naming ``control`` (shape, not finite, without actuators given a rest length
            negative) or ``duration`` (not a finite number > 0).
        EngineError
            The run failed in this stretch (and every call until :meth:`reset` says so).
        """
        if self._failure is not None:
            raise EngineError(self._failure, self.t)
        u = actuator_command(self.system, np.array(control, dtype=float), self.t, "control")
        if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
            raise ValueError(f"duration: must be a finite number > 0 [s], got {duration!r}")
        self._hold(u)
        stepper = self._stepper
        if stepper is None:
            stepper = self._stepper = self._start()
        else:
            stepper.restart()
        stepper.set_counts(dict(nsteps=0, nswitches=0, nprojections=0))
        nfev = stepper.nfev
        bound = self.t + float(duration)
        work = self.system.data.contact_work
        while True:
            code, check, value = stepper.run(bound, math.inf)
            if work is not None:  # (the changes of mode are not kept)
                work.log_count[0] = 0
            if code == dop853.RUN_BOUNDARY:
                break
            if code in (dop853.RUN_SWITCHES, dop853.RUN_YIELD):
                continue
            self._fail(code, check, value, stepper.t)
        counts = stepper.counts()
        self.nsteps += counts["nsteps"]
        self.nswitches += counts["nswitches"]
        self.nfev += stepper.nfev - nfev
        self.t = stepper.t
        return self.state()

    # ------------------------------------------------------------------ internals
    def _hold(self, u: np.ndarray) -> None:
        """Hold the command ``u`` (A,) from :attr:`t` on (the control's work ``W_u`` taking
        the jump of the elastic energy, as the run loop's controller update does)."""
        y = self._y if self._stepper is None else self._stepper.y
        self.control = self.system.command(u, self.t, y)
        self.system.take_control_log()  # (not kept)

    def _start(self) -> DOP853:
        """The stepper at the first stretch's start, the contacts' modes made there."""
        system, o = self.system, self.options
        work = system.data.contact_work
        if work is not None:
            here = system.stage_inputs(np.array([self.t]))
            start_contacts_entry(system.model, here, self.t, self._y, event_work(system))
            work.log_count[0] = 0
        return DOP853(
            system,
            self.t,
            self._y.copy(),
            rtol=o.rtol,
            atol=o.atol,
            t_end=math.inf,
            max_steps=o.max_steps,
            projection_tol=o.projection_tol,
            locate=True,
        )

    def _fail(self, code: int, check: int, value: float, t: float) -> None:
        """Raise :class:`EngineError` for the return ``code`` of :meth:`DOP853.run` at ``t``
        [s] (the failure kept until :meth:`reset`)."""
        if code == dop853.RUN_CHECK_FAILED:
            message = failure_message(check, value, t, self.options, self.system.monitor)
        elif code == dop853.RUN_MAX_STEPS:
            message = (
                f"stopped after max_steps = {self.options.max_steps:,} steps in one stretch at "
                f"t = {t:.6g} s (a stiff or unstable structure?)"
            )
        elif code == dop853.RUN_STEP_FAILED:
            message = (
                f"DOP853 failed at t = {t:.9g} s: required step size is less than spacing "
                "between numbers"
            )
        else:  # RUN_INPUT: the held control and gravity are constant, always made
            message = f"DOP853 returned code {code} at t = {t:.6g} s"
        self._failure = message
        raise EngineError(message, t)
