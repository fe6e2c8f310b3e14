"""Many copies of one structure with fixed-step RK4: :func:`simulate_batch` runs ``B``
structures that share their rods and tendons (the same ``rod_nodes`` and ``tendon_nodes``) but not
their parameters (masses, lengths, stiffnesses, rest lengths, damping, loads), each through the
engine (:func:`tensegrity.engine.loop.run`: whole stretches of RK4 steps in one compiled call per
sample interval, with ``simulate``'s projection after every step and its blow-up checks), and
returns one :class:`~tensegrity.engine.simulate.SimulationResult` per copy, exactly what
``simulate(structure, t_span, method="rk4", dt=dt, sample_dt=sample_dt, ...)`` returns, plus
``settings["batched"] = True``.  ``sample_dt`` and ``t_end - t0`` must be whole multiples of
``dt`` (samples on the step grid); loads constant in time; no steady-state stop.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from tensegrity.engine.simulate import SimulationResult, simulate
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import State

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
    """Simulate copies of one structure with fixed-step RK4 through the engine.

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
        Start states (default: each structure's :func:`~tensegrity.physics.dynamics.initial_state`).
    external_force : sequence of B (N, 3) arrays or None, optional
        Constant external nodal forces [N] per copy.
    gravity : (3,) array, optional
        Uniform gravity [m/s^2], shared.
    max_rod_length_error, max_energy_growth : float
        Blow-up thresholds, as in :func:`~tensegrity.engine.simulate.simulate`.

    Returns
    -------
    list of B SimulationResult
        As ``simulate(..., method="rk4")`` returns them (``settings["method"] == "rk4"``,
        ``settings["batched"] is True``); a copy that blows up stops there with status ``-1`` and
        the message ``simulate`` would give, the others run on.
    """
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
    _whole_steps(t1 - t0, dt, "t_span")
    _whole_steps(sample_dt, dt, "sample_dt")
    for field, value in (
        ("max_rod_length_error", max_rod_length_error),
        ("max_energy_growth", max_energy_growth),
    ):
        if not value > 0:
            raise ValueError(f"{field}: must be > 0, got {value!r}")
    initial = [None] * B if initial is None else list(initial)
    forces = [None] * B if external_force is None else list(external_force)
    for field, values in (("initial", initial), ("external_force", forces)):
        if len(values) != B:
            raise ValueError(
                f"{field}: expected {B} entries (one per structure), got {len(values)}"
            )
    results = []
    for b, structure in enumerate(structures):
        result = simulate(
            structure,
            (t0, t1),
            initial=initial[b],
            external_force=forces[b],
            gravity=gravity,
            method="rk4",
            dt=dt,
            sample_dt=sample_dt,
            locate_switches=False,
            max_rod_length_error=max_rod_length_error,
            max_energy_growth=max_energy_growth,
        )
        results.append(dataclasses.replace(result, settings=dict(result.settings, batched=True)))
    return results
