"""Actuators in the compiled engine: the control applied to each actuated tendon as a closed-form
function of time since the last command (:func:`control_at`), written into the inputs' rows
(:func:`actuate`) wherever they are made, and a new command held (:func:`hold_command`).

The model is :mod:`tensegrity.model.actuators`'s: the command is clipped to the rest-length
bounds, then the applied control ``u`` follows ``du/dt = clip((u_cmd - u) / tau, -r, r)`` (lag
``tau``, rate limit ``r``).  From ``u0`` at the command's time, with ``d = u_cmd - u0``: a ramp
at the rate limit while ``|d|`` exceeds ``r tau`` (for ``t1 = (|d| - r tau) / r``), then the
lag's exponential from the distance left; ``tau = 0``: the ramp to the command; neither: the
command at once (a zero-order hold).  This is the exact solution of that equation, so no state
is added to the ODE, and the rate ``du/dt`` it gives makes the control's work ``W_u`` exact.

The record is :class:`tensegrity.physics.records.Actuation` (``Data.actuation``), packed by
:func:`pack_actuation`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tensegrity.engine.feedback import OUTPUT_GROUPS, LinearFeedback
from tensegrity.model.actuators import Actuators, actuators
from tensegrity.model.structure import Structure
from tensegrity.physics.compiling import JIT_OPTIONS
from tensegrity.physics.records import Actuation, FeedbackLaw

#: Rows of an actuation's log (updates) before compiled code hands them to Python.
LOG_ROWS = 256


@njit(**JIT_OPTIONS)
def ramp_time(act, a):  # pragma: no cover - compiled
    """How long [s] actuator ``a`` ramps at its rate limit after its last command: while the
    distance to the command exceeds ``r tau`` (0 without a rate limit)."""
    r = act.max_rate[a]
    if not np.isfinite(r):
        return 0.0
    return max(abs(act.command[a] - act.applied[a]) - r * act.time_constant[a], 0.0) / r


@njit(**JIT_OPTIONS)
def control_at(act, a, t):  # pragma: no cover - compiled
    """``(u [m], du/dt [m/s])`` of actuator ``a`` at time ``t`` [s] (``t >= act.start``; before
    it, the control at the start and no rate)."""
    u0, target = act.applied[a], act.command[a]
    tau, r = act.time_constant[a], act.max_rate[a]
    s = t - act.start[0]
    d = target - u0
    if tau == 0.0 and not np.isfinite(r):
        return target, 0.0  # a zero-order hold
    if s < 0.0:
        return u0, 0.0
    direction = 1.0 if d >= 0.0 else -1.0
    ramp = ramp_time(act, a)
    if s < ramp:
        return u0 + direction * r * s, direction * r
    if tau == 0.0:
        return target, 0.0
    left = d - direction * r * ramp if ramp > 0.0 else d
    decay = np.exp(-(s - ramp) / tau)
    return target - left * decay, left * decay / tau


@njit(**JIT_OPTIONS)
def next_ramp_end(act, t):  # pragma: no cover - compiled
    """The first time [s] after ``t`` at which an actuator with a lag leaves its ramp at the
    rate limit (inf if none does; ``act`` None).  The control's rate is continuous there but
    its slope jumps (from 0 to ``-r / tau``): a step across it loses DOP853's order, so the
    adaptive loop ends a step there (``benchmarks/bench_actuator_steps.py``).  Without a lag the
    rate itself jumps there (from ``r`` to 0), and a step ending on that time would take its
    last stages, at the step's end, on either side of the jump by round-off; that case is left
    to the step-size control, as a table's knots are."""
    end = np.inf
    if act is None:
        return end
    for a in range(act.position.shape[0]):
        ramp = ramp_time(act, a)
        if act.time_constant[a] > 0.0 and ramp > 0.0 and act.start[0] + ramp > t:
            end = min(end, act.start[0] + ramp)
    return end


@njit(**JIT_OPTIONS)
def actuate(act, times, data):  # pragma: no cover - compiled
    """The actuated tendons' rest lengths ``L0 - u`` and rates ``du/dt`` at the stage ``times``
    (K,) [s] into ``data.rest`` and ``data.rate`` (K rows); nothing if ``act`` is None."""
    if act is None:
        return
    for k in range(times.shape[0]):
        for a in range(act.position.shape[0]):
            u, rate = control_at(act, a, times[k])
            data.rest[k, act.position[a]] = act.rest0[a] - u
            data.rate[k, act.position[a]] = rate


@njit(**JIT_OPTIONS)
def clip_command(act, raw, out):  # pragma: no cover - compiled
    """``out`` = the commands ``raw`` (A,) [m] clipped to the rest-length bounds."""
    for a in range(raw.shape[0]):
        out[a] = min(max(raw[a], act.low[a]), act.high[a])


@njit(**JIT_OPTIONS)
def hold_command(act, t, command):  # pragma: no cover - compiled
    """Hold ``command`` (A,) [m] (within the bounds) from ``t`` [s] on: the applied control
    carries on from its value at ``t``; the update is logged (False if the log is full: the
    caller takes it first, :func:`log_full`)."""
    row = act.log_count[0]
    if row >= act.log.shape[0]:
        return False
    A = act.position.shape[0]
    for a in range(A):
        u, _ = control_at(act, a, t)
        act.applied[a] = u
    act.start[0] = t
    act.log[row, 0] = t
    for a in range(A):
        act.command[a] = command[a]
        act.log[row, 1 + a] = command[a]
        act.log[row, 1 + A + a] = act.applied[a]
    act.log_count[0] = row + 1
    act.updates[0] += 1
    return True


@njit(**JIT_OPTIONS)
def log_full(act):  # pragma: no cover - compiled
    """True if ``act``'s log of updates has no room left (None: never)."""
    if act is None:
        return False
    return act.log_count[0] >= act.log.shape[0]


def pack_actuation(
    structure: Structure,
    actuators: Actuators,
    tendon_position: np.ndarray,
    *,
    outputs: int = 0,
    state: int = 0,
) -> Actuation:
    """The :class:`Actuation` record of ``actuators`` on ``structure`` (``tendon_position``
    (S,): each tendon's position in kernel order), the command zero at time ``-inf`` (the
    first command sets it); ``outputs``, ``state``: the sizes of a feedback law's scratch."""
    A = actuators.size
    low, high = actuators.command_bounds(structure)
    return Actuation(
        position=np.ascontiguousarray(tendon_position[actuators.tendons], dtype=np.int64),
        rest0=np.array(structure.tendon_rest_length[actuators.tendons], dtype=float),
        low=np.array(low, dtype=float),
        high=np.array(high, dtype=float),
        max_rate=np.array(actuators.max_rate, dtype=float),
        time_constant=np.array(actuators.time_constant, dtype=float),
        start=np.array([-math.inf]),
        applied=np.zeros(A),
        command=np.zeros(A),
        updates=np.zeros(1, np.int64),
        log=np.zeros((LOG_ROWS, 1 + 2 * A)),
        log_count=np.zeros(1, np.int64),
        proposed=np.zeros(A),
        outputs=np.zeros(outputs),
        state=np.zeros(state),
    )


def pack_feedback(
    structure: Structure,
    feedback: LinearFeedback,
    tendon_position: np.ndarray,
    node_slot: np.ndarray,
    t0: float,
) -> FeedbackLaw:
    """The :class:`FeedbackLaw` record of ``feedback`` on ``structure`` (checked against it),
    its first update at ``t0`` [s]; ``tendon_position`` (S,) each tendon's position in kernel
    order, ``node_slot`` (N,) each node's slot."""
    feedback.check(structure)
    return FeedbackLaw(
        gain=np.ascontiguousarray(feedback.K, dtype=float),
        output_ref=np.ascontiguousarray(feedback.y_ref, dtype=float),
        control_ref=np.ascontiguousarray(feedback.u_ref, dtype=float),
        groups=np.array([g in feedback.outputs for g in OUTPUT_GROUPS]),
        node_slot=np.ascontiguousarray(node_slot, dtype=np.int64),
        dim=structure.dim,
        tendon_position=np.ascontiguousarray(tendon_position, dtype=np.int64),
        schedule=np.array([float(t0), feedback.period]),
    )


def controlled_actuators(
    structure: Structure,
    given: Actuators | None,
    *,
    feedback: LinearFeedback | None = None,
    controlled: bool = False,
) -> Actuators | None:
    """The actuators of a run: those ``given``; a compiled ``feedback`` law's tendons (without
    limits, unless given: then they must be its tendons in its order); every tendon without
    limits for a run ``controlled`` by a Python controller; or None.  ``ValueError`` naming
    ``controller.tendons`` if the law does not drive the actuators given."""
    if feedback is not None:
        tendons = feedback.check(structure)
        if given is None:
            return actuators(structure, tendons.tolist())
        if not np.array_equal(given.tendons, tendons):
            raise ValueError(
                "controller.tendons: must be the actuated tendons in their order "
                f"({given.tendons.tolist()}), got {tendons.tolist()}"
            )
    if given is None and controlled:
        return actuators(structure)
    return given
