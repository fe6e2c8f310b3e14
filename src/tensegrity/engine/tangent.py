"""The tangent of the right-hand side, analytic: ``f_y(t_s, y) V_j + f_p_j(t_s, y)`` for all P
directions ``V_j`` of a stage at once (the sensitivities' stages,
:mod:`tensegrity.engine.sensitivity`), from the evaluation ``f(t_s, y)`` just made there.

Each pass of the right-hand side (:func:`tensegrity.physics.kernel_system.system_rhs`) has its
tangent here, in the same order: the node positions and velocities (eq. 18.26); the tendons'
forces ``T t / l`` with ``T = k (l - Lbar) + c l'`` (the step's side of every slack/taut
switch, as the sensitivities' steps keep it); the contacts' normal law and kinetic friction
(:func:`~tensegrity.physics.contact.friction_direction`); Theorem 18.1 for every rod (eqs.
18.17, 18.20, with gravity, the external forces and mass-proportional damping);
the point masses; the forces that hold sticking points; the joint and support forces; and the
three powers (``E_d'``, ``W_w'``, ``W_u'``).  The primal values come once per stage and serve
every direction, so a direction costs a fraction of an evaluation (the central differences
this replaces took two).

The joint and support forces: with ``lambda`` the stage's multiplier, ``q'' = a + G A^T
lambda`` and ``K lambda = -A a``, so the tangent is that same projection applied to ``a' + G'
A^T lambda`` (``G'`` the derivative of ``G(q)`` and of the masses in it).  The forces that
hold a rod's sticking ends (:func:`tensegrity.physics.contact.rod_stick`, a small solve on the
eigenvectors it keeps) are differentiated with that set of eigenvectors
(:func:`_stick_tangents`); a point mass's are a projection of its acceleration that its mass
does not enter, applied to ``a'``.

Not covered: a rod's damping relative to the rigid motion (``beta``, a fit of the whole
structure's motion); a run with it takes the central differences
(:func:`tensegrity.engine.sensitivity.directional`).  Parameters move as there: a tendon's
``k``, ``c``, rest length (``Lbar = L0 - u`` moves with ``L0``), a rod's or point mass's mass,
a plane's contact stiffness, damping and kinetic friction (its static friction does not enter
``f``: only the events' indicators), and the control table's values (the rest lengths by the
table's weights at the stage's time, and their rates by its slopes).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tensegrity.model.ground import FREE, SLIP, STICK
from tensegrity.physics.compiling import (
    ROD_C1,
    ROD_C2,
    ROD_DAMPING,
    ROD_LENGTH,
    ROD_MASS,
    compiled_only,
)
from tensegrity.physics.contact import (
    STICK_NULL,
    friction_direction,
    point_motion,
    point_stick,
    sum_end,
)
from tensegrity.physics.kernel import end_values, stage_row, tendon_vector
from tensegrity.physics.kernel_system import (
    add_constraint_response,
    body_forces,
    constraint_rows_times,
    solve_envelope_psd,
)

#: The rows of :attr:`TangentWork.plane`: the planes' parameters that enter the right-hand side.
PLANE_STIFFNESS, PLANE_DAMPING, PLANE_KINETIC_FRICTION = range(3)


class TangentWork(NamedTuple):
    """The directions' parameters and the tangent's scratch (``SensitivityWork.tangent``); P
    directions, ``S`` tendons (kernel order), ``R`` rods, ``M`` point masses, ``Pl`` planes,
    ``m`` the state's length."""

    tendon_stiffness: np.ndarray  #: (P, S) each direction's ``dk`` [N/m per unit]
    tendon_damping: np.ndarray  #: (P, S) ``dc`` [N s/m per unit]
    rest_length: np.ndarray  #: (P, S) ``dLbar`` of the rest-length parameters [m per unit]
    #: (P, S) ``dLbar`` at the stage: ``rest_length`` itself, or with control-table parameters
    #: an array of its own with the table's weights added
    rest: np.ndarray
    rate: np.ndarray  #: (P, S) ``d(du/dt)`` at the stage [m/s per unit]
    has_control: bool  #: some parameter is a value of the control table
    rod_mass: np.ndarray  #: (P, R) ``dm`` [kg per unit]
    point_mass: np.ndarray  #: (P, max(M, 1)) ``dm`` [kg per unit]
    plane: np.ndarray  #: (P, 3, max(Pl, 1)) ``dk``, ``dc``, ``dmu_k`` (rows ``PLANE_*``)
    direction: np.ndarray  #: (P, m) the stage's directions ``V``
    node_position: np.ndarray  #: (P, 3, n_slots) the nodes' tangents [m per unit]
    node_velocity: np.ndarray  #: (P, 3, n_slots) [m/s per unit]
    node_force: np.ndarray  #: (P, 3, n_slots) the tendon and contact forces' [N per unit]
    force: np.ndarray  #: (3, n_slots) those forces themselves [N]
    #: (m,) the rods' accelerations before the sticking forces [m/s^2] (rows 0..6R)
    acceleration: np.ndarray
    power: np.ndarray  #: (P, 3) the powers' tangents [W per unit]
    vectors: np.ndarray  #: (8, 6) scratch
    kept: np.ndarray  #: (max(Pl, 1), 3) scratch: a point mass's sticking forces [N]
    solve: np.ndarray  #: (4, max(c, 1)) scratch of the joint and support forces


def tangent_work(
    P: int,
    m: int,
    n_slots: int,
    n_tendons: int,
    n_rods: int,
    n_masses: int,
    n_planes: int,
    constraint_rows: int,
) -> TangentWork:
    """A :class:`TangentWork` with every parameter's derivative zero (the caller sets them)."""
    rest_length = np.zeros((P, n_tendons))
    return TangentWork(
        tendon_stiffness=np.zeros((P, n_tendons)),
        tendon_damping=np.zeros((P, n_tendons)),
        rest_length=rest_length,
        rest=rest_length,  # (a separate array only with control-table parameters)
        rate=np.zeros((P, n_tendons)),
        has_control=False,
        rod_mass=np.zeros((P, n_rods)),
        point_mass=np.zeros((P, max(n_masses, 1))),
        plane=np.zeros((P, 3, max(n_planes, 1))),
        direction=np.zeros((P, m)),
        node_position=np.zeros((P, 3, n_slots)),
        node_velocity=np.zeros((P, 3, n_slots)),
        node_force=np.zeros((P, 3, n_slots)),
        force=np.zeros((3, n_slots)),
        acceleration=np.zeros(m),
        power=np.zeros((P, 3)),
        vectors=np.zeros((8, 6)),
        kept=np.zeros((max(n_planes, 1), 3)),
        solve=np.zeros((4, max(constraint_rows, 1))),
    )


# --------------------------------------------------------------------------- compiled
@compiled_only
def rhs_tangent(model, data, s, tw, side, y, K):  # pragma: no cover - compiled
    """``K[j, s] = f_y V_j + f_p_j`` at stage ``s`` (``data``'s inputs row ``s``) for every
    direction ``V_j = tw.direction[j]`` (P, m), right after ``f(t_s, y)`` was evaluated with
    ``data`` (whose scratch holds that evaluation); ``tw.rest`` and ``tw.rate`` hold the
    parameters' derivatives at the stage; ``side`` the step's taut flags (kernel order,
    first)."""
    n = (y.shape[0] - 3) // 2
    q, qdot = y[:n], y[n : 2 * n]
    _node_tangents(model.constraints, model, tw, n)
    tw.force[:] = 0.0
    tw.node_force[:] = 0.0
    tw.power[:] = 0.0
    _tendon_tangents(model, data, s, tw, side)
    _contact_tangents(model.contacts, data, tw, q, qdot)
    _rod_tangents(model, data, s, tw, q, qdot, K)
    _stick_tangents(model.contacts, model, data, tw, q, qdot, K, s)
    _point_mass_tangents(model.constraints, model, data, s, tw, qdot, K)
    _mass_stick_tangents(model.contacts, model, data, tw, qdot, K, s)
    _constraint_tangents(model.constraints, model, data, tw, q, K, s)
    for j in range(K.shape[0]):
        out, v = K[j, s], tw.direction[j]
        for i in range(n):
            out[i] = v[n + i]
        for i in range(3):
            out[2 * n + i] = tw.power[j, i]


@compiled_only
def _node_tangents(constraints, model, tw, n):  # pragma: no cover - compiled
    """The nodes' tangents from the directions (eq. 18.26; a point mass's are its own, an
    anchor's stay zero)."""
    for j in range(tw.direction.shape[0]):
        v = tw.direction[j]
        end_values(v[:n], model.rod_slots, tw.node_position[j])
        end_values(v[n : 2 * n], model.rod_slots, tw.node_velocity[j])
        if constraints is None:
            continue
        o = 6 * model.rod_slots.shape[0]
        for k in range(constraints.mass_slots.shape[0]):
            slot = constraints.mass_slots[k]
            for i in range(3):
                tw.node_position[j, i, slot] = v[o + 3 * k + i]
                tw.node_velocity[j, i, slot] = v[n + o + 3 * k + i]


@compiled_only
def _tendon_tangents(model, data, s, tw, side):  # pragma: no cover - compiled
    """The tendons' forces into ``tw.force`` and their tangents into ``tw.node_force``; the
    tangents of the power of their damping (``tw.power[:, 0]``) and of the control's
    (``[:, 2]``).  A tendon pulls where ``side`` says (the step's side of its switch): its
    force's tangent is zero where it does not, but a stretched tendon whose damping holds it at
    zero tension keeps its elastic tension ``k (l - Lbar)`` in both powers.  (No tension caps:
    they come with actuators, which a run with sensitivities refuses.)"""
    p, v = data.node_position, data.node_velocity
    rest = stage_row(data.rest, s)
    rate_u = stage_row(data.rate, s)
    stiffness, damping = model.tendon_stiffness, model.tendon_damping
    for e in range(model.tendon_slots.shape[0]):
        tail, head, tx, ty, tz = tendon_vector(p, model.tendon_slots, e)
        length = np.sqrt(tx * tx + ty * ty + tz * tz)
        stretch = length - rest[e]
        pulling = side[e]
        if not (stretch > 0.0 or pulling) or not length > 0.0:
            continue
        ex, ey, ez = tx / length, ty / length, tz / length
        wx, wy, wz = v[0, head] - v[0, tail], v[1, head] - v[1, tail], v[2, head] - v[2, tail]
        rate = ex * wx + ey * wy + ez * wz
        k, c = stiffness[e], damping[e]
        total = data.tension[e]
        elastic = k * stretch if stretch > 0.0 else 0.0
        tw.force[0, tail] += total * ex
        tw.force[1, tail] += total * ey
        tw.force[2, tail] += total * ez
        tw.force[0, head] -= total * ex
        tw.force[1, head] -= total * ey
        tw.force[2, head] -= total * ez
        if not pulling:
            total = 0.0  # (the step's side)
        for j in range(tw.direction.shape[0]):
            dp, dv = tw.node_position[j], tw.node_velocity[j]
            dtx, dty, dtz = (
                dp[0, head] - dp[0, tail],
                dp[1, head] - dp[1, tail],
                dp[2, head] - dp[2, tail],
            )
            dwx, dwy, dwz = (
                dv[0, head] - dv[0, tail],
                dv[1, head] - dv[1, tail],
                dv[2, head] - dv[2, tail],
            )
            d_length = ex * dtx + ey * dty + ez * dtz
            d_rate = (
                dtx * wx + dty * wy + dtz * wz + tx * dwx + ty * dwy + tz * dwz - rate * d_length
            ) / length
            # (pulling, or stretched: the spring's side, though a state landed on its switch
            # may sit a round-off short of it)
            d_elastic = tw.tendon_stiffness[j, e] * stretch + k * (d_length - tw.rest[j, e])
            d_total = 0.0
            if pulling:
                d_total = d_elastic + tw.tendon_damping[j, e] * rate + c * d_rate
                turn = total / length  # (d(t / l) = (dt - e dl) / l)
                fx = d_total * ex + turn * (dtx - ex * d_length)
                fy = d_total * ey + turn * (dty - ey * d_length)
                fz = d_total * ez + turn * (dtz - ez * d_length)
                f = tw.node_force[j]
                f[0, tail] += fx
                f[1, tail] += fy
                f[2, tail] += fz
                f[0, head] -= fx
                f[1, head] -= fy
                f[2, head] -= fz
            tw.power[j, 0] += (d_total - d_elastic) * rate + (total - elastic) * d_rate
            if data.has_rate:
                tw.power[j, 2] += d_elastic * rate_u[e] + elastic * tw.rate[j, e]


@compiled_only
def _contact_tangents(contacts, data, tw, q, qdot):  # pragma: no cover - compiled
    """The pairs' normal forces and kinetic friction into ``tw.force``, their tangents into
    ``tw.node_force``, and those of the power they dissipate into ``tw.power[:, 0]``, each pair
    in its mode (:func:`tensegrity.physics.contact.contact_pass`: a free pair has no force, but
    while it penetrates, the power stored in its spring is taken from the dissipated one as
    in every mode); nothing without contacts."""
    if contacts is None:
        return
    work = data.contact_work
    normal, point = contacts.plane_normal, contacts.plane_point
    n = q.shape[0]
    x, v, dx, dv = tw.vectors[0, :3], tw.vectors[1, :3], tw.vectors[2, :3], tw.vectors[3, :3]
    planes = normal.shape[0]
    for c in range(contacts.point_radius.shape[0]):
        point_motion(contacts, q, c, x)
        point_motion(contacts, qdot, c, v)
        slot = contacts.point_slot[c]
        for p in range(planes):
            k = c * planes + p
            mode = work.mode[k]
            nx, ny, nz = normal[p, 0], normal[p, 1], normal[p, 2]
            height = (
                nx * (x[0] - point[p, 0]) + ny * (x[1] - point[p, 1]) + nz * (x[2] - point[p, 2])
            )
            rate = -(nx * v[0] + ny * v[1] + nz * v[2])
            delta = contacts.point_radius[c] - height
            stiffness, damping = contacts.contact_stiffness[p], contacts.contact_damping[p]
            mu = contacts.friction_kinetic[p]
            if mode == FREE and not delta > 0.0:
                continue
            force = stiffness * delta + damping * rate if mode != FREE else 0.0
            ux, uy, uz = v[0] + rate * nx, v[1] + rate * ny, v[2] + rate * nz  # (v_t)
            size, scale = 0.0, 0.0
            gx = gy = gz = 0.0  # (the friction's direction: none at size 0)
            if mode == SLIP:
                gx, gy, gz, size = friction_direction(ux, uy, uz, work.slip_direction[k])
                scale = -mu * force
            tw.force[0, slot] += force * nx + scale * gx
            tw.force[1, slot] += force * ny + scale * gy
            tw.force[2, slot] += force * nz + scale * gz
            for j in range(tw.direction.shape[0]):
                point_motion(contacts, tw.direction[j, :n], c, dx)
                point_motion(contacts, tw.direction[j, n : 2 * n], c, dv)
                d_delta = -(nx * dx[0] + ny * dx[1] + nz * dx[2])
                d_rate = -(nx * dv[0] + ny * dv[1] + nz * dv[2])
                dk = tw.plane[j, PLANE_STIFFNESS, p]
                d_force = stiffness * d_delta + damping * d_rate + dk * delta
                d_force += tw.plane[j, PLANE_DAMPING, p] * rate
                if mode == FREE:
                    d_force = 0.0
                d_stored = 0.0
                if delta > 0.0:
                    d_stored = dk * delta * rate + stiffness * (d_delta * rate + delta * d_rate)
                power = d_force * rate + force * d_rate - d_stored
                fx, fy, fz = d_force * nx, d_force * ny, d_force * nz
                if size > 0.0:
                    dux, duy, duz = dv[0] + d_rate * nx, dv[1] + d_rate * ny, dv[2] + d_rate * nz
                    along = gx * dux + gy * duy + gz * duz
                    d_scale = -(tw.plane[j, PLANE_KINETIC_FRICTION, p] * force + mu * d_force)
                    dgx, dgy, dgz = (
                        (dux - gx * along) / size,
                        (duy - gy * along) / size,
                        (duz - gz * along) / size,
                    )
                    hx, hy, hz = (
                        d_scale * gx + scale * dgx,
                        d_scale * gy + scale * dgy,
                        d_scale * gz + scale * dgz,
                    )
                    fx, fy, fz = fx + hx, fy + hy, fz + hz
                    power -= hx * ux + hy * uy + hz * uz
                    power -= scale * (gx * dux + gy * duy + gz * duz)
                tw.node_force[j, 0, slot] += fx
                tw.node_force[j, 1, slot] += fy
                tw.node_force[j, 2, slot] += fz
                tw.power[j, 0] += power


@compiled_only
def _response_tangent(q, dq, o, c1, c2, dc1, dc2, forces, out):  # pragma: no cover - compiled
    """``out`` (6,) ``+=`` the tangent of a rod's response to its end forces (eqs. 18.17, 18.20:
    ``q1'' = c1 (f_a + f_b)``, ``q2'' = c2 skew(q2)^2 (f_a - f_b)``), the rod's coordinates at
    ``q[o:o + 6]`` moving along ``dq[o:o + 6]`` and ``c1``, ``c2`` along ``dc1``, ``dc2``;
    ``forces`` (4, 3): ``f_a + f_b``, ``f_a - f_b`` and their tangents.  (With ``c1 = c2 =
    0``, ``dc1``, ``dc2`` the rod's own and the tangents zero: the response itself.)"""
    sum_, diff, d_sum, d_diff = forces[0], forces[1], forces[2], forces[3]
    q2_d = q2_sq = dq2_d = q2_dd = q2_dq2 = 0.0
    for i in range(3):
        q2, dq2 = q[o + 3 + i], dq[o + 3 + i]
        q2_d += q2 * diff[i]
        q2_sq += q2 * q2
        dq2_d += dq2 * diff[i]
        q2_dd += q2 * d_diff[i]
        q2_dq2 += q2 * dq2
    for i in range(3):  # skew(q2)^2 d = q2 (q2 . d) - |q2|^2 d
        q2, dq2 = q[o + 3 + i], dq[o + 3 + i]
        out[i] += dc1 * sum_[i] + c1 * d_sum[i]
        out[3 + i] += dc2 * (q2 * q2_d - q2_sq * diff[i]) + c2 * (
            dq2 * q2_d + q2 * (dq2_d + q2_dd) - 2.0 * q2_dq2 * diff[i] - q2_sq * d_diff[i]
        )


@compiled_only
def _rod_tangents(model, data, s, tw, q, qdot, K):  # pragma: no cover - compiled
    """Every rod's accelerations before the sticking forces into ``tw.acceleration`` and their
    tangents into ``K[:, s]`` (eqs. 18.17, 18.20, gravity, the external forces ``w``, the
    damping ``alpha``); the tangents of the power of ``alpha`` (``tw.power[:, 0]``) and of
    ``w`` (``[:, 1]``)."""
    n = q.shape[0]
    rod_slots, rod_param = model.rod_slots, model.rod_param
    gravity, external = model.gravity, stage_row(data.force, s)
    g = 1.0 if model.has_gravity else 0.0
    forces = tw.vectors[:4, :3]
    for r in range(rod_slots.shape[0]):
        a, b, o = rod_slots[r, 0], rod_slots[r, 1], 6 * r
        mass, alpha = rod_param[r, ROD_MASS], rod_param[r, ROD_DAMPING]
        c1, c2, L2 = rod_param[r, ROD_C1], rod_param[r, ROD_C2], rod_param[r, ROD_LENGTH] ** 2
        for i in range(3):
            fa = tw.force[i, a] + 0.5 * mass * g * gravity[i]
            fb = tw.force[i, b] + 0.5 * mass * g * gravity[i]
            if data.has_external:
                fa, fb = fa + external[i, a], fb + external[i, b]
            forces[0, i], forces[1, i] = fa + fb, fa - fb
            forces[2, i], forces[3, i] = 0.0, 0.0
        v1_sq = v2_sq = 0.0
        for i in range(3):
            v1_sq += qdot[o + i] ** 2
            v2_sq += qdot[o + 3 + i] ** 2
        acceleration = tw.acceleration
        acceleration[o : o + 6] = 0.0
        _response_tangent(q, q, o, 0.0, 0.0, c1, c2, forces, acceleration[o : o + 6])
        for i in range(3):
            acceleration[o + i] -= alpha * qdot[o + i]
            acceleration[o + 3 + i] -= v2_sq / L2 * q[o + 3 + i] + alpha * qdot[o + 3 + i]
        for j in range(K.shape[0]):
            v, out, dm = tw.direction[j], K[j, s], tw.rod_mass[j, r]
            f = tw.node_force[j]
            for i in range(3):
                dfa = f[i, a] + 0.5 * dm * g * gravity[i]
                dfb = f[i, b] + 0.5 * dm * g * gravity[i]
                forces[2, i], forces[3, i] = dfa + dfb, dfa - dfb
            out[n + o : n + o + 6] = 0.0
            dc1, dc2 = -c1 * dm / mass, -c2 * dm / mass
            _response_tangent(q, v, o, c1, c2, dc1, dc2, forces, out[n + o : n + o + 6])
            u1_du1 = u2_du2 = 0.0
            for i in range(3):
                u1, u2 = qdot[o + i], qdot[o + 3 + i]
                du1, du2 = v[n + o + i], v[n + o + 3 + i]
                u1_du1 += u1 * du1
                u2_du2 += u2 * du2
                out[n + o + i] -= alpha * du1
                out[n + o + 3 + i] -= v2_sq / L2 * v[o + 3 + i] + alpha * du2
                if data.has_external:
                    tw.power[j, 1] += 0.5 * (
                        external[i, a] * (du1 - du2) + external[i, b] * (du1 + du2)
                    )
            for i in range(3):
                out[n + o + 3 + i] -= 2.0 * u2_du2 / L2 * q[o + 3 + i]
            tw.power[j, 0] += alpha * (
                dm * (v1_sq / 4.0 + v2_sq / 12.0) + mass * (u1_du1 / 2.0 + u2_du2 / 6.0)
            )


@compiled_only
def _stick_tangents(contacts, model, data, tw, q, qdot, K, s):  # pragma: no cover - compiled
    """The tangents of the forces that hold each rod's sticking ends, added to ``K[:, s]``, and
    of their power ``-F_t . v`` (``tw.power[:, 0]``); nothing without contacts.

    :func:`tensegrity.physics.contact.rod_stick` solves ``M x = b`` for the ends' tangential
    forces ``x``: ``R`` (2c, 6) the rod's response to each unit force (eqs. 18.17, 18.20),
    ``T`` the ends' tangential accelerations, ``M = T R^T`` (symmetric), ``b = -T a`` from the
    accelerations ``a`` before them, on the eigenvectors of ``M`` above :data:`STICK_NULL` of
    its largest eigenvalue; the accelerations change by ``R^T x``.  With that set of
    eigenvectors kept (``M+`` the solve on it),

        x' = M+ (b' - M' x) + sum_(k kept, g not) (v_g (v_k . b) + v_k (v_g . b))
             (v_g . M' v_k) / ((lambda_k - lambda_g) lambda_k),

    ``M' = T R'^T``, ``b' = -T a'``, ``R'`` from the rod's ``q2'`` and mass (the eigenvectors'
    turn into the dropped ones; within the kept ones it cancels)."""
    if contacts is None:
        return
    work = data.contact_work
    n, planes, tangent = q.shape[0], contacts.plane_normal.shape[0], contacts.plane_tangent
    rod_param = model.rod_param
    forces, v, dv = tw.vectors[:4, :3], tw.vectors[6, :3], tw.vectors[7, :3]
    pairs = np.empty(2 * planes, np.int64)
    for r in range(rod_param.shape[0]):
        count = 0
        for k in range(2 * r * planes, 2 * (r + 1) * planes):
            if work.mode[k] == STICK:
                pairs[count] = k
                count += 1
        if count == 0:
            continue
        m, o = 2 * count, 6 * r
        mass, c1, c2 = rod_param[r, ROD_MASS], rod_param[r, ROD_C1], rod_param[r, ROD_C2]
        sign, axis = np.empty(m), np.empty((m, 3))  # (each force's end, and direction)
        response, d_response = np.zeros((m, 6)), np.empty((m, 6))
        matrix, d_matrix, b = np.empty((m, m)), np.empty((m, m)), np.empty(m)
        for i in range(m):
            k = pairs[i // 2]
            sign[i] = 2.0 * ((k // planes) % 2) - 1.0
            axis[i] = tangent[k % planes, i % 2]
            _unit_forces(forces, axis[i], sign[i])
            _response_tangent(q, q, o, 0.0, 0.0, c1, c2, forces, response[i])
        for i in range(m):
            b[i] = -0.5 * sum_end(axis[i], tw.acceleration[o : o + 6], sign[i])
            for g in range(m):
                matrix[i, g] = 0.5 * sum_end(axis[i], response[g], sign[i])
        values, vectors = np.linalg.eigh(matrix)
        kept = values > STICK_NULL * values[-1]
        along, projected = np.empty(m), np.empty(m)
        _in_basis(vectors, b, along)  # (v_k . b)
        x = np.zeros(m)
        for k in range(m):
            if kept[k]:
                x += vectors[:, k] * (along[k] / values[k])
        for j in range(K.shape[0]):
            out, dm = K[j, s, n + o : n + o + 6], tw.rod_mass[j, r]
            for i in range(m):
                _unit_forces(forces, axis[i], sign[i])
                d_response[i] = 0.0
                _response_tangent(
                    q,
                    tw.direction[j],
                    o,
                    c1,
                    c2,
                    -c1 * dm / mass,
                    -c2 * dm / mass,
                    forces,
                    d_response[i],
                )
            for i in range(m):
                b_i = -0.5 * sum_end(axis[i], out, sign[i])  # (out: a' before the forces)
                for g in range(m):
                    d_matrix[i, g] = 0.5 * sum_end(axis[i], d_response[g], sign[i])
                    b_i -= d_matrix[i, g] * x[g]
                b[i] = b_i  # (b' - M' x)
            _in_basis(vectors, b, projected)
            dx = np.zeros(m)
            for k in range(m):
                if not kept[k]:
                    continue
                dx += vectors[:, k] * (projected[k] / values[k])
                for g in range(m):
                    if not kept[g]:
                        turned = 0.0  # (v_g . M' v_k)
                        for i in range(m):
                            for h in range(m):
                                turned += vectors[i, g] * d_matrix[i, h] * vectors[h, k]
                        weight = turned / ((values[k] - values[g]) * values[k])
                        dx += weight * (vectors[:, g] * along[k] + vectors[:, k] * along[g])
            for i in range(6):
                for g in range(m):
                    out[i] += d_response[g, i] * x[g] + response[g, i] * dx[g]
            for a in range(count):  # the power: -(dF_t . v + F_t . dv), per sticking pair
                point = pairs[a] // planes
                point_motion(contacts, qdot, point, v)
                point_motion(contacts, tw.direction[j, n : 2 * n], point, dv)
                for i in range(3):
                    force = x[2 * a] * axis[2 * a, i] + x[2 * a + 1] * axis[2 * a + 1, i]
                    d_force = dx[2 * a] * axis[2 * a, i] + dx[2 * a + 1] * axis[2 * a + 1, i]
                    tw.power[j, 0] -= d_force * v[i] + force * dv[i]


@compiled_only
def _in_basis(vectors, b, out):  # pragma: no cover - compiled
    """``out[k] = vectors[:, k] . b``: ``b`` in the eigenvectors' basis."""
    for k in range(b.shape[0]):
        out[k] = 0.0
        for i in range(b.shape[0]):
            out[k] += vectors[i, k] * b[i]


@compiled_only
def _unit_forces(forces, axis, sign):  # pragma: no cover - compiled
    """``forces`` (4, 3) of :func:`_response_tangent` for a unit force along ``axis`` at a
    rod's end ``sign`` (-1: a, +1: b; ``f_a - f_b = -sign axis``), constant."""
    for i in range(3):
        forces[0, i], forces[1, i] = axis[i], -sign * axis[i]
        forces[2, i], forces[3, i] = 0.0, 0.0


@compiled_only
def _point_mass_tangents(constraints, model, data, s, tw, qdot, K):  # pragma: no cover - compiled
    """The tangent of every point mass's acceleration ``(f + w) / m + g`` into ``K[:, s]``; that
    of the power of ``w`` into ``tw.power[:, 1]``.  Nothing without point masses
    (``constraints`` None)."""
    if constraints is None:
        return
    n = qdot.shape[0]
    external = stage_row(data.force, s)
    first = 6 * model.rod_slots.shape[0]
    for k in range(constraints.mass_slots.shape[0]):
        slot, o, mass = constraints.mass_slots[k], first + 3 * k, constraints.point_mass[k]
        for i in range(3):
            force = tw.force[i, slot] + (external[i, slot] if data.has_external else 0.0)
            for j in range(K.shape[0]):
                dm = tw.point_mass[j, k]
                K[j, s, n + o + i] = (tw.node_force[j, i, slot] - force * dm / mass) / mass
                if data.has_external:
                    tw.power[j, 1] += external[i, slot] * tw.direction[j, n + o + i]


@compiled_only
def _mass_stick_tangents(contacts, model, data, tw, qdot, K, s):  # pragma: no cover - compiled
    """The tangents of the forces that hold each point mass's sticking pairs, added to ``K[:,
    s]``: those forces cancel the tangential part of its acceleration, a projection its mass
    does not enter, so their tangent is that projection of the tangent
    (:func:`tensegrity.physics.contact.point_stick`); the tangent of their power into
    ``tw.power[:, 0]``.  The forces the evaluation left stay.  Nothing without contacts."""
    if contacts is None:
        return
    work = data.contact_work
    n, planes = qdot.shape[0], contacts.plane_normal.shape[0]
    correction, v, dv = tw.vectors[0, :3], tw.vectors[3, :3], tw.vectors[4, :3]
    for c in range(contacts.point_rod.shape[0]):
        if contacts.point_rod[c] >= 0:
            continue
        first = c * planes
        for k in range(first, first + planes):
            tw.kept[k - first] = work.friction_force[k]
        o, mass = contacts.point_offset[c], contacts.point_mass[c]
        point_motion(contacts, qdot, c, v)
        for j in range(K.shape[0]):
            out = K[j, s]
            if point_stick(contacts, work, c, out[n + o : n + o + 3], correction) == 0:
                break
            dm = tw.point_mass[j, c - 2 * model.rod_slots.shape[0]]
            point_motion(contacts, tw.direction[j, n : 2 * n], c, dv)
            for i in range(3):
                out[n + o + i] += correction[i]
            for k in range(first, first + planes):
                if work.mode[k] != STICK:
                    continue
                f, kept = work.friction_force[k], tw.kept[k - first]
                for i in range(3):  # (F_t = m x, x the held acceleration: dF_t = dm x + m dx)
                    d_force = f[i] + dm / mass * kept[i]
                    tw.power[j, 0] -= d_force * v[i] + kept[i] * dv[i]
        for k in range(first, first + planes):
            work.friction_force[k] = tw.kept[k - first]


@compiled_only
def _constraint_tangents(constraints, model, data, tw, q, K, s):  # pragma: no cover - compiled
    """The tangents of the joint and support forces, in ``K[:, s]``: with ``lambda`` the
    evaluation's multiplier, the projection ``b -> b + G A^T mu``, ``K mu = -A b``, applied to
    ``b = a' + G' A^T lambda`` (the module docstring).  Nothing without constraint rows."""
    if constraints is None or constraints.constraint_rhs.shape[0] == 0:
        return
    work = data.constraint_work
    c = constraints.constraint_rhs.shape[0]
    n, n_rods, rod_param = q.shape[0], model.rod_slots.shape[0], model.rod_param
    multiplier, rhs, x, scratch = tw.solve[0, :c], tw.solve[1, :c], tw.solve[2, :c], tw.solve[3, :c]
    multiplier[:] = work.vectors[1, :c]  # (lambda: the evaluation's, before the solves below)
    forces, fa, fb = tw.vectors[:4, :3], tw.vectors[6, :3], tw.vectors[7, :3]
    for j in range(K.shape[0]):
        b, dq = K[j, s, n : 2 * n], tw.direction[j, :n]
        for body in range(constraints.body_start.shape[0] - 1):
            body_forces(constraints, multiplier, body, fa, fb)
            if body < n_rods:
                mass, c1, c2 = (
                    rod_param[body, ROD_MASS],
                    rod_param[body, ROD_C1],
                    rod_param[body, ROD_C2],
                )
                dm = tw.rod_mass[j, body]
                for i in range(3):
                    forces[0, i], forces[1, i] = fa[i] + fb[i], fa[i] - fb[i]
                    forces[2, i], forces[3, i] = 0.0, 0.0
                o = 6 * body
                dc1, dc2 = -c1 * dm / mass, -c2 * dm / mass
                _response_tangent(q, dq, o, c1, c2, dc1, dc2, forces, b[o : o + 6])
            else:
                k = body - n_rods
                mass, dm = constraints.point_mass[k], tw.point_mass[j, k]
                for i in range(3):
                    b[6 * n_rods + 3 * k + i] -= fa[i] * dm / (mass * mass)
        constraint_rows_times(b, n_rods, constraints, rhs)
        for i in range(c):
            rhs[i] = -rhs[i]
        solve_envelope_psd(
            work.k_values, work.k_factor, constraints.k_first, constraints.k_offset, rhs, x, scratch
        )
        add_constraint_response(q, x, rod_param, constraints, b)
