"""DOP853, the default method, with its whole step loop compiled (:func:`dop853_run`): the
attempts and their error control, the located events, the blow-up checks, the
projection onto the constraints and the step-size law run in compiled code from one output
sample (or boundary) to the next; :class:`DOP853` holds the loop's state between those calls
for the run loop (:mod:`tensegrity.engine.loop`), which records the samples, calls a
controller and saves checkpoints.

The method, coefficients, error norm and step-size law are ``scipy.integrate.DOP853``'s
(:mod:`tensegrity.engine.compiled`). Per accepted step, the events (the tendons' slack/taut
switches, the contacts' touch-down, lift-off, stick and slip) are found, located on the step's
polynomial and landed on by the one mechanism of :mod:`tensegrity.engine.events` (its module
docstring): the step is discarded and retaken to end exactly at the first event.  A rejected
attempt whose end shows an event may stand for the step (*provisional*): the event is located
on it instead of shrinking the step until the kink falls out of it.  The step size carries over
a projection or a located event.

Inputs: constant, or made where they are used by :func:`compiled.make_inputs` (tabulated ones
interpolated in compiled code, Python functions of time called through a callback: one loop for
every kind of input); a Python function is called once per attempt with the attempt's stage
times.

The loop's state lives in a few arrays (:class:`DOP853`): ``clock`` (float64, indices
``T``...), ``tally`` (int64, indices ``NFEV``...), the state buffers, and the events'
:class:`~tensegrity.engine.events.EventWork` (their sides, the taut flags, and the landing: a
located event being headed for).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from tensegrity.engine import compiled
from tensegrity.engine.actuation import log_full as actuation_log_full, next_ramp_end
from tensegrity.engine.compiled import (
    CHECK_OK,
    DOP853_C,
    DOP853_STAGES,
    check_state,
    dop853_attempt,
    dop853_dense,
    dop853_interpolate,
    feedback_update,
    inputs_vary,
    make_inputs,
    next_update,
    ode_rhs,
    update_due,
)
from tensegrity.engine.events import (
    EventWork,
    event_work,
    events_crossed,
    land_contacts,
    landing_of,
    locate_event,
    log_full,
    restore_landing,
    set_sides,
    stick_slow_slips,
)
from tensegrity.engine.sensitivity import (
    SensitivityWork,
    advance_sensitivity,
    dense_sensitivity,
    event_time_derivative,
    has_sensitivity,
    interpolate as interpolate_sensitivity,
    keep_state,
    saltation,
)
from tensegrity.engine.steppers import StepperMemory
from tensegrity.engine.system import CompiledSystem
from tensegrity.physics.compiling import JIT_OPTIONS
from tensegrity.physics.contact import refresh_slips
from tensegrity.physics.kernel import copy_values
from tensegrity.physics.kernel_system import system_project

#: Step-size law (scipy's): safety factor, smallest and largest factor, error exponent.
SAFETY, MIN_FACTOR, MAX_FACTOR, EXPONENT = 0.9, 0.2, 10.0, -1.0 / 8.0
#: Located switches :func:`dop853_run` keeps before it returns them (``RUN_SWITCHES``).
SWITCH_BUFFER = 256
#: Work of one compiled call between returns to Python, in member evaluations (members times
#: right-hand-side evaluations): about 0.05 s, so that signals (Ctrl-C, SIGTERM) and the
#: wall-clock budget are heard within a fraction of a second however small the steps.
YIELD_WORK = 2_000_000

#: Indices of ``clock`` (float64): time [s], start of the last step [s], the next step size
#: [s], the step size before heading for a switch [s], the time of the switch headed for [s],
#: the last step's largest constraint drift (rod relative, joints [m]), the time whose inputs
#: could not be made [s], the time since which the motion has been smooth (the run's start, the
#: last event landed on or the last restart) [s].
T, T_OLD, STEP, STEP_BEFORE, LANDING_TIME, DRIFT, INPUT_TIME, SMOOTH_SINCE = range(8)
N_CLOCK = 8
#: Indices of ``tally`` (int64): evaluations, accepted steps, located switches, projections;
#: flags: the last step is a provisional (rejected) attempt, its dense output is ready, a
#: provisional step may be taken, a switch is headed for, it was located exactly, the last step
#: landed on it, an accepted step waits to be finished (its samples were handed out), the
#: first stage must be evaluated again (the state changed); switches in the buffer; the run
#: starts here (its first stage, the blow-up monitor and the initial step are to be made).
(
    NFEV,
    NSTEPS,
    NSWITCHES,
    NPROJECTIONS,
    PROVISIONAL,
    DENSE_READY,
    ALLOW_PROVISIONAL,
    LANDING,
    LANDING_EXACT,
    LANDED,
    PENDING,
    RESTART,
    NEW_SWITCHES,
    START,
) = range(14)
N_TALLY = 14

#: The counts a run reports, by their index in ``tally``.
_COUNTS = {"nsteps": NSTEPS, "nswitches": NSWITCHES, "nprojections": NPROJECTIONS}

#: What :func:`dop853_run` returns: the samples up to the last step's end are due (its dense
#: output ready); the step reached ``bound``; ``max_steps`` steps were taken; the switch buffer
#: is full; a blow-up check failed; the step size fell below its minimum; an input could not be
#: made (a control table makes a rest length negative at ``clock[INPUT_TIME]``); the call has
#: made its share of attempts (``settings[6]``: Python gets its turn, for signals and the
#: wall-clock budget, at least that often).
(
    RUN_SAMPLES,
    RUN_BOUNDARY,
    RUN_MAX_STEPS,
    RUN_SWITCHES,
    RUN_CHECK_FAILED,
    RUN_STEP_FAILED,
    RUN_INPUT,
    RUN_YIELD,
) = range(8)


class LoopWork(NamedTuple):
    """The loop's own state and scratch (:func:`dop853_run`'s ``loop``), held by
    :class:`DOP853` between calls."""

    clock: np.ndarray  #: (N_CLOCK,) float64, indices ``T``...
    tally: np.ndarray  #: (N_TALLY,) int64, indices ``NFEV``...
    y: np.ndarray  #: (m,) the state
    y_old: np.ndarray  #: (m,) the state at the last step's start
    K: np.ndarray  #: (16, m) the stages
    F: np.ndarray  #: (7, m) the last step's dense-output polynomial
    y_new: np.ndarray  #: (m,) scratch
    stage: np.ndarray  #: (m,) scratch
    #: the events (:mod:`tensegrity.engine.events`): their sides (the tendons taut at the
    #: state), the located event headed for, scratch
    events: EventWork
    switch_times: np.ndarray  #: (SWITCH_BUFFER,) [s]: switches located by this call
    #: ``(rtol, atol, t_end [s], projection_tol, max_steps, locate, attempts)``: the call
    #: returns (``RUN_YIELD``) once it has made ``attempts`` attempts
    settings: tuple
    #: the sensitivities integrated with the state
    #: (:class:`~tensegrity.engine.sensitivity.SensitivityWork`), or None
    sensitivity: Any = None


@njit(**JIT_OPTIONS)
def dop853_run(model, rows, point, loop, bound, next_sample_t):  # pragma: no cover - compiled
    """The adaptive loop from ``loop.clock[T]`` until the samples of a step are due, the step
    reaches ``bound`` [s], or the run must stop (see the module doc); ``(code, check code,
    check value)``.

    ``rows`` and ``point`` are data records (:class:`tensegrity.physics.records.Data`) for a
    step's 16 stages and for one time, their inputs made where they are used
    (:func:`compiled.make_inputs`: from the tables, or through the callback to Python functions
    of time); ``loop`` the :class:`LoopWork`.

    The loop reads its state by field name (``loop.clock[T]``), never through a local alias of
    a field (``clock = loop.clock``): with such aliases captured by the closures below, numba
    0.68 compiled a store to ``clock`` just before a ``return`` to nothing (the run then failed
    with its input's time lost: ``test_control_table_bad_input_names_the_field``).

    The whole loop is one function, its heavy callees (the stages, the dense output, the switch
    distance, the checks, the projection) called from here only: numba compiles every function
    that calls them with their code linked in again, so helpers around them would each cost
    about a second of the first run's compile.  Its small helpers are closures, which numba
    inlines (a compiled function of its own costs about 0.1 s of that compile each).
    """
    settings = loop.settings
    limits = model.limits
    rtol, atol, t_end, projection_tol = settings[0], settings[1], settings[2], settings[3]
    max_steps, locate, attempts_per_call = settings[4], settings[5], settings[6]
    attempts = 0
    m = loop.y.shape[0]
    n = (m - 3) // 2
    times = np.empty(DOP853_C.shape[0])
    times1 = np.empty(1)
    varying = inputs_vary(rows)

    def inputs_at(t):
        """The inputs at the single time ``t`` [s] into ``point``: the first row they could not
        be made for, or -1 (:func:`compiled.make_inputs`)."""
        times1[0] = t
        return make_inputs(model.callback, model.tables, times1, point) if varying else -1

    def stage_times(t, h):
        """The 16 stage times of a step of ``h`` [s] from ``t`` [s] into ``times``."""
        for i in range(DOP853_C.shape[0]):
            times[i] = t + DOP853_C[i] * h

    def step_within(t, h, bound, min_step):
        """The step size [s] to try from ``t``: ``h`` but not past ``bound``, and all the way
        to it when less than ``min_step`` would be left."""
        h = max(min(h, bound - t), min_step)
        if t + h > bound or bound - (t + h) < min_step:
            h = bound - t
        return h

    def shrink(error):
        """The factor of a rejected step with error norm ``error`` (> 1, or not finite)."""
        if not np.isfinite(error):
            return MIN_FACTOR
        return max(MIN_FACTOR, SAFETY * error**EXPONENT)

    def grow(error, rejected):
        """The factor of the next step after one accepted with error norm ``error`` (< 1),
        not above 1 if the step was rejected before."""
        factor = MAX_FACTOR
        if error != 0.0:
            factor = min(MAX_FACTOR, SAFETY * error**EXPONENT)
        return min(1.0, factor) if rejected else factor

    def initial_step(f0, f1):
        """Hairer, Norsett and Wanner's initial step (II.4), as ``scipy``'s, from the first
        stage ``f0`` at ``y`` (``f1`` scratch); derivatives too large to measure (a velocity of
        1e200 m/s) give scipy's fallback ``1e-6`` s: the steps then find the state unusable
        and say so."""
        t = loop.clock[T]
        d0, d1 = 0.0, 0.0
        for i in range(m):
            scale = atol + abs(loop.y[i]) * rtol
            d0 += (loop.y[i] / scale) ** 2
            d1 += (f0[i] / scale) ** 2
        d0, d1 = np.sqrt(d0 / m), np.sqrt(d1 / m)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        if not (np.isfinite(h0) and h0 > 0.0):
            h0 = 1e-6
        h0 = min(h0, t_end - t)
        for i in range(m):
            loop.y_new[i] = loop.y[i] + h0 * f0[i]
        bad = inputs_at(t + h0)
        if bad >= 0:
            loop.clock[INPUT_TIME] = t + h0
            return np.nan
        ode_rhs(model, point, np.int64(0), loop.y_new, f1)
        loop.tally[NFEV] += 1
        d2 = 0.0
        for i in range(m):
            d2 += ((f1[i] - f0[i]) / (atol + abs(loop.y[i]) * rtol)) ** 2
        d2 = np.sqrt(d2 / m) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
        return min(100.0 * h0, h1, t_end - t)

    while True:
        if (
            attempts >= attempts_per_call
            or log_full(point.contact_work)
            or actuation_log_full(point.actuation)
        ):
            return RUN_YIELD, CHECK_OK, 0.0  # (Python takes the logs of contacts and updates)
        if loop.tally[PENDING]:  # finish the accepted step whose samples were handed out
            loop.tally[PENDING] = 0
            copy_values(loop.K[DOP853_STAGES], loop.K[0], m)  # first same as last
            if loop.tally[LANDED]:
                loop.clock[STEP] = max(loop.clock[STEP], loop.clock[STEP_BEFORE])
                loop.tally[ALLOW_PROVISIONAL] = loop.tally[LANDING_EXACT]
                loop.tally[LANDING] = 0
                # the events' actions, once the step's samples are out (contacts that change
                # mode change the right-hand side: the steps start anew)
                contacts = loop.events.side.shape[0] > model.tendon_stiffness.shape[0]
                exact = locate and bool(loop.tally[LANDING_EXACT])
                acting = contacts or has_sensitivity(loop.sensitivity)
                if exact and acting and inputs_at(loop.clock[T]) < 0:
                    keep_state(loop.sensitivity, loop.y)
                    timed = event_time_derivative(  # (the sensitivities' event time)
                        loop.sensitivity,
                        model,
                        point,
                        (loop.clock[SMOOTH_SINCE], loop.clock[T]),
                        loop.y,
                        loop.K[0],
                        loop.events,
                        varying,
                    )
                    if contacts and land_contacts(
                        model.contacts, model, point, loop.clock[T], loop.y, loop.events
                    ):
                        loop.tally[RESTART] = 1
                    saltation(loop.sensitivity, model, point, loop.clock[T], loop.y, timed)
                loop.clock[SMOOTH_SINCE] = loop.clock[T]
            if (  # (the rule for slow slips, after every step)
                loop.events.side.shape[0] > model.tendon_stiffness.shape[0]
                and inputs_at(loop.clock[T]) < 0
            ):
                keep_state(loop.sensitivity, loop.y)
                if stick_slow_slips(
                    model.contacts, model, point, loop.clock[T], loop.y, loop.events
                ):
                    loop.tally[RESTART] = 1
                    saltation(loop.sensitivity, model, point, loop.clock[T], loop.y, False)
            if loop.clock[DRIFT] > projection_tol:
                if not system_project(model, point, loop.y[:n], loop.y[n : 2 * n])[2]:
                    return RUN_CHECK_FAILED, compiled.CHECK_PROJECTION, np.nan
                loop.tally[NPROJECTIONS] += 1
                loop.tally[RESTART] = 1
            if loop.clock[T] >= t_end or loop.clock[T] >= bound:
                return RUN_BOUNDARY, CHECK_OK, 0.0  # (a controller may change the inputs)
            if loop.tally[NSTEPS] >= max_steps:
                return RUN_MAX_STEPS, CHECK_OK, 0.0
        if not loop.tally[START] and update_due(model.feedback, point.actuation, loop.clock[T]):
            # a compiled feedback law's update (the step landed on its time)
            if inputs_at(loop.clock[T]) >= 0:
                loop.clock[INPUT_TIME] = loop.clock[T]
                return RUN_INPUT, CHECK_OK, 0.0
            feedback_update(model.feedback, model, point, loop.clock[T], loop.y)
            loop.tally[RESTART] = 1
            loop.tally[LANDING] = 0
        update = next_update(model.feedback, point.actuation)
        if (
            loop.tally[RESTART] or loop.tally[START]
        ):  # the state changed, or the run starts: its first
            loop.tally[RESTART] = 0  # stage and taut flags anew
            loop.clock[SMOOTH_SINCE] = loop.clock[T]
            bad = inputs_at(loop.clock[T])
            if bad >= 0:
                loop.clock[INPUT_TIME] = loop.clock[T]
                return RUN_INPUT, CHECK_OK, 0.0
            ode_rhs(model, point, np.int64(0), loop.y, loop.K[0])
            loop.tally[NFEV] += 1
            if locate or loop.tally[START]:
                exact = bool(loop.tally[LANDED]) and bool(loop.tally[LANDING_EXACT])
                set_sides(point, loop.events, exact)
            if loop.tally[START]:  # and the monitor at the start, the initial step
                loop.tally[START] = 0
                no_limits = np.full(3, np.inf)
                check_state(model, point, np.int64(0), loop.y, no_limits, np.bool_(True))
                loop.clock[STEP] = initial_step(loop.K[0], loop.K[1])
                if np.isnan(loop.clock[STEP]):
                    return RUN_INPUT, CHECK_OK, 0.0
                loop.tally[ALLOW_PROVISIONAL] = locate
        loop.tally[LANDED] = 0
        if loop.clock[T] >= bound:
            return RUN_BOUNDARY, CHECK_OK, 0.0
        heading = bool(loop.tally[LANDING])
        detect = locate and not (heading and loop.tally[LANDING_EXACT])
        # (a feedback law's update ends a step too, and an actuator's ramp ending into its lag)
        stop = min(bound, update, next_ramp_end(point.actuation, loop.clock[T]))
        target = min(stop, loop.clock[LANDING_TIME]) if heading else stop
        use_taut = locate and bool(loop.tally[ALLOW_PROVISIONAL]) and not heading

        # ---- one step not past ``target`` (scipy's step-size law); with ``use_taut`` a
        # rejected attempt whose end shows a tendon switched stands for it (provisional)
        t, h = loop.clock[T], loop.clock[STEP]
        loop.tally[PROVISIONAL] = 0
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        rejected = False
        while True:
            h = step_within(t, h, target, min_step)
            stage_times(t, h)
            bad = make_inputs(model.callback, model.tables, times, rows) if varying else -1
            if bad >= 0:
                loop.clock[INPUT_TIME] = times[bad]
                return RUN_INPUT, CHECK_OK, 0.0
            error = dop853_attempt(
                model, rows, loop.y, h, loop.K, loop.y_new, loop.stage, (rtol, atol)
            )
            loop.tally[NFEV] += DOP853_STAGES
            attempts += 1
            if error < 1.0:
                break
            if use_taut and np.isfinite(error) and events_crossed(point, loop.events) > 0:
                loop.tally[PROVISIONAL] = 1
                break
            h *= shrink(error)
            rejected = True
            if not h >= min_step:  # (NaN too: a step size that is not a number never shrinks)
                return RUN_STEP_FAILED, CHECK_OK, 0.0
        if not loop.tally[PROVISIONAL]:
            loop.clock[STEP] = h * grow(error, rejected)
        loop.clock[T_OLD] = t
        copy_values(loop.y, loop.y_old, m)
        loop.clock[T] = target if h == target - t else t + h
        copy_values(loop.y_new, loop.y, m)
        loop.tally[DENSE_READY] = 0
        loop.tally[ALLOW_PROVISIONAL] = locate

        # ---- an event within the step: the candidates
        count = events_crossed(point, loop.events) if detect else 0
        if count == 0:  # the step stands: the checks, then the next step or the samples
            loop.tally[NSTEPS] += 1
            advance_sensitivity(
                loop.sensitivity,
                model,
                rows,
                times,
                loop.y_old,
                loop.y,
                loop.K,
                h,
                loop.events.side,
            )
            landed = bool(loop.tally[LANDING]) and loop.clock[T] >= loop.clock[LANDING_TIME]
            loop.tally[LANDED] = landed
            bad = inputs_at(loop.clock[T])
            if bad >= 0:
                loop.clock[INPUT_TIME] = loop.clock[T]
                return RUN_INPUT, CHECK_OK, 0.0
            if locate:
                exact = landed and bool(loop.tally[LANDING_EXACT])
                set_sides(point, loop.events, exact)
                refresh_slips(model.contacts, point, loop.y)
            check, value = check_state(model, point, np.int64(0), loop.y, limits, np.bool_(True))
            if check != CHECK_OK:
                return RUN_CHECK_FAILED, check, value
            loop.clock[DRIFT] = value
            loop.tally[PENDING] = 1
            if next_sample_t > loop.clock[T] + 1e-14 * abs(loop.clock[T]):  # (options.reaches)
                continue

        # ---- the step's dense output: for its samples, or to locate the switch
        t_old, h = loop.clock[T_OLD], loop.clock[T] - loop.clock[T_OLD]
        stage_times(t_old, h)
        bad = make_inputs(model.callback, model.tables, times, rows) if varying else -1
        if bad >= 0:
            loop.clock[INPUT_TIME] = times[bad]
            return RUN_INPUT, CHECK_OK, 0.0
        dop853_dense(model, rows, loop.y_old, loop.y, h, loop.K, loop.F, loop.stage)
        loop.tally[NFEV] += 3
        loop.tally[DENSE_READY] = 1
        if count == 0:
            dense_sensitivity(loop.sensitivity, model, rows, times, loop.y_old, loop.y, h, loop.K)
            return RUN_SAMPLES, CHECK_OK, 0.0

        # ---- the earliest event (tensegrity.engine.events.locate_event), headed for
        t_switch, input_time = locate_event(
            model,
            point,
            varying,
            None,
            (t_old, loop.clock[T], loop.F, loop.y_old),
            loop.events,
            count,
        )
        if np.isnan(t_switch):
            loop.clock[INPUT_TIME] = input_time
            return RUN_INPUT, CHECK_OK, 0.0
        exact = not loop.tally[PROVISIONAL]
        loop.clock[LANDING_TIME] = t_switch
        loop.tally[LANDING] = 1
        loop.tally[LANDING_EXACT] = exact
        # retreat: back to the step's start, heading for the switch
        loop.clock[T] = t_old
        copy_values(loop.y_old, loop.y, m)
        loop.tally[DENSE_READY] = 0
        loop.clock[STEP_BEFORE], loop.clock[STEP] = loop.clock[STEP], t_switch - t_old
        if exact:
            loop.tally[NSWITCHES] += 1
            loop.switch_times[loop.tally[NEW_SWITCHES]] = t_switch
            loop.tally[NEW_SWITCHES] += 1
            if loop.tally[NEW_SWITCHES] == loop.switch_times.shape[0]:
                return RUN_SWITCHES, CHECK_OK, 0.0


class DOP853:
    """Explicit Runge-Kutta of order 8(5,3), adaptive (``rtol``, ``atol``), its loop compiled
    (:func:`dop853_run`).  ``t``, ``y`` the current time [s] and state, ``nfev`` the
    right-hand-side evaluations so far."""

    def __init__(
        self,
        system: CompiledSystem,
        t0: float,
        y0: np.ndarray,
        *,
        rtol: float,
        atol: float,
        t_end: float,
        max_steps: int,
        projection_tol: float,
        locate: bool,
        memory: StepperMemory | None = None,
        sensitivity: SensitivityWork | None = None,
    ) -> None:
        """Start at ``(t0, y0)`` with Hairer's initial step, or continue with ``memory`` (of a
        checkpoint) exactly as the stepper that made it would have; ``sensitivity``: the
        derivatives of the state integrated with it (:mod:`tensegrity.engine.sensitivity`)."""
        self.system, self.rtol, self.atol = system, rtol, atol
        m = system.m
        attempts = steps_per_turn(system, DOP853_STAGES)
        y = np.array(y0, dtype=float)
        self.loop = loop = LoopWork(
            clock=np.zeros(N_CLOCK),
            tally=np.zeros(N_TALLY, np.int64),
            y=y,
            y_old=y.copy(),
            K=np.zeros((DOP853_C.size, m)),
            F=np.empty((compiled.DOP853_DENSE_ROWS, m)),
            y_new=np.empty(m),
            stage=np.empty(m),
            events=event_work(system),
            switch_times=np.zeros(SWITCH_BUFFER),
            settings=(
                float(rtol),
                float(atol),
                float(t_end),
                float(projection_tol),
                np.int64(max_steps),
                np.bool_(locate),
                np.int64(attempts),
            ),
            sensitivity=sensitivity,
        )
        self.clock, self.tally = loop.clock, loop.tally
        self.clock[T] = self.clock[T_OLD] = self.clock[SMOOTH_SINCE] = float(t0)
        if memory is None:  # (the first call makes the first stage and the initial step)
            self.tally[START] = 1
        else:
            loop.K[0] = memory.first_stage
            self.clock[STEP], self.clock[STEP_BEFORE] = memory.step, memory.step_before

    # ------------------------------------------------------------------ the state
    @property
    def t(self) -> float:
        """The current time [s]."""
        return float(self.clock[T])

    @property
    def y(self) -> np.ndarray:
        """The current state (m,), the engine's ``[q, q', E_d, W_w, W_u]`` (a buffer)."""
        return self.loop.y

    @property
    def nfev(self) -> int:
        """Right-hand-side evaluations so far."""
        return int(self.tally[NFEV])

    @property
    def taut(self) -> np.ndarray:
        """Taut flags (S,), kernel order (the events' sides)."""
        return self.loop.events.side

    def memory(self) -> StepperMemory:
        """What a checkpoint keeps to continue from the current state exactly."""
        return StepperMemory(
            self.loop.K[0].copy(), float(self.clock[STEP]), float(self.clock[STEP_BEFORE])
        )

    def landing(self) -> tuple[float, np.ndarray, np.ndarray, bool] | None:
        """The switch headed for: ``(time, tendons, taut after, exact)``, or None."""
        if not self.tally[LANDING]:
            return None
        tendons, after = landing_of(self.loop.events)
        return float(self.clock[LANDING_TIME]), tendons, after, bool(self.tally[LANDING_EXACT])

    def restore(
        self,
        taut: np.ndarray,
        landing: tuple[float, np.ndarray, np.ndarray, bool] | None,
        allow_provisional: bool,
    ) -> None:
        """The taut flags, the landing and the provisional flag of a checkpoint."""
        events = self.loop.events
        events.side[:] = taut
        self.tally[ALLOW_PROVISIONAL] = allow_provisional
        self.tally[LANDING] = landing is not None
        none = (0.0, np.zeros(0, np.int64), np.zeros(0, bool), False)
        time, tendons, after, exact = landing or none
        restore_landing(events, tendons, after)
        self.clock[LANDING_TIME], self.tally[LANDING_EXACT] = time, exact

    def counts(self) -> dict[str, int]:
        """Accepted steps, located switches and projections so far."""
        return {name: int(self.tally[i]) for name, i in _COUNTS.items()}

    def set_counts(self, counts: dict[str, int]) -> None:
        """The counts of a checkpoint (``nsteps``, ``nswitches``, ``nprojections``)."""
        for name, i in _COUNTS.items():
            self.tally[i] = counts[name]

    # ------------------------------------------------------------------ stepping
    def run(self, bound: float, next_sample_t: float) -> tuple[int, int, float]:
        """:func:`dop853_run` up to ``bound`` [s] or the step whose samples are due from
        ``next_sample_t`` [s], with the system's limits and blow-up monitor: ``(code, check
        code, check value)``.  The located switches it returns are in
        :meth:`new_switch_times`."""
        system = self.system
        self.tally[NEW_SWITCHES] = 0
        rows, point = system.input_buffers(DOP853_C.size), system.input_buffers(1)
        return dop853_run(system.model, rows, point, self.loop, float(bound), float(next_sample_t))

    def new_switch_times(self) -> list[float]:
        """The switches located by the last :meth:`run` [s]."""
        return self.loop.switch_times[: self.tally[NEW_SWITCHES]].tolist()

    def dense(self) -> Callable[[float], np.ndarray]:
        """``y(t)`` inside the last step (its dense output made by :meth:`run`)."""
        assert self.tally[DENSE_READY], "dense: the last step's dense output was not made"
        y_old, F = self.loop.y_old, self.loop.F
        t_old, h = self.clock[T_OLD], self.clock[T] - self.clock[T_OLD]

        def at(t: float) -> np.ndarray:
            out = np.empty_like(y_old)
            dop853_interpolate(F, y_old, (t - t_old) / h, out)
            return out

        return at

    def sensitivity_at(self, t: float) -> np.ndarray:
        """The sensitivities ``dy/dp`` (P, m) at ``t`` [s]: the current ones at the current
        time, else inside the last step (its dense output made by :meth:`run`)."""
        sens = self.loop.sensitivity
        if t >= self.t:
            return sens.S.copy()
        assert self.tally[DENSE_READY], "sensitivity_at: the last step's dense output was not made"
        t_old, h = self.clock[T_OLD], self.clock[T] - self.clock[T_OLD]
        out = np.empty_like(sens.S)
        interpolate_sensitivity(sens, (t - t_old) / h, out)
        return out

    def start_at(self, t0: float, y0: np.ndarray) -> None:
        """Start again at ``(t0, y0)`` as a new stepper would (its first call makes the first
        stage, the blow-up monitor and Hairer's initial step), keeping the buffers."""
        self.clock[:] = 0.0
        self.tally[:] = 0
        self.clock[T] = self.clock[T_OLD] = float(t0)
        self.loop.y[:] = y0
        self.tally[START] = 1

    def restart(self) -> None:
        """The state changed at the current time (a controller's update): the next
        :meth:`run` evaluates its first stage and taut flags anew; a switch headed for is
        forgotten."""
        self.tally[RESTART] = 1
        self.tally[LANDING] = 0


def steps_per_turn(system: CompiledSystem, evaluations: int) -> int:
    """Steps of ``evaluations`` evaluations each that make about :data:`YIELD_WORK` (at least
    one): how many a compiled call takes before Python gets its turn."""
    members = max(1, system.structure.n_rods + system.structure.n_tendons)
    return max(1, YIELD_WORK // (evaluations * members))
