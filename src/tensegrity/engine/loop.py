"""The one integration loop (:func:`run`): stepping, sampling, event location, projection onto
the constraints, blow-up checks, the steady-state stop and a stop condition's, a controller's
updates and checkpoints, for every method and every structure, samples handed to a sink as they
are made.

Per accepted step of an adaptive method: the events (the tendons' slack/taut switches) the step
crossed are found, the first is located on the step's dense output, and the step is discarded
and retaken to end exactly there, by the one mechanism of :mod:`tensegrity.engine.events`.  The
step size carries over.  Then the blow-up checks run (compiled), samples inside the step are
interpolated, and the state is projected when its drift exceeds ``projection_tol``.  DOP853,
the default, does all of this in compiled code from one sample or boundary to the next
(:mod:`tensegrity.engine.dop853`; :func:`_compiled_adaptive` records the samples, calls the
controller and saves checkpoints); the other ``scipy`` methods step by scipy here
(:func:`_adaptive`), their events located by the same compiled locator on scipy's dense
output.  ``"rk4"`` runs whole stretches of steps between samples in one compiled call.

Boundaries: steps end exactly at the times of a controller's updates (zero-order hold, every
``controller.period`` from ``t0``) and of checkpoints (every ``checkpoint.every`` samples).  At
a checkpoint the loop hands its whole state (:class:`LoopState`) to ``checkpoint.save``; a run
started with ``resume=`` that state continues bit for bit as the run that saved it.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

import numpy as np

from tensegrity.engine import compiled, dop853
from tensegrity.engine.dop853 import DOP853
from tensegrity.engine.events import (
    DenseOutputHandle,
    event_work,
    events_crossed_entry,
    land_contacts_entry,
    landing_of,
    locate_event_entry,
    refresh_slips_entry,
    restore_landing,
    set_sides_entry,
    start_contacts_entry,
    stick_slow_slips_entry,
)
from tensegrity.engine.feedback import LinearFeedback
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.options import Options, reaches, sample_count, sample_time, short_of
from tensegrity.engine.result import (
    STATUS_END,
    STATUS_FAILED,
    STATUS_STEADY,
    STATUS_STOPPED,
    RunSummary,
    Samples,
)
from tensegrity.engine.sensitivity import SensitivityWork, prepare as prepare_sensitivity
from tensegrity.engine.steppers import (
    RK4,
    IntegrationError,
    ScipyMethod,
    Stepper,
    StepperMemory,
)
from tensegrity.engine.system import CompiledSystem
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics


class Sink(Protocol):
    """Where samples go (:class:`tensegrity.engine.result.MemorySink` keeps them in memory).

    They come in blocks of one or more samples, in time order; a block is the sink's to keep.
    With checkpoints, a checkpoint's samples have all been handed over before it is saved."""

    def add(self, samples: Samples) -> None:
        """Keep a block of samples."""


class Controller(Protocol):
    """State feedback with zero-order hold: called at ``t0`` and every ``period`` [s] after it
    with ``(t, q, qdot)`` (the structure's coordinates [m], [m/s]); returns the control ``u``
    (S,) [m] (rest lengths ``L0 - u``) held until the next call."""

    @property
    def period(self) -> float:
        """Time between updates [s]."""
        ...

    def __call__(self, t: float, q: np.ndarray, qdot: np.ndarray) -> np.ndarray: ...


class StopCondition(Protocol):
    """Ends a run at a sample: called with each new sample (a :class:`Samples` block of one
    row, views valid during the call), the first one too; returns None to go on, or the reason
    the run stops there, a sentence that becomes the run's message (status
    :data:`~tensegrity.engine.result.STATUS_STOPPED`).  E.g. a member over its limits
    (:func:`tensegrity.design.utilisation.stop_at_failure`)."""

    def __call__(self, sample: Samples, /) -> str | None: ...


@dataclasses.dataclass(frozen=True)
class Feedback:
    """A :class:`Controller` made of a function ``u = law(t, q, qdot)`` and its ``period`` [s]."""

    law: Callable[[float, np.ndarray, np.ndarray], np.ndarray]
    period: float

    def __post_init__(self) -> None:
        if not (
            isinstance(self.period, (int, float)) and math.isfinite(self.period) and self.period > 0
        ):
            raise ValueError(f"period: must be a finite number > 0, got {self.period!r}")

    def __call__(self, t: float, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        return self.law(t, q, qdot)


@dataclasses.dataclass(frozen=True)
class Checkpointing:
    """Checkpoints of a run: after every ``every`` samples, ``save`` gets the :class:`LoopState`
    (once the samples up to it were handed to the sink)."""

    every: int
    save: Callable[[LoopState], None]


@dataclasses.dataclass(frozen=True, eq=False)
class LoopState:
    """Everything the loop needs to continue a run exactly where it stood (a checkpoint).

    ``y`` is the ODE state ``[q, q', E_d, W_w, W_u]`` in the engine's coordinates (m,) at time
    ``t`` [s]; ``memory`` the stepper's (:class:`~tensegrity.engine.steppers.StepperMemory`);
    ``steps_done`` the steps taken from ``t0`` (``"rk4"``); ``next_sample`` the index of the
    next sample; ``monitor`` the blow-up monitor (4,) (energy at the start, largest energy
    scale, largest rod and constraint errors); ``taut`` the tendons' taut flags (S,) in kernel
    order; ``landing`` a located switch being headed for (``(time, tendons, taut_after,
    exact)``) or None; ``counts`` ``nsteps``, ``nswitches``, ``nprojections``, ``nfev``;
    ``control`` the actuators' command held (A,) [m] (a controller's; empty without);
    ``contact_mode`` (CP,) and ``slip_direction`` (CP, 3) the contact pairs' modes and slip
    directions, ``contact_events`` (E, 4) the changes of mode so far (time [s], pair, mode
    before, mode after; :attr:`RunSummary.contact_events`), all empty without planes;
    ``actuation`` when the actuators' command was held (``start`` [s], the updates so far,
    the controls applied at ``start`` (A,)) and ``control_updates`` those updates
    (:attr:`RunSummary.control_updates`), empty without actuators.
    """

    t: float
    y: np.ndarray
    memory: StepperMemory
    steps_done: int
    next_sample: int
    monitor: np.ndarray
    taut: np.ndarray
    landing: tuple[float, np.ndarray, np.ndarray, bool] | None
    allow_provisional: bool
    counts: dict[str, int]
    switch_times: tuple[float, ...]
    last_sample_t: float
    wall_time: float
    contact_mode: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, np.int64))
    slip_direction: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    contact_events: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 4)))
    control: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    actuation: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    control_updates: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 1)))

    def to_arrays(self) -> dict[str, np.ndarray | np.generic]:
        """The state as named arrays and NumPy scalars (for a file); :meth:`from_arrays` reads
        them back."""
        landing = self.landing or (math.nan, np.zeros(0, np.int64), np.zeros(0, bool), False)
        return {
            "t": np.float64(self.t),
            "y": self.y,
            "first_stage": self.memory.first_stage,
            "step": np.float64(self.memory.step),
            "step_before": np.float64(self.memory.step_before),
            "steps_done": np.int64(self.steps_done),
            "next_sample": np.int64(self.next_sample),
            "monitor": self.monitor,
            "taut": self.taut,
            "landing_time": np.float64(landing[0]),
            "landing_tendons": landing[1],
            "landing_taut_after": landing[2],
            "landing_exact": np.bool_(landing[3]),
            "allow_provisional": np.bool_(self.allow_provisional),
            **{name: np.int64(value) for name, value in self.counts.items()},
            "switch_times": np.array(self.switch_times, dtype=float),
            "control": self.control,
            "last_sample_t": np.float64(self.last_sample_t),
            "wall_time": np.float64(self.wall_time),
            "contact_mode": self.contact_mode,
            "slip_direction": self.slip_direction,
            "contact_events": self.contact_events,
            "actuation": self.actuation,
            "control_updates": self.control_updates,
        }

    @classmethod
    def from_arrays(cls, a: Mapping[str, np.ndarray | np.generic]) -> LoopState:
        """The state written by :meth:`to_arrays` (``KeyError`` names a missing array; a state
        written before contacts existed has none)."""
        landing_time = float(a["landing_time"])
        landing = (
            None
            if math.isnan(landing_time)
            else (
                landing_time,
                np.asarray(a["landing_tendons"], dtype=np.int64),
                np.asarray(a["landing_taut_after"], dtype=bool),
                bool(a["landing_exact"]),
            )
        )
        return cls(
            t=float(a["t"]),
            y=np.asarray(a["y"], dtype=float),
            memory=StepperMemory(
                np.asarray(a["first_stage"], dtype=float), float(a["step"]), float(a["step_before"])
            ),
            steps_done=int(a["steps_done"]),
            next_sample=int(a["next_sample"]),
            monitor=np.asarray(a["monitor"], dtype=float),
            taut=np.asarray(a["taut"], dtype=bool),
            landing=landing,
            allow_provisional=bool(a["allow_provisional"]),
            counts={name: int(a[name]) for name in _COUNTS},
            switch_times=tuple(float(x) for x in np.asarray(a["switch_times"])),
            control=np.asarray(a["control"], dtype=float),
            last_sample_t=float(a["last_sample_t"]),
            wall_time=float(a["wall_time"]),
            contact_mode=np.asarray(a.get("contact_mode", np.zeros(0)), dtype=np.int64),
            slip_direction=np.asarray(a.get("slip_direction", np.zeros((0, 3))), dtype=float),
            contact_events=np.asarray(a.get("contact_events", np.zeros((0, 4))), dtype=float),
            actuation=np.asarray(a.get("actuation", np.zeros(0)), dtype=float),
            control_updates=np.asarray(a.get("control_updates", np.zeros((0, 1))), dtype=float),
        )


_COUNTS = ("nsteps", "nswitches", "nprojections", "nfev")

_FAILURES = {
    compiled.CHECK_NOT_FINITE: "unstable: the state is not finite at t = {t:.6g} s",
    compiled.CHECK_ROD_LENGTH: (
        "unstable: a rod's length error {value:.3g} (relative) exceeds "
        "{limit:g} within one step at t = {t:.6g} s (step too large, or "
        "the motion is unstable)"
    ),
    compiled.CHECK_CONSTRAINT: (
        "unstable: the joints and supports are violated by {value:.3g} m "
        "within one step at t = {t:.6g} s (step too large, or the motion "
        "is unstable)"
    ),
    compiled.CHECK_ENERGY: (
        "unstable: energy grew by {value:.3g} J (scale {scale:.3g} J) at t = {t:.6g} s"
    ),
    compiled.CHECK_PROJECTION: (
        "unstable: could not project onto the constraints at t = {t:.6g} s"
    ),
}


def blow_up_limits(structure: Structure, options: Options) -> tuple[float, float, float]:
    """The blow-up checks' limits of a run (``CompiledSystem``'s ``limits``): the relative rod
    length error, the constraint error [m] (the rod error times the longest rod, at least 1 m)
    and the energy growth."""
    length_scale = max(float(structure.rod_length.max(initial=0.0)), 1.0)
    error = options.max_rod_length_error
    return error, error * length_scale, options.max_energy_growth


def failure_message(
    code: int, value: float, t: float, options: Options, monitor: np.ndarray
) -> str:
    """The sentence of a failed blow-up check ``code`` (``compiled.CHECK_*``) with its
    ``value`` at ``t`` [s], given the run's ``options`` and blow-up ``monitor`` (4,)."""
    return _FAILURES[code].format(
        t=t, value=value, limit=options.max_rod_length_error, scale=monitor[1]
    )


@dataclasses.dataclass
class _Landing:
    """A located event the stepper is heading for: its time [s], and whether it was located on
    an accepted step's dense output (exact) or on a rejected attempt's (approximate: the steps
    up to it keep looking for events); the events fired there are in the run's
    :class:`~tensegrity.engine.events.EventWork`."""

    time: float
    exact: bool


class _Run:
    """The state of one run: the system, the monitor, the counters, the boundaries."""

    def __init__(
        self,
        structure: Structure,
        t0: float,
        t_end: float,
        inputs: Inputs,
        options: Options,
        sink: Sink,
        controller: Controller | LinearFeedback | None,
        checkpoint: Checkpointing | None,
        progress: Callable[[float], None] | None,
        stop: StopCondition | None,
    ) -> None:
        self.wall0 = time.perf_counter()
        self.structure, self.options, self.sink = structure, options, sink
        self.progress, self.stop = progress, stop
        law = controller if isinstance(controller, LinearFeedback) else None
        #: a compiled law is updated inside DOP853's compiled loop; the other loops stop at
        #: its times and have it updated (:meth:`update_control`)
        self.controller = None if (law is not None and options.method == "DOP853") else controller
        self.checkpointing = checkpoint
        self.t0, self.t_end = t0, t_end
        self.system = CompiledSystem(
            structure,
            inputs,
            limits=blow_up_limits(structure, options),
            feedback=law,
            t0=t0,
            controlled=controller is not None,
        )
        #: the blow-up monitor (4,) (``system.data.monitor``, the compiled checks update it)
        self.monitor = self.system.monitor
        self.monitor[:] = (np.nan, 0.0, 0.0, 0.0)  # (made at the first state: start_monitor)
        self.sample_dt = options.sample_spacing(t0, t_end)
        self.next_sample = 1
        self.counts = dict(nsteps=0, nswitches=0, nprojections=0)
        self.nfev_before = 0  # of the runs before a resume
        self.switch_times: list[float] = []
        self.contact_events: list[np.ndarray] = []  # blocks of (time, pair, before, after)
        self.control_log: list[np.ndarray] = []  # blocks of the actuators' updates
        self.status, self.message = STATUS_END, f"reached t_end = {t_end:g} s"
        self.last_sample_t = -np.inf
        #: the sensitivities ``dy/dp`` (P, m) at a sample's time, when the run integrates them
        #: (:mod:`tensegrity.engine.sensitivity`); each sample's, in order
        self.sensitivity_at: Callable[[float], np.ndarray] | None = None
        self.sensitivities: list[np.ndarray] = []
        self.wall_before = 0.0
        self.steps_done = 0  # "rk4"
        self.saved_at = 0  # index of the sample of the last checkpoint
        self.stopped_for_time = False  # by max_wall_time
        work = self.system.data.contact_work
        self.pairs = 0 if work is None else work.mode.size  # contact pairs
        self.block_rows = _block_rows(structure, self.pairs, options, t0, t_end, checkpoint)
        self.block, self.rows = Samples.empty(self.block_rows, structure, self.pairs), 0

    def start_monitor(self, y: np.ndarray) -> None:
        """The blow-up monitor at the first state ``y`` (its energy the reference, its errors),
        made by the loops that step in Python; DOP853 makes it in its first compiled call."""
        system = self.system
        data = system.stage_inputs(np.array([self.t0]))
        compiled.check_state_entry(system.model, data, 0, y, np.full(3, np.inf), True)

    # ------------------------------------------------------------------ samples
    def record(self, t: float, y: np.ndarray) -> int:
        """Record the sample at ``(t, y)``; its row in :attr:`block`."""
        if self.rows == self.block_rows:
            self.flush()
        row = self.rows
        self.system.record(self.block, row, t, y, self.system.stage_inputs(np.array([t])))
        if self.sensitivity_at is not None:
            self.sensitivities.append(self.sensitivity_at(t))
        self.rows += 1
        self.last_sample_t = t
        return row

    def flush(self) -> None:
        """Hand the samples recorded so far to the sink."""
        if self.rows:
            self.sink.add(self.block.head(self.rows))
            self.block, self.rows = Samples.empty(self.block_rows, self.structure, self.pairs), 0

    def sample_time(self, index: int) -> float:
        """Time of sample ``index`` [s] (:func:`tensegrity.engine.options.sample_time`)."""
        return sample_time(self.t0, self.t_end, self.sample_dt, index)

    def sample_times(self, t_new: float) -> list[float]:
        """The sample times not yet recorded up to ``t_new``."""
        times = []
        while reaches(t_new, t := self.sample_time(self.next_sample)):
            times.append(min(t, t_new))
            self.next_sample += 1
        return times

    def ends_at(self, row: int) -> bool:
        """Whether the run ends at the sample in ``row`` of :attr:`block`: it is at rest, or
        the stop condition says so (:meth:`stopped_at`; the status and message set)."""
        o, block = self.options, self.block
        if (
            o.steady_state
            and block.residual_acceleration[row] < o.acceleration_tol
            and block.largest_speed[row] < o.velocity_tol
        ):
            self.status = STATUS_STEADY
            self.message = f"steady state at t = {block.t[row]:.6g} s"
            return True
        return self.stopped_at(row)

    def stopped_at(self, row: int) -> bool:
        """Whether the stop condition ends the run at the sample in ``row`` of :attr:`block`
        (the status and message set)."""
        reason = None if self.stop is None else self.stop(self.block.row(row))
        if reason is None:
            return False
        self.status = STATUS_STOPPED
        self.message = f"stopped at t = {self.block.t[row]:.6g} s: {reason}"
        return True

    def stop_at_max_steps(self, t: float) -> None:
        """Fail the run at ``t`` [s] for its step budget, saying how many steps the whole run
        would take at the mean step so far (a small budget, or steps that became tiny)."""
        self.status = STATUS_FAILED
        steps = self.counts["nsteps"] or self.options.max_steps
        needed = steps * (self.t_end - self.t0) / (t - self.t0) if t > self.t0 else math.inf
        self.message = (
            f"stopped after max_steps (--max-steps) = {self.options.max_steps:,} steps at "
            f"t = {t:.6g} s of "
            f"{self.t_end:g} s (at their mean step of {(t - self.t0) / steps:.3g} s, the whole "
            f"run takes about {needed:,.0f} steps); raise max_steps (--max-steps), or if the "
            "steps are far smaller than the motion needs (a stiff or unstable structure?), "
            "loosen rtol and atol (--rtol, --atol) or try method='Radau' (--method Radau)"
        )

    def wall_time(self) -> float:
        """Wall-clock time of the run so far [s] (the runs before a resume included)."""
        return self.wall_before + time.perf_counter() - self.wall0

    def out_of_time(self, t: float) -> bool:
        """Whether this call has used up ``max_wall_time`` at ``t`` [s] (the run is then
        failed, :attr:`stopped_for_time`)."""
        budget = self.options.max_wall_time
        if time.perf_counter() - self.wall0 <= budget:
            return False
        self.stopped_for_time = True
        self.status = STATUS_FAILED
        self.message = (
            f"stopped after max_wall_time (--max-wall-time) = {budget:g} s of wall-clock time "
            f"at t = {t:.6g} s of {self.t_end:g} s ({self.counts['nsteps']:,} steps); raise "
            "max_wall_time (--max-wall-time), or make the steps larger (a stiff or unstable "
            "structure? loosen rtol and atol (--rtol, --atol), or try method='Radau' "
            "(--method Radau))"
        )
        return True

    def fail(self, code: int, value: float, t: float) -> None:
        self.status = STATUS_FAILED
        self.message = failure_message(code, value, t, self.options, self.monitor)

    def check(self, y: np.ndarray, t: float) -> float | None:
        """The compiled blow-up checks at the end of a step; the drift, or None on failure."""
        system = self.system
        data = system.stage_inputs(np.array([t]))
        code, value = compiled.check_state_entry(
            system.model, data, 0, y, system.model.limits, True
        )
        if code != compiled.CHECK_OK:
            self.fail(code, value, t)
            return None
        return value

    # ------------------------------------------------------------------ boundaries
    def next_boundary(self, t: float) -> float:
        """The first controller update or checkpoint time after ``t``, or ``t_end``."""
        times = [self.t_end]
        if self.controller is not None:
            times.append(self.control_time(t))
        if self.checkpointing is not None:
            every = self.checkpointing.every
            index = (math.floor((t - self.t0) / (every * self.sample_dt) + 1e-9) + 1) * every
            times.append(self.sample_time(index))
        return min(times)

    def control_time(self, t: float) -> float:
        """The first controller update after ``t`` [s] (a run with a controller)."""
        assert self.controller is not None, "control_time: the run has no controller"
        period = self.controller.period
        return self.t0 + (math.floor((t - self.t0) / period + 1e-9) + 1) * period

    def at_control_time(self, t: float) -> bool:
        """True at a controller's update time (to 1e-9 of its period)."""
        if self.controller is None:
            return False
        period = self.controller.period
        k = round((t - self.t0) / period)
        return k >= 0 and abs(self.t0 + k * period - t) <= 1e-9 * period

    def update_control(self, t: float, y: np.ndarray) -> None:
        """Update the control at ``(t, y)``: a compiled law's update, or the controller's
        output held (through the actuators, if any: their command, the energy's jump in
        ``y``); the system's inputs change."""
        system = self.system
        if system.model.feedback is not None:
            system.feedback_update(t, y)
            self.take_control_log()
            return
        controller = self.controller
        assert controller is not None and not isinstance(controller, LinearFeedback), (
            "update_control: the run has no Python controller"
        )
        q, qdot = system.coordinates(y)
        try:
            u = np.array(controller(t, q, qdot), dtype=float)
        except Exception as exc:  # (the run fails with a message naming the time)
            first = str(exc).splitlines()[0] if str(exc) else ""
            raise ValueError(
                f"controller: raised {type(exc).__name__} at t = {t:.6g} s: {first}"
            ) from exc
        system.command(self._command_of(u, t), t, y)
        self.take_control_log()

    def settings(self, inputs: Inputs) -> dict[str, Any]:
        """The run's settings record: the options and inputs, and the actuators a controller
        drove (a compiled law's own if the inputs had none)."""
        settings = self.options.settings(self.t0, self.t_end, **inputs.settings())
        if self.system.actuators is not None:
            settings["actuators"] = self.system.actuators.settings(self.structure)
        return settings

    def _command_of(self, u: np.ndarray, t: float) -> np.ndarray:
        """The actuators' command in a controller's output ``u`` (:func:`actuator_command`)."""
        return actuator_command(self.system, u, t, "controller")

    def take_control_log(self) -> None:
        """Move the actuators' updates logged since the last call to :attr:`control_log`."""
        if self.system.actuators is not None:
            self.control_log.append(self.system.take_control_log())

    def control_updates(self) -> np.ndarray:
        """The actuators' updates so far (U, 1 + 2 A): time [s], commands held [m], controls
        applied then [m]; (0, 1) without actuators."""
        self.take_control_log()
        act = self.system.data.actuation
        empty = np.zeros((0, 1 if act is None else 1 + 2 * act.position.size))
        return np.concatenate([empty, *(rows for rows in self.control_log if rows.shape[0])])

    def checkpoint_due(self) -> bool:
        """True once per checkpoint: its sample (every ``every``-th) was just recorded."""
        c, index = self.checkpointing, self.next_sample - 1
        return (
            c is not None
            and index % c.every == 0
            and index > self.saved_at
            and self.last_sample_t == self.sample_time(index)
        )

    def save(
        self,
        t: float,
        y: np.ndarray,
        stepper: Stepper | DOP853 | RK4,
        taut: np.ndarray | None,
        landing: tuple[float, np.ndarray, np.ndarray, bool] | None,
        allow_provisional: bool,
    ) -> None:
        assert self.checkpointing is not None, "save: the run has no checkpoints"
        self.flush()
        self.saved_at = self.next_sample - 1
        self.checkpointing.save(
            LoopState(
                t=t,
                y=y.copy(),
                memory=stepper.memory(),
                steps_done=self.steps_done,
                next_sample=self.next_sample,
                monitor=self.monitor.copy(),
                taut=np.zeros(0, bool) if taut is None else taut.copy(),
                landing=landing,
                allow_provisional=allow_provisional,
                counts=dict(self.counts, nfev=self.nfev_before + stepper.nfev),
                switch_times=tuple(self.switch_times),
                last_sample_t=self.last_sample_t,
                wall_time=self.wall_time(),
                **self._contact_state(),
                **self._actuation_state(),
            )
        )

    def _actuation_state(self) -> dict[str, np.ndarray]:
        """The actuators' held command and updates so far (empty without actuators)."""
        act = self.system.data.actuation
        if act is None:
            return {}
        held = np.concatenate([act.start, act.updates.astype(float), act.applied])
        return {
            "control": act.command.copy(),
            "actuation": held,
            "control_updates": self.control_updates(),
        }

    def _contact_state(self) -> dict[str, np.ndarray]:
        """The contact pairs' modes, slip directions and changes so far (copies; empty without
        planes)."""
        work = self.system.data.contact_work
        if work is None:
            return {}
        return {
            "contact_mode": work.mode.copy(),
            "slip_direction": work.slip_direction.copy(),
            "contact_events": self.contact_event_log(),
        }

    def start_contacts(self, t0: float, y0: np.ndarray) -> None:
        """The contact pairs' modes at the first state ``y0`` (in place: its sticking points
        held still; :func:`tensegrity.engine.events.start_contacts`), logged; nothing without
        planes."""
        if self.system.model.contacts is not None:
            here = self.system.stage_inputs(np.array([t0]))
            start_contacts_entry(self.system.model, here, t0, y0, event_work(self.system))
            self.take_contact_log()

    def take_contact_log(self) -> None:
        """Move the changes of mode the compiled actions logged (``ContactWork.log``) to
        :attr:`contact_events`, emptying the log."""
        work = self.system.data.contact_work
        if work is not None and work.log_count[0]:
            self.contact_events.append(work.log[: work.log_count[0]].copy())
            work.log_count[0] = 0

    def contact_event_log(self) -> np.ndarray:
        """The changes of mode so far (E, 4): time [s], pair, mode before, mode after."""
        self.take_contact_log()
        return np.concatenate([np.zeros((0, 4)), *self.contact_events])

    def restore(self, state: LoopState) -> None:
        self.next_sample = state.next_sample
        self.monitor[:] = state.monitor
        self.counts = {name: state.counts[name] for name in ("nsteps", "nswitches", "nprojections")}
        self.nfev_before = state.counts["nfev"]
        self.switch_times = list(state.switch_times)
        self.contact_events = [state.contact_events]
        self.last_sample_t, self.wall_before = state.last_sample_t, state.wall_time
        self.steps_done = state.steps_done
        self.saved_at = state.next_sample - 1
        act = self.system.data.actuation
        if act is not None:
            A = act.position.size
            if state.control.shape != (A,) or state.actuation.shape != (2 + A,):
                raise ValueError(
                    f"resume: the checkpoint holds no command of {A} actuators (another "
                    "controller or actuators)"
                )
            act.start[0], act.updates[0] = state.actuation[0], int(state.actuation[1])
            act.applied[:], act.command[:] = state.actuation[2:], state.control
            self.control_log = [state.control_updates]
        work = self.system.data.contact_work
        if work is not None:
            if state.contact_mode.shape != work.mode.shape:
                raise ValueError(
                    f"resume: the checkpoint holds {state.contact_mode.size} contact pairs, "
                    f"this run has {work.mode.size} (another ground or structure)"
                )
            work.mode[:] = state.contact_mode
            work.slip_direction[:] = state.slip_direction


#: Bytes of samples :func:`run` holds before it hands them to its sink (without checkpoints).
BLOCK_BYTES = 32 * 2**20


def _block_rows(
    structure: Structure,
    pairs: int,
    options: Options,
    t0: float,
    t_end: float,
    checkpoint: Checkpointing | None,
) -> int:
    """Samples per block handed to the sink: those of a checkpoint (every ``every`` samples,
    the first one's including the sample at ``t0``), else :data:`BLOCK_BYTES` worth (with
    ``pairs`` contact pairs), and not more than the run can make."""
    if checkpoint is not None:
        return checkpoint.every + 1
    most = sample_count(t0, t_end, options.sample_spacing(t0, t_end))
    return max(1, min(most, BLOCK_BYTES // Samples.row_bytes(structure, pairs)))


#: A loop of one method family (:func:`_fixed_step`, :func:`_compiled_adaptive`,
#: :func:`_adaptive`): the run, its stepper, the checkpoint it resumes from (or None).
_Loop = Callable[[_Run, Any, "LoopState | None"], None]


def _method(
    run: _Run,
    t: float,
    y: np.ndarray,
    memory: StepperMemory | None,
    sensitivity: SensitivityWork | None = None,
) -> tuple[Stepper | DOP853 | RK4, _Loop]:
    """The stepper of the run's method from ``(t, y)`` (and a checkpoint's ``memory``; DOP853
    with the ``sensitivity`` it integrates), and the loop that drives it: the one place the
    method is dispatched on."""
    o = run.options
    if o.method == "rk4":
        return RK4(run.system, t, y), _fixed_step
    if o.method == "DOP853":
        stepper = dop853_stepper(
            run.system, t, y, o, t_end=run.t_end, memory=memory, sensitivity=sensitivity
        )
        if sensitivity is not None:
            run.sensitivity_at = stepper.sensitivity_at
        return stepper, _compiled_adaptive
    method = ScipyMethod(
        run.system, t, y, method=o.method, rtol=o.rtol, atol=o.atol, t_end=run.t_end
    )
    return method, _adaptive


def dop853_stepper(
    system: CompiledSystem,
    t: float,
    y: np.ndarray,
    options: Options,
    *,
    t_end: float,
    memory: StepperMemory | None = None,
    sensitivity: SensitivityWork | None = None,
) -> DOP853:
    """The DOP853 stepper of a run with ``options`` from ``(t, y)`` up to ``t_end`` [s] (and a
    checkpoint's ``memory``, the ``sensitivity`` it integrates)."""
    return DOP853(
        system,
        t,
        y,
        rtol=options.rtol,
        atol=options.atol,
        t_end=t_end,
        max_steps=options.max_steps,
        projection_tol=options.projection_tol,
        locate=options.locate_switches,
        memory=memory,
        sensitivity=sensitivity,
    )


def _adaptive(run: _Run, stepper: Stepper, resume: LoopState | None) -> None:
    """The loop of scipy's adaptive methods: the DOP853 loop's (:func:`dop853.dop853_run`)
    procedure, stepping by scipy, the events located by the same compiled mechanism
    (:mod:`tensegrity.engine.events`) on scipy's dense output."""
    if resume is None:
        run.start_monitor(stepper.y)
    o, system = run.options, run.system
    locate = o.locate_switches
    events = event_work(system)
    point = system.input_buffers(1)
    varying = not system.constant
    if locate:
        set_sides_entry(stepper.evaluation(), events, False)
    landing: _Landing | None = None
    # A rejected attempt may stand for a step only when no switch is being landed on and the
    # last one was not located approximately (the step after it may find the same switch just
    # ahead: it shrinks as usual instead of locating it again, which could repeat forever).
    allow_provisional = locate
    if resume is not None:
        events.side[:] = resume.taut if locate else False
        if resume.landing is not None:
            time_, fired, side_after, exact = resume.landing
            landing = _Landing(time_, exact)
            restore_landing(events, fired, side_after)
        allow_provisional = resume.allow_provisional
    while stepper.t < run.t_end:
        detect = locate and (landing is None or not landing.exact)
        boundary = run.next_boundary(stepper.t)
        stepper.step(
            boundary if landing is None else min(boundary, landing.time),
            events.side if allow_provisional and landing is None else None,
        )
        allow_provisional = locate
        if detect:
            count = events_crossed_entry(stepper.evaluation(), events)
            if count:
                with DenseOutputHandle(stepper.dense()) as dense:
                    t_switch, input_time = locate_event_entry(
                        system.model, point, varying, dense, stepper.step_span(), events, count
                    )
                if math.isnan(t_switch):
                    system.raise_input_error()
                    system.inputs.rest_length(np.array([input_time]))  # (the ValueError)
                if not stepper.provisional:
                    run.counts["nswitches"] += 1
                    run.switch_times.append(t_switch)
                landing = _Landing(t_switch, not stepper.provisional)
                stepper.retreat(t_switch)
                continue
        run.counts["nsteps"] += 1
        landed = landing if landing is not None and stepper.t >= landing.time else None
        if locate:
            set_sides_entry(stepper.evaluation(), events, landed is not None and landed.exact)
            if system.model.contacts is not None:
                refresh_slips_entry(system.model, stepper.evaluation(), stepper.y)
        drift = run.check(stepper.y, stepper.t)
        if drift is None:
            run.record(stepper.t, stepper.y)
            return
        times = run.sample_times(stepper.t)
        if times:
            y_at = stepper.dense()
            for t in times:
                if run.ends_at(run.record(t, y_at(t) if t < stepper.t else stepper.y)):
                    return
        stepper.accept()
        if run.progress is not None:
            run.progress(stepper.t)
        restart = False
        if landed is not None:
            stepper.resume()
            allow_provisional = landed.exact
            landing = None
            if landed.exact and system.model.contacts is not None:  # the events' actions
                here = system.stage_inputs(np.array([stepper.t]))
                restart = land_contacts_entry(system.model, here, stepper.t, stepper.y, events)
        if system.model.contacts is not None:  # (the rule for slow slips)
            here = system.stage_inputs(np.array([stepper.t]))
            restart |= stick_slow_slips_entry(system.model, here, stepper.t, stepper.y, events)
            run.take_contact_log()
        if drift > o.projection_tol:
            if not system.project(stepper.y):
                run.fail(compiled.CHECK_PROJECTION, np.nan, stepper.t)
                return
            run.counts["nprojections"] += 1
            restart = True
        if stepper.t < run.t_end and run.at_control_time(stepper.t):
            run.update_control(stepper.t, stepper.y)
            landing, restart = None, True
        if restart:
            stepper.restart(stepper.y)
            if locate:
                keep = landed is not None and landed.exact
                set_sides_entry(stepper.evaluation(), events, keep)
        if stepper.t < run.t_end and run.counts["nsteps"] >= o.max_steps:
            run.stop_at_max_steps(stepper.t)
            return
        if stepper.t < run.t_end and run.out_of_time(stepper.t):
            return
        if stepper.t < run.t_end and run.checkpoint_due():
            kept = None
            if landing is not None:
                kept = (landing.time, *landing_of(events), landing.exact)
            taut = events.side if locate else None
            run.save(stepper.t, stepper.y, stepper, taut, kept, allow_provisional)


def _compiled_adaptive(run: _Run, stepper: DOP853, resume: LoopState | None) -> None:
    """The loop of DOP853: :meth:`DOP853.run` (compiled) from one sample or boundary to the
    next; here the samples are recorded, a controller called and checkpoints saved."""
    if resume is not None:
        stepper.restore(resume.taut, resume.landing, resume.allow_provisional)
        stepper.set_counts(resume.counts)
    bound = run.next_boundary(stepper.t)  # (kept until reached: a step may end past samples)
    while True:
        code, check, value = stepper.run(bound, run.sample_time(run.next_sample))
        run.counts.update(stepper.counts())
        run.switch_times.extend(stepper.new_switch_times())
        run.take_contact_log()
        run.take_control_log()
        if code == dop853.RUN_CHECK_FAILED:
            run.fail(check, value, stepper.t)
            if check != compiled.CHECK_PROJECTION:  # (the state before projection was recorded)
                run.record(stepper.t, stepper.y)
            return
        if code == dop853.RUN_STEP_FAILED:
            raise IntegrationError(
                f"DOP853 failed at t = {stepper.t:.9g} s: required step size is less than "
                "spacing between numbers"
            )
        if code == dop853.RUN_INPUT:  # (raises what a function raised, or the ValueError
            # naming the tendon and time)
            run.system.raise_input_error()
            run.system.inputs.rest_length(np.array([stepper.clock[dop853.INPUT_TIME]]))
            raise AssertionError("RUN_INPUT: the inputs were made")  # pragma: no cover
        if code == dop853.RUN_MAX_STEPS:
            run.stop_at_max_steps(stepper.t)
            return
        if run.out_of_time(stepper.t):
            return
        if run.progress is not None:
            run.progress(stepper.t)
        if code in (dop853.RUN_SWITCHES, dop853.RUN_YIELD):
            continue
        if code == dop853.RUN_SAMPLES:
            y_at = stepper.dense()
            for t in run.sample_times(stepper.t):
                if run.ends_at(run.record(t, y_at(t) if t < stepper.t else stepper.y)):
                    return
            continue
        # RUN_BOUNDARY: the end, a controller's update, a checkpoint
        if stepper.t >= run.t_end:
            return
        if run.at_control_time(stepper.t):
            run.update_control(stepper.t, stepper.y)
            stepper.restart()
        if run.checkpoint_due():
            stepper.run(stepper.t, math.inf)  # (the restart, if due)
            run.save(
                stepper.t,
                stepper.y,
                stepper,
                stepper.taut,
                stepper.landing(),
                bool(stepper.tally[dop853.ALLOW_PROVISIONAL]),
            )
        bound = run.next_boundary(stepper.t)


def _hermite(
    t: float, t0: float, y0: np.ndarray, f0: np.ndarray, t1: float, y1: np.ndarray, f1: np.ndarray
) -> np.ndarray:
    """Cubic Hermite interpolation inside a fixed step from the values and slopes at its ends."""
    h = t1 - t0
    s = (t - t0) / h
    s2, s3 = s * s, s * s * s
    return (
        (2 * s3 - 3 * s2 + 1) * y0
        + (s3 - 2 * s2 + s) * h * f0
        + (-2 * s3 + 3 * s2) * y1
        + (s3 - s2) * h * f1
    )


def _fixed_step(run: _Run, stepper: RK4, resume: LoopState | None) -> None:
    """The loop of ``"rk4"``: compiled stretches of steps up to each sample or controller update
    (the last step shorter, to land on ``t_end``); a sample inside a step is interpolated (cubic
    Hermite), one on a step's end is that end before projection.  A controller is called at the
    end of the first step at or after each of its update times.  (A resumed run's steps taken
    are :attr:`_Run.steps_done`, restored from ``resume``.)"""
    if resume is None:
        run.start_monitor(stepper.y)
    t0, dt = run.t0, run.options.dt
    assert dt is not None  # `Options` requires a step for a fixed-step method
    n_full = int(np.floor((run.t_end - t0) / dt + 1e-9))
    last = run.t_end - (t0 + n_full * dt)
    n_steps = n_full + (1 if last > 1e-9 * dt else 0)

    def step_reaching(t: float) -> int:
        return min(int(np.ceil((t - t0) / dt - 1e-9)), n_steps)

    while run.steps_done < n_steps:
        done = run.steps_done
        reach = step_reaching(run.sample_time(run.next_sample))
        if run.controller is not None:
            reach = min(reach, max(step_reaching(run.control_time(t0 + done * dt)), done + 1))
        if reach - done > 1 and not _rk4_steps(run, stepper, reach - done - 1, dt):
            return  # (the whole steps before the one that reaches the sample)
        h = last if run.steps_done == n_full else dt
        t_old, y_old = stepper.t, stepper.y.copy()
        if not _rk4_steps(run, stepper, 1, h, keep_first=True):
            return
        stepper.t = run.t_end if run.steps_done == n_steps else t0 + run.steps_done * dt
        if run.progress is not None:
            run.progress(stepper.t)
        for t in run.sample_times(stepper.t):
            y = stepper.y_end
            if abs(t - stepper.t) > 1e-9 * dt:
                f_new = np.empty_like(y_old)
                data = run.system.stage_inputs(np.array([stepper.t]))
                compiled.ode_rhs_entry(run.system.model, data, 0, stepper.y_end, f_new)
                stepper.nfev += 1
                y = _hermite(t, t_old, y_old, stepper.first, stepper.t, stepper.y_end, f_new)
            if run.ends_at(run.record(t, y)):
                return
        if (
            run.controller is not None
            and run.steps_done < n_steps
            and (step_reaching(run.control_time(t0 + (run.steps_done - 1) * dt)) <= run.steps_done)
        ):
            run.update_control(stepper.t, stepper.y)
        if run.steps_done < n_steps and run.checkpoint_due():
            run.save(stepper.t, stepper.y, stepper, None, None, False)


def _rk4_steps(run: _Run, stepper: RK4, n: int, h: float, *, keep_first: bool = False) -> bool:
    """``n`` checked, projected RK4 steps of ``h``, the stepper's time moved on, in compiled
    calls of at most :func:`dop853.steps_per_turn` steps (the wall-clock budget checked between
    them); False (and the run failed) on a blow-up or when out of time.  ``keep_first``: the
    stepper keeps ``f`` at the last step's start (:attr:`RK4.first`)."""
    # (whole multiples of the energy check's period: each call checks the energy at its end)
    every = compiled.ENERGY_CHECK_EVERY
    per_call = max(1, dop853.steps_per_turn(run.system, 4) // every) * every
    t_start, done = stepper.t, 0
    while done < n:
        steps, code, value = stepper.advance(min(n - done, per_call), h, keep_first=keep_first)
        done += steps
        stepper.t = t_start + done * h
        run.steps_done += steps
        run.counts["nsteps"] += steps
        failed = code not in (compiled.CHECK_OK, compiled.CHECK_INPUT)
        run.counts["nprojections"] += steps - failed
        if code == compiled.CHECK_INPUT:  # (the last state, projected, is recorded at the end)
            run.status, run.message = STATUS_FAILED, stepper.input_error
            return False
        if code != compiled.CHECK_OK:
            run.fail(code, value, stepper.t)
            run.record(stepper.t, stepper.y_end)
            return False
        if run.out_of_time(stepper.t):
            return False
    return True


def actuator_command(system: CompiledSystem, u: np.ndarray, t: float, name: str) -> np.ndarray:
    """The actuators' command (A,) [m] in the output ``u`` of a controller (or the control
    ``name`` stands for) at ``t`` [s]: (A,), or (S,) with zero on the tendons that are not
    actuated; ``ValueError`` naming ``name`` and the time if it is neither, is not finite, or
    (without actuators given) makes a rest length negative."""
    actuated = system.actuators
    assert actuated is not None, "actuator_command: the system has no actuators"
    S, A = system.structure.n_tendons, actuated.size
    if u.shape not in ((A,), (S,)):
        raise ValueError(
            f"{name}: got shape {u.shape} at t = {t:.6g} s; expected ({A},) (the "
            f"actuated tendons) or ({S},)"
        )
    if not np.all(np.isfinite(u)):
        raise ValueError(f"{name}: got a value that is not finite at t = {t:.6g} s")
    command = u if u.shape == (A,) else u[actuated.tendons]
    rest0 = system.structure.tendon_rest_length[actuated.tendons]
    if system.inputs.actuators is None and np.any(rest0 - command < 0):
        # (without actuators a controller may not make a rest length negative)
        a = int(np.flatnonzero(rest0 - command < 0)[0])
        raise ValueError(
            f"{name}[{actuated.tendons[a]}]: rest length {rest0[a]:g} - {command[a]:g} "
            f"is negative at t = {t:g} s"
        )
    if u.shape == (A,):
        return command
    idle = np.ones(S, bool)
    idle[actuated.tendons] = False
    if np.any(u[idle] != 0):
        s = int(np.flatnonzero(idle & (u != 0))[0])
        raise ValueError(
            f"{name}: got u = {u[s]:g} m for tendon "
            f"{system.structure.tendon_name[s]!r} at t = {t:.6g} s, which is not actuated"
        )
    return command


def time_span(t_span: Any) -> tuple[float, float]:
    """``(t0, t_end)`` [s] of a run, finite with ``t0 < t_end``; ``ValueError`` naming
    ``t_span`` otherwise."""
    try:
        t0, t_end = t_span
        t0, t_end = float(t0), float(t_end)
    except (TypeError, ValueError):
        raise ValueError(
            f"t_span: expected (t0, t_end), two numbers in s, got {t_span!r:.60}"
        ) from None
    if not (np.isfinite(t0) and np.isfinite(t_end) and t_end > t0):
        raise ValueError(f"t_span: need finite t0 < t_end, got {t_span!r}")
    return t0, t_end


def check_initial(structure: Structure, state: Any) -> None:
    """``TypeError`` unless ``state`` is a :class:`~tensegrity.physics.dynamics.State`,
    ``ValueError`` unless its ``q`` and ``qdot`` are finite and have the structure's
    coordinates."""
    if not isinstance(state, dynamics.State):
        raise TypeError(f"initial: expected a State (t, q, qdot), got {type(state).__name__}")
    n = structure.n_coordinates
    for name in ("q", "qdot"):
        value = getattr(state, name)
        shape = np.shape(value)
        if shape != (n,):
            raise ValueError(
                f"initial.{name}: expected shape ({n},) for this structure, got {shape}"
            )
        if not np.all(np.isfinite(value)):
            bad = int(np.flatnonzero(~np.isfinite(value))[0])
            raise ValueError(f"initial.{name}[{bad}]: must be finite, got {value[bad]!r}")


def run(
    structure: Structure,
    t_span: tuple[float, float],
    *,
    initial: dynamics.State | None = None,
    inputs: Inputs | None = None,
    options: Options | None = None,
    sink: Sink,
    progress: Callable[[float], None] | None = None,
    controller: Controller | LinearFeedback | None = None,
    checkpoint: Checkpointing | None = None,
    resume: LoopState | None = None,
    stop: StopCondition | None = None,
    sensitivity: Sequence[Any] | None = None,
) -> RunSummary:
    """Integrate ``structure`` over ``t_span = (t0, t_end)`` [s], handing samples to ``sink``
    (Theorem 18.1 with eqs. 18.39-18.60; the loop of the module docstring).

    ``initial`` defaults to the structure's node positions and velocities at ``t0``;
    ``inputs`` (:class:`Inputs`) to no control, load or gravity, ``options`` to ``Options()``.
    ``progress``, if given, is called with the time reached after each stretch of steps.
    ``controller``
    (:class:`Controller`, or a :class:`~tensegrity.engine.feedback.LinearFeedback` that
    compiled code runs) sets the control at ``t0`` and every ``controller.period`` after (the
    inputs may then have no control of their own), through the inputs' actuators if they have
    any.  ``checkpoint`` saves the loop's state every
    ``checkpoint.every`` samples; ``resume`` continues from such a state (the same structure,
    inputs, options and controller, and no ``initial``; the samples up to it are not handed to
    ``sink`` again).  ``stop`` (:class:`StopCondition`) may end the run at a sample.
    ``sensitivity``: parameters (:func:`tensegrity.engine.sensitivity.prepare`) whose
    derivatives of the state are integrated with it (DOP853; no controller, actuators or
    checkpoints), at every sample in the summary's ``sensitivity``.  Returns a
    :class:`RunSummary`; the samples went to ``sink``, the last one at the end time, the steady
    state, the stop or the failing state.
    """
    options = Options() if options is None else options
    t0, t_end = time_span(t_span)
    inputs = Inputs(structure) if inputs is None else inputs
    if controller is not None and inputs.control.kind != "none":
        raise ValueError("control: give a control or a controller, not both")
    if checkpoint is not None and not (isinstance(checkpoint.every, int) and checkpoint.every > 0):
        raise ValueError(f"checkpoint.every: must be a whole number > 0, got {checkpoint.every!r}")
    options.check_span(t0, t_end)
    if inputs.ground and (options.fixed_step or not options.locate_switches):
        raise ValueError(
            "ground (--ground): contact needs an adaptive method that locates events (not "
            "method='rk4' (--method rk4), not locate_switches=False)"
        )
    inputs.rest_length(np.array([t0]))  # a control making a rest length negative fails here
    if sensitivity is not None and (
        options.method != "DOP853"
        or not options.locate_switches
        or controller is not None
        or inputs.actuators is not None
        or checkpoint is not None
        or resume is not None
    ):
        raise ValueError(
            "sensitivity: integrated by method='DOP853' only, locating its events, without a "
            "controller, actuators or checkpoints"
        )
    r = _Run(structure, t0, t_end, inputs, options, sink, controller, checkpoint, progress, stop)
    if resume is None:
        state = dynamics.initial_state(structure, t=t0) if initial is None else initial
        check_initial(structure, state)
        y0 = r.system.state_vector(state)
        r.system.check_contacts(y0)
        if controller is not None:
            r.update_control(t0, y0)
        work = None if sensitivity is None else prepare_sensitivity(r.system, sensitivity, y0)
        r.start_contacts(t0, y0)
        stepper, loop = _method(r, t0, y0.copy(), None, work)
        r.stopped_at(r.record(t0, y0))
    else:
        r.restore(resume)
        stepper, loop = _method(r, resume.t, resume.y.copy(), resume.memory)
    try:
        if r.status != STATUS_STOPPED:  # (by the stop condition, at the first sample)
            loop(r, stepper, resume)
    except (IntegrationError, ValueError, FloatingPointError) as exc:
        r.status, r.message = STATUS_FAILED, str(exc)
    if r.status not in (STATUS_STEADY, STATUS_STOPPED) and short_of(r.last_sample_t, stepper.t):
        r.record(stepper.t, stepper.y)  # the end, or the last state before a failure
    r.flush()
    return RunSummary(
        status=r.status,
        message=r.message,
        t_final=r.last_sample_t,
        nfev=r.nfev_before + stepper.nfev,
        max_rod_length_error=float(r.monitor[2]),
        max_constraint_error=float(r.monitor[3]),
        wall_time=r.wall_time(),
        settings=r.settings(inputs),
        switch_times=tuple(r.switch_times),
        contact_events=r.contact_event_log(),
        control_updates=r.control_updates(),
        stopped_for_time=r.stopped_for_time,
        sensitivity=None if sensitivity is None else r.system.sensitivity_layout(r.sensitivities),
        **r.counts,
    )
