"""Events: the instants where the dynamics change form, found by one compiled mechanism that
every loop locating them calls (the compiled DOP853 loop,
:func:`tensegrity.engine.dop853.dop853_run`, and the loop of scipy's methods,
:func:`tensegrity.engine.loop.run`).

An *event* ``e`` (``0 <= e < E``) is

- an **indicator** ``g_e(t, y)``, continuous along a trajectory, whose sign says on which side
  of the event's switching surface the state is (:func:`event_indicators`);
- a **direction**: the loop keeps the side the state is on, ``side[e]`` (True where
  ``g_e > 0``); the event fires when ``g_e`` leaves it, i.e. when its *distance*
  ``d_e = g_e`` (``side[e]``) or ``-g_e`` (not ``side[e]``) reaches 0 (:func:`event_distance`);
- an **action** at the located time: ``side[e]`` flips to ``side_after[e]``
  (:func:`set_sides`), and the kind's own action follows, if it has one.

Kinds, in the order of their events:

- the tendons' slack/taut switches (``e`` the tendon's kernel position, ``S`` events): ``g =
  min(k d, k d + c l')``, ``d = l - Lbar``, whose sign changes exactly at the kinks of the
  tension law (eqs. 18.39-18.40); the action is the flip alone (the law is continuous: the
  event keeps its kink out of a step's polynomial);
- with planes, two per contact pair (:mod:`tensegrity.physics.contact`): contact (touch-down,
  lift-off) and friction (stick, slip), their indicators written by every evaluation, their
  sides the pairs' modes; the action changes the pair's mode (:func:`land_contacts`), and with
  it the right-hand side, so the loops start their steps anew.

A new kind adds its rows to :func:`event_indicators`, :func:`events_crossed` and
:func:`set_sides`, its count to :func:`event_work`, and its action to what the loops call when
they land on an event.

Per accepted step of an adaptive method:

1. :func:`events_crossed`: the candidates, the events whose sign at the step's end (known from
   its last stage: a tendon's tension > 0) disagrees with their side;
2. if there are any, :func:`locate_event`: the first root of ``min_e d_e(t)`` over the candidates
   on the step's dense output, by regula falsi with the Illinois modification and bisection
   (:func:`bracket_start`), to a bracket of :data:`EVENT_RTOL` (relative), reported at the
   bracket's right end, just past the root, so that events firing within the bracket (the
   symmetric twins of a regular shell) fire together instead of one by one; ``fired`` marks them;
3. the loop discards the step and retakes it to end exactly there (the *landing*); once there,
   :func:`set_sides` makes the sides from the evaluation at the new state, the fired events
   keeping the side they went to (the state retaken up to an event may sit a round-off short),
   and once that step's samples are out, the actions run (:func:`land_contacts`).

The dense output is the DOP853 step's polynomial (compiled), or, for scipy's methods, their
``dense_output()`` called back from compiled code (:data:`DENSE_OUTPUTS`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit, objmode

from tensegrity.engine.compiled import (
    dop853_interpolate,
    make_inputs,
)
from tensegrity.physics.compiling import (
    JIT_OPTIONS,
    compiled_only,
)
from tensegrity.physics.contact import (
    FREE,
    REVERSAL_SPEED,
    SLIP,
    SLOW_SLIP,
    SLOW_START,
    SLOW_STOP,
    STICK,
    STICK_SPEED,
    refresh_slips,
    stick_velocities,
    tangential_velocity,
)
from tensegrity.physics.kernel import (
    tendon_vector,
)
from tensegrity.physics.kernel_system import system_nodes, system_rhs

if TYPE_CHECKING:
    from tensegrity.engine.system import CompiledSystem

#: Relative width of the final bracket of a located event.
EVENT_RTOL = 1e-13


class EventWork(NamedTuple):
    """The events' state and scratch, kept by a loop (:func:`event_work`); ``E`` events,
    ``m`` the length of the ODE state."""

    side: np.ndarray  #: (E,) bool: the side of each event's surface the state is on (taut)
    fired: np.ndarray  #: (E,) bool: the events of the located time headed for (the landing)
    side_after: np.ndarray  #: (E,) bool: the side of a fired event after it
    candidates: np.ndarray  #: (E,) int64 scratch: the events crossed in the last step
    distance: np.ndarray  #: (E,) scratch: the candidates' distances
    indicator: np.ndarray  #: (E,) scratch: every event's indicator
    y_at: np.ndarray  #: (m,) scratch: the state inside the step
    p: np.ndarray  #: (3, n_slots) scratch: node positions
    v: np.ndarray  #: (3, n_slots) scratch: node velocities
    time: np.ndarray  #: (1,) scratch: the time whose inputs are made
    qddot: np.ndarray  #: (n,) scratch: accelerations of an evaluation for the contacts


def event_work(system: CompiledSystem) -> EventWork:
    """New :class:`EventWork` for ``system``: its events are one per tendon, then two per
    contact pair (contact, friction) if it has planes."""
    contacts = system.model.contacts
    pairs = 0 if contacts is None else contact_pairs(contacts)
    E = system.structure.n_tendons + 2 * pairs
    return EventWork(
        side=np.zeros(E, bool),
        fired=np.zeros(E, bool),
        side_after=np.zeros(E, bool),
        candidates=np.zeros(E, np.int64),
        distance=np.zeros(E),
        indicator=np.zeros(E),
        y_at=np.zeros(system.m),
        p=system.scratch_p,
        v=system.scratch_v,
        time=np.zeros(1),
        qddot=np.zeros(system.n),
    )


def contact_pairs(contacts: Any) -> int:
    """The contact pairs of packed ``contacts`` (:class:`~tensegrity.physics.records.Contacts`):
    points times planes."""
    return int(contacts.point_radius.size * contacts.plane_normal.shape[0])


def landing_of(events: EventWork) -> tuple[np.ndarray, np.ndarray]:
    """The fired events (kernel positions) and their sides after (for a checkpoint)."""
    fired = np.flatnonzero(events.fired)
    return fired, events.side_after[fired].copy()


def restore_landing(events: EventWork, fired: np.ndarray, side_after: np.ndarray) -> None:
    """The fired events and their sides after, as :func:`landing_of` gave them."""
    events.fired[:] = False
    events.fired[fired] = True
    events.side_after[fired] = side_after


# --------------------------------------------------------------------------- indicators
@njit(**JIT_OPTIONS)
def event_indicators(model, data, y, events):  # pragma: no cover - compiled
    """Every event's indicator ``g`` (E,) at the state ``y`` into ``events.indicator``, with
    the inputs' row 0 of ``data``.  Tendon ``s``: ``min(k d, k d + c l')`` [N], positive while
    it pulls and <= 0 while it does not; contact pairs: an evaluation's
    (:mod:`tensegrity.physics.contact`)."""
    damping = model.tendon_damping
    n = (y.shape[0] - 3) // 2
    system_nodes(model, y[:n], y[n : 2 * n], events.p, events.v, damping is not None)
    _tendon_indicators(damping, model, data.rest[0], events.p, events.v, events.indicator)
    _contact_indicators(model.contacts, model, data, y, events)


@compiled_only
def _contact_indicators(contacts, model, data, y, events):  # pragma: no cover - compiled
    """The contact pairs' rows of :func:`event_indicators` (after the tendons'), from an
    evaluation at ``y``; nothing without contacts (``contacts`` None)."""
    if contacts is None:
        return
    n = (y.shape[0] - 3) // 2
    system_rhs(model, data, np.int64(0), y[:n], y[n : 2 * n], events.qddot)
    indicator = data.contact_work.indicator
    first = events.indicator.shape[0] - indicator.shape[0]
    for i in range(indicator.shape[0]):
        events.indicator[first + i] = indicator[i]


@compiled_only
def _tendon_indicators(damping, model, rest, p, v, out):  # pragma: no cover - compiled
    """The tendons' rows of :func:`event_indicators` from the node positions ``p`` and
    velocities ``v``; ``damping`` (``model.tendon_damping``) None: undamped tendons (decided at
    compile time)."""
    tendon_slots, stiffness = model.tendon_slots, model.tendon_stiffness
    for s in range(tendon_slots.shape[0]):
        a, b, tx, ty, tz = tendon_vector(p, tendon_slots, s)
        length = np.sqrt(tx * tx + ty * ty + tz * tz)
        stretch = stiffness[s] * (length - rest[s])
        if damping is None:
            out[s] = stretch
        else:
            rate = (
                tx * (v[0, b] - v[0, a]) + ty * (v[1, b] - v[1, a]) + tz * (v[2, b] - v[2, a])
            ) / length
            out[s] = min(stretch, stretch + damping[s] * rate)


@njit(inline="always", **JIT_OPTIONS)
def events_crossed(data, events):  # pragma: no cover - compiled
    """The events whose sign at the last evaluation (``data``: a tendon's tension > 0) disagrees
    with their side, into ``events.candidates``; their number."""
    count = 0
    tension = data.tension
    for e in range(tension.shape[0]):
        if (tension[e] > 0.0) != events.side[e]:
            events.candidates[count] = e
            count += 1
    return _contacts_crossed(data.contact_work, events, count)


@compiled_only
def _contacts_crossed(work, events, count):  # pragma: no cover - compiled
    """:func:`events_crossed` of the contact pairs' rows (``work``: ``data.contact_work``,
    None without contacts) after the ``count`` candidates found; the new count."""
    if work is None:
        return count
    indicator = work.indicator
    first = events.side.shape[0] - indicator.shape[0]
    for i in range(indicator.shape[0]):
        if (indicator[i] > 0.0) != events.side[first + i]:
            events.candidates[count] = first + i
            count += 1
    return count


@njit(inline="always", **JIT_OPTIONS)
def set_sides(data, events, keep_fired):  # pragma: no cover - compiled
    """The sides from the last evaluation (``data``: a tendon is taut while its tension > 0);
    with ``keep_fired`` (the loop landed on a located event) the fired events keep the side
    they went to (the state retaken up to an event may sit a round-off short of it)."""
    tension = data.tension
    for e in range(tension.shape[0]):
        events.side[e] = tension[e] > 0.0
        if keep_fired and events.fired[e]:
            events.side[e] = events.side_after[e]
    _contact_sides(data.contact_work, events)


@compiled_only
def _contact_sides(work, events):  # pragma: no cover - compiled
    """The contact pairs' sides from their modes (in contact; sticking), which the events'
    actions set (:func:`land_contacts`); nothing without contacts (``work`` None)."""
    if work is None:
        return
    first = events.side.shape[0] - work.indicator.shape[0]
    for k in range(work.mode.shape[0]):
        events.side[first + 2 * k] = work.mode[k] != FREE
        events.side[first + 2 * k + 1] = work.mode[k] == STICK


@compiled_only
def event_distance(model, data, y, events, count):  # pragma: no cover - compiled
    """The distances (:mod:`the module docstring <tensegrity.engine.events>`) of the first
    ``count`` candidates at ``y`` into ``events.distance``, with the inputs' row 0 of
    ``data``; their least (``<= 0``: one has fired)."""
    event_indicators(model, data, y, events)
    least = np.inf
    for k in range(count):
        e = events.candidates[k]
        g = events.indicator[e]
        events.distance[k] = g if events.side[e] else -g
        least = min(least, events.distance[k])
    return least


# --------------------------------------------------------------------------- location
#: Python dense outputs by handle, ``(t, out)`` writing ``y(t)`` into ``out``: what
#: :func:`locate_event` calls back for scipy's methods (:class:`DenseOutputHandle`).
DENSE_OUTPUTS: dict[int, Callable[[float, np.ndarray], None]] = {}
_HANDLES = itertools.count()


def _call_dense(handle: int, t: float, out: np.ndarray) -> None:
    """Python's side of a dense output called from :func:`locate_event`."""
    DENSE_OUTPUTS[int(handle)](float(t), out)


class DenseOutputHandle:
    """A handle of :data:`DENSE_OUTPUTS` for ``dense`` (``y(t)`` inside the last step), while
    the ``with`` block lasts."""

    def __init__(self, dense: Callable[[float], np.ndarray]) -> None:
        self.dense = dense
        self.handle = next(_HANDLES)

    def _write(self, t: float, out: np.ndarray) -> None:
        out[:] = self.dense(t)

    def __enter__(self) -> np.int64:
        DENSE_OUTPUTS[self.handle] = self._write
        return np.int64(self.handle)

    def __exit__(self, *exc: object) -> None:
        del DENSE_OUTPUTS[self.handle]


@compiled_only
def _distance_at(model, point, varying, dense_callback, step, events, count, t):  # pragma: no cover
    """:func:`event_distance` at the time ``t`` [s] inside the step, its inputs made into
    ``point`` where they vary; ``(least distance, inputs failed)``."""
    t_lo, t_hi, F, y_old = step
    if varying:
        events.time[0] = t
        if make_inputs(model.callback, model.tables, events.time, point) >= 0:
            return np.nan, True
    if dense_callback is None:
        dop853_interpolate(F, y_old, (t - t_lo) / (t_hi - t_lo), events.y_at)
    else:
        with objmode():
            _call_dense(dense_callback, t, events.y_at)
    return event_distance(model, point, events.y_at, events, count), False


@compiled_only
def locate_event(model, point, varying, dense_callback, step, events, count):  # pragma: no cover
    """The first event among the ``count`` candidates inside the step ``step`` = ``(t_lo, t_hi
    [s], F, y_old)``: its time [s], the events fired there marked in ``events.fired`` with
    their sides after in ``events.side_after``.  Returns ``(time, NaN)``, or ``(NaN, t)`` when
    the inputs at ``t`` [s] could not be made (:func:`compiled.make_inputs`).

    ``point`` is a data record of one input row, made at each time where the inputs vary
    (``varying``); the state inside the step is the DOP853 polynomial ``F`` from ``y_old``
    (:func:`compiled.dop853_interpolate`) when ``dense_callback`` is None, else the Python dense
    output of that handle (:data:`DENSE_OUTPUTS`)."""
    t_lo, t_hi = step[0], step[1]
    input_time = np.nan
    g_lo, failed = _distance_at(model, point, varying, dense_callback, step, events, count, t_lo)
    if failed:
        input_time = t_lo
    g_hi, failed_hi = _distance_at(model, point, varying, dense_callback, step, events, count, t_hi)
    if failed_hi:
        input_time = t_hi
    failed = failed or failed_hi
    bracket = bracket_start(t_lo, t_hi, g_lo, g_hi, EVENT_RTOL * max(1.0, abs(t_hi)))
    t = bracket_next(bracket, np.nan, np.nan)
    while not failed and not np.isnan(t):
        g, failed = _distance_at(model, point, varying, dense_callback, step, events, count, t)
        if failed:
            input_time = t
        t = bracket_next(bracket, t, g)
    lo, hi = bracket[LO], bracket[HI]
    t_event = min(max(hi, lo + bracket[TOL]), t_hi)
    if not failed:
        g, failed = _distance_at(
            model, point, varying, dense_callback, step, events, count, t_event
        )
        if not failed and not g <= 0.0:  # (switched back within the bracket: the root)
            t_event = hi
            g, failed = _distance_at(
                model, point, varying, dense_callback, step, events, count, t_event
            )
        if failed:
            input_time = t_event
    if failed:
        return np.nan, input_time
    events.fired[:] = False
    for k in range(count):  # the events fired by then (distance <= 0 there)
        e = events.candidates[k]
        if events.distance[k] <= 0.0:
            events.fired[e] = True
            events.side_after[e] = not events.side[e]
    return t_event, np.nan


#: Fields of an event bracket (:func:`bracket_start`): its ends [s], the distances there, which
#: end stayed put last (-1 lo, +1 hi, 0 none), the width at the round's start [s], whether a
#: bisection is due, the width to reach [s].
LO, HI, G_LO, G_HI, KEPT, WIDTH, BISECT, TOL = range(8)


@njit(**JIT_OPTIONS)
def bracket_start(lo, hi, g_lo, g_hi, tol):  # pragma: no cover - compiled
    """A bracket ``[lo, hi]`` [s] of the first root of a distance ``g`` (``g(lo) > 0 >= g(hi)``)
    for :func:`bracket_next`: regula falsi with the Illinois modification (superlinear on a
    smooth ``g``), kept shrinking by a bisection whenever a false-position step leaves more than
    half of the bracket, down to a width of ``tol`` [s].  The caller evaluates ``g`` (reverse
    communication)::

        b = bracket_start(lo, hi, g(lo), g(hi), tol)
        t = bracket_next(b, nan, nan)  # the first time to evaluate g at; NaN: done
        while not isnan(t):
            t = bracket_next(b, t, g(t))
        # the root is in [b[LO], b[HI]]
    """
    b = np.zeros(8)
    b[LO], b[HI], b[G_LO], b[G_HI], b[TOL] = lo, hi, g_lo, g_hi, tol
    return b


@njit(**JIT_OPTIONS)
def bracket_next(b, t, g):  # pragma: no cover - compiled
    """The bracket after the distance ``g`` at the time ``t`` [s] it asked for (nothing if ``t``
    is NaN), and the next time to evaluate the distance at, or NaN once the bracket is within
    its tolerance."""
    if not np.isnan(t):
        if b[BISECT] != 0.0:
            if g > 0.0:
                b[LO], b[G_LO] = t, g
            else:
                b[HI], b[G_HI] = t, g
            b[KEPT], b[BISECT] = 0.0, 0.0
        else:
            if g > 0.0:
                b[LO], b[G_LO] = t, g
                if b[KEPT] == 1.0:
                    b[G_HI] *= 0.5
                b[KEPT] = 1.0
            else:
                b[HI], b[G_HI] = t, g
                if b[KEPT] == -1.0:
                    b[G_LO] *= 0.5
                b[KEPT] = -1.0
            if b[HI] - b[LO] > 0.5 * b[WIDTH]:  # false position crawled: bisect
                b[BISECT] = 1.0
    lo, hi, tol = b[LO], b[HI], b[TOL]
    if b[BISECT] != 0.0:
        return 0.5 * (lo + hi)
    if not hi - lo > tol:
        return np.nan
    b[WIDTH] = hi - lo
    mid = 0.5 * (lo + hi)
    if b[G_LO] > 0.0 > b[G_HI]:
        mid = lo + b[G_LO] * (hi - lo) / (b[G_LO] - b[G_HI])
    return min(max(mid, lo + 0.25 * tol), hi - 0.25 * tol)


# --------------------------------------------------------------------------- entries for Python
# The loop of scipy's methods (Python) calls the mechanism through these; the DOP853 loop calls
# the functions above from compiled code, so a DOP853 run compiles none of them.
@njit(**JIT_OPTIONS)
def events_crossed_entry(data, events):  # pragma: no cover - compiled
    """:func:`events_crossed`, called from Python."""
    return events_crossed(data, events)


@njit(**JIT_OPTIONS)
def set_sides_entry(data, events, keep_fired):  # pragma: no cover - compiled
    """:func:`set_sides`, called from Python."""
    set_sides(data, events, keep_fired)


@njit(**JIT_OPTIONS)
def locate_event_entry(
    model, point, varying, dense_callback, step, events, count
):  # pragma: no cover - compiled
    """:func:`locate_event`, called from Python."""
    return locate_event(model, point, varying, dense_callback, step, events, count)


# --------------------------------------------------------------------------- contact actions
@compiled_only
def land_contacts(contacts, model, data, t, y, events):  # pragma: no cover - compiled
    """The actions of the contact events fired at the state ``y`` at ``t`` [s] the loop landed
    on (``events.fired``; ``data`` with the inputs there): a point touching down slips, or
    sticks if it is still; lifting off frees it; a stick whose force left the friction cone
    slips against that force; a slip whose velocity reversed sticks if the point is still, or
    slips on in its new direction.  Sticks are then settled (:func:`settle_sticks`) and the
    modes' changes logged (:func:`log_changes`).  Returns whether a mode changed (the
    right-hand side did: the loop starts its steps anew)."""
    if contacts is None:
        return False
    work = data.contact_work
    first = events.side.shape[0] - work.indicator.shape[0]
    before = work.mode.copy()
    changed = False
    for k in range(work.mode.shape[0]):
        touch, slide = events.fired[first + 2 * k], events.fired[first + 2 * k + 1]
        if touch or slide:
            switch_mode(contacts, work, y, k, touch)
            changed = True
    if changed:
        settle_sticks(contacts, model, data, y, events)
        log_changes(work, t, before)
    return changed


@compiled_only
def start_contacts(contacts, model, data, t, y, events):  # pragma: no cover - compiled
    """The pairs' modes at the start of a run at ``y`` at ``t`` [s]: those whose law pushes
    touch down (:func:`switch_mode`), then the sticks are settled, and the pairs in contact
    logged (:func:`log_changes`); nothing without contacts."""
    if contacts is None:
        return
    work = data.contact_work
    n = (y.shape[0] - 3) // 2
    work.mode[:] = FREE
    before = work.mode.copy()
    system_rhs(model, data, np.int64(0), y[:n], y[n : 2 * n], events.qddot)
    for k in range(work.mode.shape[0]):
        if work.indicator[2 * k] > 0.0:
            switch_mode(contacts, work, y, k, True)
    settle_sticks(contacts, model, data, y, events)
    log_changes(work, t, before)


@compiled_only
def stick_slow_slips(contacts, model, data, t, y, events):  # pragma: no cover - compiled
    """The rule for slow slips, at the end of an accepted step at ``(t, y)`` (``data`` with the
    inputs there), once its samples are out: each pair slipping slower than :data:`SLOW_SLIP`
    that is not about to stop on its own (its velocity along the slip's direction ``s`` reaching
    ``-REVERSAL_SPEED`` within :data:`SLOW_STOP` at its deceleration along ``s``: that stop is
    located as an event) nor to speed up (past :data:`SLOW_SLIP` along ``s`` within
    :data:`SLOW_START`) sticks if the force it then needs is inside the static cone.
    A slip that crawls, its speed set by the structure's motion and its direction turning,
    would otherwise be followed one ever shorter step at a time (its friction damps the
    velocity across it by ``mu_k F_n / |v_t|``).  A slip that speeds up is one whose stick has
    just failed: the force it would need at rest sits on the cone's edge, a hair inside after
    the sticks' impulses, and stuck again it would fail again a round-off later, without end
    (a crawl speeds up far slower, and sticks).  The sticks are settled (:func:`settle_sticks`,
    their speed removed by an impulse counted as dissipated) and logged.  Returns whether a
    mode changed (the loop starts its steps anew); nothing without contacts."""
    if contacts is None:
        return False
    work = data.contact_work
    n = (y.shape[0] - 3) // 2
    v, a = np.empty(3), np.empty(3)
    before = work.mode.copy()
    slow = np.zeros(work.mode.shape[0], np.bool_)
    for k in range(work.mode.shape[0]):
        if work.mode[k] == SLIP:
            slow[k] = tangential_velocity(contacts, y[n : 2 * n], k, v) <= SLOW_SLIP
    if not slow.any():
        return False
    system_rhs(model, data, np.int64(0), y[:n], y[n : 2 * n], events.qddot)
    tried = False
    for k in range(work.mode.shape[0]):
        if slow[k]:
            tangential_velocity(contacts, y[n : 2 * n], k, v)
            tangential_velocity(contacts, events.qddot, k, a)
            s = work.slip_direction[k]
            # its speed along s, what is left of it to the located reversal (v_t . s =
            # -REVERSAL_SPEED), the rate it falls at
            along = v[0] * s[0] + v[1] * s[1] + v[2] * s[2]
            left = along + REVERSAL_SPEED
            slowing = -(a[0] * s[0] + a[1] * s[1] + a[2] * s[2])
            if left >= slowing * SLOW_STOP and along - slowing * SLOW_START <= SLOW_SLIP:
                work.mode[k] = STICK
                tried = True
    if not tried:  # (the work arrays are the kept modes')
        return False
    system_rhs(model, data, np.int64(0), y[:n], y[n : 2 * n], events.qddot)
    changed = False
    for k in range(work.mode.shape[0]):
        if before[k] == SLIP and work.mode[k] == STICK:
            if work.indicator[2 * k + 1] < 0.0:  # the stick would not hold: it slips on
                work.mode[k] = SLIP
            else:
                changed = True
    if changed:
        settle_sticks(contacts, model, data, y, events)
        log_changes(work, t, before)
    else:  # (the work arrays as the modes kept make them)
        system_rhs(model, data, np.int64(0), y[:n], y[n : 2 * n], events.qddot)
    return changed


@compiled_only
def log_changes(work, t, before):  # pragma: no cover - compiled
    """Append to ``work.log`` a row ``(t, pair, mode before, mode after)`` for each pair whose
    mode differs from ``before`` (CP,) (the loops take the rows before the log can fill:
    :func:`log_full`)."""
    for k in range(work.mode.shape[0]):
        if work.mode[k] != before[k]:
            row = work.log[work.log_count[0]]
            row[0], row[1], row[2], row[3] = t, k, before[k], work.mode[k]
            work.log_count[0] += 1


@compiled_only
def log_full(work):  # pragma: no cover - compiled
    """Whether the log of mode changes may not hold another step's (a landing's and the slow
    slips', every pair changing in each): the loop hands the rows to Python first (False
    without contacts)."""
    if work is None:
        return False
    return work.log_count[0] + 2 * work.mode.shape[0] > work.log.shape[0]


@compiled_only
def switch_mode(contacts, work, y, k, touch):  # pragma: no cover - compiled
    """Pair ``k``'s mode after its contact (``touch``) or friction event at ``y``: see
    :func:`land_contacts`."""
    p = k % contacts.plane_normal.shape[0]
    n = (y.shape[0] - 3) // 2
    v = np.empty(3)
    speed = tangential_velocity(contacts, y[n : 2 * n], k, v)
    mode = work.mode[k]
    if touch and mode != FREE:
        work.mode[k] = FREE
        return
    if mode == STICK:  # the force needed left the cone: slip along the force that is not held
        _slip_against_force(contacts, work, k, p)
        return
    if speed <= STICK_SPEED:  # touching down or reversing while still: stick, if it holds
        work.mode[k] = STICK
        return
    work.mode[k] = SLIP
    for i in range(3):
        work.slip_direction[k, i] = v[i] / speed


@compiled_only
def _slip_against_force(contacts, work, k, p):  # pragma: no cover - compiled
    """Pair ``k`` slips in the direction opposite its last sticking force (the resultant of
    the other tangential forces), or along the plane's first tangent if that force is zero."""
    f = work.friction_force[k]
    size = np.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    work.mode[k] = SLIP
    for i in range(3):
        work.slip_direction[k, i] = -f[i] / size if size > 0.0 else contacts.plane_tangent[p, 0, i]


@compiled_only
def settle_sticks(contacts, model, data, y, events):  # pragma: no cover - compiled
    """Make the pairs' modes at ``y`` consistent: hold the sticking points still
    (:func:`tensegrity.physics.contact.stick_velocities`) and evaluate; a stick whose force is
    outside the friction cone slips against that force; a point slipping from rest (speed at
    most :data:`STICK_SPEED`) takes the direction it can keep (:func:`slip_from_rest`); again
    until nothing changes (at most ``4 CP + 4`` rounds)."""
    work = data.contact_work
    P = contacts.plane_normal.shape[0]
    n = (y.shape[0] - 3) // 2
    v = np.empty(3)
    for _ in range(4 * work.mode.shape[0] + 4):
        stick_velocities(contacts, model, data, y)
        system_rhs(model, data, np.int64(0), y[:n], y[n : 2 * n], events.qddot)
        changed = False
        for k in range(work.mode.shape[0]):
            if work.mode[k] == STICK and work.indicator[2 * k + 1] < 0.0:
                _slip_against_force(contacts, work, k, k % P)
                changed = True
        if not changed:
            for k in range(work.mode.shape[0]):
                at_rest = tangential_velocity(contacts, y[n : 2 * n], k, v) <= STICK_SPEED
                if work.mode[k] == SLIP and at_rest:
                    changed |= slip_from_rest(contacts, model, data, y, events, k)
        if not changed:
            return


@compiled_only
def slip_from_rest(contacts, model, data, y, events, k):  # pragma: no cover - compiled
    """The direction ``s`` of pair ``k`` slipping from rest at ``y``: the one along which its
    tangential acceleration points when kinetic friction ``-mu_k F_n s`` opposes it, ``a(s) =
    lambda s`` with ``lambda > 0`` (a slip from rest keeps no other; on a rod its end's
    mobility is not isotropic, and with the rod's other end held, the way its rigidity lets
    the end move).  ``a`` is affine in ``s``, ``a = a0 - mu_k F_n W s`` (2 x 2 in the plane's
    tangents), made from four evaluations; then ``s = (lambda I + mu_k F_n W)^-1 a0`` of unit
    length, ``lambda`` by bisection.  If there is no such direction (the force holding it at
    rest, ``(mu_k F_n W)^-1 a0``, is inside ``mu_k F_n``: the stick that failed did so with
    the pair's neighbours held, e.g. the rod's other end), the pair sticks.  Returns whether
    ``s`` or the mode changed."""
    work = data.contact_work
    P = contacts.plane_normal.shape[0]
    n = (y.shape[0] - 3) // 2
    tangent = contacts.plane_tangent[k % P]
    s = work.slip_direction[k]
    kept = s.copy()
    a = np.empty(3)
    probe = np.empty((4, 2))  # a in the tangents' coordinates for s = +t0, -t0, +t1, -t1
    for j in range(4):
        sign = 1.0 - 2.0 * (j % 2)
        for i in range(3):
            s[i] = sign * tangent[j // 2, i]
        system_rhs(model, data, np.int64(0), y[:n], y[n : 2 * n], events.qddot)
        tangential_velocity(contacts, events.qddot, k, a)
        for c in range(2):
            probe[j, c] = a[0] * tangent[c, 0] + a[1] * tangent[c, 1] + a[2] * tangent[c, 2]
    g0, g1 = (
        0.25 * (probe[0, 0] + probe[1, 0] + probe[2, 0] + probe[3, 0]),
        0.25 * (probe[0, 1] + probe[1, 1] + probe[2, 1] + probe[3, 1]),
    )
    # columns j of mu_k F_n W: (a(-t_j) - a(+t_j)) / 2
    m00, m10 = 0.5 * (probe[1, 0] - probe[0, 0]), 0.5 * (probe[1, 1] - probe[0, 1])
    m01, m11 = 0.5 * (probe[3, 0] - probe[2, 0]), 0.5 * (probe[3, 1] - probe[2, 1])
    lo, hi = 0.0, np.sqrt(g0 * g0 + g1 * g1) + np.sqrt(m00**2 + m01**2 + m10**2 + m11**2)
    x0, x1 = _solve_shifted(m00, m01, m10, m11, lo, g0, g1)
    if not x0 * x0 + x1 * x1 > 1.0:  # kinetic friction holds it: no slip from rest, a stick
        for i in range(3):
            s[i] = kept[i]
        work.mode[k] = STICK
        return True
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        x0, x1 = _solve_shifted(m00, m01, m10, m11, mid, g0, g1)
        if x0 * x0 + x1 * x1 > 1.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    x0, x1 = _solve_shifted(m00, m01, m10, m11, hi, g0, g1)
    size = np.sqrt(x0 * x0 + x1 * x1)
    moved = 0.0
    for i in range(3):
        s[i] = (x0 * tangent[0, i] + x1 * tangent[1, i]) / size
        moved = max(moved, abs(s[i] - kept[i]))
    return moved > 1e-9


@compiled_only
def _solve_shifted(m00, m01, m10, m11, shift, g0, g1):  # pragma: no cover - compiled
    """``(shift I + M)^-1 g`` for the 2 x 2 ``M`` (Cramer's rule; ``(0, 0)`` if singular)."""
    a, b, c, d = m00 + shift, m01, m10, m11 + shift
    det = a * d - b * c
    if det == 0.0:
        return 0.0, 0.0
    return (d * g0 - b * g1) / det, (a * g1 - c * g0) / det


@njit(**JIT_OPTIONS)
def land_contacts_entry(model, data, t, y, events):  # pragma: no cover - compiled
    """:func:`land_contacts`, called from Python."""
    return land_contacts(model.contacts, model, data, t, y, events)


@njit(**JIT_OPTIONS)
def start_contacts_entry(model, data, t, y, events):  # pragma: no cover - compiled
    """:func:`start_contacts`, called from Python."""
    start_contacts(model.contacts, model, data, t, y, events)


@njit(**JIT_OPTIONS)
def stick_slow_slips_entry(model, data, t, y, events):  # pragma: no cover - compiled
    """:func:`stick_slow_slips`, called from Python."""
    return stick_slow_slips(model.contacts, model, data, t, y, events)


@njit(**JIT_OPTIONS)
def refresh_slips_entry(model, data, y):  # pragma: no cover - compiled
    """:func:`tensegrity.physics.contact.refresh_slips`, called from Python."""
    refresh_slips(model.contacts, data, y)
