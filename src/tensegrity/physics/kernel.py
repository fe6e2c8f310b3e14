"""The compiled (numba) right-hand side of Theorem 18.1 for free class 1 structures.

The physics is exactly that of :func:`tensegrity.physics.dynamics.evaluate` (the readable NumPy
reference):

- tendon tension ``T = max(k (l - Lbar) + c l', 0)`` while taut (``l > Lbar``), else 0;
- nodal forces from tendons, external forces ``w`` and gravity (half a rod's weight per end);
- accelerations (eqs. 18.17, 18.20) plus mass-proportional rod damping to ground ``-alpha q'``
  and relative to the rigid-body motion ``-beta (q' - rigid)`` (:func:`_rigid_motion`)::

      q1'' = (2/m) (f_a + f_b) - alpha q1' - beta (q1' - rigid1)
      q2'' = -(|q2'|^2 / L^2) q2 + (6 / (m L^2)) skew(q2)^2 (f_a - f_b) - alpha q2'
             - beta (q2' - rigid2)

- the power removed by tendon and rod damping and the power of ``w``.

Differences from the reference are round-off only (the summation order of the nodal forces, one
reciprocal instead of three divisions per tendon, the length rate as ``t . (p'_b - p'_a) / l``),
so that the two agree to ~1e-15 relative; no fast-math flags, not even fused multiply-adds
(:data:`~tensegrity.physics.compiling.JIT_OPTIONS` says why).  When no tendon is damped (all
``c = 0``, :func:`pack` then gives ``tendon_damping=None``) the same functions are compiled
without the node velocities and the length rates (numba specializes on None): the same numbers
as with zero damping, a quarter less time per evaluation on large shells.  As in the reference,
rest lengths must be ``>= 0`` (``dynamics.rest_lengths`` checks them); they are not checked again
here, for speed.

Every compiled function takes the two records of :mod:`tensegrity.physics.records`: ``model``
(read-only: the packed structure, gravity) and ``data`` (the inputs' stage rows and the scratch
the evaluation writes).  :mod:`tensegrity.physics.kernel_system` adds point masses, anchors,
joints and supports around these passes, and makes the records
(:func:`~tensegrity.physics.kernel_system.make_records`).

The kernel keeps its own layout (:func:`stencil_layout`, :func:`pack`): nodes in *slots*, grouped
by class (node index modulo K) and stored by coordinate, and tendons in a *kernel order* whose
first part is *runs*, tendons whose tails and heads sit at consecutive slots.  A run is evaluated
by a loop without indirection that compiles to 4-wide vector code (:func:`_tendon_run`): on the
(100,100) shell 99.5% of the tendons are in runs and an RK4 step takes ~0.75x the time of the
one-tendon-at-a-time loop (docs/performance.md).

This module imports numba; import it lazily (inside the function that needs it) so that
``import tensegrity`` stays fast.  Compiled code is cached on disk (``cache=True``): the first use
on a machine compiles for a few seconds, later processes load the cache in well under a second.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from tensegrity.model.structure import Structure
from tensegrity.physics.compiling import (
    JIT_OPTIONS,
    ROD_C1,
    ROD_C2,
    ROD_DAMPING,
    ROD_LENGTH,
    ROD_MASS,
    ROD_RELATIVE_DAMPING,
    compiled_only,
)
from tensegrity.physics.contact import contact_pass, stick_pass
from tensegrity.physics.coordinates import rod_damping_rates

__all__ = [
    "PackedStructure",
    "StencilLayout",
    "energies",
    "pack",
    "project",
    "rhs",
    "stencil_layout",
    "tendon_vector",
]


# --------------------------------------------------------------------------- compiled code
# The layout of the records' arrays (:mod:`tensegrity.physics.records`): nodes in *slots*, tendons
# in a *kernel order* of their own (see :func:`pack` and docs/performance.md, "The stencil
# layout").  Slots are unsigned (uint64): numba wraps every signed index that the compiler cannot
# prove >= 0 (one read from an array) around the array's length.  Never add a signed integer to a
# slot: in numba ``uint64 + int64`` is a float64.  The columns of ``Model.rod_param`` are
# ``compiling.ROD_*``.
#: A rigid-body fit whose inertia has ``det <= SINGULAR_INERTIA (trace / 3)^3`` has its rods on
#: one line (to about 1e-5 of their size), about which they have no inertia: it is solved with
#: ``trace / 3`` of inertia added about that line (:func:`_rigid_motion`).
SINGULAR_INERTIA = 1e-10


@njit(inline="always", **JIT_OPTIONS)
def copy_values(source, out, n):  # pragma: no cover - compiled
    """``out[:n] = source[:n]``, as a loop: an array-to-array slice assignment makes numba
    compile its shape-mismatch error message (string formatting, about 2 s of a first run's
    compilation) into every function that holds one."""
    for i in range(n):
        out[i] = source[i]


@njit(inline="always", **JIT_OPTIONS)
def end_values(x, rod_slots, out):  # pragma: no cover - compiled
    """``out[:, slot of a] = (x1 - x2) / 2``, ``out[:, slot of b] = (x1 + x2) / 2`` for every rod
    (``x`` = ``q`` or ``q'``, 6 per rod): the end positions or velocities ``P x`` (eq. 18.26)."""
    for r in range(rod_slots.shape[0]):
        a = rod_slots[r, 0]
        b = rod_slots[r, 1]
        o = 6 * r
        for i in range(3):
            out[i, a] = 0.5 * (x[o + i] - x[o + 3 + i])
            out[i, b] = 0.5 * (x[o + i] + x[o + 3 + i])


@njit(inline="always", **JIT_OPTIONS)
def tendon_vector(p, tendon_slots, s):  # pragma: no cover - compiled
    """``(tail, head, tx, ty, tz)``: tendon ``s``'s slots and ``t = p_head - p_tail``."""
    tail = tendon_slots[s, 0]
    head = tendon_slots[s, 1]
    return (tail, head, p[0, head] - p[0, tail], p[1, head] - p[1, tail], p[2, head] - p[2, tail])


@njit(inline="always", **JIT_OPTIONS)
def stage_row(values, s):  # pragma: no cover - compiled
    """Row ``s`` of per-stage inputs (``Data.rest``, ``rate``, ``force``), or row 0 when they
    are constant over the step (one row)."""
    return values[s] if values.shape[0] > 1 else values[0]


@njit(inline="always", **JIT_OPTIONS)
def _node_pass(tendon_damping, model, data, q, qdot):  # pragma: no cover - compiled
    """Node positions ``p = P q`` (eq. 18.26) into ``data.node_position`` and, if
    ``tendon_damping`` (``model.tendon_damping``) is not None (the tendon pass needs them only
    then), the node velocities into ``data.node_velocity``.  One loop per array: a rod's ends
    are in two classes, so a loop writing both arrays would write 24 streams of slots at once
    (with the forces, which this pass set before, 36 streams took twice the time beyond the L3
    cache, measured at (300,300)).  The nodal forces need no start: the rod pass leaves them
    zero (:func:`_take_force`)."""
    end_values(q, model.rod_slots, data.node_position)
    if tendon_damping is not None:
        end_values(qdot, model.rod_slots, data.node_velocity)


@njit(inline="always", **JIT_OPTIONS)
def _tendon_force(tx, ty, tz, length, rest, stiffness, c, t_dot_dv, cap):  # pragma: no cover
    """One tendon from its vector ``t = p_head - p_tail`` and ``length = |t|``: returns
    ``(tension, elastic_tension, fx, fy, fz, dissipated_power)``, with ``f = T t / l`` the force
    on the tail (the head gets ``-f``).  ``c`` is None (undamped; ``t_dot_dv`` unused) or the
    damping coefficient, and ``t_dot_dv = t . (p'_head - p'_tail)``, so that the length rate is
    ``t_dot_dv / l``.  ``cap`` is None or the largest tension [N] (an actuator's winch): the
    tension and its elastic part are capped there (the spring's potential grows linearly
    beyond, :func:`capped_energy`).  A slack tendon (``l <= Lbar``) gives zeros, without
    branches (so that runs of tendons vectorize); its ``1/l`` is not formed."""
    stretch = length - rest
    taut = stretch > 0.0  # then length > 0: rest lengths are >= 0
    inv = 1.0 / (length if taut else 1.0)  # one division instead of three (an ulp at most)
    ex = tx * inv
    ey = ty * inv
    ez = tz * inv
    elastic = stiffness * stretch if taut else 0.0
    total = elastic
    dissipated = 0.0
    if c is not None:
        rate = t_dot_dv * inv
        total = elastic + c * rate if taut else 0.0
        if total < 0.0:
            total = 0.0
        if cap is not None:
            elastic = min(elastic, cap)
            total = min(total, cap)
        dissipated = (total - elastic) * rate
    elif cap is not None:
        elastic = min(elastic, cap)
        total = elastic
    return total, elastic, total * ex, total * ey, total * ez, dissipated


@njit(inline="always", **JIT_OPTIONS)
def capped_energy(stiffness, stretch, cap):  # pragma: no cover - compiled
    """Twice the elastic energy [J] of a taut tendon stretched by ``stretch`` [m] whose tension
    is capped at ``cap`` [N] (None: no cap): ``k x^2`` while ``k x <= cap``, then
    ``2 cap x - cap^2 / k`` (the cap's tension times the stretch beyond)."""
    if cap is not None and stiffness * stretch > cap:
        return 2.0 * cap * stretch - cap * cap / stiffness
    return stiffness * stretch * stretch


@njit(inline="always", **JIT_OPTIONS)
def _store_tendon(data, s, tail, head, total, elastic, f):  # pragma: no cover - compiled
    """Tendon ``s``'s tension and elastic tension into ``data``, and its force ``f`` (fx, fy,
    fz) added at the tail slot and ``-f`` at the head slot of ``data.node_force``."""
    data.tension[s] = total
    data.elastic_tension[s] = elastic
    force = data.node_force
    force[0, tail] += f[0]
    force[1, tail] += f[1]
    force[2, tail] += f[2]
    force[0, head] -= f[0]
    force[1, head] -= f[1]
    force[2, head] -= f[2]


@compiled_only
def _tendon_rates(data, a, b, first, n):  # pragma: no cover - compiled
    """``data.damping_power[first + e] = t . (v_b - v_a)`` along a run of ``n`` tendons
    (offsets as in :func:`_tendon_run`), in a loop of its own: with the velocities in it,
    :func:`_tendon_run` would touch more memory ranges than the compiler checks for overlap at
    run time, and stay scalar."""
    p, v, out = data.node_position, data.node_velocity, data.damping_power
    for e in range(n):
        ia = a + e
        ib = b + e
        out[first + e] = (
            (p[0, ib] - p[0, ia]) * (v[0, ib] - v[0, ia])
            + (p[1, ib] - p[1, ia]) * (v[1, ib] - v[1, ia])
            + (p[2, ib] - p[2, ia]) * (v[2, ib] - v[2, ia])
        )


@compiled_only
def _tendon_run(tendon_damping, tendon_cap, model, data, rest, a, b, first, n):  # pragma: no cover
    """A run of ``n`` tendons whose tails and heads sit at consecutive slots: tendon ``e`` of the
    run is at kernel position ``first + e``, its tail at slot ``a + e`` and its head at
    ``b + e`` of ``data.node_position`` and ``data.node_force``; ``rest`` (S,) the rest lengths.
    The offsets are unsigned (uint64), so that every index is a base plus the loop counter,
    without numba's negative-index wrap-around: the loop compiles to 4-wide vector code.
    (Slices of the arrays would do the same, but each slice takes and releases a reference
    count: 116 ns a run, 15% of the tendon pass on the (100,100) shell.)  The compiler checks
    at run time that the force ranges do not overlap (they may, when tails and heads share a
    node class) and otherwise runs the scalar loop.  With damping (``tendon_damping``, which is
    ``model.tendon_damping``), ``data.damping_power`` holds ``t . (v_b - v_a)`` on entry
    (:func:`_tendon_rates`) and each tendon's dissipated power on return (a sum here would keep
    the loop scalar: the compiler may not reorder it)."""
    p = data.node_position
    stiffness = model.tendon_stiffness
    damping_power = data.damping_power
    for e in range(n):
        ia = a + e
        ib = b + e
        s = first + e
        tx = p[0, ib] - p[0, ia]
        ty = p[1, ib] - p[1, ia]
        tz = p[2, ib] - p[2, ia]
        length = np.sqrt(tx * tx + ty * ty + tz * tz)
        cap = _cap(tendon_cap, s)
        if tendon_damping is None:
            total, elastic, fx, fy, fz, _ = _tendon_force(
                tx, ty, tz, length, rest[s], stiffness[s], None, 0.0, cap
            )
        else:
            total, elastic, fx, fy, fz, power = _tendon_force(
                tx, ty, tz, length, rest[s], stiffness[s], tendon_damping[s], damping_power[s], cap
            )
            damping_power[s] = power
        _store_tendon(data, s, ia, ib, total, elastic, (fx, fy, fz))


@njit(inline="always", **JIT_OPTIONS)
def _cap(tendon_cap, s):  # pragma: no cover - compiled
    """Tendon ``s``'s tension cap [N] (``model.tendon_max_tension``), or None without caps."""
    if tendon_cap is None:
        return None
    return tendon_cap[s]


@njit(inline="always", **JIT_OPTIONS)
def _sum(values):  # pragma: no cover - compiled
    """``sum(values)`` in four interleaved partial sums: four independent chains of additions
    instead of one, in a fixed order (deterministic)."""
    n = values.shape[0]
    s0 = s1 = s2 = s3 = 0.0
    for i in range(0, n - n % 4, 4):
        s0 += values[i]
        s1 += values[i + 1]
        s2 += values[i + 2]
        s3 += values[i + 3]
    for i in range(n - n % 4, n):
        s0 += values[i]
    return (s0 + s1) + (s2 + s3)


@njit(inline="always", **JIT_OPTIONS)
def _tendon_pass(tendon_damping, tendon_cap, model, data, rest):  # pragma: no cover - compiled
    """Every tendon: tension and elastic tension into ``data``, nodal forces added to
    ``data.node_force``, the tail pulled toward the head and the head toward the tail;
    ``rest`` (S,) the rest lengths.  The runs (:func:`_tendon_run`) first, then the tendons
    outside runs, one by one through ``model.tendon_slots``.  Returns the power removed by
    tendon damping.  With ``tendon_damping`` (``model.tendon_damping``) None (all ``c = 0``)
    the node velocities are not read and the tension is the elastic tension: the same numbers
    as with zero damping, for finite velocities.  ``tendon_cap`` (``model.tendon_max_tension``)
    None: no tension caps (compiled without them)."""
    dissipation = 0.0
    in_runs = 0
    tendon_runs = model.tendon_runs
    for g in range(tendon_runs.shape[0]):
        start = tendon_runs[g, 0]
        length = tendon_runs[g, 1]
        in_runs = start + length
        a = np.uint64(tendon_runs[g, 2])
        b = np.uint64(tendon_runs[g, 3])
        first_run = np.uint64(start)
        n = np.uint64(length)
        if tendon_damping is not None:
            _tendon_rates(data, a, b, first_run, n)
        _tendon_run(tendon_damping, tendon_cap, model, data, rest, a, b, first_run, n)
        if tendon_damping is not None:
            dissipation += _sum(data.damping_power[start:in_runs])
    # The tendons outside runs (kernel positions in_runs:S), one by one.
    p, v = data.node_position, data.node_velocity
    tendon_slots = model.tendon_slots[in_runs:]
    stiffness = model.tendon_stiffness[in_runs:]
    rest = rest[in_runs:]
    tension = data.tension[in_runs:]
    elastic_tension = data.elastic_tension[in_runs:]
    for s in range(tendon_slots.shape[0]):
        tail, head, tx, ty, tz = tendon_vector(p, tendon_slots, s)
        length = np.sqrt(tx * tx + ty * ty + tz * tz)
        if not length > rest[s]:  # slack: skip the work (one by one, a branch is cheap)
            tension[s] = 0.0
            elastic_tension[s] = 0.0
            continue
        cap = _cap(tendon_cap, in_runs + s)
        if tendon_damping is None:
            total, elastic, fx, fy, fz, _ = _tendon_force(
                tx, ty, tz, length, rest[s], stiffness[s], None, 0.0, cap
            )
        else:
            t_dot_dv = (
                tx * (v[0, head] - v[0, tail])
                + ty * (v[1, head] - v[1, tail])
                + tz * (v[2, head] - v[2, tail])
            )
            total, elastic, fx, fy, fz, d = _tendon_force(
                tx, ty, tz, length, rest[s], stiffness[s], tendon_damping[in_runs + s], t_dot_dv,
                cap,
            )  # fmt: skip
            dissipation += d
        _store_tendon(data, in_runs + s, tail, head, total, elastic, (fx, fy, fz))
    return dissipation


@njit(inline="always", **JIT_OPTIONS)
def _take_force(force, slot):  # pragma: no cover - compiled
    """``(fx, fy, fz)``, the tendon forces summed at ``slot`` of ``force`` (3, n_slots), leaving
    zeros there: the next evaluation's tendon pass adds to zero, without a pass that sets the
    forces to zero first (one stream of writes less)."""
    fx, fy, fz = force[0, slot], force[1, slot], force[2, slot]
    force[0, slot] = 0.0
    force[1, slot] = 0.0
    force[2, slot] = 0.0
    return fx, fy, fz


@njit(inline="always", **JIT_OPTIONS)
def _line_direction(q, rod_param):  # pragma: no cover - compiled
    """The unit vector ``q2 / |q2|`` of the first rod with relative damping."""
    for r in range(rod_param.shape[0]):
        if rod_param[r, ROD_RELATIVE_DAMPING] != 0.0:
            o = 6 * r + 3
            norm = np.sqrt(q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2])
            return q[o] / norm, q[o + 1] / norm, q[o + 2] / norm
    return 1.0, 0.0, 0.0


@njit(**JIT_OPTIONS)
def _rigid_motion(q, qdot, rod_param):  # pragma: no cover - compiled
    """The rigid-body motion that best fits the rods' motion with weights ``beta m``, as
    :func:`tensegrity.physics.coordinates.rigid_body_rates`: ``(V, omega, c)``, each a tuple
    of 3 floats (velocity [m/s] of the point ``c`` [m], angular velocity [1/s]); all zero when
    no rod has relative damping."""
    zero = (0.0, 0.0, 0.0)
    for r in range(rod_param.shape[0]):  # (without relative damping, a pass of reads only)
        if rod_param[r, ROD_RELATIVE_DAMPING] != 0.0:
            break
    else:
        return zero, zero, zero
    # One pass about the first rod's centre p0 (within the structure: no cancellation), then
    # moved to the weighted centre c = p0 + d (parallel axes).  Rods of weight 0 add zeros.
    px, py, pz = 0.5 * q[0], 0.5 * q[1], 0.5 * q[2]
    total = dx_ = dy_ = dz_ = vx = vy = vz = hx = hy = hz = 0.0
    ixx = iyy = izz = ixy = ixz = iyz = 0.0
    for r in range(rod_param.shape[0]):
        w = rod_param[r, ROD_RELATIVE_DAMPING] * rod_param[r, ROD_MASS]
        o = 6 * r
        rx, ry, rz = 0.5 * q[o] - px, 0.5 * q[o + 1] - py, 0.5 * q[o + 2] - pz
        ux, uy, uz = 0.5 * qdot[o], 0.5 * qdot[o + 1], 0.5 * qdot[o + 2]
        x, y, z = q[o + 3], q[o + 4], q[o + 5]
        sx, sy, sz = qdot[o + 3], qdot[o + 4], qdot[o + 5]
        w12 = w / 12.0
        total += w
        dx_ += w * rx
        dy_ += w * ry
        dz_ += w * rz
        vx += w * ux
        vy += w * uy
        vz += w * uz
        hx += w * (ry * uz - rz * uy) + w12 * (y * sz - z * sy)
        hy += w * (rz * ux - rx * uz) + w12 * (z * sx - x * sz)
        hz += w * (rx * uy - ry * ux) + w12 * (x * sy - y * sx)
        ixx += w * (ry * ry + rz * rz) + w12 * (y * y + z * z)
        iyy += w * (rx * rx + rz * rz) + w12 * (x * x + z * z)
        izz += w * (rx * rx + ry * ry) + w12 * (x * x + y * y)
        ixy -= w * rx * ry + w12 * x * y
        ixz -= w * rx * rz + w12 * x * z
        iyz -= w * ry * rz + w12 * y * z
    if not total > 0.0:
        return zero, zero, zero
    dx_, dy_, dz_, vx, vy, vz = (
        dx_ / total,
        dy_ / total,
        dz_ / total,
        vx / total,
        vy / total,
        vz / total,
    )
    # H about c: H - W d x V; I about c: I - W (|d|^2 1 - d d^T)
    hx -= total * (dy_ * vz - dz_ * vy)
    hy -= total * (dz_ * vx - dx_ * vz)
    hz -= total * (dx_ * vy - dy_ * vx)
    ixx -= total * (dy_ * dy_ + dz_ * dz_)
    iyy -= total * (dx_ * dx_ + dz_ * dz_)
    izz -= total * (dx_ * dx_ + dy_ * dy_)
    ixy += total * dx_ * dy_
    ixz += total * dx_ * dz_
    iyz += total * dy_ * dz_
    cx, cy, cz = px + dx_, py + dy_, pz + dz_
    # omega = I^-1 H by the adjugate (I symmetric)
    third = (ixx + iyy + izz) / 3.0
    for shift in (0.0, third):
        # singular: the rods on one line (along the first damped rod's e) have no inertia about
        # it and H has no part along it; adding shift e e^T makes I invertible and leaves
        # omega = I^+ H as it is
        ex, ey, ez = _line_direction(q, rod_param) if shift else (0.0, 0.0, 0.0)
        jxx, jyy, jzz = ixx + shift * ex * ex, iyy + shift * ey * ey, izz + shift * ez * ez
        jxy, jxz, jyz = ixy + shift * ex * ey, ixz + shift * ex * ez, iyz + shift * ey * ez
        a00 = jyy * jzz - jyz * jyz
        a01 = jxz * jyz - jxy * jzz
        a02 = jxy * jyz - jxz * jyy
        det = jxx * a00 + jxy * a01 + jxz * a02
        if det > SINGULAR_INERTIA * third * third * third:
            break
    ixx, iyy, izz, ixy, ixz, iyz = jxx, jyy, jzz, jxy, jxz, jyz
    a11 = ixx * izz - ixz * ixz
    a12 = ixy * ixz - ixx * iyz
    a22 = ixx * iyy - ixy * ixy
    wx = (a00 * hx + a01 * hy + a02 * hz) / det
    wy = (a01 * hx + a11 * hy + a12 * hz) / det
    wz = (a02 * hx + a12 * hy + a22 * hz) / det
    return (vx, vy, vz), (wx, wy, wz), (cx, cy, cz)


@njit(inline="always", **JIT_OPTIONS)
def _rod_pass(model, data, q, qdot, qddot, external_force, rigid):  # pragma: no cover - compiled
    """Every rod: eqs. 18.17, 18.20 and mass-proportional damping into ``qddot``, from the
    tendon forces ``data.node_force`` (left zero, :func:`_take_force`), half the rod's weight at
    each end if ``model.has_gravity``, and ``w`` (``external_force`` (3, n_slots), the stage's
    row of ``data.force``) if ``data.has_external``; the power of ``w`` uses ``p' = P q'``.
    ``rigid`` is :func:`_rigid_motion`'s ``(V, omega, c)``, the reference of the relative
    damping.  Returns ``(rod_dissipation, external_power)``."""
    vx, vy, vz = rigid[0][0], rigid[0][1], rigid[0][2]
    wx, wy, wz = rigid[1][0], rigid[1][1], rigid[1][2]
    cx, cy, cz = rigid[2][0], rigid[2][1], rigid[2][2]
    rod_slots, rod_param = model.rod_slots, model.rod_param
    has_gravity, gravity = model.has_gravity, model.gravity
    has_external = data.has_external
    force = data.node_force
    external_power = 0.0
    rod_dissipation = 0.0
    for r in range(rod_slots.shape[0]):
        a = rod_slots[r, 0]
        b = rod_slots[r, 1]
        o = 6 * r
        fax, fay, faz = _take_force(force, a)
        fbx, fby, fbz = _take_force(force, b)
        if has_gravity:
            half_m = rod_param[r, ROD_MASS] / 2
            fax += half_m * gravity[0]
            fay += half_m * gravity[1]
            faz += half_m * gravity[2]
            fbx += half_m * gravity[0]
            fby += half_m * gravity[1]
            fbz += half_m * gravity[2]
        if has_external:
            for i in range(3):  # node velocities p' = P q' (eq. 18.26)
                v1 = qdot[o + i]
                v2 = qdot[o + 3 + i]
                external_power += external_force[i, a] * (0.5 * (v1 - v2)) + external_force[
                    i, b
                ] * (0.5 * (v1 + v2))
            fax += external_force[0, a]
            fay += external_force[1, a]
            faz += external_force[2, a]
            fbx += external_force[0, b]
            fby += external_force[1, b]
            fbz += external_force[2, b]
        L = rod_param[r, ROD_LENGTH]
        L2 = L * L
        alpha = rod_param[r, ROD_DAMPING]
        c1 = rod_param[r, ROD_C1]
        c2 = rod_param[r, ROD_C2]
        sx = fax + fbx
        sy = fay + fby
        sz = faz + fbz
        dx = fax - fbx
        dy = fay - fby
        dz = faz - fbz
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
        beta = rod_param[r, ROD_RELATIVE_DAMPING]
        if beta != 0.0:
            # rates relative to the rigid motion: q1' - 2 (V + omega x (q1/2 - c)), q2' - omega x q2
            rx, ry, rz = 0.5 * q[o] - cx, 0.5 * q[o + 1] - cy, 0.5 * q[o + 2] - cz
            d1x = u1x - 2.0 * (vx + wy * rz - wz * ry)
            d1y = u1y - 2.0 * (vy + wz * rx - wx * rz)
            d1z = u1z - 2.0 * (vz + wx * ry - wy * rx)
            d2x = ux - (wy * z - wz * y)
            d2y = uy - (wz * x - wx * z)
            d2z = uz - (wx * y - wy * x)
            qddot[o] -= beta * d1x
            qddot[o + 1] -= beta * d1y
            qddot[o + 2] -= beta * d1z
            qddot[o + 3] -= beta * d2x
            qddot[o + 4] -= beta * d2y
            qddot[o + 5] -= beta * d2z
            rod_dissipation += (
                beta
                * rod_param[r, ROD_MASS]
                * (
                    (u1x * d1x + u1y * d1y + u1z * d1z) / 4.0
                    + (ux * d2x + uy * d2y + uz * d2z) / 12.0
                )
            )
    return rod_dissipation, external_power


@njit(inline="always", **JIT_OPTIONS)
def rhs(model, data, s, q, qdot, qddot):  # pragma: no cover - compiled
    """Theorem 18.1 for all rods of a free class 1 structure: fills ``qddot`` (6R,)
    [m/s^2], ``data.tension`` and ``data.elastic_tension`` (S,) [N], and with tendon damping
    ``data.damping_power`` (S,) [W], tendons in kernel order; the inputs are row ``s`` of
    ``data.rest`` and ``data.force`` (:class:`tensegrity.physics.records.Data`).  Returns
    ``(dissipated_power, external_power)`` [W].

    ``model.tendon_damping`` is None when every ``c`` is 0 (the undamped specialization,
    chosen at compile time); ``data.node_force`` is zero on entry and left zero.
    """
    return _rhs(
        model.tendon_damping, model.tendon_max_tension, model.contacts, model, data, s, q, qdot,
        qddot,
    )  # fmt: skip


@compiled_only
def _rhs(tendon_damping, tendon_cap, contacts, model, data, s, q, qdot, qddot):  # pragma: no cover
    """:func:`rhs` with ``tendon_damping``, ``tendon_cap`` and ``contacts``
    (``model.tendon_damping``, ``model.tendon_max_tension``, ``model.contacts``) arguments: the
    passes inlined here test them for None, which numba decides at compile time only for an
    argument."""
    return rhs_passes(tendon_damping, tendon_cap, contacts, model, data, s, q, qdot, qddot)


@njit(inline="always", **JIT_OPTIONS)
def rhs_passes(
    tendon_damping, tendon_cap, contacts, model, data, s, q, qdot, qddot
):  # pragma: no cover
    """The passes of :func:`rhs`, inlined into a function that has ``tendon_damping``,
    ``tendon_cap`` and ``contacts`` (``model.tendon_damping``, ``model.tendon_max_tension``,
    ``model.contacts``) as arguments (:func:`_rhs`, and ``kernel_system._system_rhs``): one
    call per evaluation takes the records.  With contacts
    (:mod:`tensegrity.physics.contact`), their normal and sliding forces join the tendons'
    before the rod pass, and the sticking ends are held after it."""
    rest = stage_row(data.rest, s)
    _node_pass(tendon_damping, model, data, q, qdot)
    tendon_dissipation = _tendon_pass(tendon_damping, tendon_cap, model, data, rest)
    if contacts is not None:
        tendon_dissipation += contact_pass(contacts, model, data, q, qdot)
    rod_dissipation, external_power = _rod_pass(
        model,
        data,
        q,
        qdot,
        qddot,
        stage_row(data.force, s),
        _rigid_motion(q, qdot, model.rod_param),
    )
    if contacts is not None:
        rod_dissipation += stick_pass(contacts, model, data, q, qdot, qddot)
    return tendon_dissipation + rod_dissipation, external_power


@njit(**JIT_OPTIONS)
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


@njit(inline="always", **JIT_OPTIONS)
def energies(model, data, rest, q, qdot):  # pragma: no cover - compiled
    """``(kinetic, elastic, gravity)`` energies [J] of the rods and tendons, as
    ``dynamics.kinetic_energy``, ``elastic_energy`` and ``gravity_energy``, with the rest
    lengths ``rest`` (S,) [m], kernel order (the tensions capped by ``model.tendon_max_tension``:
    :func:`capped_energy`); ``data.node_position`` receives the node positions."""
    return _energies(model.tendon_max_tension, model, data, rest, q, qdot)


@njit(**JIT_OPTIONS)
def _energies(tendon_cap, model, data, rest, q, qdot):  # pragma: no cover - compiled
    """:func:`energies` with ``tendon_cap`` (``model.tendon_max_tension``) an argument, which
    numba tests for None at compile time."""
    p = data.node_position
    rod_slots, rod_param = model.rod_slots, model.rod_param
    has_gravity, gravity = model.has_gravity, model.gravity
    end_values(q, rod_slots, p)
    kinetic = 0.0
    potential = 0.0
    for r in range(rod_slots.shape[0]):
        o = 6 * r
        m = rod_param[r, ROD_MASS]
        v1 = 0.0
        v2 = 0.0
        for i in range(3):
            v1 += qdot[o + i] * qdot[o + i]
            v2 += qdot[o + 3 + i] * qdot[o + 3 + i]
            if has_gravity:
                potential -= m * gravity[i] * 0.5 * q[o + i]
        kinetic += m * (v1 / 8 + v2 / 24)
    elastic = 0.0
    tendon_slots, stiffness = model.tendon_slots, model.tendon_stiffness
    for s in range(tendon_slots.shape[0]):
        _, _, tx, ty, tz = tendon_vector(p, tendon_slots, s)
        stretch = np.sqrt(tx * tx + ty * ty + tz * tz) - rest[s]
        if stretch > 0.0:
            elastic += capped_energy(stiffness[s], stretch, _cap(tendon_cap, s))
    return kinetic, 0.5 * elastic, potential


#: Longest piece of a run (:func:`stencil_layout`), evaluated in one call: small enough that a
#: damped piece's rates, forces and powers stay in the L1/L2 cache between their loops.
RUN_CHUNK = 1024
#: Shortest run of tendons (:func:`_tendon_run`) worth a call of its own; shorter ones are
#: evaluated one by one with the tendons outside runs.  (With 32, the (10,10) shell's runs of
#: 32-100 tendons made an RK4 step 1.2-1.4x slower, each call slicing 12-18 arrays; with 96 or
#: 128 it is within 3% of the one-by-one loop.  96 keeps the (100,100) shell's runs of 99.)
MIN_RUN = 96
#: Fewest tendons in runs worth the layout: below it :func:`stencil_layout` makes no runs, so that
#: the tendons keep the structure's order and the engine's reordering of per-tendon values is the
#: identity (~1 us per call each way otherwise, more than runs save on a (10,10) shell).
MIN_TENDONS_IN_RUNS = 2048
#: Node classes tried by :func:`stencil_layout` (nodes per cell; 4 for the class 1 shell).
MAX_NODE_CLASSES = 8


class StencilLayout(NamedTuple):
    """How the kernel stores nodes and orders tendons (:func:`stencil_layout`)."""

    node_slot: np.ndarray  #: (N,) int64: slot of node i, ``(i % K) n_cells + i // K``
    node_classes: int  #: K
    n_slots: int  #: ``K n_cells``, the length of a node array
    tendon_order: np.ndarray  #: (S,) int64: the tendon at each kernel position
    tendon_runs: np.ndarray  #: (G, 4) int64: first position, length, tail and head slot


def stencil_layout(tendon_nodes: np.ndarray, n_nodes: int) -> StencilLayout:
    """The node slots and the tendon order that let most tendons be evaluated in runs.

    Nodes are split into ``K`` classes by ``i % K`` and numbered within a class by their cell
    ``i // K``; a node array holds the classes one after the other.  Tendons that join class
    ``c_a`` to class ``c_b`` at a fixed cell offset, for consecutive cells, then have tails and
    heads at consecutive slots: a *run*, evaluated without indirection (:func:`_tendon_run`).
    For each ``K`` from 1 to :data:`MAX_NODE_CLASSES` the tendons are sorted by
    ``(c_a, c_b, offset, cell)`` and cut into runs of at least :data:`MIN_RUN`; the ``K`` that
    puts the most tendons into runs wins (the smallest on a tie).  Kernel order: the runs, cut into
    pieces of at most :data:`RUN_CHUNK` and ordered by the cell of their first tail, then the
    other tendons in their own order.  Any network gets a valid layout;
    one without such regularity gets no runs (and its own tendon order).  For the class 1 shell,
    ``K = 4`` (two rods per element), and 99.5% of the (100,100) shell's tendons are in runs.
    Fewer than :data:`MIN_TENDONS_IN_RUNS` tendons in runs: no runs, ``K = 1``, and the
    structure's own order.
    """
    tendon_nodes = np.asarray(tendon_nodes, dtype=np.int64).reshape(-1, 2)
    S = tendon_nodes.shape[0]
    best = (0, 1, np.zeros((0, 2), dtype=np.int64), np.arange(S))
    for K in range(1, MAX_NODE_CLASSES + 1):
        node_class, cell = tendon_nodes % K, tendon_nodes // K
        key = np.stack([node_class[:, 0], node_class[:, 1], cell[:, 1] - cell[:, 0]])
        order = np.lexsort((cell[:, 0], *key[::-1]))
        same_key = np.all(key[:, order[1:]] == key[:, order[:-1]], axis=0)
        next_cell = np.diff(cell[order, 0]) == 1
        cuts = np.flatnonzero(~(same_key & next_cell)) + 1
        starts = np.r_[0, cuts] if S else np.zeros(0, dtype=np.int64)
        lengths = np.diff(np.r_[starts, S])
        keep = lengths >= MIN_RUN
        if lengths[keep].sum() > best[0]:
            best = (
                int(lengths[keep].sum()),
                K,
                np.stack([starts[keep], lengths[keep]], axis=1),
                order,
            )
    if best[0] < MIN_TENDONS_IN_RUNS:
        best = (0, 1, np.zeros((0, 2), dtype=np.int64), np.arange(S))
    _, K, runs, order = best
    n_cells = -(-n_nodes // K)
    nodes = np.arange(n_nodes)
    node_slot = (nodes % K) * n_cells + nodes // K
    # Runs cut into pieces of at most RUN_CHUNK tendons, ordered by the cell of their first tail:
    # consecutive pieces then work on the same cells, whose node data stay in cache (beyond the
    # L3 cache, whole runs one after the other re-read the node arrays from memory once a run).
    run_tendons = [
        order[piece : min(piece + RUN_CHUNK, start + length)]
        for start, length in runs
        for piece in range(start, start + length, RUN_CHUNK)
    ]
    first_cell = np.array([tendon_nodes[t[0], 0] // K for t in run_tendons], dtype=np.int64)
    run_tendons = [run_tendons[g] for g in np.argsort(first_cell, kind="stable")]
    in_runs = np.zeros(S, dtype=bool)
    in_runs[np.concatenate([*run_tendons, np.zeros(0, dtype=np.int64)])] = True
    tendon_order = np.concatenate([*run_tendons, np.flatnonzero(~in_runs)]).astype(np.int64)
    tendon_runs = np.zeros((len(run_tendons), 4), dtype=np.int64)
    position = 0
    for g, tendons in enumerate(run_tendons):
        tail, head = node_slot[tendon_nodes[tendons[0]]]
        tendon_runs[g] = position, len(tendons), tail, head
        position += len(tendons)
    return StencilLayout(node_slot, K, K * n_cells, tendon_order, tendon_runs)


class PackedStructure(NamedTuple):
    """A structure as the contiguous, writable arrays the compiled functions take (:func:`pack`);
    tendon arrays in kernel order, node arrays by slot (see :class:`StencilLayout`)."""

    rod_slots: np.ndarray  #: (R, 2) uint64
    rod_param: np.ndarray  #: (R, 6) float64: m, L, alpha, 2/m, 6/(m L^2), beta
    tendon_slots: np.ndarray  #: (S, 2) uint64, kernel order
    tendon_runs: np.ndarray  #: (G, 4) int64
    tendon_stiffness: np.ndarray  #: (S,) float64, kernel order
    tendon_damping: np.ndarray | None  #: (S,) float64, kernel order; None if every c is 0
    layout: StencilLayout

    def to_kernel_order(self, values: np.ndarray) -> np.ndarray:
        """Per-tendon ``values`` (..., S) in kernel order (a new array)."""
        return np.ascontiguousarray(np.take(values, self.layout.tendon_order, axis=-1))

    def to_slots(self, node_values: np.ndarray) -> np.ndarray:
        """Per-node vectors (..., N, 3) as (..., 3, n_slots), by coordinate and slot (zero in
        slots that hold no node)."""
        node_values = np.asarray(node_values, dtype=np.float64)
        out = np.zeros((*node_values.shape[:-2], 3, self.layout.n_slots))
        out[..., self.layout.node_slot] = np.swapaxes(node_values, -1, -2)
        return out


def pack(structure: Structure, *, general: bool = False) -> PackedStructure:
    """The structure as the compiled functions take it (``2/m`` and ``6/(m L^2)`` computed as
    ``dynamics.evaluate`` computes them); ``tendon_damping`` is None when every tendon's damping
    is zero (the compiled code then skips the length rates).

    By default only free 3-D class 1 structures are accepted (what :func:`rhs` alone simulates).
    ``general=True`` accepts any 3-D structure (point masses, anchors, joints, supports): the
    arrays then describe its rods and tendons, every node having a slot, and
    :mod:`tensegrity.physics.kernel_system` adds the rest.
    """
    if not general:
        structure.require_free_class1("the compiled kernel")
    elif structure.dim != 3:
        raise ValueError(
            "structure: the compiled kernel takes 3-D structures only (embed a "
            "planar one with tensegrity.physics.kernel_system.embed_planar)"
        )
    m, L = structure.rod_mass, structure.rod_length
    rod_param = np.empty((structure.n_rods, 6))
    rod_param[:, ROD_MASS] = m
    rod_param[:, ROD_LENGTH] = L
    rod_param[:, ROD_DAMPING], rod_param[:, ROD_RELATIVE_DAMPING] = rod_damping_rates(structure)
    rod_param[:, ROD_C1] = 2.0 / m
    rod_param[:, ROD_C2] = 6.0 / (m * L**2)
    tendon_nodes = structure.tendon_nodes.reshape(-1, 2)
    layout = stencil_layout(tendon_nodes, structure.n_nodes)
    order = layout.tendon_order
    damping = structure.tendon_damping
    return PackedStructure(
        rod_slots=np.ascontiguousarray(layout.node_slot[structure.rod_nodes], dtype=np.uint64),
        rod_param=rod_param,
        tendon_slots=np.ascontiguousarray(layout.node_slot[tendon_nodes[order]], dtype=np.uint64),
        tendon_runs=layout.tendon_runs,
        tendon_stiffness=np.ascontiguousarray(structure.tendon_stiffness[order], dtype=np.float64),
        tendon_damping=(
            np.ascontiguousarray(damping[order], dtype=np.float64) if np.any(damping != 0) else None
        ),
        layout=layout,
    )
