"""The options of a run, defined once: ``simulate``, the CLI, streamed runs and sweeps take them
from here (:class:`Options`), and a run's ``settings`` record is made from them."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

#: Adaptive methods the engine integrates in compiled code (the default first).
COMPILED_ADAPTIVE_METHODS = ("DOP853",)
#: ``scipy.integrate`` methods still accepted, stepped through ``scipy`` with the compiled
#: right-hand side (implicit ones, for stiff problems).
SCIPY_METHODS = ("RK45", "RK23", "Radau", "BDF", "LSODA")
ADAPTIVE_METHODS = COMPILED_ADAPTIVE_METHODS + SCIPY_METHODS
FIXED_STEP_METHODS = ("rk4",)
#: :attr:`Options.max_steps` by default: far beyond a structure settling (a (10,10) shell: 4,049
#: DOP853 steps over 60 s) or a long fixed-step run (1000 s at 1e-4 s), it bounds the grind of a
#: stiff or unstable adaptive run (minutes at (3,1), about 30 us a step).
DEFAULT_MAX_STEPS = 10_000_000
#: :attr:`Options.max_samples` by default (a (10,10) shell's sample holds 51 kB).
DEFAULT_MAX_SAMPLES = 10_000_000


ALL_METHODS = ADAPTIVE_METHODS + FIXED_STEP_METHODS


def _number(value: object) -> float | None:
    """``value`` as a float if it is a real number (not a bool, not text), else None."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return None
    return float(value)


def _positive(value: object) -> str | None:
    """The problem of a tolerance or limit that must be a number > 0, or None."""
    number = _number(value)
    return None if number is not None and number > 0 else f"must be > 0, got {value!r}"


def _seconds(value: object) -> str | None:
    """The problem of a time [s] that must be a number > 0 (``inf`` too), or None."""
    number = _number(value)
    if number is not None and number > 0:
        return None
    return f"must be a number > 0 in s, got {value!r}"


def _optional_seconds(value: object) -> str | None:
    """The problem of a step or spacing [s]: None (not given) or a finite number > 0."""
    number = _number(value)
    if value is None or (number is not None and math.isfinite(number) and number > 0):
        return None
    return f"must be a number > 0 in s, got {value!r}"


def _whole_positive(value: object) -> str | None:
    """The problem of a count that must be a whole number > 0, or None."""
    if isinstance(value, int) and not isinstance(value, bool) and value > 0:
        return None
    return f"must be a whole number > 0, got {value!r}"


def _option(
    default: Any, unit: str, help: str, check: Callable[[Any], str | None] | None = None
) -> Any:
    """A field of :class:`Options`: its default, its unit (SI, ``""`` for none), a line of
    help (the CLI's help is made from it: :func:`option_help`) and its check (the problem of a
    value as text, or None), the one check of that option."""
    return dataclasses.field(default=default, metadata={"unit": unit, "help": help, "check": check})


def option_help(name: str, default: Any = dataclasses.MISSING) -> str:
    """The help of option ``name`` of :class:`Options`: its line, unit and default
    (``default`` instead of its own if given, e.g. a CLI's), as ``--help`` shows it:
    ``"fixed step [s] (rk4 only)"``, ``"relative tolerance ... (default 1e-09)"``."""
    field = OPTION_FIELDS[name]
    unit = field.metadata["unit"]
    text = field.metadata["help"] + (f" [{unit}]" if unit else "")
    value = field.default if default is dataclasses.MISSING else default
    if value is None or isinstance(value, bool):
        return text
    if value == math.inf:
        return f"{text} (default: none)"
    shown = (
        f"{value:,}"
        if isinstance(value, int)
        else f"{value:g}"
        if isinstance(value, float)
        else value
    )
    return f"{text} (default {shown})"


#: A sample time within this fraction of ``sample_dt`` of the end time is the end time: the
#: round-off of a ``sample_dt`` given in decimals (2 s at 0.0333333333333 s falls 2e-12 s
#: short of 2 s) makes no second sample, nor a segment of a streamed run, a sliver before the end.
END_SNAP = 1e-9
#: A step's end reaches a sample time within this relative round-off of it (the sample is
#: then recorded at the step's end), and the run's last sample falls short of its end time
#: only by more (:func:`reaches`, :func:`short_of`).
REACH_RTOL = 1e-14


def reaches(t_now: float, t: float) -> bool:
    """Whether time ``t_now`` [s] has reached time ``t`` [s], to :data:`REACH_RTOL`."""
    return t <= t_now + REACH_RTOL * abs(t_now)


def short_of(t: float, t_now: float) -> bool:
    """Whether time ``t`` [s] falls short of ``t_now`` [s] by more than :data:`REACH_RTOL`."""
    return t < t_now - REACH_RTOL * abs(t_now)


def sample_time(t0: float, t_end: float, sample_dt: float, index: int) -> float:
    """Time [s] of sample ``index`` of a run over ``(t0, t_end)`` sampled every ``sample_dt``
    [s]: ``t0 + index sample_dt``, or ``t_end`` within ``END_SNAP sample_dt`` of it.  The one
    formula for every sample and checkpoint boundary of a run."""
    t = t0 + index * sample_dt
    return t_end if abs(t - t_end) <= END_SNAP * sample_dt else t


def sample_count(t0: float, t_end: float, sample_dt: float) -> int:
    """Samples a run over ``(t0, t_end)`` [s] makes when it runs to ``t_end``: those of
    :func:`sample_time` up to ``t_end``, and ``t_end`` itself if the last of them falls short of
    it (by more than :data:`REACH_RTOL`).  A streamed run's segments are counted from it."""
    guess = math.floor((t_end - t0) / sample_dt)  # (off by round-off: one either way)
    k = max(
        (
            j
            for j in range(max(0, guess - 2), guess + 3)
            if reaches(t_end, sample_time(t0, t_end, sample_dt, j))
        ),
        default=0,
    )
    last = min(sample_time(t0, t_end, sample_dt, k), t_end)
    return k + 1 + (1 if short_of(last, t_end) else 0)


def _count(n: float) -> str:
    """A count for a message: ``1,000``, or ``6e+10`` when too long to read."""
    return f"{n:,}" if n < 10**12 else f"{n:.3g}"


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
    max_steps : the most steps a run may take.  ``"rk4"``: a run that would take more is refused
        before it starts; an adaptive run that has taken this many steps without reaching its
        end stops (status -1): its steps have become tiny (a stiff or unstable structure).
    max_samples : the most samples a run may make (each holds the whole state: memory, or
        disk for a streamed run); a run that would make more is refused before it starts.
    max_wall_time : the longest one call may run [s of wall-clock time]; a run still going
        then stops (status -1) within about 0.1 s, its samples so far kept (a streamed run
        keeps its partial file, to be resumed: a budget per session, for batch queues).  Not
        part of the run's ``settings``: a resumed run may have another budget.
    """

    method: str = _option(
        "DOP853",
        "",
        "the integration method: adaptive (DOP853 compiled, or a scipy.integrate method) or "
        "fixed-step 'rk4' (needs dt)",
        lambda v: (
            None
            if v in ALL_METHODS
            else f"unknown method {v!r}; choose one of {', '.join(ALL_METHODS)}"
        ),
    )
    rtol: float = _option(1e-9, "", "relative tolerance of the adaptive methods", _positive)
    atol: float = _option(1e-12, "", "absolute tolerance of the adaptive methods", _positive)
    dt: float | None = _option(None, "s", "fixed step, rk4 only", _optional_seconds)
    sample_dt: float | None = _option(None, "s", "output spacing", _optional_seconds)
    locate_switches: bool = _option(
        True, "", "adaptive methods: end a step at each slack/taut switch of a tendon"
    )
    steady_state: bool = _option(False, "", "stop at the first sample at rest")
    velocity_tol: float = _option(
        1e-6, "m/s", "at rest when every node's speed is below this", _positive
    )
    acceleration_tol: float = _option(
        1e-6, "m/s^2", "... and every node's acceleration below this", _positive
    )
    projection_tol: float = _option(
        1e-12, "", "adaptive methods: project onto the constraints beyond this error", _positive
    )
    max_rod_length_error: float = _option(
        1e-3, "", "the run fails beyond this relative rod-length error", _positive
    )
    max_energy_growth: float = _option(
        0.1, "", "the run fails beyond this growth of the energy balance", _positive
    )
    max_steps: int = _option(
        DEFAULT_MAX_STEPS, "", "stop (failed) after this many steps", _whole_positive
    )
    max_samples: int = _option(
        DEFAULT_MAX_SAMPLES, "", "refuse a run of more samples than this", _whole_positive
    )
    max_wall_time: float = _option(
        math.inf, "s", "stop (failed) after this much wall-clock time", _seconds
    )

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            check = field.metadata["check"]
            problem = None if check is None else check(getattr(self, field.name))
            if problem is not None:
                raise ValueError(f"{field.name}: {problem}")
        if self.fixed_step and self.dt is None:
            raise ValueError(f"dt: method {self.method!r} is fixed-step and needs a step dt")

    def check_span(self, t0: float, t_end: float) -> None:
        """``ValueError`` if a run over ``(t0, t_end)`` [s] would take more than ``max_steps``
        fixed steps, or a step ``dt`` too small to advance the time, or make more than
        ``max_samples`` samples: before any work, each naming the option to change."""
        span = t_end - t0
        if self.dt is not None and self.fixed_step:
            if t_end + self.dt == t_end or t0 + self.dt == t0:
                raise ValueError(
                    f"dt: {self.dt:g} s does not advance the time (at t = {t_end:g} s a step "
                    "must be at least its rounding); use a larger dt (--dt)"
                )
            steps = math.ceil(span / self.dt - 1e-9)
            if steps > self.max_steps:
                raise ValueError(
                    f"dt: {self.dt:g} s over {span:g} s is {_count(steps)} steps, more than "
                    f"max_steps (--max-steps) = {self.max_steps:,}; use a larger dt (--dt), or "
                    "raise max_steps (--max-steps)"
                )
        intervals = span / self.sample_spacing(t0, t_end)
        if not intervals + 1e-9 < self.max_samples:  # (inf for a huge span: no integer)
            samples = math.floor(intervals + 1e-9) + 1 if math.isfinite(intervals) else math.inf
            raise ValueError(
                f"sample_dt: {self.sample_spacing(t0, t_end):g} s over {span:g} s is "
                f"{_count(samples)} samples, more than max_samples = {self.max_samples:,}; use a "
                "larger sample_dt (--sample-dt), or raise max_samples"
            )

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


#: The fields of :class:`Options` by name: each option's default, unit, help and check.
OPTION_FIELDS = {field.name: field for field in dataclasses.fields(Options)}
