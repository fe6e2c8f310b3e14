"""Forward sensitivities of a run: the derivatives ``S = dy/dp`` (P, m) of the state ``y = [q,
q', E_d, W_w, W_u]`` with respect to P parameters ``p``, integrated with the state inside the
compiled DOP853 loop (:func:`tensegrity.engine.dop853.dop853_run`; ``docs/sensitivity.md``).

**Internal differentiation** (Bock's *internal numerical differentiation*): each accepted step
of the state is differentiated as the step it is -- the same step size, the same stages, the
same modes -- so ``S`` is the derivative of the computed trajectory, not of a second
integration that would choose its own steps.  Stage ``i`` of a step from ``y`` with stages
``K_i = f(t_i, Y_i)``, ``Y_i = y + h sum_j a_ij K_j``, has the derivative

    K'_i = f_y(t_i, Y_i) Y'_i + f_p(t_i, Y_i),   Y'_i = S + h sum_j a_ij K'_j,

and ``S_new = S + h sum_i b_i K'_i``; ``f_y Y' + f_p`` is the tangent of the right-hand side,
analytic (:mod:`tensegrity.engine.tangent`): one evaluation per stage, whose values serve all P
parameters at once, and a tangent pass for each.  A run with a rod's relative damping (which
the tangent does not cover) takes it by central differences along ``(Y'_i, e_j)`` instead
(:func:`directional`, a relative step of :data:`STEP`; 2 P evaluations per stage).  The dense
output of ``S`` is the step's dense polynomial differentiated the same way (three more stages,
only for steps with samples).

**Events.**  The loop lands on every event (:mod:`tensegrity.engine.events`), so no step
straddles one; the derivative is taken on the step's side of every slack/taut switch (the
tangent takes each tendon as the step's taut flags say; a difference whose point falls past a
switch the step does not cross, as a stage at the step's end on the event, is taken
one-sided).  At a located event, with indicator ``g`` (0 at the
event time ``tau``), ``dtau/dp = -(g_y S + g_p) / g'`` and the *saltation*

    S+ = R_y (S- + f- dtau/dp) + R_p - f+ dtau/dp,

``f-``, ``f+`` the right-hand side before and after (a damped tendon snapping taut makes its
tension jump; a contact's mode change changes the law), ``R`` the event's reset of the state
(the impulse that holds sticking points still; the identity elsewhere).

What is not differentiated: the projections onto the constraints (``S`` keeps its own, tiny,
drift), the friction's slip direction refreshed after each step (its effect on the force is
``STICK_SPEED / |v_t|`` relative), the times of the slow-slip rule's sticks, which are not
located events (:func:`tensegrity.engine.events.stick_slow_slips`; their reset is), and the
sticks settled at the start (``S0`` is given).

Parameters (:data:`KIND_CODES`): a tendon's stiffness ``k`` [N/m], damping ``c`` [N s/m] and
rest length ``L0`` [m], a rod's mass [kg], a point mass [kg], a ground plane's static and
kinetic friction coefficients, its contact stiffness [N/m] and damping [N s/m], components of
the initial state, and values of the control table [m] (each moves the rest lengths and their
rates where the table's interpolation weighs it).  A parameter sets a group of members together
(each member's value moves by the same amount).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit

from tensegrity.engine.compiled import (
    DOP853_A,
    DOP853_B,
    DOP853_STAGES,
    combine_stages,
    dop853_dense_polynomial,
    dop853_interpolate,
    make_inputs,
    ode_rhs,
    table_rows,
)
from tensegrity.engine.events import contact_pairs, event_indicators
from tensegrity.engine.tangent import (
    PLANE_DAMPING,
    PLANE_KINETIC_FRICTION,
    PLANE_STIFFNESS,
    rhs_tangent,
    tangent_work,
)
from tensegrity.physics.compiling import (
    JIT_OPTIONS,
    ROD_C1,
    ROD_C2,
    ROD_LENGTH,
    ROD_MASS,
    ROD_RELATIVE_DAMPING,
    compiled_only,
)
from tensegrity.physics.contact import (
    SLIP,
    STICK_SPEED,
    stick_velocities,
    tangential_velocity,
)

if TYPE_CHECKING:
    from tensegrity.engine.system import CompiledSystem

#: The parameters' kinds and their codes in compiled code.
(
    TENDON_STIFFNESS,
    TENDON_DAMPING,
    TENDON_REST_LENGTH,
    ROD_MASS_KIND,
    POINT_MASS,
    FRICTION,
    KINETIC_FRICTION,
    CONTACT_STIFFNESS,
    CONTACT_DAMPING,
    INITIAL_STATE,
    CONTROL,
) = range(11)
KIND_CODES = {
    "tendon_stiffness": TENDON_STIFFNESS,
    "tendon_damping": TENDON_DAMPING,
    "tendon_rest_length": TENDON_REST_LENGTH,
    "rod_mass": ROD_MASS_KIND,
    "point_mass": POINT_MASS,
    "friction": FRICTION,
    "kinetic_friction": KINETIC_FRICTION,
    "contact_stiffness": CONTACT_STIFFNESS,
    "contact_damping": CONTACT_DAMPING,
    "initial_state": INITIAL_STATE,
    "control": CONTROL,
}
#: The kinds of the ground planes' parameters, and the :class:`~tensegrity.model.ground.Plane`
#: field each sets.
PLANE_FIELDS = {
    "friction": "friction",
    "kinetic_friction": "kinetic_friction",
    "contact_stiffness": "stiffness",
    "contact_damping": "damping",
}

#: The most a central difference moves a slipping point's tangential velocity, relative to
#: the velocity its friction's direction follows (:func:`_slip_step`).
SLIP_STEP = 1e-3

#: The backward steps at an event: the time in which the state moves by this fraction of its
#: size (the state the loop landed on lies off the event by the width of its bracket,
#: ``EVENT_RTOL`` of the time, far less).
BACK = 1e-9

#: Relative step of the central differences: about the cube root of the machine epsilon
#: (their truncation and round-off errors balanced).
STEP = 6e-6


class SensitivityWork(NamedTuple):
    """The sensitivities of a run and their scratch (``LoopWork.sensitivity``); P parameters,
    ``m`` the length of the state."""

    kind: np.ndarray  #: (P,) int64: each parameter's kind (codes of :data:`KIND_CODES`)
    start: np.ndarray  #: (P + 1,) int64: parameter j's members are member[start[j]:start[j+1]]
    #: (M,) int64: tendons' kernel positions, rods, point masses, planes, indices into the
    #: state, or control-table entries (``knot * S + kernel position``)
    member: np.ndarray
    saved: np.ndarray  #: (max(M, 1), 3) scratch: the members' values while perturbed
    size: np.ndarray  #: (P,) each parameter's scale (its value, or 1 at 0) [its unit]
    S: np.ndarray  #: (P, m) ``dy/dp`` at the state
    S_old: np.ndarray  #: (P, m) at the last step's start
    K: np.ndarray  #: (P, 16, m) the stages' derivatives
    F: np.ndarray  #: (P, 7, m) the dense polynomial of ``S`` over the last step
    Y: np.ndarray  #: (16, m) scratch: the stages' states
    v: np.ndarray  #: (m,) scratch: a stage's direction
    y_at: np.ndarray  #: (m,) scratch
    f_at: np.ndarray  #: (m,) scratch
    dtau: np.ndarray  #: (P,) scratch: an event time's derivatives [s / unit]
    #: (16,) the times of the inputs' rows [s]: a step's stage times, or row 0's time
    stage_time: np.ndarray
    knot: np.ndarray  #: (max(Tc, 1), 1) scratch: one knot of the control table at 1
    knot_weight: np.ndarray  #: (1, 1) scratch: that knot's weight in a row of the table
    knot_slope: np.ndarray  #: (1, 1) scratch: its weight in the row's slope [1/s]
    side: np.ndarray  #: (E,) bool: the events' sides over the last step
    y_before: np.ndarray  #: (m,) the state before an event's action
    f_before: np.ndarray  #: (m,) scratch: the right-hand side before it
    w: np.ndarray  #: (m,) scratch
    #: scratch: the contacts' normal forces, friction forces and indicators, kept
    kept: tuple
    #: the right-hand side's analytic tangent (:class:`tensegrity.engine.tangent.TangentWork`),
    #: or None: central differences (:func:`directional`; a rod with relative damping)
    tangent: Any = None


def sensitivity_work(
    kinds: Sequence[str],
    members: Sequence[np.ndarray],
    sizes: np.ndarray,
    S0: np.ndarray,
    n_tendons: int,
    pairs: int,
    knots: int,
    tangent: Any = None,
) -> SensitivityWork:
    """New :class:`SensitivityWork`: parameter ``j`` of kind ``kinds[j]`` (a key of
    :data:`KIND_CODES`) over ``members[j]`` (indices as :class:`SensitivityWork` says), scale
    ``sizes[j]``; ``S0`` (P, m) the derivatives of the initial state; ``n_tendons`` tendons and
    ``pairs`` contact pairs make the run's events; ``knots`` rows of its control table;
    ``tangent`` the right-hand side's tangent's work, or None (central differences)."""
    P, m = S0.shape
    start = np.zeros(P + 1, np.int64)
    start[1:] = np.cumsum([len(x) for x in members])
    flat = np.concatenate([np.asarray(x, np.int64) for x in members]) if P else np.zeros(0)
    return SensitivityWork(
        kind=np.array([KIND_CODES[k] for k in kinds], np.int64),
        start=start,
        member=flat.astype(np.int64),
        saved=np.zeros((max(int(start[-1]), 1), 3)),
        size=np.asarray(sizes, dtype=float),
        S=np.array(S0, dtype=float),
        S_old=np.array(S0, dtype=float),
        K=np.zeros((P, 16, m)),
        F=np.zeros((P, 7, m)),
        Y=np.zeros((16, m)),
        v=np.zeros(m),
        y_at=np.zeros(m),
        f_at=np.zeros(m),
        dtau=np.zeros(P),
        stage_time=np.zeros(DOP853_A.shape[0]),
        knot=np.zeros((max(knots, 1), 1)),
        knot_weight=np.zeros((1, 1)),
        knot_slope=np.zeros((1, 1)),
        side=np.zeros(n_tendons + 2 * pairs, bool),
        y_before=np.zeros(m),
        f_before=np.zeros(m),
        w=np.zeros(m),
        kept=(np.zeros(max(pairs, 1)), np.zeros(max(3 * pairs, 1)), np.zeros(max(2 * pairs, 1))),
        tangent=tangent,
    )


# --------------------------------------------------------------------------- compiled
@compiled_only
def _move_plane(contacts, kind, p, delta, saved, i, restore):  # pragma: no cover - compiled
    """Plane ``p``'s coefficient(s) of ``kind`` (friction, contact stiffness or damping) moved
    by ``delta``, or restored."""
    if contacts is None:
        return
    if kind in (CONTACT_STIFFNESS, CONTACT_DAMPING):
        values = (
            contacts.contact_stiffness if kind == CONTACT_STIFFNESS else contacts.contact_damping
        )
        if restore:
            values[p] = saved[i, 0]
        else:
            saved[i, 0] = values[p]
            values[p] += delta
        return
    if restore:
        if kind == FRICTION:
            contacts.friction_static[p] = saved[i, 0]
        else:
            contacts.friction_kinetic[p] = saved[i, 0]
        return
    if kind == FRICTION:
        saved[i, 0] = contacts.friction_static[p]
        contacts.friction_static[p] += delta
    else:
        saved[i, 0] = contacts.friction_kinetic[p]
        contacts.friction_kinetic[p] += delta


@compiled_only
def _move_contact_mass(contacts, c, mass):  # pragma: no cover - compiled
    """Contact point ``c``'s mass set to ``mass`` [kg] (nothing without contacts)."""
    if contacts is not None:
        contacts.point_mass[c] = mass


@compiled_only
def _move_point_mass(constraints, contacts, k, c, delta, saved, i, restore):  # pragma: no cover
    """Point mass ``k`` (contact point ``c``) moved by ``delta`` [kg], or restored; the
    contacts' copy of its mass follows."""
    if constraints is None:
        return
    if restore:
        constraints.point_mass[k] = saved[i, 0]
    else:
        saved[i, 0] = constraints.point_mass[k]
        constraints.point_mass[k] += delta
    _move_contact_mass(contacts, c, constraints.point_mass[k])


@compiled_only
def _knot_weight(tables, sens, k, s):  # pragma: no cover - compiled
    """Entry ``k = knot * S + position`` of the control table: ``(position, weight, slope
    [1/s])``, the knot's weight in the table's row at stage ``s``'s time ``sens.stage_time[s]``
    and in that row's slope (:func:`tensegrity.engine.compiled.table_rows` of the knot
    alone)."""
    control_time, _, control_zero, rest0, _, _, _ = tables
    knot, position = k // rest0.shape[0], k % rest0.shape[0]
    sens.knot[knot, 0] = 1.0
    table_rows(
        control_time,
        sens.knot,
        control_zero,
        sens.stage_time[s : s + 1],
        sens.knot_weight,
        sens.knot_slope,
    )
    sens.knot[knot, 0] = 0.0
    return position, sens.knot_weight[0, 0], sens.knot_slope[0, 0]


@compiled_only
def _move_control(tables, data, sens, k, s, delta, i, restore):  # pragma: no cover - compiled
    """Entry ``k`` of the control table moved by ``delta`` [m] where it acts: in ``data``'s
    rest length and rate of the row of stage ``s``, by its weight and slope there
    (:func:`_knot_weight`); or restored."""
    if tables is None:
        return
    position = k % tables[3].shape[0]
    row = s if data.rest.shape[0] > 1 else 0
    saved = sens.saved
    if restore:
        data.rest[row, position], data.rate[row, position] = saved[i, 0], saved[i, 1]
        return
    saved[i, 0], saved[i, 1] = data.rest[row, position], data.rate[row, position]
    _, weight, slope = _knot_weight(tables, sens, k, s)
    data.rest[row, position] -= delta * weight  # (Lbar = L0 - u)
    data.rate[row, position] += delta * slope


@compiled_only
def _stage_parameters(tables, sens, tw, s):  # pragma: no cover - compiled
    """The tangent's ``tw.rest`` and ``tw.rate`` at stage ``s``: the rest-length parameters',
    and each control-table entry's weight and slope there (:func:`_knot_weight`; ``Lbar = L0 -
    u``: an entry moves the rest length by minus its weight).  Nothing without control-table
    parameters (``tw.rest`` is then ``tw.rest_length`` itself)."""
    if tables is None or not tw.has_control:
        return
    tw.rest[:] = tw.rest_length
    tw.rate[:] = 0.0
    for j in range(sens.kind.shape[0]):
        if sens.kind[j] != CONTROL:
            continue
        for i in range(sens.start[j], sens.start[j + 1]):
            position, weight, slope = _knot_weight(tables, sens, sens.member[i], s)
            tw.rest[j, position] -= weight
            tw.rate[j, position] += slope


@njit(**JIT_OPTIONS)
def stage_tangent_entry(model, data, s, sens, side, y):  # pragma: no cover - compiled
    """:func:`_stage_tangent` with ``sens.tangent``, called from Python."""
    _stage_tangent(model, data, s, sens, sens.tangent, side, y)


@compiled_only
def _stage_tangent(model, data, s, sens, tw, side, y):  # pragma: no cover - compiled
    """``sens.K[:, s]`` from the directions ``tw.direction`` at stage ``s`` from ``y``: the
    evaluation there, then its tangent (:func:`tensegrity.engine.tangent.rhs_tangent`)."""
    _stage_parameters(model.tables, sens, tw, s)
    ode_rhs(model, data, s, y, sens.f_at)
    rhs_tangent(model, data, s, tw, side, y, sens.K)


@compiled_only
def _move(model, data, sens, j, s, delta, restore):  # pragma: no cover - compiled
    """Parameter ``j``'s members moved by ``delta`` in ``model`` (and in ``data``'s inputs row of
    stage ``s``, for rest lengths), or (``restore``) given back the values they had: the
    records are the same objects before and after, bit for bit.  (Row ``s``'s time is
    ``sens.stage_time[s]``.)"""
    kind = sens.kind[j]
    saved = sens.saved
    first, end = sens.start[j], sens.start[j + 1]
    for n in range(end - first):
        i = end - 1 - n if restore else first + n  # (restored in reverse: entries of one
        k = sens.member[i]  # tendon at several knots move the same rest length)
        if kind == TENDON_STIFFNESS:
            if restore:
                model.tendon_stiffness[k] = saved[i, 0]
            else:
                saved[i, 0] = model.tendon_stiffness[k]
                model.tendon_stiffness[k] += delta
        elif kind == TENDON_DAMPING:  # (an array: prepare gives one to every run)
            if restore:
                model.tendon_damping[k] = saved[i, 0]
            else:
                saved[i, 0] = model.tendon_damping[k]
                model.tendon_damping[k] += delta
        elif kind == TENDON_REST_LENGTH:  # (Lbar = L0 - u moves with L0)
            row = s if data.rest.shape[0] > 1 else 0
            if restore:
                data.rest[row, k] = saved[i, 0]
            else:
                saved[i, 0] = data.rest[row, k]
                data.rest[row, k] += delta
        elif kind == ROD_MASS_KIND:
            rod = model.rod_param[k]
            if restore:
                rod[ROD_MASS], rod[ROD_C1], rod[ROD_C2] = saved[i, 0], saved[i, 1], saved[i, 2]
            else:
                saved[i, 0], saved[i, 1], saved[i, 2] = rod[ROD_MASS], rod[ROD_C1], rod[ROD_C2]
                mass = rod[ROD_MASS] + delta
                rod[ROD_MASS] = mass
                rod[ROD_C1] = 2.0 / mass
                rod[ROD_C2] = 6.0 / (mass * rod[ROD_LENGTH] ** 2)
        elif kind == POINT_MASS:
            point = 2 * model.rod_param.shape[0] + k  # (its contact point)
            _move_point_mass(model.constraints, model.contacts, k, point, delta, saved, i, restore)
        elif kind == CONTROL:
            _move_control(model.tables, data, sens, k, s, delta, i, restore)
        elif kind != INITIAL_STATE:
            _move_plane(model.contacts, kind, k, delta, saved, i, restore)


@compiled_only
def _on_side(data, side):  # pragma: no cover - compiled
    """Whether every tendon of the last evaluation pulls exactly where ``side`` says it does
    (the step's side of every slack/taut switch)."""
    tension = data.tension
    for e in range(tension.shape[0]):  # noqa: SIM110 (compiled: no generators)
        if (tension[e] > 0.0) != side[e]:
            return False
    return True


@compiled_only
def _step_size(sens, j, y, v):  # pragma: no cover - compiled
    """The step ``eps`` of the difference along ``(v, e_j)`` from ``y``: :data:`STEP` of the
    state's size along ``v``, and of parameter ``j``'s size (0: the direction is zero)."""
    v_size, y_size = 0.0, 1.0
    for i in range(y.shape[0] - 3):  # (q and q': not the energies, of another unit)
        v_size = max(v_size, abs(v[i]))
        y_size = max(y_size, abs(y[i]))
    eps = y_size / v_size if v_size > 0.0 else np.inf
    if sens.kind[j] != INITIAL_STATE:
        eps = min(eps, sens.size[j])
    return 0.0 if eps == np.inf else STEP * eps


@compiled_only
def _slip_step(contacts, work, y, v, eps):  # pragma: no cover - compiled
    """``eps`` no larger than makes each slipping point's tangential velocity move by
    :data:`SLIP_STEP` of ``|v_t + STICK_SPEED s|``, the size its friction's direction turns
    on (a slip from rest starts at ``STICK_SPEED``: there a difference of the state's size
    would turn the friction's direction by a finite angle); ``eps`` without contacts."""
    if contacts is None or work is None:
        return eps
    n = (y.shape[0] - 3) // 2
    u, du = np.empty(3), np.empty(3)
    for k in range(work.mode.shape[0]):
        if work.mode[k] != SLIP:
            continue
        tangential_velocity(contacts, y[n : 2 * n], k, u)
        moved = tangential_velocity(contacts, v[n : 2 * n], k, du)
        if moved == 0.0:
            continue
        s = work.slip_direction[k]
        size = 0.0
        for i in range(3):
            size += (u[i] + STICK_SPEED * s[i]) ** 2
        eps = min(eps, SLIP_STEP * np.sqrt(size) / moved)
    return eps


@compiled_only
def _evaluate_moved(model, data, s, sens, j, y, v, e, out, side):  # pragma: no cover - compiled
    """``out = f(y + e v)`` with parameter ``j`` moved by ``e``, at stage ``s``; whether that
    point is on the step's ``side`` of every slack/taut switch."""
    for i in range(y.shape[0]):
        sens.y_at[i] = y[i] + e * v[i]
    _move(model, data, sens, j, s, e, False)
    ode_rhs(model, data, s, sens.y_at, out)
    _move(model, data, sens, j, s, e, True)
    return _on_side(data, side)


@compiled_only
def directional(model, data, s, sens, j, y, v, f0, out, side):  # pragma: no cover - compiled
    """``out = f_y(y) v + f_p_j(y)`` at stage ``s`` (``data``'s inputs row) by a central
    difference; one-sided from ``f0 = f(y)`` where one of its points lies past a slack/taut
    switch that ``side`` (the step's taut flags) does not."""
    eps = _step_size(sens, j, y, v)
    m = y.shape[0]
    if eps == 0.0:
        out[:] = 0.0
        return
    eps = _slip_step(model.contacts, data.contact_work, y, v, eps)
    ahead = _evaluate_moved(model, data, s, sens, j, y, v, eps, out, side)
    behind = _evaluate_moved(model, data, s, sens, j, y, v, -eps, sens.f_at, side)
    if ahead == behind:
        for i in range(m):
            out[i] = (out[i] - sens.f_at[i]) / (2.0 * eps)
    elif ahead:
        for i in range(m):
            out[i] = (out[i] - f0[i]) / eps
    else:
        for i in range(m):
            out[i] = (f0[i] - sens.f_at[i]) / eps


@compiled_only
def advance_sensitivity(sens, model, data, times, y_old, y, K, h, side):  # pragma: no cover
    """``S`` across the accepted step of ``h`` [s] from ``y_old`` to ``y`` with stages ``K`` at
    ``times`` (``data`` holding their inputs' rows) and the events' ``side`` at its start: the
    module docstring's recursion; ``K'_12`` (at ``y``) too, for the dense output.  Afterwards
    ``data``'s scratch holds the evaluation at ``y`` again, as the step left it.  Nothing
    without sensitivities (``sens`` None)."""
    if sens is None:
        return
    sens.stage_time[:] = times
    sens.side[:] = side
    side = sens.side
    last = np.int64(DOP853_STAGES)
    copy = sens.S_old
    copy[:] = sens.S
    sens.Y[0] = y_old
    for s in range(1, DOP853_STAGES):
        combine_stages(y_old, K, DOP853_A[s], s, h, sens.Y[s])
    sens.Y[last] = y
    _advance_stages(sens.tangent, sens, model, data, K, h, side)


@compiled_only
def _advance_stages(tw, sens, model, data, K, h, side):  # pragma: no cover - compiled
    """The stages' derivatives ``sens.K`` and ``S`` at the step's end, from ``sens.S_old`` and
    the stages' states ``sens.Y`` and right-hand sides ``K`` (:func:`advance_sensitivity`): by
    the analytic tangent, stage by stage for every parameter (``tw``), or by central
    differences, parameter by parameter (``tw`` None)."""
    last = np.int64(DOP853_STAGES)
    copy, Y = sens.S_old, sens.Y
    if tw is not None:  # (numba compiles one branch: tw's type decides)
        for s in range(last + 1):
            for j in range(copy.shape[0]):
                if s == last:
                    combine_stages(copy[j], sens.K[j], DOP853_B, last, h, sens.S[j])
                    tw.direction[j] = sens.S[j]
                else:
                    combine_stages(copy[j], sens.K[j], DOP853_A[s], s, h, tw.direction[j])
            _stage_tangent(model, data, np.int64(s), sens, tw, side, Y[s])
    else:
        y_old, y = Y[0], Y[last]
        for j in range(sens.S.shape[0]):
            Kp = sens.K[j]
            directional(model, data, np.int64(0), sens, j, y_old, copy[j], K[0], Kp[0], side)
            for s in range(1, DOP853_STAGES):
                combine_stages(copy[j], Kp, DOP853_A[s], s, h, sens.v)
                directional(model, data, np.int64(s), sens, j, Y[s], sens.v, K[s], Kp[s], side)
            combine_stages(copy[j], Kp, DOP853_B, last, h, sens.S[j])
            directional(model, data, last, sens, j, y, sens.S[j], K[last], Kp[last], side)
        ode_rhs(model, data, last, y, sens.f_at)  # (the scratch as the step left it)


@compiled_only
def dense_sensitivity(sens, model, data, times, y_old, y, h, K):  # pragma: no cover - compiled
    """The dense polynomial of ``S`` over the last step into ``sens.F``: the three extra stages'
    derivatives (``K[13:16]`` at ``times[13:16]`` given; on the step's side, as
    :func:`advance_sensitivity` kept it), then the state's formula
    (:func:`tensegrity.engine.compiled.dop853_dense_polynomial`).  Nothing without
    sensitivities."""
    if sens is None:
        return
    sens.stage_time[:] = times
    side = sens.side
    first = DOP853_STAGES + 1
    for s in range(first, DOP853_A.shape[0]):
        combine_stages(y_old, K, DOP853_A[s], s, h, sens.Y[s])
    _dense_stages(sens.tangent, sens, model, data, K, h, side)
    for j in range(sens.S.shape[0]):
        dop853_dense_polynomial(sens.S_old[j], sens.S[j], h, sens.K[j], sens.F[j])


@compiled_only
def _dense_stages(tw, sens, model, data, K, h, side):  # pragma: no cover - compiled
    """The three extra stages' derivatives into ``sens.K`` (:func:`dense_sensitivity`), as
    :func:`_advance_stages` takes them; ``data``'s scratch left as the last stage's
    evaluation."""
    first, last = DOP853_STAGES + 1, np.int64(DOP853_A.shape[0] - 1)
    if tw is not None:  # (numba compiles one branch: tw's type decides)
        for s in range(first, last + 1):
            for j in range(sens.S.shape[0]):
                combine_stages(sens.S_old[j], sens.K[j], DOP853_A[s], s, h, tw.direction[j])
            _stage_tangent(model, data, np.int64(s), sens, tw, side, sens.Y[s])
    else:
        for j in range(sens.S.shape[0]):
            Kp = sens.K[j]
            for s in range(first, last + 1):
                combine_stages(sens.S_old[j], Kp, DOP853_A[s], s, h, sens.v)
                directional(model, data, np.int64(s), sens, j, sens.Y[s], sens.v, K[s], Kp[s], side)
        ode_rhs(model, data, last, sens.Y[last], sens.f_at)  # (the scratch as the stages left it)


@compiled_only
def _keep_contacts(work, kept):  # pragma: no cover - compiled
    """The contacts' scratch an event's action reads (normal and friction forces, indicators)
    copied into ``kept`` (3 arrays), or nothing without contacts (``work`` None)."""
    if work is None:
        return
    for k in range(work.normal_force.shape[0]):
        kept[0][k] = work.normal_force[k]
        for i in range(3):
            kept[1][3 * k + i] = work.friction_force[k, i]
    for k in range(work.indicator.shape[0]):
        kept[2][k] = work.indicator[k]


@compiled_only
def _restore_contacts(work, kept):  # pragma: no cover - compiled
    """:func:`_keep_contacts` undone."""
    if work is None:
        return
    for k in range(work.normal_force.shape[0]):
        work.normal_force[k] = kept[0][k]
        for i in range(3):
            work.friction_force[k, i] = kept[1][3 * k + i]
    for k in range(work.indicator.shape[0]):
        work.indicator[k] = kept[2][k]


@compiled_only
def _indicator(model, data, y, events, e):  # pragma: no cover - compiled
    """Event ``e``'s indicator at ``y`` (:func:`tensegrity.engine.events.event_indicators`,
    ``data``'s row 0 of the inputs)."""
    event_indicators(model, data, y, events)
    return events.indicator[e]


@compiled_only
def _inputs_at(model, data, sens, t, varying):  # pragma: no cover - compiled
    """``data``'s inputs (row 0, ``sens.stage_time[0]``) made at ``t`` [s] when they vary in
    time."""
    sens.stage_time[0] = t
    if varying:
        make_inputs(model.callback, model.tables, sens.stage_time[:1], data)


@compiled_only
def event_time_derivative(sens, model, data, times, y, f_end, events, varying):  # pragma: no cover
    """At a located event the loop landed on at ``(t, y)``, before its action, ``times = (t0,
    t)`` [s] with the motion smooth since ``t0`` (the last event or restart; ``data`` with the
    inputs at ``t``, ``varying``: they vary in time; ``f_end`` the right-hand side the last
    step ended with): ``sens.dtau = dtau/dp`` of the first event fired, and ``sens.f_at`` the
    right-hand side on the side before it, extrapolated from ``(t - delta, y - delta f_end)``
    and ``(t - 2 delta, y - 2 delta f_end)``; the indicator's rate ``g'`` from the first of them
    (the inputs' own change included).  Nothing without sensitivities (False); False if no
    event fired.  The scratch the action reads, and the inputs, are left as they were.

    ``delta`` [s] is the time in which the state moves by :data:`BACK` of its size (the state
    sits on either side of the event by the width of its bracket, far less), but at most a
    quarter of the smooth stretch ``t - t0``, so that both points lie after the event before:
    a state at rest (a point stuck until a growing load makes it slip) would take them back
    seconds, across the stick, with ``g'`` and ``f-`` of another motion.  That bound is not
    taken below :data:`BACK` of the time (at least 1 s; events that come together), where
    round-off would rule.  (A control or force table's knot is no restart: a point at rest may
    look back across one.)"""
    if sens is None:
        return False
    e = -1
    for i in range(events.fired.shape[0]):
        if events.fired[i]:
            e = i
            break
    if e < 0:
        return False
    m = y.shape[0]
    y_size, f_size = 1.0, 0.0
    for i in range(m):  # (the whole state: with q and q' alone, 4 times the error on the robot)
        y_size, f_size = max(y_size, abs(y[i])), max(f_size, abs(f_end[i]))
    t0, t = times
    delta = max((t - t0) / 4.0, BACK * max(1.0, abs(t)))
    if BACK * y_size < delta * f_size:
        delta = BACK * y_size / f_size
    _keep_contacts(data.contact_work, sens.kept)
    for i in range(m):  # f- extrapolated from two points before: 2 f(y - d f) - f(y - 2 d f)
        sens.v[i] = y[i] - 2.0 * delta * f_end[i]
    _inputs_at(model, data, sens, t - 2.0 * delta, varying)
    ode_rhs(model, data, np.int64(0), sens.v, sens.y_at)
    for i in range(m):
        sens.v[i] = y[i] - delta * f_end[i]
    _inputs_at(model, data, sens, t - delta, varying)
    ode_rhs(model, data, np.int64(0), sens.v, sens.f_at)
    for i in range(m):
        sens.f_at[i] = 2.0 * sens.f_at[i] - sens.y_at[i]
    g_before = _indicator(model, data, sens.v, events, e)
    _inputs_at(model, data, sens, t, varying)
    g0 = _indicator(model, data, y, events, e)
    rate = (g0 - g_before) / delta
    for j in range(sens.S.shape[0]):
        eps = _step_size(sens, j, y, sens.S[j])
        if eps == 0.0 or rate == 0.0:
            sens.dtau[j] = 0.0
            continue
        slope = 0.0
        for sign in (1.0, -1.0):
            for i in range(m):
                sens.y_at[i] = y[i] + sign * eps * sens.S[j, i]
            _move(model, data, sens, j, np.int64(0), sign * eps, False)
            slope += sign * _indicator(model, data, sens.y_at, events, e)
            _move(model, data, sens, j, np.int64(0), sign * eps, True)
        sens.dtau[j] = -(slope / (2.0 * eps)) / rate
    _restore_contacts(data.contact_work, sens.kept)
    return True


@compiled_only
def has_sensitivity(sens):  # pragma: no cover - compiled
    """Whether the run integrates sensitivities (decided at compile time)."""
    return sens is not None


@compiled_only
def keep_state(sens, y):  # pragma: no cover - compiled
    """``y`` kept as the state before an event's action (:func:`saltation`); nothing without
    sensitivities."""
    if sens is None:
        return
    sens.y_before[:] = y


@compiled_only
def _reset_derivative(contacts, model, data, sens, j, w, out):  # pragma: no cover - compiled
    """``out = R_y w + R_p_j``: the derivative of the contacts' reset at ``sens.y_before``
    (:func:`tensegrity.physics.contact.stick_velocities`: the sticking points' velocities
    removed, with the modes as they are now) along ``(w, e_j)``, by a central difference;
    ``w`` itself without contacts."""
    if contacts is None:
        out[:] = w
        return
    y = sens.y_before
    eps = _step_size(sens, j, y, w)
    if eps == 0.0:
        out[:] = 0.0
        return
    for sign in (1.0, -1.0):
        e = sign * eps
        for i in range(y.shape[0]):
            sens.y_at[i] = y[i] + e * w[i]
        _move(model, data, sens, j, np.int64(0), e, False)
        stick_velocities(contacts, model, data, sens.y_at)
        _move(model, data, sens, j, np.int64(0), e, True)
        if sign > 0.0:
            out[:] = sens.y_at
    for i in range(y.shape[0]):
        out[i] = (out[i] - sens.y_at[i]) / (2.0 * eps)


@compiled_only
def saltation(sens, model, data, t, y, timed):  # pragma: no cover - compiled
    """After an event's action at ``t`` [s] took the state from ``sens.y_before``
    (:func:`keep_state`) to ``y`` (``data``'s row 0 with the inputs there): ``S+ = R_y w + R_p -
    f+ dtau/dp`` with ``w =
    S- + f- dtau/dp`` the derivative of the state reaching the event, ``R`` the action's reset
    of the state (:func:`_reset_derivative`; the identity without sticks), ``f+`` the
    right-hand side at ``y`` now.  ``timed``: :func:`event_time_derivative` gave ``dtau/dp``
    and ``f-`` (in ``sens.f_at``); else the action came at a time that does not move with the
    parameters (the slow-slip rule, at a step's end).  Nothing without sensitivities."""
    if sens is None:
        return
    m = y.shape[0]
    sens.stage_time[0] = t
    sens.f_before[:] = sens.f_at
    ode_rhs(model, data, np.int64(0), y, sens.f_at)
    for j in range(sens.S.shape[0]):
        dtau = sens.dtau[j] if timed else 0.0
        for i in range(m):
            sens.w[i] = sens.S[j, i] + sens.f_before[i] * dtau
        _reset_derivative(model.contacts, model, data, sens, j, sens.w, sens.S[j])
        for i in range(m):
            sens.S[j, i] -= sens.f_at[i] * dtau


def interpolate(sens: SensitivityWork, x: float, out: np.ndarray) -> None:
    """``S`` at the fraction ``x`` (0..1) of the last step (its dense polynomial) into ``out``
    (P, m)."""
    for j in range(sens.S.shape[0]):
        dop853_interpolate(sens.F[j], sens.S_old[j], x, out[j])


# --------------------------------------------------------------------------- set-up
def prepare(system: CompiledSystem, parameters: Sequence[Any], y0: np.ndarray) -> SensitivityWork:
    """The sensitivities of a run of ``system`` from ``y0`` with respect to ``parameters``, and
    the system's model record given arrays of its own for every field they move (so that a
    perturbation never touches arrays shared with another run).

    Each parameter has a ``kind`` (a key of :data:`KIND_CODES`) and ``members``: tendon or rod
    indices of the structure for the structure's kinds; nodes carrying a point mass for
    ``point_mass``; ignored for the planes' (every plane); indices into the state ``y`` (the
    engine's 3-D layout ``[q, q', E_d, W_w, W_u]``) for ``initial_state``; entries ``knot * S +
    tendon`` of the control table's values (its ``control`` (Tc, S), row-major, structure
    order) for ``control``.  ``name`` names it in errors, if it has one.  ``ValueError`` (one
    line, naming the parameter) for an unknown kind, no members, members out of range, a
    plane's parameter in a run without planes, or ``control`` in a run without a control table.
    """
    structure, model = system.structure, system.model
    planes = tuple(system.inputs.ground or ())
    control = system.inputs.control.value if system.inputs.control.kind == "table" else None
    knots = 0 if control is None else len(control.time)
    P, m = len(parameters), system.m
    mass_nodes = structure.point_mass_nodes
    count = {  # (each kind's members: how many, of what)
        "tendon": (structure.n_tendons, "tendon indices"),
        "rod": (structure.n_rods, "rod indices"),
        "point": (structure.n_nodes, "node indices"),
        "state": (2 * system.n, "indices into the state"),
        "control": (knots * structure.n_tendons, "control-table entries (knot * S + tendon)"),
    }
    kinds, members, sizes = [], [], np.ones(P)
    S0 = np.zeros((P, m))
    for j, p in enumerate(parameters):
        name = getattr(p, "name", p.kind)
        if p.kind not in KIND_CODES:
            raise ValueError(
                f"sensitivity: parameter {name!r} has kind {p.kind!r}; expected one of "
                + ", ".join(KIND_CODES)
            )
        kind = p.kind
        if kind in PLANE_FIELDS:
            if not planes:
                raise ValueError(f"sensitivity: parameter {name!r}: the run has no ground planes")
            index = np.arange(len(planes))
            value = float(np.mean([_coefficient(plane, p.kind) for plane in planes]))
        else:
            group = {"initial_state": "state", "control": "control"}.get(kind, kind.split("_")[0])
            if kind == "control" and control is None:
                raise ValueError(f"sensitivity: parameter {name!r}: the run has no control table")
            if kind == "control" and model.tables is None:
                raise ValueError(
                    f"sensitivity: parameter {name!r}: the control table's values need the "
                    "run's other inputs as tables too (its external force is a Python function)"
                )
            size, what = count[group]
            index = np.unique(np.asarray(p.members, dtype=np.int64))
            if index.size == 0 or index.min() < 0 or index.max() >= size:
                raise ValueError(
                    f"sensitivity: parameter {name!r}: members must be {what} in "
                    f"0..{size - 1}, got {index.tolist()}"
                )
            if kind == "point_mass" and not np.isin(index, mass_nodes).all():
                raise ValueError(
                    f"sensitivity: parameter {name!r}: members must be nodes with a point mass "
                    f"({mass_nodes.tolist()}), got {index.tolist()}"
                )
            if kind == "initial_state":
                S0[j, index] = 1.0
                value = 1.0
            elif kind == "control":  # (its scale: the rest lengths it moves)
                S = structure.n_tendons
                value = float(np.mean(structure.tendon_rest_length[index % S]))
                index = index // S * S + system.tendon_position[index % S]
            elif group == "tendon":
                value = float(np.mean(np.abs(getattr(structure, kind)[index])))
                index = system.tendon_position[index]
            elif kind == "point_mass":
                value = float(np.mean(structure.node_point_mass[index]))
                index = np.searchsorted(mass_nodes, index)
            else:
                value = float(np.mean(structure.rod_mass[index]))
        kinds.append(kind)
        members.append(index)
        sizes[j] = value if value > 0.0 else 1.0
    damping = model.tendon_damping  # (an array always: one compiled loop for every run)
    if damping is None:
        damping = np.zeros(structure.n_tendons)
    contacts = model.contacts
    if contacts is not None:
        contacts = contacts._replace(
            friction_static=contacts.friction_static.copy(),
            friction_kinetic=contacts.friction_kinetic.copy(),
            contact_stiffness=contacts.contact_stiffness.copy(),
            contact_damping=contacts.contact_damping.copy(),
            point_mass=contacts.point_mass.copy(),
        )
    constraints = model.constraints
    if constraints is not None:
        constraints = constraints._replace(point_mass=constraints.point_mass.copy())
    system.model = model._replace(
        tendon_stiffness=model.tendon_stiffness.copy(),
        tendon_damping=damping.copy(),
        rod_param=model.rod_param.copy(),
        constraints=constraints,
        contacts=contacts,
    )
    pairs = 0 if contacts is None else contact_pairs(contacts)
    tangent = None
    if not np.any(model.rod_param[:, ROD_RELATIVE_DAMPING]):
        tangent = _tangent_parameters(system, kinds, members, len(planes))
    return sensitivity_work(kinds, members, sizes, S0, structure.n_tendons, pairs, knots, tangent)


def _tangent_parameters(
    system: CompiledSystem, kinds: list[str], members: list[np.ndarray], n_planes: int
) -> Any:
    """The analytic tangent's work (:func:`tensegrity.engine.tangent.tangent_work`) with each
    parameter's derivative of the model's values: 1 at its members (each moves by the
    parameter's change), for the kinds that enter the right-hand side."""
    constraints = system.model.constraints
    masses = 0 if constraints is None else constraints.point_mass.shape[0]
    rows = 0 if constraints is None else constraints.constraint_rhs.shape[0]
    tw = tangent_work(
        len(kinds), system.m, system.data.node_force.shape[1], system.structure.n_tendons,
        system.structure.n_rods, masses, n_planes, rows,
    )  # fmt: skip
    by_kind = {
        "tendon_stiffness": tw.tendon_stiffness,
        "tendon_damping": tw.tendon_damping,
        "tendon_rest_length": tw.rest_length,
        "rod_mass": tw.rod_mass,
        "point_mass": tw.point_mass,
    }
    plane_rows = {
        "contact_stiffness": PLANE_STIFFNESS,
        "contact_damping": PLANE_DAMPING,
        "kinetic_friction": PLANE_KINETIC_FRICTION,
    }
    for j, (kind, index) in enumerate(zip(kinds, members, strict=True)):
        if kind in by_kind:
            by_kind[kind][j, index] = 1.0
        elif kind in plane_rows:
            tw.plane[j, plane_rows[kind], :] = 1.0
    if "control" in kinds:
        tw = tw._replace(has_control=True, rest=tw.rest_length.copy())
    return tw


def _coefficient(plane: Any, kind: str) -> float:
    """A plane's coefficient of ``kind`` (:data:`PLANE_FIELDS`)."""
    return float(getattr(plane, PLANE_FIELDS[kind]))
