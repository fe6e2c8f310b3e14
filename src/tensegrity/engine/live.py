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
from collections.abc import Sequence
from typing import Any

import numpy as np
from numba import njit, prange, typed

from tensegrity.engine import dop853
from tensegrity.engine.actuation import clip_command
from tensegrity.engine.compiled import DOP853_C, held, make_inputs
from tensegrity.engine.dop853 import (
    LANDING,
    NEW_SWITCHES,
    NSTEPS,
    NSWITCHES,
    RESTART,
    RUN_SWITCHES,
    RUN_YIELD,
    dop853_run,
)
from tensegrity.engine.events import event_work, start_contacts_entry
from tensegrity.engine.loop import (
    actuator_command,
    blow_up_limits,
    check_initial,
    dop853_stepper,
    failure_message,
)
from tensegrity.engine.options import DEFAULT_MAX_STEPS
from tensegrity.engine.result import Samples
from tensegrity.engine.simulate import options_and_inputs
from tensegrity.engine.system import CompiledSystem
from tensegrity.model.actuators import Actuators
from tensegrity.model.structure import Structure
from tensegrity.physics.compiling import JIT_OPTIONS
from tensegrity.physics.dynamics import State

__all__ = ["EngineError", "Live", "LiveBatch", "advance_stretches"]


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
    nfev : int
        Right-hand-side evaluations since the last :meth:`reset`.
    nsteps : int
        Steps since the last :meth:`reset`.
    nswitches : int
        Located events since the last :meth:`reset`.
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
        self.system = system = CompiledSystem(
            structure, inputs, limits=blow_up_limits(structure, self.options), controlled=True
        )
        self.t = math.nan
        self.control = np.zeros(system.actuation.position.size)
        self.nfev = self.nsteps = self.nswitches = 0
        #: the stepper, kept across resets (:meth:`DOP853.start_at`)
        self.stepper = dop853_stepper(system, 0.0, np.zeros(system.m), self.options, t_end=math.inf)
        self._failure: str | None = "no state yet: call reset(state) first"
        self._records = _Records([self])

    def reset(self, state: State) -> None:
        """Start again from ``state`` (:class:`~tensegrity.physics.dynamics.State`, projected
        onto the rod constraints), the actuators' command and control zero.
        ``TypeError``/``ValueError`` naming ``initial`` for a state that is not one of this
        structure, ``ValueError`` naming ``ground`` for a contact point below a plane."""
        check_initial(self.structure, state)
        system = self.system
        y = system.state_vector(state)
        system.check_contacts(y)
        self.t, self._failure = float(state.t), None
        self.control = np.zeros_like(self.control)
        system.reset_actuation()
        system.monitor[:] = (np.nan, 0.0, 0.0, 0.0)  # (made by the stepper's first call)
        self.nfev = self.nsteps = self.nswitches = 0
        work = system.data.contact_work
        if work is not None:  # the contacts' modes at the start (their changes not kept)
            here = system.stage_inputs(np.array([self.t]))
            start_contacts_entry(system.model, here, self.t, y, event_work(system))
            work.log_count[0] = 0
        self.stepper.start_at(self.t, y)

    @property
    def y(self) -> np.ndarray:
        """The engine's state ``[q, q', E_d, W_w, W_u]`` (m,) at :attr:`t` (a copy)."""
        return self.stepper.y.copy()

    def state(self) -> State:
        """The state at :attr:`t`: coordinates [m] and rates [m/s] in the structure's order."""
        q, qdot = self.system.coordinates(self.stepper.y)
        return State(t=self.t, q=q, qdot=qdot)

    def sample(self) -> Samples:
        """The state at :attr:`t` as one sample (a :class:`Samples` block of one row: node
        positions and velocities, tendon lengths and tensions, energies, the contact pairs'
        forces and modes), from one evaluation as a run records its samples."""
        system = self.system
        work = system.data.contact_work
        samples = Samples.empty(1, self.structure, 0 if work is None else work.mode.size)
        system.record(samples, 0, self.t, self.stepper.y, system.stage_inputs(np.array([self.t])))
        return samples

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
        (outcome,) = self._records.advance([control], duration)
        if isinstance(outcome, EngineError):
            raise outcome
        return outcome

    # ------------------------------------------------------------------ internals
    def _command(self, control: Any) -> np.ndarray:
        """The command (A,) [m] of ``control`` (checked), or ``EngineError`` if the run has
        failed."""
        if self._failure is not None:
            raise EngineError(self._failure, self.t)
        return actuator_command(self.system, np.array(control, dtype=float), self.t, "control")

    def _finish(self, code: int, check: int, value: float) -> State:
        """Book a stretch that ended with ``code`` (:meth:`DOP853.run`'s; ``RUN_BOUNDARY``: it
        reached its end): counts, time, the command held (after the bounds); the state, or
        :class:`EngineError`."""
        stepper = self.stepper
        self.control = self.system.actuation.command.copy()
        counts = stepper.counts()
        self.nsteps += counts["nsteps"]
        self.nswitches += counts["nswitches"]
        self.nfev = stepper.nfev
        self.t = stepper.t
        if code != dop853.RUN_BOUNDARY:
            self._fail(code, check, value, stepper.t)
        return self.state()

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


class _Records:
    """The records of some :class:`Live` runs as the compiled stretch takes them (numba typed
    lists: models, stage rows, points, loops), made once (the steppers are kept)."""

    def __init__(self, lives: Sequence[Live], *, parallel: bool = False) -> None:
        self.lives = list(lives)
        self.stretches = advance_stretches_parallel if parallel else advance_stretches
        systems = [live.system for live in self.lives]
        self.models = typed.List([system.model for system in systems])
        self.rows = typed.List([system.input_buffers(DOP853_C.size) for system in systems])
        self.points = typed.List([system.input_buffers(1) for system in systems])
        self.loops = typed.List([live.stepper.loop for live in self.lives])

    def advance(
        self, controls: Sequence[Any], duration: float, which: Sequence[int] | None = None
    ) -> list[State | EngineError]:
        """The runs ``which`` (indices; default all) holding their commands ``controls`` (one
        each) for ``duration`` [s], all in one compiled call; each one's state at the end, or
        its :class:`EngineError`."""
        if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
            raise ValueError(f"duration: must be a finite number > 0 [s], got {duration!r}")
        B = len(self.lives)
        index = np.arange(B) if which is None else np.asarray(which, dtype=np.int64)
        if len(controls) != index.size:
            raise ValueError(f"controls: expected {index.size} commands, got {len(controls)}")
        active = np.zeros(B, bool)
        active[index] = True
        commands = np.zeros((B, self.lives[0].control.size))
        for b, u in zip(index, controls, strict=True):
            commands[b] = self.lives[b]._command(u)
        start = np.array([live.t for live in self.lives])
        codes = np.zeros((B, 2), np.int64)
        values = np.zeros(B)
        self.stretches(
            self.models, self.rows, self.points, self.loops, active, commands, start,
            start + float(duration), codes, values,
        )  # fmt: skip
        outcomes: list[State | EngineError] = []
        for b in index:
            try:
                outcomes.append(self.lives[b]._finish(codes[b, 0], codes[b, 1], values[b]))
            except EngineError as failure:
                outcomes.append(failure)
        return outcomes


class LiveBatch:
    """Copies of one structure advanced together (:class:`Live` runs of the same structure and
    scene, their parameters free): one compiled call advances them all, spread over numba's
    threads (``parallel``, default) or one after the other (:func:`advance_stretches`), each
    exactly as its own :meth:`Live.advance` would."""

    def __init__(self, lives: Sequence[Live], *, parallel: bool = True) -> None:
        lives = list(lives)
        if not lives:
            raise ValueError("lives: need at least one Live run")
        first = lives[0].structure
        for b, live in enumerate(lives[1:], start=1):
            s = live.structure
            if not (
                s.n_nodes == first.n_nodes
                and np.array_equal(s.rod_nodes, first.rod_nodes)
                and np.array_equal(s.tendon_nodes, first.tendon_nodes)
                and live.control.size == lives[0].control.size
            ):
                raise ValueError(
                    f"lives[{b}]: another structure or actuators than lives[0] (a batch holds "
                    "copies of one structure)"
                )
        self.lives = lives
        self._records = _Records(lives, parallel=parallel and len(lives) > 1)

    def advance(
        self, controls: Sequence[Any], duration: float, which: Sequence[int] | None = None
    ) -> list[State | EngineError]:
        """Hold the command ``controls[k]`` (A,) [m] of copy ``which[k]`` (default: every copy,
        in order) for ``duration`` [s]; each of those copies' state at the end, or the
        :class:`EngineError` it failed with (the others go on).  ``ValueError`` naming
        ``controls``, ``control`` or ``duration`` for a bad one."""
        return self._records.advance(controls, duration, which)


@njit(**JIT_OPTIONS)
def _clear_contact_log(work):  # pragma: no cover - compiled
    """Forget the contacts' changes of mode (a live run does not keep them)."""
    if work is not None:
        work.log_count[0] = 0


@njit(**JIT_OPTIONS)
def advance_stretch(model, rows, point, loop, command, start, bound):  # pragma: no cover
    """Advance one run (its records) from ``start`` to ``bound`` [s] holding ``command`` (A,)
    [m]: the command held (:func:`compiled.held`: clipped to the bounds, the energy's jump
    booked), the stepper restarted, then :func:`dop853.dop853_run` until it reaches ``bound``
    or fails; its last ``(code, check code, check value)``."""
    one = np.full(1, start)
    make_inputs(model.callback, model.tables, one, point)
    act = point.actuation
    act.log_count[0] = 0
    clip_command(act, command, act.proposed)
    held(model, point, start, loop.y, act.proposed)
    act.log_count[0] = 0
    loop.tally[RESTART] = 1
    loop.tally[LANDING] = 0
    loop.tally[NSTEPS] = 0
    loop.tally[NSWITCHES] = 0
    while True:
        loop.tally[NEW_SWITCHES] = 0
        code, check, value = dop853_run(model, rows, point, loop, bound, np.inf)
        _clear_contact_log(point.contact_work)
        if code not in (RUN_SWITCHES, RUN_YIELD):
            return code, check, value


@njit(**JIT_OPTIONS)
def advance_stretches(
    models, rows, points, loops, active, commands, start, bound, codes, values
):  # pragma: no cover - compiled
    """:func:`advance_stretch` for each ``active`` run ``b`` (its records ``models[b]``,
    ``rows[b]``, ``points[b]``, ``loops[b]``), one after the other: ``codes[b]`` = its last
    return code and check code, ``values[b]`` the check's value."""
    for b in range(len(models)):
        if active[b]:
            code, check, value = advance_stretch(
                models[b], rows[b], points[b], loops[b], commands[b], start[b], bound[b]
            )
            codes[b, 0], codes[b, 1], values[b] = code, check, value


@njit(parallel=True, **JIT_OPTIONS)
def advance_stretches_parallel(
    models, rows, points, loops, active, commands, start, bound, codes, values
):  # pragma: no cover - compiled
    """:func:`advance_stretches` with the runs spread over numba's threads (each run's
    arithmetic is its own: the results are those of one thread, bit for bit)."""
    for i in prange(len(models)):
        b = np.int64(i)  # prange's index is unsigned; typed lists take a signed one
        if active[b]:
            code, check, value = advance_stretch(
                models[b], rows[b], points[b], loops[b], commands[b], start[b], bound[b]
            )
            codes[b, 0], codes[b, 1], values[b] = code, check, value
