"""A compiled (numba) right-hand side and fixed-step RK4 loop for Theorem 18.1.

The physics is exactly that of :func:`tensegrity.dynamics.evaluate` (the readable NumPy reference):

- tendon tension ``T = max(k (l - Lbar) + c l', 0)`` while taut (``l > Lbar``), else 0;
- nodal forces from tendons, external forces ``w`` and gravity (half a rod's weight per end);
- accelerations (eqs. 18.17, 18.20) plus mass-proportional rod damping ``-alpha q'``::

      q1'' = (2/m) (f_a + f_b) - alpha q1'
      q2'' = -(|q2'|^2 / L^2) q2 + (6 / (m L^2)) skew(q2)^2 (f_a - f_b) - alpha q2'

- the power removed by tendon and rod damping and the power of ``w``.

Differences from the reference are round-off only (the summation order of the nodal forces, one
reciprocal instead of three divisions per tendon, fused multiply-adds); the kernel is compiled
with ``fastmath={"contract"}`` only (a * b + c may become one FMA instruction; no reassociation,
no approximate square roots or reciprocals, NaN and infinity kept), so that the two agree to
~1e-15 relative.  When no tendon is damped (all ``c = 0``, :func:`pack` then gives
``tendon_damping=None``) the same functions are compiled without the node velocities and the
length rates (numba specializes on None, as for ``block_force``): the same numbers as with zero
damping, a quarter less time per evaluation on large shells.  As in the reference, rest lengths
must be ``>= 0`` (``dynamics.rest_lengths`` checks them); they are not checked again here, for
speed.

The loops over rods and tendons run inside one compiled function writing into preallocated
buffers, and :func:`rk4_steps` runs a whole fixed-step RK4 integration (with projection onto the
rod constraints ``|q2| = L``, ``q2 . q2' = 0`` after every step, as ``simulate(method="rk4")``
does) in compiled code, so that small structures are not dominated by Python call overhead.
:func:`rk4_batch` does the same for many copies of one structure held in ``(B, ...)`` arrays,
with ``simulate``'s blow-up checks (used by :mod:`tensegrity.batch`); :func:`energies` gives the
kinetic, elastic and gravity energies for those checks.

This module imports numba; import it lazily (``from tensegrity.kernel import FastKernel`` inside
the function that needs it) so that ``import tensegrity`` stays fast.  Compiled code is cached on
disk (``cache=True``): the first use on a machine compiles for a few seconds, later processes load
the cache in well under a second.

Usage::

    from tensegrity.kernel import FastKernel

    kernel = FastKernel(structure)
    qddot, tension, dissipated, external = kernel.evaluate(q, qdot, rest_length)
    q, qdot = kernel.rk4(q, qdot, dt=1e-4, n_steps=1000, rest_length=rest_length)

A :class:`FastKernel` owns scratch buffers and is therefore not thread-safe: use one per thread.
``FastKernel(structure, threads=2)`` evaluates large structures on two cores (see
:class:`FastKernel`).
"""

from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from tensegrity.structure import Structure

__all__ = [
    "FastKernel", "KernelEvaluation", "RK4Result", "energies", "pack", "project", "rhs",
    "rk4_batch", "rk4_step", "rk4_steps",
]

_JIT = dict(
    cache=True, fastmath={"contract"}, nogil=True, boundscheck=False, error_model="numpy",
)


# --------------------------------------------------------------------------- compiled code
# Packed model arrays (built by :func:`pack`), few arguments being cheaper to pass from Python:
#   rod_nodes (R, 2) int64        end nodes (a, b) of each rod
#   rod_param (R, 5) float64      m, L, alpha, 2/m, 6/(m L^2)
#   tendon_nodes (S, 2) int64     (tail, head) of each tendon
#   tendon_stiffness (S,) float64 k
#   tendon_damping None or (S,) float64   c; None when every c is 0 (the common case): the
#       tendon pass is then compiled without the node velocities and the length rates (a
#       separate specialization of the same code, chosen at compile time like ``block_force``)
#   node_work (3, N, 3) float64   scratch: node positions, velocities (written only when
#       ``tendon_damping`` is not None), total nodal forces
#   block_force None or (B - 1, N, 3) float64   scratch of the threaded evaluation (B blocks)
ROD_MASS, ROD_LENGTH, ROD_DAMPING, ROD_C1, ROD_C2 = range(5)

# Inside the passes the node arrays are flat, (3N,) views of the (N, 3) buffers, and node ``i``'s
# x, y, z sit at ``3 i``, ``3 i + 1``, ``3 i + 2`` (:func:`_offset`).  The offsets are unsigned:
# numba wraps every signed index that the compiler cannot prove >= 0 (an index read from an
# array) around the array's length, a compare and an add per access; with 2-D (N, 3) arrays
# each access also multiplies by a stride held in a register, and the tendon pass ran out of
# registers.  With flat arrays and unsigned offsets an evaluation takes 0.94x the time with
# damped tendons and 0.78-0.87x on 2 threads, bitwise the same (docs/performance.md).  Unsigned
# arithmetic must stay unsigned: in numba ``uint64 + int64`` is a float64, so the offsets are
# only ever combined with the uint64 constants below.
_U1, _U2, _U3 = np.uint64(1), np.uint64(2), np.uint64(3)


@njit(inline="always", **_JIT)
def _offset(node):  # pragma: no cover - compiled
    """Index of node ``node``'s x coordinate in a flat (3N,) node array, as a uint64."""
    return _U3 * np.uint64(node)


@njit(inline="always", **_JIT)
def _node_pass(
    q, qdot, rod_nodes, rod_param, has_gravity, gravity, tendon_damping, p, v, force, first,
    last,
):  # pragma: no cover - compiled
    """Rods ``first:last``: node positions ``p = P q`` (eq. 18.26) into ``p`` (3N,) and, if
    ``tendon_damping`` is not None (the tendon pass needs them only then), the node velocities
    into ``v`` (3N,); the nodal forces ``force`` (3N,) start at gravity (or zero)."""
    # Every pass loops over slices, from 0 to their length: with ``range(first, last)`` the
    # compiler cannot prove an index >= 0 when ``first`` is not known at compile time (the
    # threaded blocks), and keeps numba's negative-index wrap-around on every access.
    rod_nodes = rod_nodes[first:last]
    rod_param = rod_param[first:last]
    q = q[6 * first:6 * last]
    qdot = qdot[6 * first:6 * last]
    for r in range(rod_nodes.shape[0]):
        a = _offset(rod_nodes[r, 0])
        b = _offset(rod_nodes[r, 1])
        o = 6 * r
        half_m = rod_param[r, ROD_MASS] / 2
        for i in range(3):
            j = np.uint64(i)
            q1 = q[o + i]
            q2 = q[o + 3 + i]
            p[a + j] = 0.5 * (q1 - q2)
            p[b + j] = 0.5 * (q1 + q2)
            if tendon_damping is not None:
                v1 = qdot[o + i]
                v2 = qdot[o + 3 + i]
                v[a + j] = 0.5 * (v1 - v2)
                v[b + j] = 0.5 * (v1 + v2)
            weight = half_m * gravity[i] if has_gravity else 0.0
            force[a + j] = weight
            force[b + j] = weight


@njit(inline="always", **_JIT)
def _tendon_pass(
    p, v, force, tendon_nodes, tendon_stiffness, tendon_damping, rest_length, tension,
    elastic_tension, first, last,
):  # pragma: no cover - compiled
    """Tendons ``first:last``: tension and elastic tension, nodal forces added to ``force``
    (3N,), the tail pulled toward the head and the head toward the tail.  Returns the power
    removed by tendon damping.  With ``tendon_damping`` None (all ``c = 0``) the node velocities
    ``v`` (3N,) are not read and the tension is the elastic tension: the same numbers as with
    zero damping, for finite velocities (0.70-0.78x the time of a whole evaluation at
    (100,100))."""
    tendon_nodes = tendon_nodes[first:last]
    tendon_stiffness = tendon_stiffness[first:last]
    rest_length = rest_length[first:last]
    tension = tension[first:last]
    elastic_tension = elastic_tension[first:last]
    dissipation = 0.0
    for s in range(tendon_nodes.shape[0]):
        tail = _offset(tendon_nodes[s, 0])
        head = _offset(tendon_nodes[s, 1])
        tx = p[head] - p[tail]
        ty = p[head + _U1] - p[tail + _U1]
        tz = p[head + _U2] - p[tail + _U2]
        length = np.sqrt(tx * tx + ty * ty + tz * tz)
        stretch = length - rest_length[s]
        if stretch > 0.0:  # taut (then length > 0: rest lengths are >= 0)
            inv = 1.0 / length  # one division instead of three (differs by an ulp at most)
            ex = tx * inv
            ey = ty * inv
            ez = tz * inv
            elastic = tendon_stiffness[s] * stretch
            total = elastic
            if tendon_damping is not None:
                rate = (
                    ex * (v[head] - v[tail])
                    + ey * (v[head + _U1] - v[tail + _U1])
                    + ez * (v[head + _U2] - v[tail + _U2])
                )
                total = elastic + tendon_damping[first + s] * rate
                if total < 0.0:
                    total = 0.0
                dissipation += (total - elastic) * rate
            tension[s] = total
            elastic_tension[s] = elastic
            fx = total * ex
            fy = total * ey
            fz = total * ez
            force[tail] += fx
            force[tail + _U1] += fy
            force[tail + _U2] += fz
            force[head] -= fx
            force[head + _U1] -= fy
            force[head + _U2] -= fz
        else:
            tension[s] = 0.0
            elastic_tension[s] = 0.0
    return dissipation


@njit(inline="always", **_JIT)
def _rod_pass(
    q, qdot, rod_nodes, rod_param, has_external, external_force, force, qddot, first, last,
):  # pragma: no cover - compiled
    """Rods ``first:last``: eqs. 18.17, 18.20 and mass-proportional damping into ``qddot``, from
    the nodal forces ``force`` (3N,), to which ``w`` (``external_force``, 3N,) is added; its
    power uses ``p' = P q'``.  Returns ``(rod_dissipation, external_power)``."""
    rod_nodes = rod_nodes[first:last]
    rod_param = rod_param[first:last]
    q = q[6 * first:6 * last]
    qdot = qdot[6 * first:6 * last]
    qddot = qddot[6 * first:6 * last]
    external_power = 0.0
    rod_dissipation = 0.0
    for r in range(rod_nodes.shape[0]):
        a = _offset(rod_nodes[r, 0])
        b = _offset(rod_nodes[r, 1])
        o = 6 * r
        if has_external:
            for i in range(3):  # node velocities p' = P q' (eq. 18.26)
                j = np.uint64(i)
                v1 = qdot[o + i]
                v2 = qdot[o + 3 + i]
                external_power += (external_force[a + j] * (0.5 * (v1 - v2))
                                   + external_force[b + j] * (0.5 * (v1 + v2)))
                force[a + j] += external_force[a + j]
                force[b + j] += external_force[b + j]
        L = rod_param[r, ROD_LENGTH]
        L2 = L * L
        alpha = rod_param[r, ROD_DAMPING]
        c1 = rod_param[r, ROD_C1]
        c2 = rod_param[r, ROD_C2]
        sx = force[a] + force[b]
        sy = force[a + _U1] + force[b + _U1]
        sz = force[a + _U2] + force[b + _U2]
        dx = force[a] - force[b]
        dy = force[a + _U1] - force[b + _U1]
        dz = force[a + _U2] - force[b + _U2]
        x = q[o + 3]
        y = q[o + 4]
        z = q[o + 5]
        u1x = qdot[o]
        u1y = qdot[o + 1]
        u1z = qdot[o + 2]
        ux = qdot[o + 3]
        uy = qdot[o + 4]
        uz = qdot[o + 5]
        q2_dot_f = x * dx + y * dy + z * dz
        q2_sq = x * x + y * y + z * z
        v2_sq = ux * ux + uy * uy + uz * uz
        cq = v2_sq / L2
        # skew(q2)^2 f = q2 (q2 . f) - |q2|^2 f
        qddot[o] = c1 * sx - alpha * u1x
        qddot[o + 1] = c1 * sy - alpha * u1y
        qddot[o + 2] = c1 * sz - alpha * u1z
        qddot[o + 3] = -cq * x + c2 * (x * q2_dot_f - q2_sq * dx) - alpha * ux
        qddot[o + 4] = -cq * y + c2 * (y * q2_dot_f - q2_sq * dy) - alpha * uy
        qddot[o + 5] = -cq * z + c2 * (z * q2_dot_f - q2_sq * dz) - alpha * uz
        if alpha != 0.0:
            v1_sq = u1x * u1x + u1y * u1y + u1z * u1z
            rod_dissipation += alpha * rod_param[r, ROD_MASS] * (v1_sq / 4.0 + v2_sq / 12.0)
    return rod_dissipation, external_power


@njit(inline="always", **_JIT)
def _flat(node_work):  # pragma: no cover - compiled
    """``(p, v, force)``: flat (3N,) views of the (3, N, 3) ``node_work``."""
    flat = node_work.reshape((3, node_work.shape[1] * 3))
    return flat[0], flat[1], flat[2]


@njit(**_JIT)
def _block(k, n_blocks, n):  # pragma: no cover - compiled
    """Bounds ``(first, last)`` of block ``k`` of ``n_blocks`` nearly equal blocks of ``range(n)``."""
    return k * n // n_blocks, (k + 1) * n // n_blocks


@njit(parallel=True, **_JIT)
def _rhs_threaded(
    q, qdot, rod_nodes, rod_param, tendon_nodes, tendon_stiffness, tendon_damping, rest_length,
    has_external, external_force, has_gravity, gravity,
    node_work, block_force, qddot, tension, elastic_tension,
):  # pragma: no cover - compiled
    """:func:`rhs` on ``B = block_force.shape[0] + 1`` threads: each pass is cut into B blocks run
    in parallel (``prange``).  Tendon block 0 adds its forces to ``node_work[2]`` (the weights),
    block ``k > 0`` to its own ``block_force[k - 1]`` (no two threads write the same memory), and
    the rod pass sums the blocks in order, so the result does not depend on the scheduling; it
    differs from the one-block sum by round-off."""
    n_blocks = block_force.shape[0] + 1
    n_rods = rod_nodes.shape[0]
    n_tendons = tendon_nodes.shape[0]
    p, v, force0 = _flat(node_work)
    extra_force = block_force.reshape((n_blocks - 1, block_force.shape[1] * 3))
    w = external_force.reshape(external_force.size)
    for k in prange(n_blocks):
        first, last = _block(k, n_blocks, n_rods)
        _node_pass(q, qdot, rod_nodes, rod_param, has_gravity, gravity, tendon_damping,
                   p, v, force0, first, last)
    tendon_power = np.empty(n_blocks)
    for k in prange(n_blocks):
        force = force0 if k == 0 else extra_force[k - 1]
        if k > 0:
            force[:] = 0.0
        first, last = _block(k, n_blocks, n_tendons)
        tendon_power[k] = _tendon_pass(p, v, force, tendon_nodes, tendon_stiffness,
                                       tendon_damping, rest_length, tension, elastic_tension,
                                       first, last)
    rod_power = np.empty((n_blocks, 2))
    for k in prange(n_blocks):
        first, last = _block(k, n_blocks, n_rods)
        for r in range(first, last):  # the blocks' forces summed into force0, in order
            a = _offset(rod_nodes[r, 0])
            b = _offset(rod_nodes[r, 1])
            for j in range(n_blocks - 1):
                for i in range(3):
                    c = np.uint64(i)
                    force0[a + c] += extra_force[j, a + c]
                    force0[b + c] += extra_force[j, b + c]
        rod_power[k, 0], rod_power[k, 1] = _rod_pass(
            q, qdot, rod_nodes, rod_param, has_external, w, force0, qddot, first, last)
    dissipated = 0.0
    external = 0.0
    for k in range(n_blocks):  # fixed order: deterministic
        dissipated += tendon_power[k]
    for k in range(n_blocks):
        dissipated += rod_power[k, 0]
        external += rod_power[k, 1]
    return dissipated, external


@njit(**_JIT)
def rhs(
    q, qdot, rod_nodes, rod_param, tendon_nodes, tendon_stiffness, tendon_damping, rest_length,
    has_external, external_force, has_gravity, gravity,
    node_work, block_force, qddot, tension, elastic_tension,
):  # pragma: no cover - compiled
    """Theorem 18.1 for all rods: fills ``qddot`` (6R,), ``tension`` and ``elastic_tension`` (S,).

    ``tendon_stiffness`` (S,); ``tendon_damping`` (S,) or None (all zero: the undamped
    specialization, see :func:`_tendon_pass`).  ``external_force`` (N, 3) is read only if
    ``has_external``, ``gravity`` (3,) only if ``has_gravity``.  ``node_work`` (3, N, 3) is
    scratch.  ``block_force`` is None (one thread) or (B - 1, N, 3) scratch: the evaluation runs
    on B threads (:func:`_rhs_threaded`; the choice is made at compile time).  Returns
    ``(dissipated_power, external_power)``.
    """
    if block_force is not None:
        return _rhs_threaded(q, qdot, rod_nodes, rod_param, tendon_nodes, tendon_stiffness,
                             tendon_damping, rest_length, has_external, external_force,
                             has_gravity, gravity, node_work, block_force, qddot, tension,
                             elastic_tension)
    n_rods = rod_nodes.shape[0]
    p, v, force = _flat(node_work)
    _node_pass(q, qdot, rod_nodes, rod_param, has_gravity, gravity, tendon_damping, p, v, force,
               0, n_rods)
    tendon_dissipation = _tendon_pass(p, v, force, tendon_nodes, tendon_stiffness,
                                      tendon_damping, rest_length, tension, elastic_tension, 0,
                                      tendon_nodes.shape[0])
    rod_dissipation, external_power = _rod_pass(
        q, qdot, rod_nodes, rod_param, has_external, external_force.reshape(external_force.size),
        force, qddot, 0, n_rods)
    return tendon_dissipation + rod_dissipation, external_power


@njit(**_JIT)
def project(q, qdot, rod_param):  # pragma: no cover - compiled
    """In place: ``q2 *= L / |q2|``, then ``q2' -= (q2 . q2' / L^2) q2`` for every rod.

    Returns the largest relative rod-length error ``| |q2| / L - 1 |`` before the projection
    (NaN if some ``q2`` or ``q2'`` is not finite).
    """
    worst = 0.0
    finite = True  # kept apart from ``worst``: a later rod's error must not hide a NaN
    for r in range(rod_param.shape[0]):
        o = 6 * r + 3
        L = rod_param[r, ROD_LENGTH]
        norm = np.sqrt(q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2])
        error = abs(norm / L - 1.0)
        if error > worst:
            worst = error
        scale = L / norm
        for i in range(3):
            q[o + i] = q[o + i] * scale
        dot = q[o] * qdot[o] + q[o + 1] * qdot[o + 1] + q[o + 2] * qdot[o + 2]
        finite = finite and np.isfinite(error) and np.isfinite(dot)
        c = dot / (L * L)
        for i in range(3):
            qdot[o + i] -= c * q[o + i]
    return worst if finite else np.nan


@njit(**_JIT)
def rk4_step(q, qdot, h, model, tension, elastic_tension, stage_work):  # pragma: no cover - compiled
    """One classical RK4 step of ``h`` on ``y = [q, q']`` in place (no projection); ``model`` is
    the tuple of :func:`rhs`'s model arguments.  The stage arithmetic is that of
    :class:`tensegrity.integrators.RK4`: ``y + h/6 (k1 + 2 k2 + 2 k3 + k4)``.  ``stage_work`` is
    (5, 6R) scratch.  Returns the step's increments of dissipated energy and external work,
    ``h/6 (P1 + 2 P2 + 2 P3 + P4)``."""
    n = q.shape[0]
    q_stage = stage_work[0]
    v_stage = stage_work[1]
    accel = stage_work[2]
    acc_q = stage_work[3]
    acc_v = stage_work[4]
    hh = h / 2
    h6 = h / 6
    # k1 = [v, a(q, v)]
    d_sum, w_sum = rhs(q, qdot, *model, accel, tension, elastic_tension)
    for i in range(n):
        acc_q[i] = qdot[i]
        acc_v[i] = accel[i]
        q_stage[i] = q[i] + hh * qdot[i]
        v_stage[i] = qdot[i] + hh * accel[i]
    # k2 at y + h/2 k1, then k3 at y + h/2 k2 (and the stage for k4, at y + h k3)
    for step in (hh, h):
        d, w = rhs(q_stage, v_stage, *model, accel, tension, elastic_tension)
        d_sum = d_sum + 2.0 * d
        w_sum = w_sum + 2.0 * w
        for i in range(n):
            acc_q[i] = acc_q[i] + 2.0 * v_stage[i]
            acc_v[i] = acc_v[i] + 2.0 * accel[i]
            q_stage[i] = q[i] + step * v_stage[i]
            v_stage[i] = qdot[i] + step * accel[i]
    # k4 at y + h k3
    d, w = rhs(q_stage, v_stage, *model, accel, tension, elastic_tension)
    for i in range(n):
        q[i] = q[i] + h6 * (acc_q[i] + v_stage[i])
        qdot[i] = qdot[i] + h6 * (acc_v[i] + accel[i])
    return h6 * (d_sum + d), h6 * (w_sum + w)


@njit(**_JIT)
def rk4_steps(
    q, qdot, dt, n_steps, max_rod_length_error,
    rod_nodes, rod_param, tendon_nodes, tendon_stiffness, tendon_damping, rest_length,
    has_external, external_force, has_gravity, gravity,
    node_work, block_force, tension, elastic_tension, stage_work,
):  # pragma: no cover - compiled
    """Advance ``(q, qdot)`` in place by ``n_steps`` classical RK4 steps of ``dt``
    (:func:`rk4_step`), projecting onto the rod constraints after every step; inputs are constant
    over the call.  ``stage_work`` is (5, 6R) scratch.

    Stops early, after the step (already projected), if a step ends with a relative rod-length
    error above ``max_rod_length_error`` or a non-finite rod vector or rate (blow-up).

    Returns ``(steps_taken, dissipated_energy, external_work, worst_rod_length_error)``: the
    energies integrated over the steps with the RK4 weights, and the largest relative rod-length
    error seen at the end of a step before its projection (NaN if the state became non-finite).
    """
    dissipated = 0.0
    external = 0.0
    worst = 0.0
    taken = 0
    model = (rod_nodes, rod_param, tendon_nodes, tendon_stiffness, tendon_damping, rest_length,
             has_external, external_force, has_gravity, gravity, node_work, block_force)
    while taken < n_steps:
        d, w = rk4_step(q, qdot, dt, model, tension, elastic_tension, stage_work)
        dissipated = dissipated + d
        external = external + w
        error = project(q, qdot, rod_param)
        taken += 1
        if not error <= worst:
            worst = error
        if not error <= max_rod_length_error:
            break
    return taken, dissipated, external, worst


@njit(**_JIT)
def energies(
    q, qdot, rod_nodes, rod_param, tendon_nodes, tendon_stiffness, rest_length, has_gravity,
    gravity, node_work,
):  # pragma: no cover - compiled
    """``(kinetic, elastic, gravity)`` energies [J], as ``dynamics.kinetic_energy``,
    ``elastic_energy`` and ``gravity_energy``; ``node_work[0]`` receives the node positions."""
    p = node_work[0]
    kinetic = 0.0
    potential = 0.0
    for r in range(rod_nodes.shape[0]):
        a = rod_nodes[r, 0]
        b = rod_nodes[r, 1]
        o = 6 * r
        m = rod_param[r, ROD_MASS]
        v1 = 0.0
        v2 = 0.0
        for i in range(3):
            p[a, i] = 0.5 * (q[o + i] - q[o + 3 + i])
            p[b, i] = 0.5 * (q[o + i] + q[o + 3 + i])
            v1 += qdot[o + i] * qdot[o + i]
            v2 += qdot[o + 3 + i] * qdot[o + 3 + i]
            if has_gravity:
                potential -= m * gravity[i] * 0.5 * q[o + i]
        kinetic += m * (v1 / 8 + v2 / 24)
    elastic = 0.0
    for s in range(tendon_nodes.shape[0]):
        tail = tendon_nodes[s, 0]
        head = tendon_nodes[s, 1]
        tx = p[head, 0] - p[tail, 0]
        ty = p[head, 1] - p[tail, 1]
        tz = p[head, 2] - p[tail, 2]
        stretch = np.sqrt(tx * tx + ty * ty + tz * tz) - rest_length[s]
        if stretch > 0.0:
            elastic += tendon_stiffness[s] * stretch * stretch
    return kinetic, 0.5 * elastic, potential


@njit(inline="always", **_JIT)
def _row(array, b):  # pragma: no cover - compiled
    """``array[b]``, or None if ``array`` is None (decided at compile time)."""
    if array is None:
        return None
    return array[b]


#: :func:`rk4_batch` case status: still running, or stopped on a blow-up.
BATCH_RUNNING, BATCH_FAILED = 0, 1


@njit(**_JIT)
def rk4_batch(
    q, qdot, dt, n_steps, max_rod_length_error, max_energy_growth, energy0, scale0,
    status, steps, work, worst, end_q, end_qdot,
    rod_nodes, rod_param, tendon_nodes, tendon_stiffness, tendon_damping, rest_length,
    has_external, external_force, has_gravity, gravity,
    node_work, tension, elastic_tension, stage_work,
):  # pragma: no cover - compiled
    """``n_steps`` RK4 steps of ``dt`` for each of ``B`` copies of one structure (same rods and
    tendons, per-copy parameters), with the blow-up checks of ``simulate``; in place.

    Per copy ``b`` (rows of the (B, ...) arrays): ``q``, ``qdot`` (B, 6R); ``rod_param``
    (B, R, 5); ``tendon_stiffness`` (B, S); ``tendon_damping`` (B, S), or None if
    every copy's is zero; ``rest_length`` (B, S); ``external_force`` (B, N, 3)
    (read if ``has_external``); ``energy0``, ``scale0`` (B,) the energy balance at the start and
    its scale [J] (``simulate``'s ``_Model.energy_balance``; ``scale0`` is raised in place to the
    largest scale seen, the measure the energy drift is judged against); ``status``, ``steps`` (B,) int64;
    ``work`` (B, 2) dissipated energy and external work so far [J]; ``worst`` (B,) largest
    relative rod-length error so far.  Copies whose status is not ``BATCH_RUNNING`` are skipped.

    Every step ends as in ``simulate(method="rk4")``: if the state is not finite, a relative
    rod-length error exceeds ``max_rod_length_error`` or the energy balance
    ``E_kin + E_el + E_grav + E_d - W_w - E0`` exceeds ``max_energy_growth`` times its scale, the
    copy's status becomes ``BATCH_FAILED`` and it stops; otherwise the state is projected onto
    the rod constraints.  ``end_q``, ``end_qdot`` (B, 6R) receive each copy's state at the end of
    its last step *before* projection (what ``simulate`` samples, and its failing state).
    """
    n = q.shape[1]
    for b in range(q.shape[0]):
        if status[b] != BATCH_RUNNING:
            continue
        qb = q[b]
        vb = qdot[b]
        w_b = external_force[b] if has_external else external_force[0]
        model = (rod_nodes, rod_param[b], tendon_nodes, tendon_stiffness[b],
                 _row(tendon_damping, b), rest_length[b],
                 has_external, w_b, has_gravity, gravity, node_work, None)
        for j in range(n_steps):
            d, w = rk4_step(qb, vb, dt, model, tension, elastic_tension, stage_work)
            work[b, 0] = work[b, 0] + d
            work[b, 1] = work[b, 1] + w
            kinetic, elastic, potential = energies(
                qb, vb, rod_nodes, rod_param[b], tendon_nodes, tendon_stiffness[b], rest_length[b],
                has_gravity, gravity, node_work)
            total = kinetic + elastic + potential + work[b, 0] - work[b, 1]
            scale = kinetic + elastic + abs(potential) + abs(work[b, 0]) + abs(work[b, 1])
            finite = np.isfinite(total) and np.isfinite(scale)
            for i in range(n):
                finite = finite and np.isfinite(qb[i])
            end_q[b, :] = qb  # the state before projection (cheap next to four evaluations)
            end_qdot[b, :] = vb
            error = project(qb, vb, rod_param[b])
            steps[b] += 1
            if not error <= worst[b]:
                worst[b] = error
            if scale > scale0[b]:  # the largest energy magnitude seen, as in ``simulate``
                scale0[b] = scale
            growth = total - energy0[b] > max_energy_growth * max(scale0[b], 1e-300)
            if not finite or not error <= max_rod_length_error or growth:
                status[b] = BATCH_FAILED
                break


def pack(structure: Structure) -> tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None
]:
    """``(rod_nodes, rod_param, tendon_nodes, tendon_stiffness, tendon_damping)``: the structure
    as the contiguous, writable arrays the compiled functions take (``2/m`` and ``6/(m L^2)``
    computed as ``dynamics.evaluate`` computes them); ``tendon_damping`` is None when every
    tendon's damping is zero (the compiled code then skips the length rates)."""
    structure.require_free_class1("the compiled kernel")
    m, L = structure.rod_mass, structure.rod_length
    rod_param = np.empty((structure.n_rods, 5))
    rod_param[:, ROD_MASS] = m
    rod_param[:, ROD_LENGTH] = L
    rod_param[:, ROD_DAMPING] = structure.rod_damping
    rod_param[:, ROD_C1] = 2.0 / m
    rod_param[:, ROD_C2] = 6.0 / (m * L**2)
    damping = structure.tendon_damping
    return (
        np.array(structure.rod_nodes, dtype=np.int64, order="C"),
        rod_param,
        np.array(structure.tendon_nodes.reshape(-1, 2), dtype=np.int64, order="C"),
        np.array(structure.tendon_stiffness, dtype=np.float64, order="C"),
        np.array(damping, dtype=np.float64, order="C") if np.any(damping != 0) else None,
    )


# --------------------------------------------------------------------------- Python wrapper
class KernelEvaluation(NamedTuple):
    """One evaluation by :meth:`FastKernel.evaluate`."""

    qddot: np.ndarray  #: accelerations (6R,) [m/s^2]
    tension: np.ndarray  #: tendon tensions (S,) [N], damping included
    dissipated_power: float  #: [W], >= 0
    external_power: float  #: power of the external nodal forces [W]


class RK4Result(NamedTuple):
    """The end of :meth:`FastKernel.rk4_with_work`."""

    q: np.ndarray
    qdot: np.ndarray
    dissipated_energy: float  #: energy removed by damping over the steps taken [J]
    external_work: float  #: work of the external forces over the steps taken [J]
    n_steps: int  #: steps taken (fewer than asked if it stopped on a blow-up)
    #: largest relative rod-length error at the end of a step, before its projection (NaN: the
    #: state was not finite)
    max_rod_length_error: float


_F64 = np.dtype(np.float64)


def _float_input(value, shape: tuple[int, ...], field: str) -> np.ndarray:
    """``value`` as a writable C-contiguous float64 array of ``shape``, copied only if needed.

    (Writable, because numba compiles a separate specialization for read-only arrays.)
    """
    if type(value) is np.ndarray and value.dtype == _F64 and value.flags.carray:
        array = value
    else:
        array = np.array(value, dtype=np.float64, order="C")
    if array.shape != shape:
        raise ValueError(f"{field}: expected shape {shape}, got {array.shape}")
    return array


def _check_buffer(array: np.ndarray, shape: tuple[int, ...], field: str) -> None:
    if not (
        type(array) is np.ndarray
        and array.dtype == _F64
        and array.flags.carray
        and array.shape == shape
    ):
        raise ValueError(
            f"{field}: expected a writable C-contiguous float64 array of shape {shape}"
        )


class FastKernel:
    """The compiled equations of motion of one :class:`Structure`.

    ``__init__`` packs the structure's data into contiguous, writable int64/float64 arrays (see
    :func:`pack`) and allocates scratch buffers; compilation happens (or the disk cache is loaded)
    on first use, or at :meth:`warm_up`.

    ``threads`` (keyword-only, default 1): split every evaluation into that many blocks of rods
    and of tendons run in parallel (numba ``prange``, on up to ``NUMBA_NUM_THREADS`` threads),
    each block of tendons adding its nodal forces to its own buffer.  The result is deterministic
    (it does not depend on the scheduling) and differs from ``threads=1`` by round-off only (the
    order in which the forces on a node are summed).  Worth it for large structures only (the
    parallel sections cost ~10 microseconds per evaluation), and only when the cores are not busy
    with other work.  With ``threads > 1`` the constructor sets the environment variable
    ``OMP_WAIT_POLICY=PASSIVE`` unless it is already set (see the comment there).
    """

    def __init__(self, structure: Structure, *, threads: int = 1) -> None:
        if isinstance(threads, bool) or int(threads) != threads or threads < 1:
            raise ValueError(f"threads: must be an integer >= 1, got {threads!r}")
        self.structure = structure
        self.threads = int(threads)
        if self.threads > 1:
            # numba's OpenMP layer spins at its barriers by default; on a machine whose cores are
            # busy with other work a spinning thread can hold a core the other block is waiting
            # for (measured: ~8 ms per parallel section).  Waiting passively costs nothing
            # measurable here.  Read when the OpenMP runtime loads (the first threaded call);
            # a value set by the user wins.
            os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
        self.n_rods, self.n_tendons, self.n_nodes = (
            structure.n_rods, structure.n_tendons, structure.n_nodes,
        )
        self.n_coordinates = 6 * self.n_rods
        (self._rod_nodes, self._rod_param, self._tendon_nodes, self._tendon_stiffness,
         self._tendon_damping) = pack(structure)
        self._node_work = np.zeros((3, self.n_nodes, 3))
        self._block_force = (
            None if self.threads == 1 else np.zeros((self.threads - 1, self.n_nodes, 3))
        )
        self._elastic = np.zeros(self.n_tendons)
        self._no_external = np.zeros((1, 3))
        self._no_gravity = np.zeros(3)
        self._last_rest_source = None
        self._last_rest = None

    # ------------------------------------------------------------------ inputs
    def _rest(self, rest_length) -> np.ndarray:
        # The common case passes the same read-only array (structure.tendon_rest_length) again and
        # again: keep one writable copy of it instead of copying on every call.
        if rest_length is self._last_rest_source and not rest_length.flags.writeable:
            return self._last_rest
        rest = _float_input(rest_length, (self.n_tendons,), "rest_length")
        if (rest is not rest_length and type(rest_length) is np.ndarray
                and not rest_length.flags.writeable):
            self._last_rest_source, self._last_rest = rest_length, rest
        return rest

    def _loads(self, external_force, gravity):
        if external_force is None:
            has_w, w = False, self._no_external
        else:
            has_w, w = True, _float_input(external_force, (self.n_nodes, 3), "external_force")
        if gravity is None:
            has_g, g = False, self._no_gravity
        else:
            has_g, g = True, _float_input(gravity, (3,), "gravity")
        return has_w, w, has_g, g

    # ------------------------------------------------------------------ API
    def evaluate(
        self,
        q: np.ndarray,
        qdot: np.ndarray,
        rest_length: np.ndarray,
        external_force: np.ndarray | None = None,
        gravity: np.ndarray | None = None,
        out: tuple[np.ndarray, np.ndarray] | None = None,
        elastic_tension_out: np.ndarray | None = None,
    ) -> KernelEvaluation:
        """``(qddot, tension, dissipated_power, external_power)``, as ``dynamics.evaluate``.

        Parameters
        ----------
        q, qdot : (6R,) coordinates and rates.
        rest_length : (S,) controlled rest lengths ``Lbar >= 0`` (see ``dynamics.rest_lengths``).
        external_force : (N, 3), optional.  gravity : (3,), optional.
        out : ``(qddot, tension)`` float64 C-contiguous buffers of shapes (6R,), (S,) to fill
            (and return) instead of allocating new arrays.
        elastic_tension_out : (S,), optional buffer that receives ``k max(l - Lbar, 0)`` (for
            the power of a time-varying control).
        """
        n = self.n_coordinates
        q = _float_input(q, (n,), "q")
        qdot = _float_input(qdot, (n,), "qdot")
        rest = self._rest(rest_length)
        has_w, w, has_g, g = self._loads(external_force, gravity)
        if out is None:
            qddot, tension = np.empty(n), np.empty(self.n_tendons)
        else:
            qddot, tension = out
            _check_buffer(qddot, (n,), "out[0]")
            _check_buffer(tension, (self.n_tendons,), "out[1]")
        if elastic_tension_out is None:
            elastic = self._elastic
        else:
            elastic = elastic_tension_out
            _check_buffer(elastic, (self.n_tendons,), "elastic_tension_out")
        dissipated, external = rhs(
            q, qdot, self._rod_nodes, self._rod_param, self._tendon_nodes, self._tendon_stiffness,
            self._tendon_damping, rest, has_w, w, has_g, g, self._node_work, self._block_force,
            qddot, tension, elastic,
        )
        return KernelEvaluation(qddot, tension, dissipated, external)

    def rk4_with_work(
        self,
        q: np.ndarray,
        qdot: np.ndarray,
        dt: float,
        n_steps: int,
        rest_length: np.ndarray,
        external_force: np.ndarray | None = None,
        gravity: np.ndarray | None = None,
        *,
        max_rod_length_error: float = np.inf,
    ) -> RK4Result:
        """``n_steps`` RK4 steps of ``dt`` (projection after each), inputs constant over the call.

        Returns new arrays ``q``, ``qdot`` (the inputs are not modified), the dissipated energy
        and external work over the steps (RK4-integrated like ``simulate``'s ODE state), the
        number of steps taken and the largest relative rod-length error seen at the end of a step
        before its projection.  The loop stops early, after the offending step, when that error
        exceeds ``max_rod_length_error`` or the state is not finite (error NaN): blow-up checks
        as in ``simulate`` without leaving compiled code.
        """
        n = self.n_coordinates
        dt = float(dt)
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt: must be > 0, got {dt!r}")
        if int(n_steps) != n_steps or n_steps < 0:
            raise ValueError(f"n_steps: must be an integer >= 0, got {n_steps!r}")
        q = np.array(q, dtype=np.float64, order="C", copy=True)
        qdot = np.array(qdot, dtype=np.float64, order="C", copy=True)
        for name, x in (("q", q), ("qdot", qdot)):
            if x.shape != (n,):
                raise ValueError(f"{name}: expected shape {(n,)}, got {x.shape}")
        rest = self._rest(rest_length)
        has_w, w, has_g, g = self._loads(external_force, gravity)
        taken, dissipated, external, worst = rk4_steps(
            q, qdot, dt, int(n_steps), float(max_rod_length_error),
            self._rod_nodes, self._rod_param, self._tendon_nodes, self._tendon_stiffness,
            self._tendon_damping, rest,
            has_w, w, has_g, g, self._node_work, self._block_force, np.empty(self.n_tendons),
            self._elastic,
            np.empty((5, n)),
        )
        return RK4Result(q, qdot, dissipated, external, taken, worst)

    def rk4(
        self,
        q: np.ndarray,
        qdot: np.ndarray,
        dt: float,
        n_steps: int,
        rest_length: np.ndarray,
        external_force: np.ndarray | None = None,
        gravity: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(q, qdot)`` after ``n_steps`` RK4 steps of ``dt``; see :meth:`rk4_with_work`."""
        result = self.rk4_with_work(q, qdot, dt, n_steps, rest_length, external_force, gravity)
        return result.q, result.qdot

    def project(self, q: np.ndarray, qdot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """New arrays projected onto ``|q2| = L``, ``q2 . q2' = 0`` (as
        ``dynamics.project_to_constraints``)."""
        n = self.n_coordinates
        q = np.array(q, dtype=np.float64, order="C", copy=True)
        qdot = np.array(qdot, dtype=np.float64, order="C", copy=True)
        for name, x in (("q", q), ("qdot", qdot)):
            if x.shape != (n,):
                raise ValueError(f"{name}: expected shape {(n,)}, got {x.shape}")
        project(q, qdot, self._rod_param)
        return q, qdot

    def warm_up(self) -> None:
        """Compile (or load from the disk cache) every compiled function now."""
        q = np.zeros(self.n_coordinates)
        q[3::6] = self._rod_param[:, ROD_LENGTH]
        qdot = np.zeros(self.n_coordinates)
        rest = np.zeros(self.n_tendons)
        self.evaluate(q, qdot, rest)
        self.rk4(q, qdot, 1e-3, 1, rest)
