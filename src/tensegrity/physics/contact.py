"""Contact of the rods' ends and the point masses with rigid planes, compiled (the law:
:mod:`tensegrity.model.ground`).

The records' optional parts ``Model.contacts`` (:class:`~tensegrity.physics.records.Contacts`)
and ``Data.contact_work`` (:class:`~tensegrity.physics.records.ContactWork`) hold the planes and
the pairs' modes.  Point ``c < 2R`` is end ``c % 2`` of rod ``c // 2`` (``p_a = (q1 - q2) /
2``, ``p_b = (q1 + q2) / 2``, eq. 18.26), the next ``M`` the point masses; pair ``k = c P +
p``; ``delta = r - n . (x - x0)`` its penetration [m], ``delta' = -n . v``.

Modes (changed only by the engine's events, :mod:`tensegrity.engine.events`):

- ``FREE``: no force;
- ``SLIP``: ``F_n = k delta + c delta'`` along ``n`` and kinetic friction ``-mu_k F_n d``,
  ``d`` the direction of ``v_t + v_s s`` (``v_t`` the tangential velocity, ``s`` the slip's
  direction, ``v_s`` :data:`STICK_SPEED`): ``v_t``'s once it moves, ``s`` from rest,
  continuous in between;
- ``STICK``: ``F_n`` and the tangential force that keeps the point's tangential acceleration
  zero, solved per rod after the rod pass (:func:`stick_pass`; Theorem 18.1's accelerations are
  affine in the end forces), per point mass after theirs (:func:`mass_stick_pass`).

Every evaluation writes the events' indicators (``ContactWork.indicator``, rows ``2k``, ``2k +
1``): contact ``min(k delta, k delta + c delta')`` (> 0 while the law pushes), friction
``mu_s F_n - |F_t|`` sticking (> 0 while the force needed is inside the cone), ``-v_t . s -
v_r`` slipping (> 0 once the point moves against the slip's direction ``s`` at ``v_r``
:data:`REVERSAL_SPEED`: it may stick), ``-1`` free.  Energy: ``k max(delta, 0)^2 / 2`` per
pair is elastic energy, and the power ``(F_n - k delta) delta'`` (for ``delta > 0``, else
``F_n delta'``) and ``-F_t . v_t`` is dissipated, so that the energy balance holds.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tensegrity.model.ground import FREE, SLIP, STICK, Plane
from tensegrity.physics.compiling import ROD_C1, ROD_C2, ROD_MASS, compiled_only
from tensegrity.physics.records import Contacts, ContactWork

#: A rod's sticking system holds its ends only along the directions whose stiffness exceeds this
#: share of its largest (:func:`solve_stick_system`).
STICK_NULL = 1e-6
#: A contact point whose tangential speed is at most this [m/s] is at rest: landing or ending a
#: slip there, it may stick; slipping, its friction takes the slip's direction rather than
#: that of its velocity (the speed left by locating a reversal to the events' tolerance is far
#: below it; a slip that turns keeps a speed far above it).
STICK_SPEED = 1e-8
#: A slip has reversed once its point moves against the slip's direction at this speed [m/s]
#: (half :data:`STICK_SPEED`: the point is still at rest, and its friction keeps its direction).
#: A slip that starts from rest with little to drive it would otherwise "reverse" on the
#: integrator's error in a velocity of a few 1e-10 m/s: stick, fail, slip again, every 1e-8 s
#: (measured on a six-bar rolling at ``mu_s = mu_k``).
REVERSAL_SPEED = 0.5 * STICK_SPEED
#: A slip slower than this [m/s] at the end of a step sticks if the force it then needs is inside
#: the static cone (the rule for slow slips: a vanishing velocity turns ever faster, and its
#: direction field would stall the steps; :func:`tensegrity.engine.events.stick_slow_slips`).
SLOW_SLIP = 1e-6
#: ... unless its deceleration stops it within this time [s] (then the stop is located) ...
SLOW_STOP = 1e-3
#: ... or its acceleration takes it past :data:`SLOW_SLIP` within this time [s] (a stick that
#: just failed, which kinetic friction cannot hold: it slips on; a crawl speeds up far slower).
SLOW_START = 1e-5
#: The log of the modes' changes (``ContactWork.log``) holds this many landings' worth (every
#: pair changing) before the loop must take its rows.
LOG_LANDINGS = 8


@compiled_only
def end_motion(q, r, end, out):  # pragma: no cover - compiled
    """Position (or velocity, from ``q'``) of end ``end`` (0: a, 1: b) of rod ``r`` into ``out``
    (3,): ``(q1 -+ q2) / 2``."""
    o = 6 * r
    sign = 2.0 * end - 1.0
    for i in range(3):
        out[i] = 0.5 * (q[o + i] + sign * q[o + 3 + i])


@compiled_only
def point_motion(contacts, q, c, out):  # pragma: no cover - compiled
    """Position (or velocity, from ``q'``, or acceleration) of contact point ``c`` into ``out``
    (3,): a rod's end (:func:`end_motion`) or a point mass (its coordinates)."""
    r = contacts.point_rod[c]
    if r >= 0:
        end_motion(q, r, c % 2, out)
    else:
        o = contacts.point_offset[c]
        for i in range(3):
            out[i] = q[o + i]


@compiled_only
def tangential_velocity(contacts, qdot, k, out):  # pragma: no cover - compiled
    """The velocity of pair ``k``'s point along its plane into ``out`` (3,) [m/s] from the
    rates ``qdot`` (or its acceleration [m/s^2] from ``q''``); returns its size."""
    P = contacts.plane_normal.shape[0]
    c, p = k // P, k % P
    point_motion(contacts, qdot, c, out)
    normal = contacts.plane_normal[p]
    along = out[0] * normal[0] + out[1] * normal[1] + out[2] * normal[2]
    for i in range(3):
        out[i] -= along * normal[i]
    return np.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])


@compiled_only
def contact_pass(contacts, model, data, q, qdot):  # pragma: no cover - compiled
    """The normal forces and the sliding friction of every pair into ``data.node_force`` (before
    the rod pass), the pairs' forces and indicators into ``data.contact_work`` (the friction
    indicator of sticking pairs: :func:`stick_pass`); returns the power dissipated [W]."""
    work = data.contact_work
    normal, point = contacts.plane_normal, contacts.plane_point
    P = normal.shape[0]
    x, v = np.empty(3), np.empty(3)
    dissipated = 0.0
    for c in range(contacts.point_radius.shape[0]):
        point_motion(contacts, q, c, x)
        point_motion(contacts, qdot, c, v)
        slot = contacts.point_slot[c]
        for p in range(P):
            k = c * P + p
            height, rate = 0.0, 0.0
            for i in range(3):
                height += normal[p, i] * (x[i] - point[p, i])
                rate -= normal[p, i] * v[i]
            delta = contacts.point_radius[c] - height
            stiffness, damping = contacts.contact_stiffness[p], contacts.contact_damping[p]
            law = stiffness * delta + damping * rate
            work.indicator[2 * k] = min(stiffness * delta, law)
            mode = work.mode[k]
            force = law if mode != FREE else 0.0
            work.normal_force[k] = force
            stored = stiffness * delta * rate if delta > 0.0 else 0.0
            dissipated += force * rate - stored
            normal_speed = -rate
            tx, ty, tz = (
                v[0] - normal_speed * normal[p, 0],
                v[1] - normal_speed * normal[p, 1],
                v[2] - normal_speed * normal[p, 2],
            )
            friction = work.friction_force[k]
            friction[0], friction[1], friction[2] = 0.0, 0.0, 0.0
            if mode == SLIP:
                s = work.slip_direction[k]
                dx, dy, dz, _ = friction_direction(tx, ty, tz, s)
                scale = -contacts.friction_kinetic[p] * force
                friction[0], friction[1], friction[2] = scale * dx, scale * dy, scale * dz
                work.indicator[2 * k + 1] = -(tx * s[0] + ty * s[1] + tz * s[2]) - REVERSAL_SPEED
                dissipated -= friction[0] * tx + friction[1] * ty + friction[2] * tz
            elif mode == FREE:
                work.indicator[2 * k + 1] = -1.0
            for i in range(3):
                data.node_force[i, slot] += force * normal[p, i] + friction[i]
    return dissipated


@compiled_only
def friction_direction(tx, ty, tz, s):  # pragma: no cover - compiled
    """A slipping point's kinetic friction opposes the unit direction ``(dx, dy, dz)`` of ``v_t
    + STICK_SPEED s`` (``v_t = (tx, ty, tz)`` [m/s], ``s`` (3,) the slip's direction): of
    ``v_t`` once it moves, ``s`` from rest, continuous in between.  Returns ``(dx, dy, dz,
    size)``, ``size`` that vector's length [m/s] (zero: no direction, zeros)."""
    dx, dy, dz = tx + STICK_SPEED * s[0], ty + STICK_SPEED * s[1], tz + STICK_SPEED * s[2]
    size = np.sqrt(dx * dx + dy * dy + dz * dz)
    if size > 0.0:
        dx, dy, dz = dx / size, dy / size, dz / size
    return dx, dy, dz, size


@compiled_only
def rod_stick(contacts, model, work, r, q, values, correction):  # pragma: no cover - compiled
    """The tangential forces at rod ``r``'s sticking pairs that cancel the tangential part of
    its end ``values`` (the rod's 6 coordinates' accelerations, or rates: the same affine map,
    eqs. 18.17, 18.20) into ``work.friction_force``, and the change of those 6 values they make
    into ``correction``; returns the number of sticking pairs (0: nothing written)."""
    P = contacts.plane_normal.shape[0]
    tangent = contacts.plane_tangent
    pairs = np.empty(2 * P, np.int64)
    count = 0
    for end in range(2):
        for p in range(P):
            k = (2 * r + end) * P + p
            if work.mode[k] == STICK:
                pairs[count] = k
                count += 1
    if count == 0:
        return 0
    o = 6 * r
    c1, c2 = model.rod_param[r, ROD_C1], model.rod_param[r, ROD_C2]
    x2, y2, z2 = q[o + 3], q[o + 4], q[o + 5]
    q2_sq = x2 * x2 + y2 * y2 + z2 * z2
    m = 2 * count
    matrix = np.zeros((m, m))
    rhs = np.zeros(m)
    response = np.zeros((m, 6))  # the 6 values' change per unit tangential force
    for j in range(m):
        k = pairs[j // 2]
        p, sign = k % P, 2.0 * ((k // P) % 2) - 1.0
        fx, fy, fz = tangent[p, j % 2, 0], tangent[p, j % 2, 1], tangent[p, j % 2, 2]
        # a force F at end a (sign -1) or b (+1): q1'' += c1 F, q2'' += c2 (q2 (q2.Fd) - |q2|^2
        # Fd) with Fd = -sign F (the force on a minus that on b)
        dx, dy, dz = -sign * fx, -sign * fy, -sign * fz
        along = x2 * dx + y2 * dy + z2 * dz
        response[j, 0], response[j, 1], response[j, 2] = c1 * fx, c1 * fy, c1 * fz
        response[j, 3] = c2 * (x2 * along - q2_sq * dx)
        response[j, 4] = c2 * (y2 * along - q2_sq * dy)
        response[j, 5] = c2 * (z2 * along - q2_sq * dz)
    for i in range(m):
        k = pairs[i // 2]
        p, sign = k % P, 2.0 * ((k // P) % 2) - 1.0
        t = tangent[p, i % 2]
        rhs[i] = -0.5 * sum_end(t, values, sign)
        for j in range(m):
            matrix[i, j] = 0.5 * sum_end(t, response[j], sign)
    force = solve_stick_system(matrix, rhs)
    for i in range(6):
        correction[i] = 0.0
        for j in range(m):
            correction[i] += force[j] * response[j, i]
    for a in range(count):
        k = pairs[a]
        p = k % P
        for i in range(3):
            work.friction_force[k, i] = (
                force[2 * a] * tangent[p, 0, i] + force[2 * a + 1] * tangent[p, 1, i]
            )
    return count


@compiled_only
def point_stick(contacts, work, c, values, correction):  # pragma: no cover - compiled
    """:func:`rod_stick` for point mass ``c``: the tangential forces at its sticking pairs that
    cancel the tangential part of its ``values`` (3,) (acceleration or velocity; a force ``F``
    changes them by ``F / m``) into ``work.friction_force``, the change into ``correction``
    (3,); returns the number of sticking pairs (0: nothing written)."""
    P = contacts.plane_normal.shape[0]
    tangent, mass = contacts.plane_tangent, contacts.point_mass[c]
    pairs = np.empty(P, np.int64)
    count = 0
    for p in range(P):
        if work.mode[c * P + p] == STICK:
            pairs[count] = c * P + p
            count += 1
    if count == 0:
        return 0
    m = 2 * count
    matrix, rhs = np.empty((m, m)), np.empty(m)
    for i in range(m):
        ti = tangent[pairs[i // 2] % P, i % 2]
        rhs[i] = -(ti[0] * values[0] + ti[1] * values[1] + ti[2] * values[2])
        for j in range(m):
            tj = tangent[pairs[j // 2] % P, j % 2]
            matrix[i, j] = (ti[0] * tj[0] + ti[1] * tj[1] + ti[2] * tj[2]) / mass
    force = solve_stick_system(matrix, rhs)
    correction[:] = 0.0
    for a in range(count):
        k = pairs[a]
        for i in range(3):
            f = force[2 * a] * tangent[k % P, 0, i] + force[2 * a + 1] * tangent[k % P, 1, i]
            work.friction_force[k, i] = f
            correction[i] += f / mass
    return count


@compiled_only
def sum_end(t, values, sign):  # pragma: no cover - compiled
    """``t . (v1 + sign v2)`` for the 6 ``values`` ``(v1, v2)`` of a rod (twice an end's)."""
    total = 0.0
    for i in range(3):
        total += t[i] * (values[i] + sign * values[3 + i])
    return total


@compiled_only
def solve_stick_system(matrix, rhs):  # pragma: no cover - compiled
    """``x`` with ``matrix x = rhs`` on the span of the eigenvectors of the small symmetric
    positive semi-definite ``matrix`` whose eigenvalues exceed :data:`STICK_NULL` of the
    largest, and no part along the others: the forces of a rod's sticking ends, which cannot
    hold what the rod's rigidity moves (a rod lying with both ends stuck: the pair of forces
    along its axis moves nothing, and with the axis tilted by ``theta`` only ``theta^2`` of it;
    the ends' distance along the plane then follows the rod, a creep that vanishes with the
    rod's motion)."""
    m = rhs.shape[0]
    x = np.zeros(m)
    if not (np.isfinite(matrix).all() and np.isfinite(rhs).all()):
        x[:] = np.nan  # (a trial stage gone bad: NaN on, for the step's error control)
        return x
    values, vectors = np.linalg.eigh(matrix)
    floor = STICK_NULL * values[-1]
    for j in range(m):
        if values[j] > floor:
            c = 0.0
            for i in range(m):
                c += vectors[i, j] * rhs[i]
            c /= values[j]
            for i in range(m):
                x[i] += c * vectors[i, j]
    return x


@compiled_only
def stick_pass(contacts, model, data, q, qdot, qddot):  # pragma: no cover - compiled
    """After the rod pass: each rod with sticking ends gets the tangential forces that hold
    them (:func:`rod_stick`) added to its accelerations ``qddot``; the sticking pairs' friction
    indicators ``mu_s F_n - |F_t|``; returns the power of those forces' (``-F_t . v_t``, zero
    but for round-off) [W]."""
    work = data.contact_work
    correction, v = np.empty(6), np.empty(3)
    dissipated = 0.0
    for r in range(model.rod_slots.shape[0]):
        o = 6 * r
        if rod_stick(contacts, model, work, r, q, qddot[o : o + 6], correction) == 0:
            continue
        for i in range(6):
            qddot[o + i] += correction[i]
        for end in range(2):
            dissipated += _held(contacts, work, 2 * r + end, qdot, v)
    return dissipated


@compiled_only
def mass_stick_pass(contacts, data, qdot, qddot):  # pragma: no cover - compiled
    """After the point masses' pass: each point mass with sticking pairs gets the tangential
    forces that hold it (:func:`point_stick`) added to its acceleration in ``qddot``; their
    friction indicators; returns their power [W] (zero but for round-off)."""
    work = data.contact_work
    correction, v = np.empty(3), np.empty(3)
    dissipated = 0.0
    for c in range(contacts.point_rod.shape[0]):
        if contacts.point_rod[c] >= 0:
            continue
        o = contacts.point_offset[c]
        if point_stick(contacts, work, c, qddot[o : o + 3], correction) == 0:
            continue
        for i in range(3):
            qddot[o + i] += correction[i]
        dissipated += _held(contacts, work, c, qdot, v)
    return dissipated


@compiled_only
def _held(contacts, work, c, qdot, v):  # pragma: no cover - compiled
    """The friction indicators ``mu_s F_n - |F_t|`` of point ``c``'s sticking pairs; returns
    the power ``-F_t . v`` of their forces [W] (``v`` (3,) scratch)."""
    P = contacts.plane_normal.shape[0]
    point_motion(contacts, qdot, c, v)
    dissipated = 0.0
    for p in range(P):
        k = c * P + p
        if work.mode[k] != STICK:
            continue
        f = work.friction_force[k]
        size = np.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
        work.indicator[2 * k + 1] = contacts.friction_static[p] * work.normal_force[k] - size
        dissipated -= f[0] * v[0] + f[1] * v[1] + f[2] * v[2]
    return dissipated


@compiled_only
def record_contacts(work, normal_force, friction_force, mode, row):  # pragma: no cover
    """Row ``row`` of a sample's contact columns (``Samples.contact_*``) from the evaluation
    that wrote ``work`` (nothing without contacts)."""
    if work is None:
        return
    for k in range(work.mode.shape[0]):
        normal_force[row, k] = work.normal_force[k]
        mode[row, k] = work.mode[k]
        for i in range(3):
            friction_force[row, k, i] = work.friction_force[k, i]


@compiled_only
def contact_energy(contacts, q):  # pragma: no cover - compiled
    """The contacts' elastic energy ``sum k max(delta, 0)^2 / 2`` [J]."""
    normal, point = contacts.plane_normal, contacts.plane_point
    P = normal.shape[0]
    x = np.empty(3)
    energy = 0.0
    for c in range(contacts.point_radius.shape[0]):
        point_motion(contacts, q, c, x)
        for p in range(P):
            height = 0.0
            for i in range(3):
                height += normal[p, i] * (x[i] - point[p, i])
            delta = contacts.point_radius[c] - height
            if delta > 0.0:
                energy += 0.5 * contacts.contact_stiffness[p] * delta * delta
    return energy


# --------------------------------------------------------------------------- records
def pack_contacts(
    planes: Sequence[Plane],
    radius: float,
    rod_slots: np.ndarray,
    mass_slots: np.ndarray,
    point_mass: np.ndarray,
) -> Contacts:
    """The :class:`~tensegrity.physics.records.Contacts` of ``planes`` for contact points of
    ``radius`` [m]: the rods' ends (``rod_slots`` (R, 2), ``2 r + end``), then the point
    masses (``mass_slots`` (M,), of ``point_mass`` (M,) [kg], coordinates from ``6 R``)."""
    R, M = rod_slots.shape[0], mass_slots.shape[0]
    return Contacts(
        plane_point=np.array([plane.point for plane in planes], dtype=np.float64),
        plane_normal=np.array([plane.normal for plane in planes], dtype=np.float64),
        plane_tangent=np.array([plane.tangents() for plane in planes], dtype=np.float64),
        friction_static=np.array([plane.friction for plane in planes], dtype=np.float64),
        friction_kinetic=np.array([plane.kinetic_friction for plane in planes], dtype=np.float64),
        contact_stiffness=np.array([plane.stiffness for plane in planes], dtype=np.float64),
        contact_damping=np.array([plane.damping for plane in planes], dtype=np.float64),
        point_radius=np.full(2 * R + M, float(radius)),
        point_rod=np.concatenate([np.repeat(np.arange(R), 2), np.full(M, -1)]).astype(np.int64),
        point_offset=np.concatenate([np.zeros(2 * R), 6 * R + 3 * np.arange(M)]).astype(np.int64),
        point_slot=np.concatenate([rod_slots.reshape(-1), mass_slots]).astype(np.uint64),
        point_mass=np.concatenate([np.zeros(2 * R), point_mass]).astype(np.float64),
    )


def contact_work(contacts: Contacts) -> ContactWork:
    """A :class:`~tensegrity.physics.records.ContactWork` for ``contacts``, every pair free."""
    pairs = contacts.point_radius.shape[0] * contacts.plane_normal.shape[0]
    return ContactWork(
        mode=np.full(pairs, FREE, np.int64),
        slip_direction=np.zeros((pairs, 3)),
        normal_force=np.zeros(pairs),
        friction_force=np.zeros((pairs, 3)),
        indicator=np.zeros(2 * pairs),
        log=np.zeros((LOG_LANDINGS * pairs, 4)),
        log_count=np.zeros(1, np.int64),
    )


@compiled_only
def rod_kinetic(model, r, qdot):  # pragma: no cover - compiled
    """Kinetic energy of rod ``r`` [J]: ``m (|q1'|^2 / 8 + |q2'|^2 / 24)``."""
    o = 6 * r
    v1, v2 = 0.0, 0.0
    for i in range(3):
        v1 += qdot[o + i] * qdot[o + i]
        v2 += qdot[o + 3 + i] * qdot[o + 3 + i]
    return model.rod_param[r, ROD_MASS] * (v1 / 8.0 + v2 / 24.0)


@compiled_only
def stick_velocities(contacts, model, data, y):  # pragma: no cover - compiled
    """Zero the tangential velocity of every sticking point of the state ``y`` (m,) (per rod,
    the impulses :func:`rod_stick` solves for on the rates): the inelastic end of a slip, its
    kinetic energy added to the dissipated energy ``y[2n]``."""
    work = data.contact_work
    n = (y.shape[0] - 3) // 2
    q, qdot = y[:n], y[n : 2 * n]
    correction = np.empty(6)
    removed = 0.0
    for r in range(model.rod_slots.shape[0]):
        o = 6 * r
        if rod_stick(contacts, model, work, r, q, qdot[o : o + 6], correction) == 0:
            continue
        before = rod_kinetic(model, r, qdot)
        for i in range(6):
            qdot[o + i] += correction[i]
        removed += before - rod_kinetic(model, r, qdot)
    for c in range(contacts.point_rod.shape[0]):
        o = contacts.point_offset[c]
        if (
            contacts.point_rod[c] >= 0
            or point_stick(contacts, work, c, qdot[o : o + 3], correction) == 0
        ):
            continue
        before = qdot[o] ** 2 + qdot[o + 1] ** 2 + qdot[o + 2] ** 2
        for i in range(3):
            qdot[o + i] += correction[i]
        after = qdot[o] ** 2 + qdot[o + 1] ** 2 + qdot[o + 2] ** 2
        removed += 0.5 * contacts.point_mass[c] * (before - after)
    y[2 * n] += removed


@compiled_only
def refresh_slips(contacts, data, y):  # pragma: no cover - compiled
    """After an accepted step ending at ``y``: each slipping point's direction ``s`` becomes
    that of its tangential velocity if it moves faster than :data:`SLOW_SLIP`, so that the
    next step's friction indicator ``-v_t . s - v_r`` crosses zero wherever the point stops, however
    its velocity turned on the way (in the plane a slip that comes to rest turns ever faster as
    it slows); nothing without contacts.  The friction's direction at ``y`` does not change
    (that of ``v_t + STICK_SPEED s`` is ``v_t``'s when ``s`` is), and elsewhere by at most
    ``STICK_SPEED / SLOW_SLIP`` of the turn since the last step."""
    if contacts is None:
        return
    work = data.contact_work
    n = (y.shape[0] - 3) // 2
    v = np.empty(3)
    for k in range(work.mode.shape[0]):
        if work.mode[k] != SLIP:
            continue
        speed = tangential_velocity(contacts, y[n : 2 * n], k, v)
        if speed > SLOW_SLIP:
            for i in range(3):
                work.slip_direction[k, i] = v[i] / speed
