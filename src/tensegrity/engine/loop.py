"""The one integration loop (:func:`run`): stepping, sampling, slack/taut switch location,
projection onto the constraints, blow-up checks and the steady-state stop, for every method
and every structure, samples handed to a sink as they are made.

Per accepted step of an adaptive method: the tensions at the step's end (known from its last
stage) are compared with those at its start; if a tendon went slack or taut, the earliest switch
is found by bisection on the step's dense output (to 1e-13 s relative), the step is discarded
and retaken to end exactly there, and the switching tendons are marked as switched, so that the
same switch is not found again a round-off later.  The step size carries over.  Then the blow-up
checks run (compiled), samples inside the step are interpolated, and the state is projected when
its drift exceeds ``projection_tol``.  ``"rk4"`` runs whole stretches of steps between samples in
one compiled call.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Protocol

import numpy as np

from tensegrity.physics import dynamics
from tensegrity.engine import compiled
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.options import Options
from tensegrity.engine.steppers import DOP853, RK4, IntegrationError, ScipyMethod
from tensegrity.engine.result import STATUS_END, STATUS_FAILED, STATUS_STEADY, RunSummary, Sample
from tensegrity.engine.system import CompiledSystem
from tensegrity.model.structure import Structure

#: Relative width of the final bracket of a located switch.
SWITCH_RTOL = 1e-13


class Sink(Protocol):
    """Where samples go (:class:`tensegrity.engine.result.MemorySink` keeps them in memory)."""

    def add(self, sample: Sample) -> None:
        """Keep one sample."""


_FAILURES = {
    compiled.CHECK_NOT_FINITE: "unstable: the state is not finite at t = {t:.6g} s",
    compiled.CHECK_ROD_LENGTH: ("unstable: a rod's length error {value:.3g} (relative) exceeds "
                                "{limit:g} within one step at t = {t:.6g} s (step too large, or "
                                "the motion is unstable)"),
    compiled.CHECK_CONSTRAINT: ("unstable: the joints and supports are violated by {value:.3g} m "
                                "within one step at t = {t:.6g} s (step too large, or the motion "
                                "is unstable)"),
    compiled.CHECK_ENERGY: "unstable: energy grew by {value:.3g} J (scale {scale:.3g} J) at t = {t:.6g} s",
    compiled.CHECK_PROJECTION: ("unstable: could not project onto the constraints at t = {t:.6g} s"),
}


class _Run:
    """The state of one run: the system, the stepper, the monitor and the counters."""

    def __init__(self, structure: Structure, t0: float, t_end: float, y0: dynamics.State,
                 inputs: Inputs, options: Options, sink: Sink) -> None:
        self.structure, self.options, self.sink = structure, options, sink
        self.t0, self.t_end = t0, t_end
        self.system = system = CompiledSystem(structure, inputs)
        self.y0 = system.state_vector(y0)
        self.sample_dt = options.sample_spacing(t0, t_end)
        self.next_sample = 1
        length_scale = max(float(structure.rod_length.max(initial=0.0)), 1.0)
        self.limits = (options.max_rod_length_error, options.max_rod_length_error * length_scale,
                       options.max_energy_growth)
        # monitor: energy balance at the start, largest energy scale, largest errors
        inputs0 = system.stage_inputs(np.array([t0]))
        _, _, _, total, scale = compiled.energy_balance(self.y0, 0, system.system, inputs0,
                                                        system.work)
        self.monitor = np.array([total, scale, 0.0, 0.0])
        compiled.check_state(self.y0, 0, system.system, inputs0, system.work,
                             (np.inf, np.inf, np.inf), self.monitor)
        self.counts = dict(nsteps=0, nswitches=0, nprojections=0)
        self.progress: Any = None
        self.switch_times: list[float] = []
        self.status, self.message = STATUS_END, f"reached t_end = {t_end:g} s"
        self.last_sample_t = -np.inf

    # ------------------------------------------------------------------ samples
    def record(self, t: float, y: np.ndarray) -> Sample:
        sample = self.system.sample(t, y, self.system.stage_inputs(np.array([t])))
        self.sink.add(sample)
        self.last_sample_t = t
        return sample

    def sample_times(self, t_new: float) -> list[float]:
        """The sample times not yet recorded up to ``t_new``."""
        times = []
        while (t := self.t0 + self.next_sample * self.sample_dt) <= t_new * (1 + 1e-14):
            times.append(min(t, t_new))
            self.next_sample += 1
        return times

    def steady(self, sample: Sample) -> bool:
        o = self.options
        if (o.steady_state and sample.residual_acceleration < o.acceleration_tol
                and sample.largest_speed < o.velocity_tol):
            self.status = STATUS_STEADY
            self.message = f"steady state at t = {sample.t:.6g} s"
            return True
        return False

    def fail(self, code: int, value: float, t: float) -> None:
        self.status = STATUS_FAILED
        self.message = _FAILURES[code].format(
            t=t, value=value, limit=self.options.max_rod_length_error, scale=self.monitor[1])

    def check(self, y: np.ndarray, t: float) -> float | None:
        """The compiled blow-up checks at the end of a step; the drift, or None on failure."""
        system = self.system
        inputs = system.stage_inputs(np.array([t]))
        code, value = compiled.check_state(y, 0, system.system, inputs, system.work, self.limits,
                                           self.monitor)
        if code != compiled.CHECK_OK:
            self.fail(code, value, t)
            return None
        return value


def _stepper(run: _Run, y: np.ndarray) -> Any:
    o = run.options
    if o.method == "rk4":
        return RK4(run.system, run.t0, y)
    if o.method == "DOP853":
        return DOP853(run.system, run.t0, y, rtol=o.rtol, atol=o.atol, t_end=run.t_end)
    return ScipyMethod(run.system, run.t0, y, method=o.method, rtol=o.rtol, atol=o.atol,
                       t_end=run.t_end)


def _first_switch(run: _Run, stepper: Any, candidates: np.ndarray,
                  was_taut: np.ndarray) -> tuple[float, np.ndarray]:
    """Earliest time in the last step at which one of ``candidates`` (kernel positions) changes
    taut/slack state, by bisection on the dense output, and the tendons that have switched by
    then.  Returns the right end of the final bracket: just past the switch."""
    system = run.system
    y_at = stepper.dense()
    indicator = np.empty(system.structure.n_tendons)

    def switched(t: float) -> np.ndarray:
        compiled.switch_indicator(y_at(t), system.system, system.rest_row(t), system.work,
                                  system.scratch_p, system.scratch_v, indicator)
        return (indicator[candidates] > 0) != was_taut[candidates]

    lo, hi = stepper.t_old, stepper.t
    tol = SWITCH_RTOL * max(1.0, abs(hi))
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if np.any(switched(mid)):
            hi = mid
        else:
            lo = mid
    return hi, candidates[switched(hi)]


@dataclasses.dataclass
class _Landing:
    """A located switch the stepper is heading for: its time, the tendons that switch there,
    their flags after it, and whether it was located on an accepted step's dense output (exact)
    or on a rejected attempt's (approximate: the steps up to it keep looking for switches)."""

    time: float
    tendons: np.ndarray
    taut_after: np.ndarray
    exact: bool


def _taut(stepper: Any, landed: _Landing | None) -> np.ndarray:
    """Taut flags at the stepper's state; tendons that have just switched keep the side they
    switched to (the state retaken up to a switch may sit a round-off short of it)."""
    taut = stepper.tensions() > 0
    if landed is not None and landed.exact:
        taut[landed.tendons] = landed.taut_after
    return taut


def _adaptive(run: _Run, stepper: Any) -> None:
    """The loop of an adaptive method."""
    o, system = run.options, run.system
    locate = o.locate_switches
    taut = _taut(stepper, None) if locate else None
    landing: _Landing | None = None
    # A rejected attempt may stand for a step only when no switch is being landed on and the
    # last one was not located approximately (the step after it may find the same switch just
    # ahead: it shrinks as usual instead of locating it again, which could repeat forever).
    allow_provisional = locate
    while stepper.t < run.t_end:
        detect = locate and (landing is None or not landing.exact)
        stepper.step(run.t_end if landing is None else landing.time,
                     taut if allow_provisional and landing is None else None)
        allow_provisional = locate
        if detect:
            changed = np.flatnonzero((stepper.tensions() > 0) != taut)
            if changed.size:
                t_switch, tendons = _first_switch(run, stepper, changed, taut)
                if not stepper.provisional:
                    run.counts["nswitches"] += 1
                    run.switch_times.append(t_switch)
                landing = _Landing(t_switch, tendons, ~taut[tendons], not stepper.provisional)
                stepper.retreat(t_switch)
                continue
        run.counts["nsteps"] += 1
        landed = landing if landing is not None and stepper.t >= landing.time else None
        if locate:
            taut = _taut(stepper, landed)
        drift = run.check(stepper.y, stepper.t)
        if drift is None:
            run.record(stepper.t, stepper.y)
            return
        times = run.sample_times(stepper.t)
        if times:
            y_at = stepper.dense()
            for t in times:
                if run.steady(run.record(t, y_at(t) if t < stepper.t else stepper.y)):
                    return
        stepper.accept()
        if run.progress is not None:
            run.progress(stepper.t)
        if landed is not None:
            stepper.resume()
            allow_provisional = landed.exact
            landing = None
        if drift > o.projection_tol:
            if not system.project(stepper.y):
                run.fail(compiled.CHECK_PROJECTION, np.nan, stepper.t)
                return
            run.counts["nprojections"] += 1
            stepper.restart(stepper.y)
            if locate:
                taut = _taut(stepper, landed)


def _hermite(t: float, t0: float, y0: np.ndarray, f0: np.ndarray, t1: float, y1: np.ndarray,
             f1: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation inside a fixed step from the values and slopes at its ends."""
    h = t1 - t0
    s = (t - t0) / h
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * h * f0 + (-2 * s3 + 3 * s2) * y1
            + (s3 - s2) * h * f1)


def _fixed_step(run: _Run, stepper: RK4) -> None:
    """The loop of ``"rk4"``: compiled stretches of steps up to each sample (the last step
    shorter, to land on ``t_end``); a sample inside a step is interpolated (cubic Hermite), one
    on a step's end is that end before projection."""
    t0, dt = run.t0, run.options.dt
    n_full = int(np.floor((run.t_end - t0) / dt + 1e-9))
    last = run.t_end - (t0 + n_full * dt)
    n_steps = n_full + (1 if last > 1e-9 * dt else 0)
    done = 0
    while done < n_steps:
        target = t0 + run.next_sample * run.sample_dt
        reach = min(int(np.ceil((target - t0) / dt - 1e-9)), n_steps)
        if reach - done > 1 and not _rk4_steps(run, stepper, reach - done - 1, dt):
            return  # (the whole steps before the one that reaches the sample)
        done = max(done, reach - 1)
        h = last if done == n_full else dt
        t_old, y_old = stepper.t, stepper.y.copy()
        if not _rk4_steps(run, stepper, 1, h):
            return
        done += 1
        stepper.t = run.t_end if done == n_steps else t0 + done * dt
        if run.progress is not None:
            run.progress(stepper.t)
        for t in run.sample_times(stepper.t):
            y = stepper.y_end
            if abs(t - stepper.t) > 1e-9 * dt:
                f_new = np.empty_like(y_old)
                compiled.ode_rhs(stepper.y_end, f_new, 0, run.system.system,
                                 run.system.stage_inputs(np.array([stepper.t])), run.system.work)
                stepper.nfev += 1
                y = _hermite(t, t_old, y_old, stepper.K[0], stepper.t, stepper.y_end, f_new)
            if run.steady(run.record(t, y)):
                return


def _rk4_steps(run: _Run, stepper: RK4, n: int, h: float) -> bool:
    """``n`` checked, projected RK4 steps of ``h``, the stepper's time moved on; False (and the
    run failed) on a blow-up."""
    steps, code, value = stepper.advance(n, h, run.limits, run.monitor)
    stepper.t += steps * h
    run.counts["nsteps"] += steps
    run.counts["nprojections"] += steps - (code != compiled.CHECK_OK)
    if code != compiled.CHECK_OK:
        run.fail(code, value, stepper.t)
        run.record(stepper.t, stepper.y_end)
        return False
    return True


def run(
    structure: Structure,
    t_span: tuple[float, float],
    *,
    initial: dynamics.State | None = None,
    inputs: Inputs | None = None,
    options: Options = Options(),
    sink: Sink,
    progress: Any = None,
) -> RunSummary:
    """Integrate ``structure`` over ``t_span = (t0, t_end)`` [s], handing samples to ``sink``
    (Theorem 18.1 with eqs. 18.39-18.60; the loop of the module docstring).

    ``initial`` defaults to the structure's node positions and velocities at ``t0``;
    ``inputs`` (:class:`Inputs`) to no control, load or gravity.  ``progress``, if given, is
    called with the time reached after each stretch of steps.  Returns a :class:`RunSummary`;
    the samples went to ``sink``, the last one at the end time, the steady state or the failing
    state.
    """
    t0, t_end = (float(x) for x in t_span)
    if not (np.isfinite(t0) and np.isfinite(t_end) and t_end > t0):
        raise ValueError(f"t_span: need finite t0 < t_end, got {t_span!r}")
    inputs = Inputs(structure) if inputs is None else inputs
    inputs.rest_length(np.array([t0]))  # a control making a rest length negative fails here
    state = dynamics.initial_state(structure, t=t0) if initial is None else initial
    wall0 = time.perf_counter()
    r = _Run(structure, t0, t_end, state, inputs, options, sink)
    r.progress = progress
    stepper = _stepper(r, r.y0.copy())
    r.record(t0, r.y0)
    try:
        (_fixed_step if options.fixed_step else _adaptive)(r, stepper)
    except (IntegrationError, ValueError, FloatingPointError) as exc:
        r.status, r.message = STATUS_FAILED, str(exc)
    if r.status != STATUS_STEADY and r.last_sample_t < stepper.t * (1 - 1e-14):
        r.record(stepper.t, stepper.y)  # the end, or the last state before a failure
    return RunSummary(
        status=r.status, message=r.message, t_final=r.last_sample_t, nfev=stepper.nfev,
        max_rod_length_error=float(r.monitor[2]), max_constraint_error=float(r.monitor[3]),
        wall_time=time.perf_counter() - wall0,
        settings=options.settings(t0, t_end, **inputs.settings()),
        switch_times=tuple(r.switch_times), **r.counts,
    )
