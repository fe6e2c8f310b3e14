"""Many copies of one structure, simulated together through the compiled kernel.

:func:`simulate_batch` runs ``B`` structures that share their rods and tendons (the same
``rod_nodes`` and ``tendon_nodes``) but not their parameters (masses, lengths, stiffnesses, rest
lengths, damping, loads) with fixed-step RK4, holding all states in one ``(B, 6R)`` array and
advancing them in one compiled call (:func:`tensegrity.kernel.rk4_batch`) per sample interval.  It
returns one :class:`~tensegrity.simulate.SimulationResult` per copy, sampled and checked as
``simulate(structure, t_span, method="rk4", dt=dt, sample_dt=sample_dt, ...)`` samples and checks
it: the same start (the initial state projected onto the rod constraints), the same projection
after every step, the same blow-up tests after every step (non-finite state, rod-length error,
energy growth) and the same sample quantities (computed by ``simulate``'s own recorder).

Differences from ``simulate``: round-off only (the kernel sums nodal forces in another order), and
``simulate``'s samples are Hermite-interpolated at the sample time inside the step that reaches
it, which here is the state at the end of the step nearest the sample time (before projection).
With sample times on the step grid the two differ by the round-off of the time sum (the
interpolation weight of the other end of the step is ~1e-12 or less) and by the rod-length
projection of one step (of the order of RK4's local error), far below 1e-12 relative for usual
steps.  Hence the restrictions: ``sample_dt`` and ``t_end - t0`` must be whole multiples of
``dt``; no steady-state stop; loads and rest lengths constant in time.

``wall_time`` of each result is the batch's wall time divided by ``B``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from types import SimpleNamespace

import numpy as np

from tensegrity import dynamics
from tensegrity.dynamics import State
from tensegrity.simulate import (
    STATUS_END,
    STATUS_FAILED,
    SimulationResult,
    _as_time_function,
    _check_blowup,
    _Model,
    _Recorder,
    _result,
    run_settings,
)
from tensegrity.structure import Structure

#: Largest relative misfit of ``sample_dt / dt`` and ``(t_end - t0) / dt`` to whole numbers.
GRID_RTOL = 1e-9


def _whole_steps(duration: float, dt: float, field: str) -> int:
    steps = round(duration / dt)
    if steps < 1 or abs(steps * dt - duration) > GRID_RTOL * duration:
        raise ValueError(f"{field}: must be a whole multiple of dt = {dt:g} s, got {duration:g} s")
    return steps


def _same_topology(structures: Sequence[Structure]) -> None:
    first = structures[0]
    for b, s in enumerate(structures[1:], start=1):
        if not (
            s.n_nodes == first.n_nodes
            and np.array_equal(s.rod_nodes, first.rod_nodes)
            and np.array_equal(s.tendon_nodes, first.tendon_nodes)
        ):
            raise ValueError(
                f"structures[{b}]: rods and tendons differ from structures[0] (a batch holds "
                "copies of one structure)"
            )


def simulate_batch(
    structures: Sequence[Structure],
    t_span: tuple[float, float],
    *,
    dt: float,
    sample_dt: float,
    initial: Sequence[State | None] | None = None,
    external_force: Sequence[np.ndarray | None] | None = None,
    gravity: np.ndarray | None = None,
    max_rod_length_error: float = 1e-3,
    max_energy_growth: float = 0.1,
) -> list[SimulationResult]:
    """Simulate copies of one structure with fixed-step RK4 in one compiled loop.

    Parameters
    ----------
    structures : sequence of B Structure
        Same ``rod_nodes``, ``tendon_nodes`` and node count; any parameters.
    t_span : (float, float)
        ``(t0, t_end)`` [s], shared; ``t_end - t0`` a whole multiple of ``dt``.
    dt : float
        RK4 step [s].
    sample_dt : float
        Output spacing [s], a whole multiple of ``dt``.
    initial : sequence of B State or None, optional
        Start states (default: each structure's :func:`~tensegrity.dynamics.initial_state`).
    external_force : sequence of B (N, 3) arrays or None, optional
        Constant external nodal forces [N] per copy.
    gravity : (3,) array, optional
        Uniform gravity [m/s^2], shared.
    max_rod_length_error, max_energy_growth : float
        Blow-up thresholds, as in :func:`~tensegrity.simulate.simulate`.

    Returns
    -------
    list of B SimulationResult
        As ``simulate(..., method="rk4")`` returns them (``settings["method"] == "rk4"``,
        ``settings["batched"] is True``); a copy that blows up stops there with status ``-1`` and
        the message ``simulate`` would give, the others run on.
    """
    from tensegrity.kernel import BATCH_RUNNING, pack, rk4_batch

    structures = list(structures)
    if not structures:
        raise ValueError("structures: need at least one structure")
    _same_topology(structures)
    B = len(structures)
    t0, t1 = (float(x) for x in t_span)
    if not (np.isfinite(t0) and np.isfinite(t1) and t1 > t0):
        raise ValueError(f"t_span: need finite t0 < t_end, got {t_span!r}")
    dt, sample_dt = float(dt), float(sample_dt)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: must be > 0, got {dt!r}")
    n_total = _whole_steps(t1 - t0, dt, "t_span")
    per_sample = _whole_steps(sample_dt, dt, "sample_dt")
    for field, value in (("max_rod_length_error", max_rod_length_error),
                         ("max_energy_growth", max_energy_growth)):
        if not value > 0:
            raise ValueError(f"{field}: must be > 0, got {value!r}")
    initial = [None] * B if initial is None else list(initial)
    forces = [None] * B if external_force is None else list(external_force)
    for field, values in (("initial", initial), ("external_force", forces)):
        if len(values) != B:
            raise ValueError(f"{field}: expected {B} entries (one per structure), got {len(values)}")
    if gravity is not None:
        gravity = np.asarray(gravity, dtype=float)
        if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
            raise ValueError(f"gravity: expected 3 finite numbers, got {gravity!r}")

    first = structures[0]
    n, N, S = first.n_coordinates, first.n_nodes, first.n_tendons
    models, recorders = [], []
    q = np.empty((B, n))
    qdot = np.empty((B, n))
    energy0, scale0, worst = np.empty(B), np.empty(B), np.empty(B)
    for b, structure in enumerate(structures):
        w = _as_time_function(forces[b], (N, 3), f"external_force[{b}]")
        model = _Model(structure, None, True, w, gravity)
        state = dynamics.initial_state(structure, t=t0) if initial[b] is None else initial[b]
        q[b], qdot[b] = dynamics.project_to_constraints(structure, state.q, state.qdot)
        y = np.concatenate([q[b], qdot[b], np.zeros(3)])
        energy0[b], scale0[b] = model.energy_balance(t0, y)
        worst[b] = float(np.max(np.abs(dynamics.rod_length_error(structure, q[b]))))
        recorder = _Recorder(model)
        recorder.add(t0, y)
        models.append(model)
        recorders.append(recorder)

    packed = [pack(s) for s in structures]  # same topology: the same layout and tendon order
    packed0 = packed[0]
    rod_param = np.stack([p.rod_param for p in packed])
    tendon_stiffness = np.stack([p.tendon_stiffness for p in packed])
    tendon_damping = (None if all(p.tendon_damping is None for p in packed)
                      else np.stack([np.zeros(S) if p.tendon_damping is None else p.tendon_damping
                                     for p in packed]))
    rest = packed0.to_kernel_order(np.stack([dynamics.rest_lengths(s) for s in structures]))
    has_w = any(f is not None for f in forces)
    w_all = (packed0.to_slots(np.stack([np.zeros((N, 3)) if f is None else np.asarray(f, float)
                                        for f in forces]))
             if has_w else np.zeros((1, 3, 1)))
    g = np.zeros(3) if gravity is None else gravity

    status = np.full(B, BATCH_RUNNING, dtype=np.int64)
    steps = np.zeros(B, dtype=np.int64)
    work = np.zeros((B, 2))
    end_q, end_qdot = np.empty((B, n)), np.empty((B, n))
    scratch = (np.zeros((3, 3, packed0.layout.n_slots)), np.empty(S), np.empty(S), np.empty(S),
               np.empty((5, n)))
    messages = [f"reached t_end = {t1:g} s"] * B
    samples = [0] * B
    wall0 = time.perf_counter()
    done = 0
    k = 0
    while done < n_total and np.any(status == BATCH_RUNNING):
        k += 1
        chunk = min(per_sample, n_total - done)
        running = status == BATCH_RUNNING
        rk4_batch(
            q, qdot, dt, chunk, float(max_rod_length_error), float(max_energy_growth),
            energy0, scale0, status, steps, work, worst, end_q, end_qdot,
            packed0.rod_slots, rod_param, packed0.tendon_slots, packed0.tendon_runs,
            tendon_stiffness, tendon_damping, rest, has_w, w_all, gravity is not None, g,
            *scratch,
        )
        done += chunk
        for b in np.flatnonzero(running):
            y = np.concatenate([end_q[b], end_qdot[b], work[b], [0.0]])
            if status[b] != BATCH_RUNNING:
                t_fail = t0 + int(steps[b]) * dt
                messages[b] = (_check_blowup(models[b], t_fail, y, energy0[b], [scale0[b]],
                                             max_rod_length_error, max_energy_growth)
                               or f"unstable at t = {t_fail:.6g} s")
                recorders[b].add(t_fail, y)
            elif chunk == per_sample:
                recorders[b].add(t0 + k * sample_dt, y)
                samples[b] += 1
            else:  # a last, partial interval: the end of the run, after projection
                recorders[b].add(t1, np.concatenate([q[b], qdot[b], work[b], [0.0]]))
    wall = (time.perf_counter() - wall0) / B

    results = []
    for b, structure in enumerate(structures):
        failed = status[b] != BATCH_RUNNING
        settings = run_settings(
            t0, t1, method="rk4", rtol=None, atol=None, dt=dt, sample_dt=sample_dt,
            locate_switches=False, steady_state=False, velocity_tol=None, acceleration_tol=None,
            gravity=gravity, control=None, external_force=forces[b],
        )
        settings["batched"] = True
        counts = dict(nsteps=int(steps[b]), nswitches=0,
                      nprojections=int(steps[b]) - (1 if failed else 0))
        results.append(_result(
            structure, recorders[b], STATUS_FAILED if failed else STATUS_END, messages[b],
            SimpleNamespace(total_nfev=4 * int(steps[b]) + samples[b]), counts, float(worst[b]),
            0.0, wall, settings,
        ))
    return results
