"""The engine's compiled (numba) half: the ODE right-hand side on ``y = [q, q', E_d, W_w, W_u]``,
the steps of the integrators (DOP853 with its error estimate and dense output, classical RK4),
the checks made after every step, and the outputs of a sample.

Constant arguments go to compiled callees as runtime values (``np.int64(0)``,
``np.bool_(True)``): numba compiles a callee once per argument type, and a literal ``0`` or
``True`` is a type of its own, so each would compile (and cache) another copy of the kernel.

Every function here evaluates the physics through :mod:`tensegrity.physics.kernel_system`
(``system_rhs``, ``system_project``, ...), so that one code path serves every structure
``simulate`` accepts, and takes its two records (:mod:`tensegrity.physics.records`), made once
per run by :class:`tensegrity.engine.system.CompiledSystem`: ``model`` (read-only: the packed
structure, gravity, the input tables, the limits) and ``data`` (the inputs' stage rows, the
scratch, the blow-up monitor).  Stage ``s`` of a step reads row ``s`` of ``data.rest``,
``data.rate`` and ``data.force`` when they have more than one row, and row 0 otherwise (inputs
constant over the step).  Tabulated inputs (:class:`~tensegrity.model.loads.ForceTable`,
:class:`~tensegrity.model.loads.ControlTable`) are interpolated here into those rows
(:func:`fill_stage_inputs`), inside a compiled stretch of steps too; Python functions of time
are called from the compiled loops through a callback (:func:`make_inputs`), so that every input
drives the same compiled loop.

The DOP853 coefficients, step-size law and error norm are those of ``scipy.integrate.DOP853``
(Hairer, Norsett and Wanner, *Solving Ordinary Differential Equations I*, II.10), so that the
engine follows the trajectories of the adaptive path it replaces.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
from numba import njit, objmode
from numba.core.errors import NumbaWarning

from tensegrity.engine import dop853_tableau
from tensegrity.engine.actuation import actuate, clip_command, hold_command
from tensegrity.physics.compiling import (
    JIT_OPTIONS,
    compiled_only,
)
from tensegrity.physics.contact import record_contacts
from tensegrity.physics.kernel import (
    copy_values,
    stage_row,
    tendon_vector,
)
from tensegrity.physics.kernel_system import (
    all_finite,
    system_energies,
    system_errors,
    system_nodes,
    system_project,
    system_rhs,
)

#: DOP853 tableau (:mod:`tensegrity.engine.dop853_tableau`, scipy's): 12 stages, the 13th is f at
#: the new point (first same as last), then 3 extra stages for the dense output.
DOP853_STAGES = dop853_tableau.N_STAGES
DOP853_A = dop853_tableau.A  # (16, 16)
DOP853_B = dop853_tableau.B  # (12,)
DOP853_C = dop853_tableau.C  # (16,)
DOP853_E3 = dop853_tableau.E3  # (13,)
DOP853_E5 = dop853_tableau.E5  # (13,)
DOP853_D = dop853_tableau.D  # (4, 16)
#: Rows of the dense-output polynomial.
DOP853_DENSE_ROWS = dop853_tableau.INTERPOLATOR_POWER
#: Stage times of one RK4 step, as fractions of the step.
RK4_C = np.array([0.0, 0.5, 0.5, 1.0])

#: ``"rk4"`` checks the energy balance after every this many steps (and after each stretch).
ENERGY_CHECK_EVERY = 8
#: Codes of :func:`check_state` and :func:`rk4_segment` (0: the state is sound;
#: ``CHECK_INPUT``: a control table makes a rest length negative).
(
    CHECK_OK,
    CHECK_NOT_FINITE,
    CHECK_ROD_LENGTH,
    CHECK_CONSTRAINT,
    CHECK_ENERGY,
    CHECK_PROJECTION,
    CHECK_INPUT,
) = range(7)


# --------------------------------------------------------------------------- tables
# (Compiled without fused multiply-adds, as all the package's code: the rows and stage times
# are bit for bit those NumPy computes, :meth:`tensegrity.model.loads.ForceTable.at`, so that a
# table drives a run exactly as the same table called as a function of time does.)


@njit(**JIT_OPTIONS)
def table_rows(time, values, zero_outside, times, rows, slopes):  # pragma: no cover
    """Rows (K, X) of a piecewise-linear table at ``times`` (K,) [s] into ``rows``, as
    :meth:`tensegrity.model.loads.ForceTable.at`: ``time`` (T,) strictly increasing,
    ``values`` (T, X), linear in between, outside ``[time[0], time[-1]]`` the end rows or
    (``zero_outside``) zero.  With ``slopes`` (K, X) (None: not wanted) the time derivatives
    too, zero outside the table."""
    T = time.shape[0]
    for k in range(times.shape[0]):
        t = times[k]
        after = min(max(np.searchsorted(time, t, side="right"), 1), max(T - 1, 1))
        lo = after - 1
        hi = min(lo + 1, T - 1)
        outside = t < time[0] or t > time[T - 1]
        w = 0.0
        if T > 1:
            w = min(max((t - time[lo]) / (time[after] - time[lo]), 0.0), 1.0)
        for x in range(values.shape[1]):
            rows[k, x] = (1.0 - w) * values[lo, x] + w * values[hi, x]
            if outside and zero_outside:
                rows[k, x] = 0.0
        if slopes is not None:
            for x in range(values.shape[1]):
                slope = 0.0
                if T > 1 and not outside:
                    slope = (values[hi, x] - values[lo, x]) / (time[hi] - time[lo])
                slopes[k, x] = slope


@njit(**JIT_OPTIONS)
def rk4_stage_times(t, k, h, out):  # pragma: no cover - compiled
    """The stage times of step ``k`` of ``h`` [s] from ``t`` [s] into ``out`` (4,), as Python
    computes them (``t + k h + RK4_C h``)."""
    for i in range(RK4_C.shape[0]):
        out[i] = (t + k * h) + RK4_C[i] * h


@njit(**JIT_OPTIONS)
def fill_stage_inputs(tables, times, data):  # pragma: no cover - compiled
    """The rows of the tabulated inputs at the stage ``times`` (K,) [s] into ``data``: with a
    control table, ``data.rest`` (K, S) the rest lengths ``Lbar = L0 - u`` [m] and ``data.rate``
    (K, S) ``du/dt`` [m/s]; with a force table, ``data.force`` (K, 3, n_slots) [N].  ``tables``
    (``model.tables``) = ``(control_time, control (Tc, S) [m], control_zero_outside, L0 (S,)
    [m], force_time, force (Tf, 3 * n_slots) [N], force_zero_outside)``, kernel order and slot
    layout; an empty time array: no such table; None: no tables (nothing to fill).  Returns the
    first row holding a negative rest length, or -1."""
    if tables is None:
        return -1
    rest, rate, force = data.rest, data.rate, data.force
    control_time, control, control_zero, rest0, force_time, force_values, force_zero = tables
    first_negative = -1
    if control_time.shape[0] > 0:
        table_rows(control_time, control, control_zero, times, rest, rate)
        for k in range(times.shape[0]):
            for s in range(rest0.shape[0]):
                rest[k, s] = rest0[s] - rest[k, s]
                if rest[k, s] < 0.0 and first_negative < 0:
                    first_negative = k
    if force_time.shape[0] > 0:
        rows = force.reshape((force.shape[0], -1))
        table_rows(force_time, force_values, force_zero, times, rows, None)
    return first_negative


#: Python functions of time among a run's inputs, by handle (``Model.callback``): what
#: :func:`make_inputs` calls from compiled code.  A
#: :class:`tensegrity.engine.system.CompiledSystem` registers its own, which is dropped with it.
INPUT_CALLBACKS: dict[int, Callable[[np.ndarray], int]] = {}


def _call_inputs(handle: int, times: np.ndarray) -> int:
    """Python's side of :func:`make_inputs`: the registered callback at ``times``."""
    return INPUT_CALLBACKS[int(handle)](times)


# The callback's block of object mode runs holding the GIL (it calls Python), in functions compiled
# ``nogil`` for the rest: numba says so in a warning each time it compiles the block.
warnings.filterwarnings(
    "ignore",
    message=".*Code running in object mode won't allow parallel execution despite nogil=True",
    category=NumbaWarning,
)


@njit(inline="always", **JIT_OPTIONS)
def inputs_vary(data):  # pragma: no cover - compiled
    """Whether the inputs of ``data`` (a record of a step's stage rows) vary over the step: some
    input is tabulated or a Python function, whose rows :func:`make_inputs` makes (constant
    inputs have one row, and are not made again)."""
    return data.rest.shape[0] > 1 or data.force.shape[0] > 1


@compiled_only
def make_inputs(callback, tables, times, data):  # pragma: no cover - compiled
    """The inputs' rows at the stage ``times`` (K,) [s] into ``data`` (whose inputs have K rows
    where they vary): from the tables (:func:`fill_stage_inputs`), or, when some input is a
    Python function of time, by Python (``callback``, ``model.callback``: a handle of
    :data:`INPUT_CALLBACKS`, called through numba's object mode; None compiles it out).
    Returns the first row the inputs could not be made for (a rest length negative, or the
    function failed: the callback keeps the error), or -1.  The actuated tendons' rows are the
    actuators' (:func:`tensegrity.engine.actuation.actuate`)."""
    if callback is not None:
        with objmode(bad="int64"):
            bad = _call_inputs(callback, times)
    else:
        bad = fill_stage_inputs(tables, times, data)
    actuate(data.actuation, times, data)
    return bad


@njit(**JIT_OPTIONS)
def fill_inputs_entry(tables, times, data):  # pragma: no cover - compiled
    """:func:`fill_stage_inputs` and the actuators' rows, for Python (no callback)."""
    bad = fill_stage_inputs(tables, times, data)
    actuate(data.actuation, times, data)
    return bad


# --------------------------------------------------------------------------- right-hand side
@njit(inline="always", **JIT_OPTIONS)
def accelerations(model, data, s, q, qdot, qddot):  # pragma: no cover - compiled
    """``qddot`` = the accelerations of Theorem 18.1 (eqs. 18.17, 18.20, constraint forces
    included) at ``(q, q')`` with the inputs' row ``s``; returns the powers ``(dissipated,
    external, control)`` [W]: damping, external forces, and ``sum_i T_el,i du_i/dt`` (``Lbar =
    L0 - u``), the rates of ``E_d``, ``W_w`` and ``W_u``."""
    dissipated, external = system_rhs(model, data, s, q, qdot, qddot)
    control = 0.0
    if data.has_rate:
        rate_s = stage_row(data.rate, s)
        elastic = data.elastic_tension
        for i in range(elastic.shape[0]):
            control += elastic[i] * rate_s[i]
    return dissipated, external, control


@compiled_only
def ode_rhs(model, data, s, y, dy):  # pragma: no cover - compiled
    """``dy = f(t_s, y)`` for ``y = [q, q', E_d, W_w, W_u]`` (length ``2n + 3``): ``q'``, the
    accelerations and the three powers of :func:`accelerations`; ``s`` selects the stage's row
    of the inputs."""
    n = (y.shape[0] - 3) // 2
    qdot = y[n : 2 * n]
    dy[2 * n], dy[2 * n + 1], dy[2 * n + 2] = accelerations(
        model, data, s, y[:n], qdot, dy[n : 2 * n]
    )
    copy_values(qdot, dy, n)


# --------------------------------------------------------------------------- DOP853
@compiled_only
def combine_stages(y, K, row, stages, h, out):  # pragma: no cover - compiled
    """``out = y + h sum_j row[j] K[j]`` over ``j < stages``."""
    copy_values(y, out, y.shape[0])
    for j in range(stages):
        a = h * row[j]
        if a != 0.0:
            kj = K[j]
            for i in range(y.shape[0]):
                out[i] += a * kj[i]


@compiled_only
def dop853_attempt(model, data, y, h, K, y_new, stage, tol):  # pragma: no cover - compiled
    """One DOP853 step of ``h`` [s] from ``y`` with ``K[0] = f(y)`` given; fills ``K[1:13]``
    (``K[12] = f(y_new)``, after which ``data`` holds the tensions at ``y_new``) and ``y_new``.
    ``stage`` (len(y),) is scratch; ``tol`` = ``(rtol, atol)``.  Returns the error norm of
    ``scipy.integrate.DOP853`` (accept the step when < 1)."""
    rtol, atol = tol
    for s in range(1, DOP853_STAGES):
        combine_stages(y, K, DOP853_A[s], s, h, stage)
        ode_rhs(model, data, s, stage, K[s])
    last = np.int64(DOP853_STAGES)
    combine_stages(y, K, DOP853_B, last, h, y_new)
    ode_rhs(model, data, last, y_new, K[last])
    err5 = 0.0
    err3 = 0.0
    m = y.shape[0]
    for i in range(m):
        e5 = 0.0
        e3 = 0.0
        for j in range(DOP853_STAGES + 1):
            e5 += DOP853_E5[j] * K[j, i]
            e3 += DOP853_E3[j] * K[j, i]
        scale = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        err5 += (e5 / scale) ** 2
        err3 += (e3 / scale) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    if not (np.isfinite(err5) and np.isfinite(err3)):
        return np.inf
    return abs(h) * err5 / np.sqrt((err5 + 0.01 * err3) * m)


@compiled_only
def dop853_dense(model, data, y_old, y, h, K, F, stage):  # pragma: no cover - compiled
    """The step's dense-output polynomial into ``F`` (7, len(y)), as ``scipy``'s DOP853: three
    more stages (rows 13-15 of ``K`` and of the inputs).  ``K[0]`` and ``K[12]`` are f at the
    step's two ends."""
    for s in range(DOP853_STAGES + 1, DOP853_A.shape[0]):
        combine_stages(y_old, K, DOP853_A[s], s, h, stage)
        ode_rhs(model, data, s, stage, K[s])
    dop853_dense_polynomial(y_old, y, h, K, F)


@compiled_only
def dop853_dense_polynomial(y_old, y, h, K, F):  # pragma: no cover - compiled
    """The dense-output polynomial ``F`` (7, len(y)) of a step of ``h`` [s] from ``y_old`` to
    ``y`` with all 16 stages ``K`` (linear in them: the sensitivities' polynomial is the same
    formula of their derivatives)."""
    for i in range(y.shape[0]):
        delta = y[i] - y_old[i]
        F[0, i] = delta
        F[1, i] = h * K[0, i] - delta
        F[2, i] = 2.0 * delta - h * (K[DOP853_STAGES, i] + K[0, i])
        for r in range(DOP853_D.shape[0]):
            acc = 0.0
            for j in range(DOP853_D.shape[1]):
                acc += DOP853_D[r, j] * K[j, i]
            F[3 + r, i] = h * acc


@njit(**JIT_OPTIONS)
def dop853_interpolate(F, y_old, x, out):  # pragma: no cover - compiled
    """``y`` at the fraction ``x`` (0..1) of the step from its dense polynomial ``F``."""
    for i in range(y_old.shape[0]):
        acc = 0.0
        for k in range(F.shape[0] - 1, -1, -1):
            acc += F[k, i]
            acc *= x if (F.shape[0] - 1 - k) % 2 == 0 else 1.0 - x
        out[i] = acc + y_old[i]


# --------------------------------------------------------------------------- RK4
@njit(inline="always", **JIT_OPTIONS)
def rk4_step(model, data, y, h, work_step, keep_first, y_end):  # pragma: no cover - compiled
    """One classical RK4 step of ``h`` [s] on ``y`` in place, ``y + h/6 (k1 + 2 k2 + 2 k3 +
    k4)``, the result also written to ``y_end``.  Stage rows of the inputs: 0, 1, 2, 3 at ``t,
    t + h/2, t + h/2, t + h``.

    The sum is accumulated stage by stage in the order written, so the result is that of the
    four stages kept apart, bit for bit, with two vectors of scratch instead of four: a pass
    after each stage adds it to the sum and makes the next stage's state (at (100,100) the step
    is 15% faster than with the stages kept, measured).  ``work_step`` = ``(total (m,), stage
    (m,), qddot (n,), first (m,))``; with ``keep_first``, ``first`` receives ``k1 = f(t, y)``
    (what a cubic Hermite sample inside the step needs)."""
    total, stage, qddot, first = work_step
    n = (y.shape[0] - 3) // 2
    q, qdot = y[:n], y[n : 2 * n]
    q_stage, qdot_stage = stage[:n], stage[n : 2 * n]
    # k1 = f(y): the sum starts with it, and stage 2 is y + h/2 k1
    powers = accelerations(model, data, np.int64(0), q, qdot, qddot)
    c = h * RK4_C[1]
    for i in range(n):
        total[i] = qdot[i]
        q_stage[i] = q[i] + c * qdot[i]
    for i in range(n):
        total[n + i] = qddot[i]
        qdot_stage[i] = qdot[i] + c * qddot[i]
    for j in range(3):
        total[2 * n + j] = powers[j]
    if keep_first:
        copy_values(total, first, y.shape[0])
    # k2 and k3 (weight 2), each making the next stage, y + c k
    for s in range(1, 3):
        powers = accelerations(model, data, s, q_stage, qdot_stage, qddot)
        c = h * RK4_C[s + 1]
        for i in range(n):  # (q_stage is made from qdot_stage before that is overwritten)
            total[i] = total[i] + 2.0 * qdot_stage[i]
            q_stage[i] = q[i] + c * qdot_stage[i]
        for i in range(n):
            total[n + i] = total[n + i] + 2.0 * qddot[i]
            qdot_stage[i] = qdot[i] + c * qddot[i]
        for j in range(3):
            total[2 * n + j] = total[2 * n + j] + 2.0 * powers[j]
    # k4 (weight 1) goes straight into the step's end
    powers = accelerations(model, data, np.int64(3), q_stage, qdot_stage, qddot)
    h6 = h / 6.0
    for i in range(n):
        y_end[i] = q[i] + h6 * (total[i] + qdot_stage[i])
        q[i] = y_end[i]
    for i in range(n):
        y_end[n + i] = qdot[i] + h6 * (total[n + i] + qddot[i])
        qdot[i] = y_end[n + i]
    for j in range(2 * n, 2 * n + 3):
        y_end[j] = y[j] + h6 * (total[j] + powers[j - 2 * n])
        y[j] = y_end[j]


@njit(**JIT_OPTIONS)
def rk4_segment(model, data, y, y_end, work_step, keep_first, t, h, n_steps):  # pragma: no cover
    """Up to ``n_steps`` RK4 steps of ``h`` [s] from time ``t`` [s], each followed by
    :func:`check_state` and the projection onto the rod and joint constraints (as
    ``simulate(method="rk4")``). Inputs constant (one row in ``data``), or varying (4 stage
    rows, made by :func:`make_inputs` into ``data`` before each step). The energy balance is
    checked every :data:`ENERGY_CHECK_EVERY` steps and after the last one (it costs about one
    evaluation; the other checks are cheap); it reads the inputs at the step's end. ``y_end``
    receives the state at the end of the last step before its projection (what a sample records,
    and the failing state). Returns ``(steps_taken, check_code, check_value)``; the loop stops
    at the first failed check, and before a step whose control table makes a rest length
    negative (:data:`CHECK_INPUT`, that step not taken)."""
    n = (y.shape[0] - 3) // 2
    step_end = min(RK4_C.shape[0], data.rest.shape[0]) - 1
    times = np.empty(RK4_C.shape[0])
    varying = inputs_vary(data)
    for k in range(n_steps):
        if varying:
            rk4_stage_times(t, k, h, times)
            if make_inputs(model.callback, model.tables, times, data) >= 0:
                return k, CHECK_INPUT, np.nan
        rk4_step(model, data, y, h, work_step, keep_first, y_end)
        # The projection measures the errors it removes: they are the checks' (one pass less).
        rod_error, constraint_error, ok = system_project(model, data, y[:n], y[n : 2 * n])
        if not all_finite(y_end[2 * n :]):
            rod_error = np.nan
        with_energy = k == n_steps - 1 or (k + 1) % ENERGY_CHECK_EVERY == 0
        code, value = judge_state(
            model, data, step_end, y_end, (rod_error, constraint_error), model.limits, with_energy
        )
        if code != CHECK_OK:
            return k + 1, code, value
        if not ok:
            return k + 1, CHECK_PROJECTION, np.nan
    return n_steps, CHECK_OK, 0.0


# --------------------------------------------------------------------------- checks and outputs
@compiled_only
def energy_balance(model, data, s, y):  # pragma: no cover - compiled
    """``(kinetic, elastic, gravity, total, scale)`` [J] at ``y`` with the inputs' row ``s``:
    ``total = E_kin + E_el + E_grav + E_d - W_w - W_u`` (constant up to integration error) and a
    magnitude to judge its drift by."""
    n = (y.shape[0] - 3) // 2
    kinetic, elastic, potential = system_energies(
        model, data, stage_row(data.rest, s), y[:n], y[n : 2 * n]
    )
    d, w, u = y[2 * n], y[2 * n + 1], y[2 * n + 2]
    total = kinetic + elastic + potential + d - w - u
    scale = kinetic + elastic + abs(potential) + abs(d) + abs(w) + abs(u)
    return kinetic, elastic, potential, total, scale


@compiled_only
def check_state(model, data, s, y, limits, with_energy):  # pragma: no cover - compiled
    """The blow-up checks after a step ending at ``y`` (inputs' row ``s``): ``(code, value)``
    with ``code`` one of ``CHECK_*``; ``value`` the offending number, or on success the larger
    of the rod-length error (relative) and the constraint error [m].  The energy balance is
    checked only ``with_energy``.

    ``limits`` (3,) = ``(max_rod_length_error, max_constraint_error [m], max_energy_growth)``
    (``model.limits``, or infinite for the start's check); ``data.monitor`` (4,) is updated in
    place: ``[energy0, largest scale seen, largest rod error, largest constraint error]``
    (``energy0`` NaN: set to this state's energy).  The energy balance may not grow by more
    than ``max_energy_growth`` times the largest energy magnitude seen so far."""
    n = (y.shape[0] - 3) // 2
    rod_error, constraint_error = system_errors(model, data, y[:n])
    if not all_finite(y):
        rod_error = np.nan
    return judge_state(model, data, s, y, (rod_error, constraint_error), limits, with_energy)


@compiled_only
def judge_state(model, data, s, y, errors, limits, with_energy):  # pragma: no cover - compiled
    """:func:`check_state` from the state's ``errors`` = ``(rod_error, constraint_error)``,
    measured by the caller: ``rod_error`` NaN if the state is not finite."""
    rod_error, constraint_error = errors
    monitor = data.monitor
    if np.isnan(rod_error):
        return CHECK_NOT_FINITE, np.nan
    monitor[2] = max(monitor[2], rod_error)
    monitor[3] = max(monitor[3], constraint_error)
    if not rod_error <= limits[0]:
        return CHECK_ROD_LENGTH, rod_error
    if not constraint_error <= limits[1]:
        return CHECK_CONSTRAINT, constraint_error
    if not with_energy:
        return CHECK_OK, max(rod_error, constraint_error)
    _, _, _, total, scale = energy_balance(model, data, s, y)
    if np.isnan(monitor[0]):  # (the first check of a run: its energy is the reference)
        monitor[0] = total
    monitor[1] = max(monitor[1], scale)
    growth = total - monitor[0]
    if not growth <= limits[2] * max(monitor[1], 1e-300):
        return CHECK_ENERGY, growth
    return CHECK_OK, max(rod_error, constraint_error)


@njit(**JIT_OPTIONS)
def tendon_lengths(p, tendon_slots, out):  # pragma: no cover - compiled
    """``|p_head - p_tail|`` [m] per tendon (kernel order) from node positions ``p``
    (3, n_slots): bit for bit
    :func:`tensegrity.physics.dynamics.tendon_lengths`, which a trajectory file's reader
    computes them with (they are not stored)."""
    for s in range(tendon_slots.shape[0]):
        _, _, tx, ty, tz = tendon_vector(p, tendon_slots, s)
        out[s] = np.sqrt(tx * tx + ty * ty + tz * tz)


@njit(**JIT_OPTIONS)
def record_sample(model, data, y, scratch, maps, columns, row):  # pragma: no cover - compiled
    """Sample ``row`` of ``columns`` (:class:`tensegrity.engine.result.Samples`' fields after
    ``t``) at ``y``, from one evaluation with the inputs' row 0 of ``data``: coordinates, node
    positions and velocities, tendon lengths and tensions, the energies, and the largest node
    acceleration [m/s^2] and speed [m/s] over the moving slots (rod ends and point masses); the
    contact pairs' columns: :func:`record_contacts_entry`.

    ``scratch`` = ``(dy (m,), p, v, accel (3, n_slots), lengths (S,), moving slots)``;
    ``maps`` = ``(kept, node_slot, tendon_position)``: the coordinates of ``y`` the structure
    has (all, or those not in ``z`` for a planar structure), each node's slot, each tendon's
    position in kernel order.
    """
    q, qdot, nodes, velocities, tendon_length, tension, energy, largest_accel, largest_speed = (
        columns
    )
    dy, p, v, accel, lengths, moving = scratch
    kept, node_slot, position = maps
    n = (y.shape[0] - 3) // 2
    first = np.int64(0)
    ode_rhs(model, data, first, y, dy)
    kinetic, elastic, potential, _, _ = energy_balance(model, data, first, y)
    system_nodes(model, y[:n], y[n : 2 * n], p, v, np.bool_(True))
    tendon_lengths(p, model.tendon_slots, lengths)
    system_nodes(model, dy[n : 2 * n], dy[n : 2 * n], accel, accel, np.bool_(False))
    for i in range(kept.shape[0]):
        q[row, i] = y[kept[i]]
        qdot[row, i] = y[n + kept[i]]
    for i in range(node_slot.shape[0]):
        for k in range(nodes.shape[2]):
            nodes[row, i, k] = p[k, node_slot[i]]
            velocities[row, i, k] = v[k, node_slot[i]]
    tensions = data.tension
    for j in range(position.shape[0]):
        tendon_length[row, j] = lengths[position[j]]
        tension[row, j] = tensions[position[j]]
    energy[row, 0], energy[row, 1], energy[row, 2] = kinetic, elastic, potential
    energy[row, 3], energy[row, 4], energy[row, 5] = y[-3], y[-2], y[-1]
    largest_accel[row] = _largest_at(accel, moving)
    largest_speed[row] = _largest_at(v, moving)


@njit(**JIT_OPTIONS)
def _largest_at(x, slots):  # pragma: no cover - compiled
    """``max |x[:, slots]|``."""
    worst = 0.0
    for k in range(slots.shape[0]):
        for i in range(3):
            worst = max(worst, abs(x[i, slots[k]]))
    return worst


# --------------------------------------------------------------------------- entries for Python
# The loops call the functions above from compiled code only.  Python calls three of them (the
# scipy methods' right-hand side, a sample inside an rk4 step, the checks of the loop of the scipy
# methods, a controller's update) through these entries, compiled with the wrapper that unboxes
# the records only when Python first calls them: a DOP853 run compiles none of them.
@njit(**JIT_OPTIONS)
def record_contacts_entry(data, columns, row):  # pragma: no cover - compiled
    """:func:`tensegrity.physics.contact.record_contacts` (the contact columns of ``Samples``,
    ``columns``) after :func:`record_sample`'s evaluation, called from Python for runs with
    planes only (a run without them passes no more arrays per sample than before)."""
    normal, friction, mode = columns
    record_contacts(data.contact_work, normal, friction, mode, row)


@njit(**JIT_OPTIONS)
def ode_rhs_entry(model, data, s, y, dy):  # pragma: no cover - compiled
    """:func:`ode_rhs`, called from Python."""
    ode_rhs(model, data, s, y, dy)


@njit(**JIT_OPTIONS)
def check_state_entry(model, data, s, y, limits, with_energy):  # pragma: no cover - compiled
    """:func:`check_state`, called from Python."""
    return check_state(model, data, s, y, limits, with_energy)


# --------------------------------------------------------------------------- feedback
@njit(**JIT_OPTIONS)
def next_update(law, act):  # pragma: no cover - compiled
    """The time [s] of a compiled feedback law's next update (inf without one)."""
    if law is None:
        return np.inf
    return law.schedule[0] + act.updates[0] * law.schedule[1]


@njit(**JIT_OPTIONS)
def update_due(law, act, t):  # pragma: no cover - compiled
    """True if a compiled feedback law's update is due at ``t`` [s] (to 1e-9 of its
    period); False without one."""
    if law is None:
        return False
    return t >= next_update(law, act) - 1e-9 * law.schedule[1]


@njit(**JIT_OPTIONS)
def feedback_outputs(law, model, data, y):  # pragma: no cover - compiled
    """The outputs ``law`` reads at ``y`` into ``data.actuation.outputs`` (Y,), from one
    evaluation with the inputs' row 0 of ``data`` (:class:`tensegrity.engine.feedback
    .LinearFeedback`'s groups: node positions, node velocities, tendon lengths, tensions)."""
    act = data.actuation
    n = (y.shape[0] - 3) // 2
    ode_rhs(model, data, np.int64(0), y, act.state)  # (the tensions)
    p, v = data.node_position, data.node_velocity
    system_nodes(model, y[:n], y[n : 2 * n], p, v, np.bool_(True))
    out, k = act.outputs, 0
    for group in range(2):
        if law.groups[group]:
            x = p if group == 0 else v
            for i in range(law.node_slot.shape[0]):
                for c in range(law.dim):
                    out[k] = x[c, law.node_slot[i]]
                    k += 1
    if law.groups[2]:
        for j in range(law.tendon_position.shape[0]):
            _, _, tx, ty, tz = tendon_vector(p, model.tendon_slots, law.tendon_position[j])
            out[k] = np.sqrt(tx * tx + ty * ty + tz * tz)
            k += 1
    if law.groups[3]:
        for j in range(law.tendon_position.shape[0]):
            out[k] = data.tension[law.tendon_position[j]]
            k += 1


@njit(**JIT_OPTIONS)
def feedback_update(law, model, data, t, y):  # pragma: no cover - compiled
    """A compiled feedback law's update at ``(t, y)``, ``data`` holding the inputs at ``t``
    (nothing without a law): the command ``u_ref - K (y - y_ref)`` clipped to the bounds, held
    from ``t`` (:func:`tensegrity.engine.actuation.hold_command`); the inputs at ``t`` made
    again and the jump of the elastic energy (a command held at once) added to ``W_u``, so
    that the energy balance holds across it.  False if the log of updates is full (nothing
    changed)."""
    if law is None:
        return False
    act = data.actuation
    command = act.proposed
    feedback_outputs(law, model, data, y)
    gain, out, ref = law.gain, act.outputs, law.output_ref
    for a in range(gain.shape[0]):
        u = law.control_ref[a]
        for j in range(gain.shape[1]):
            u -= gain[a, j] * (out[j] - ref[j])
        command[a] = u
    clip_command(act, command, command)
    return held(model, data, t, y, command)


@njit(**JIT_OPTIONS)
def held(model, data, t, y, command):  # pragma: no cover - compiled
    """Hold ``command`` (A,) [m] (within the bounds) from ``t`` with ``data`` holding the
    inputs at ``t`` (one row); the elastic energy's jump goes to ``W_u``.  False if the log of
    updates is full (nothing changed)."""
    first = np.int64(0)
    before = energy_balance(model, data, first, y)[1]
    if not hold_command(data.actuation, t, command):
        return False
    times = np.full(1, t)
    actuate(data.actuation, times, data)
    y[-1] += energy_balance(model, data, first, y)[1] - before
    return True


__all__ = [
    "CHECK_CONSTRAINT",
    "CHECK_ENERGY",
    "CHECK_INPUT",
    "CHECK_NOT_FINITE",
    "CHECK_OK",
    "CHECK_PROJECTION",
    "CHECK_ROD_LENGTH",
    "DOP853_C",
    "DOP853_DENSE_ROWS",
    "DOP853_STAGES",
    "ENERGY_CHECK_EVERY",
    "RK4_C",
    "check_state",
    "check_state_entry",
    "dop853_attempt",
    "dop853_dense",
    "dop853_interpolate",
    "energy_balance",
    "feedback_outputs",
    "feedback_update",
    "fill_inputs_entry",
    "fill_stage_inputs",
    "held",
    "next_update",
    "ode_rhs",
    "ode_rhs_entry",
    "record_contacts_entry",
    "record_sample",
    "rk4_segment",
    "rk4_step",
    "tendon_lengths",
    "update_due",
]
