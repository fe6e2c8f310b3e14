"""Simulation of a structure: integration, slack-switch events, constraint projection, energy
bookkeeping, blow-up detection, steady-state stop and sampled outputs (eq. 18.60).

The ODE state is ``y = [q, q', E_d, W_w, W_u]``: coordinates and rates (6R each) followed by the
energy dissipated by damping, the work of the external forces ``w`` and the work of the control
``u`` (rest-length changes), all integrated with the motion so that the energy balance
``E_kin + E_el + E_grav + E_d - W_w - W_u = E(0)`` can be checked at every step.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from tensegrity import dynamics
from tensegrity.dynamics import State
from tensegrity.integrators import IntegrationError, make_integrator
from tensegrity.structure import Structure

TimeFunction = Callable[[float], np.ndarray]

#: ``SimulationResult.status`` values.
STATUS_FAILED, STATUS_END, STATUS_STEADY = -1, 0, 1


@dataclasses.dataclass(frozen=True, eq=False)
class SimulationResult:
    """Samples of a simulation and how it ended.

    Sampled arrays have ``T`` rows, one per output time.

    Attributes
    ----------
    t : (T,) sample times [s].
    q, qdot : (T, 6R) coordinates [m] and rates [m/s].
    node_position, node_velocity : (T, N, 3) ``p = P q`` [m] and ``P q'`` [m/s] (eq. 18.60);
        (T, N, 2) for a planar structure.
    tendon_length : (T, S) [m].  tendon_tension : (T, S) [N], damping included.
    energy : dict of (T,) arrays [J]: ``kinetic``, ``elastic``, ``gravity``, ``dissipated``,
        ``external_work``, ``control_work``.
    residual_acceleration : (T,) largest node acceleration [m/s^2].
    status : ``1`` steady state reached, ``0`` end time reached, ``-1`` failed (see ``message``).
    nfev, nsteps, nswitches, nprojections : right-hand-side evaluations, steps, located slack/taut
        switches, projections onto the rod constraints.
    max_rod_length_error : largest relative rod-length error seen at the end of a step.
    max_constraint_error : largest violation ``|A q - b|`` [m] of the joints and supports seen at
        the end of a step (0 without any; see ``docs/constraints.md``).
    wall_time : [s].  settings : the options of the run.
    """

    structure: Structure
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    node_position: np.ndarray
    node_velocity: np.ndarray
    tendon_length: np.ndarray
    tendon_tension: np.ndarray
    energy: dict[str, np.ndarray]
    residual_acceleration: np.ndarray
    status: int
    message: str
    nfev: int
    nsteps: int
    nswitches: int
    nprojections: int
    max_rod_length_error: float
    wall_time: float
    settings: dict[str, Any]
    max_constraint_error: float = 0.0

    @property
    def success(self) -> bool:
        """True unless the run failed."""
        return self.status >= 0

    @property
    def final_state(self) -> State:
        """The state at the last sample."""
        return State(t=float(self.t[-1]), q=self.q[-1], qdot=self.qdot[-1])

    @property
    def total_energy(self) -> np.ndarray:
        """``E_kin + E_el + E_grav + E_d - W_w - W_u`` [J], (T,): constant up to integration error."""
        e = self.energy
        return (
            e["kinetic"] + e["elastic"] + e["gravity"] + e["dissipated"]
            - e["external_work"] - e["control_work"]
        )

    @property
    def slack_count(self) -> np.ndarray:
        """Number of slack (zero-tension) tendons at each sample, (T,)."""
        return np.sum(self.tendon_tension <= 0, axis=1)


def _as_time_function(value: Any, shape: tuple[int, ...], field: str) -> TimeFunction | None:
    """A constant array or a callable of time, checked for shape and finiteness at call time."""
    if value is None:
        return None
    if callable(value):
        def checked(t: float) -> np.ndarray:
            out = np.asarray(value(t), dtype=float)
            if out.shape != shape:
                raise ValueError(f"{field}: expected shape {shape} at t = {t}, got {out.shape}")
            if not np.all(np.isfinite(out)):
                raise ValueError(f"{field}: not finite at t = {t}")
            return out
        return checked
    array = np.asarray(value, dtype=float)
    if array.shape != shape:
        raise ValueError(f"{field}: expected shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{field}: must be finite")
    return lambda t: array


class _Model:
    """The right-hand side ``f(t, y)`` and the quantities derived from the ODE state."""

    def __init__(self, structure, control, control_is_constant, external_force, gravity):
        self.structure = structure
        self.n = structure.n_coordinates
        self.control, self.control_is_constant = control, control_is_constant
        self.external_force, self.gravity = external_force, gravity

    def rest_length(self, t: float) -> np.ndarray:
        u = None if self.control is None else self.control(t)
        return dynamics.rest_lengths(self.structure, u)

    def evaluate(self, t: float, y: np.ndarray) -> dynamics.Evaluation:
        w = None if self.external_force is None else self.external_force(t)
        return dynamics.evaluate(
            self.structure, y[: self.n], y[self.n : 2 * self.n],
            rest_length=self.rest_length(t), external_force=w, gravity=self.gravity,
        )

    def control_power(self, t: float, elastic_tension: np.ndarray) -> float:
        """Power fed in by changing rest lengths: ``sum k max(l - Lbar, 0) du/dt`` [W]."""
        if self.control is None or self.control_is_constant:
            return 0.0
        h = 1e-6 * max(1.0, abs(t))
        rate = (self.control(t + h) - self.control(t - h)) / (2 * h)
        return float(np.sum(elastic_tension * rate))

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        ev = self.evaluate(t, y)
        power = [ev.dissipated_power, ev.external_power,
                 self.control_power(t, ev.tendons.elastic_tension)]
        return np.concatenate([y[self.n : 2 * self.n], ev.qddot, power])

    def switch_indicator(self, t: float, y: np.ndarray) -> np.ndarray:
        """Per tendon, positive while it pulls and <= 0 while it does not: ``min(k d, k d + c l')``
        with ``d = l - Lbar``.  Its sign changes exactly at the kinks of the tension law."""
        s = self.structure
        p = dynamics.nodes_from_coordinates(s, y[: self.n])
        v = dynamics.nodes_from_coordinates(s, y[self.n : 2 * self.n], rates=True)
        tendons = dynamics.tendon_forces(s, p, v, self.rest_length(t))
        stretch = s.tendon_stiffness * (tendons.length - self.rest_length(t))
        return np.minimum(stretch, stretch + s.tendon_damping * tendons.length_rate)

    def potential(self, t: float, y: np.ndarray) -> tuple[float, float, float]:
        s, q = self.structure, y[: self.n]
        p = dynamics.nodes_from_coordinates(s, q)
        return (
            float(dynamics.kinetic_energy(s, y[self.n : 2 * self.n])),
            float(dynamics.elastic_energy(s, p, self.rest_length(t))),
            float(dynamics.gravity_energy(s, q, self.gravity)),
        )

    def energy_balance(self, t: float, y: np.ndarray) -> tuple[float, float]:
        """``(total, scale)``: the conserved total and a magnitude to compare its drift with."""
        kinetic, elastic, gravity = self.potential(t, y)
        dissipated, external, control = y[2 * self.n :]
        total = kinetic + elastic + gravity + dissipated - external - control
        scale = kinetic + elastic + abs(gravity) + abs(dissipated) + abs(external) + abs(control)
        return total, scale

    def project(self, y: np.ndarray) -> np.ndarray:
        q, qdot = dynamics.project_to_constraints(
            self.structure, y[: self.n], y[self.n : 2 * self.n]
        )
        return np.concatenate([q, qdot, y[2 * self.n :]])


class _Recorder:
    """Accumulates samples and their outputs."""

    def __init__(self, model: _Model) -> None:
        self.model = model
        self.rows: dict[str, list] = {
            k: [] for k in ("t", "y", "p", "v", "length", "tension", "energy", "accel")
        }

    def add(self, t: float, y: np.ndarray) -> float:
        """Record a sample; return its largest node acceleration [m/s^2]."""
        m, s = self.model, self.model.structure
        ev = m.evaluate(t, y)
        accel = float(np.max(np.abs(dynamics.nodes_from_coordinates(s, ev.qddot, rates=True))))
        r = self.rows
        r["t"].append(t)
        r["y"].append(y)
        r["p"].append(dynamics.nodes_from_coordinates(s, y[: m.n]))
        r["v"].append(dynamics.nodes_from_coordinates(s, y[m.n : 2 * m.n], rates=True))
        r["length"].append(ev.tendons.length)
        r["tension"].append(ev.tendons.tension)
        r["energy"].append([*m.potential(t, y), *y[2 * m.n :]])
        r["accel"].append(accel)
        return accel

    def speed(self) -> float:
        return float(np.max(np.abs(self.rows["v"][-1])))


def simulate(
    structure: Structure,
    t_span: tuple[float, float],
    *,
    initial: State | None = None,
    control: np.ndarray | TimeFunction | None = None,
    external_force: np.ndarray | TimeFunction | None = None,
    gravity: np.ndarray | None = None,
    method: str = "DOP853",
    rtol: float = 1e-9,
    atol: float = 1e-12,
    dt: float | None = None,
    sample_dt: float | None = None,
    locate_switches: bool = True,
    steady_state: bool = False,
    velocity_tol: float = 1e-6,
    acceleration_tol: float = 1e-6,
    projection_tol: float = 1e-12,
    max_rod_length_error: float = 1e-3,
    max_energy_growth: float = 0.1,
    progress: bool = False,
) -> SimulationResult:
    """Simulate ``structure`` over ``t_span = (t0, t_end)`` [s] (Theorem 18.1, eqs. 18.39-18.60).

    Parameters
    ----------
    initial : State, optional
        Start state; default :func:`dynamics.initial_state` (the structure's nodes at ``t0``).
    control : (S,) array or callable ``u(t)``, optional
        Rest-length changes ``u`` [m]: ``Lbar = L0 - u`` must stay ``>= 0``.
    external_force : (N, 3) array or callable ``w(t)``, optional (``(N, 2)`` if planar)
        External nodal forces [N].
    gravity : (3,) array, optional (``(2,)`` if planar)
        Uniform gravity [m/s^2], e.g. ``(0, 0, -9.81)``.
    method : str
        An adaptive ``scipy.integrate`` method (``"DOP853"``, ``"RK45"``, ``"Radau"``, ...) with
        ``rtol``, ``atol``; or ``"rk4"``, fixed step ``dt`` [s].
    sample_dt : float, optional
        Output spacing [s]; default ``(t_end - t0) / 1000``.  The last sample is where the run ended.
    locate_switches : bool
        Adaptive methods only: when a tendon goes slack or taut within a step, find the switch
        (bisection on the step's dense output, to 1e-13 s relative), discard the step, integrate
        again from its start up to the switch and restart there, so that no stage of any step
        sees both sides of a kink of the tension law and the method keeps its order.
    steady_state : bool
        Stop at the first sample where every node's speed is below ``velocity_tol`` [m/s] and
        every node's acceleration below ``acceleration_tol`` [m/s^2].
    projection_tol : float
        Adaptive methods project onto the rod constraints (and restart) when a relative rod-length
        error, or a violation of the joints and supports in metres, exceeds this; ``"rk4"``
        projects after every step.
    max_rod_length_error, max_energy_growth : float
        Blow-up detection: the run fails if, at the end of a step, the state is not finite, a
        relative rod-length error exceeds ``max_rod_length_error``, or the energy balance has grown
        by more than ``max_energy_growth`` times its scale.

    Returns
    -------
    SimulationResult
        With ``status`` and ``message``.  A failed run keeps its samples up to the failure.
    """
    t0, t_end = (float(x) for x in t_span)
    if not (np.isfinite(t0) and np.isfinite(t_end) and t_end > t0):
        raise ValueError(f"t_span: need finite t0 < t_end, got {t_span!r}")
    sample_dt = (t_end - t0) / 1000 if sample_dt is None else float(sample_dt)
    if not (np.isfinite(sample_dt) and sample_dt > 0):
        raise ValueError(f"sample_dt: must be > 0, got {sample_dt!r}")
    for field, value in (
        ("velocity_tol", velocity_tol), ("acceleration_tol", acceleration_tol),
        ("projection_tol", projection_tol), ("max_rod_length_error", max_rod_length_error),
        ("max_energy_growth", max_energy_growth),
    ):
        if not value > 0:
            raise ValueError(f"{field}: must be > 0, got {value!r}")
    if gravity is not None:
        gravity = np.asarray(gravity, dtype=float)
        if gravity.shape != (structure.dim,) or not np.all(np.isfinite(gravity)):
            raise ValueError(f"gravity: expected {structure.dim} finite numbers, got {gravity!r}")
    integrator = make_integrator(method, rtol=rtol, atol=atol, dt=dt)
    S, N = structure.n_tendons, structure.n_nodes
    model = _Model(
        structure,
        _as_time_function(control, (S,), "control"),
        not callable(control),
        _as_time_function(external_force, (N, structure.dim), "external_force"),
        gravity,
    )
    model.rest_length(t0)  # reject a control that makes a rest length negative, up front
    state = dynamics.initial_state(structure, t=t0) if initial is None else initial
    q, qdot = dynamics.project_to_constraints(structure, state.q, state.qdot)
    y = np.concatenate([q, qdot, np.zeros(3)])
    energy0, scale0 = model.energy_balance(t0, y)
    energy_scale = [scale0]  # the largest energy magnitude seen so far

    settings = run_settings(
        t0, t_end, method=method, rtol=rtol, atol=atol, dt=dt, sample_dt=sample_dt,
        locate_switches=locate_switches, steady_state=steady_state, velocity_tol=velocity_tol,
        acceleration_tol=acceleration_tol, gravity=gravity, control=control,
        external_force=external_force,
    )
    recorder = _Recorder(model)
    wall0 = time.perf_counter()
    bar = _progress_bar(t0, t_end) if progress else None
    counts = dict(nsteps=0, nswitches=0, nprojections=0)
    max_length_error = float(np.max(np.abs(dynamics.rod_length_error(structure, q)), initial=0.0))
    max_joint_error = dynamics.constraint_error(structure, q)
    status, message = STATUS_END, f"reached t_end = {t_end:g} s"

    recorder.add(t0, y)
    next_sample = 1
    integrator.start(model, t0, y, t_end)
    locate = locate_switches and integrator.adaptive
    indicator = model.switch_indicator(t0, y) if locate else None
    switch_time = None  # while re-integrating up to a located switch
    try:
        while integrator.t < t_end:
            t_old, y_old = integrator.t, integrator.y.copy()
            integrator.step()
            counts["nsteps"] += 1
            t_new, y_new = integrator.t, integrator.y
            if locate and switch_time is None:
                new_indicator = model.switch_indicator(t_new, y_new)
                switched = np.flatnonzero((new_indicator > 0) != (indicator > 0))
                if switched.size:
                    # Some stages of this step saw the far side of a kink: discard it and
                    # integrate again from its start up to the switch, then restart there.
                    switch_time = _first_switch(model, integrator, switched, indicator > 0)
                    counts["nswitches"] += 1
                    integrator.start(model, t_old, y_old, switch_time)
                    continue
                indicator = new_indicator
            failure = _check_blowup(
                model, t_new, y_new, energy0, energy_scale, max_rod_length_error, max_energy_growth
            )
            if failure:
                status, message = STATUS_FAILED, failure
                break
            length_error = float(np.max(np.abs(dynamics.rod_length_error(structure, y_new[: model.n])),
                                        initial=0.0))
            max_length_error = max(max_length_error, length_error)
            joint_error = dynamics.constraint_error(structure, y_new[: model.n])
            max_joint_error = max(max_joint_error, joint_error)
            # Samples up to t_new, from the step's interpolant.
            while (t_sample := t0 + next_sample * sample_dt) <= t_new * (1 + 1e-14):
                accel = recorder.add(t_sample, integrator.interpolate(min(t_sample, t_new)))
                next_sample += 1
                if steady_state and accel < acceleration_tol and recorder.speed() < velocity_tol:
                    status = STATUS_STEADY
                    message = f"steady state at t = {t_sample:.6g} s"
                    break
            if status == STATUS_STEADY:
                break
            at_switch = switch_time is not None and t_new >= switch_time
            drift = max(length_error, joint_error)
            if not integrator.adaptive or at_switch or drift > projection_tol:
                y_new = model.project(y_new)
                counts["nprojections"] += 1
                integrator.start(model, t_new, y_new, t_end)
                indicator = model.switch_indicator(t_new, y_new) if locate else None
                switch_time = None
            if bar is not None:
                bar.update(t_new - bar.n)
    except (IntegrationError, ValueError, FloatingPointError) as exc:
        status, message = STATUS_FAILED, str(exc)
    finally:
        if bar is not None:
            bar.close()
    if status != STATUS_STEADY and recorder.rows["t"][-1] < integrator.t * (1 - 1e-14):
        recorder.add(integrator.t, integrator.y)  # the end, or the last state before failure
    return _result(structure, recorder, status, message, integrator, counts, max_length_error,
                   max_joint_error, time.perf_counter() - wall0, settings)


def run_settings(
    t0: float, t_end: float, *, method, rtol, atol, dt, sample_dt, locate_switches, steady_state,
    velocity_tol, acceleration_tol, gravity, control, external_force,
) -> dict[str, Any]:
    """``SimulationResult.settings``: the options of a run, JSON-friendly (arrays and functions
    given for ``control`` and ``external_force`` are recorded as ``True`` / ``"function"``)."""
    return dict(
        t_span=[t0, t_end], method=method, rtol=rtol, atol=atol, dt=dt, sample_dt=sample_dt,
        locate_switches=locate_switches, steady_state=steady_state, velocity_tol=velocity_tol,
        acceleration_tol=acceleration_tol, gravity=None if gravity is None else gravity.tolist(),
        control="function" if callable(control) else control is not None,
        external_force="function" if callable(external_force) else external_force is not None,
    )


def _first_switch(model: _Model, integrator, candidates: np.ndarray, was_taut: np.ndarray) -> float:
    """Earliest time in the last step at which one of ``candidates`` changes taut/slack state.

    Bisection on the dense output; returns the right end of the final bracket, just past the
    switch, so that the restarted integration starts on the new side of the kink.
    """
    lo, hi = integrator.t_old, integrator.t
    tol = 1e-13 * max(1.0, abs(hi))
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        g = model.switch_indicator(mid, integrator.interpolate(mid))[candidates]
        if np.any((g > 0) != was_taut[candidates]):
            hi = mid
        else:
            lo = mid
    return hi


def _check_blowup(model, t, y, energy0, energy_scale, max_length_error, max_growth) -> str | None:
    """A one-line reason if the state at ``t`` is unphysical, else None.

    ``energy_scale`` is a one-element list holding the largest energy magnitude seen so far
    (updated here): the energy balance's drift is judged against it, not against the magnitude
    at this instant, which can pass through zero (a pendulum at rest at the height of the origin).
    """
    n = model.n
    if not np.all(np.isfinite(y)):
        return f"unstable: the state is not finite at t = {t:.6g} s"
    error = np.abs(dynamics.rod_length_error(model.structure, y[:n]))
    if error.max(initial=0.0) > max_length_error:
        r = int(np.argmax(error))
        return (f"unstable: rods[{r}] length error {error[r]:.3g} (relative) exceeds "
                f"{max_length_error:g} within one step at t = {t:.6g} s (step too large, or the "
                "motion is unstable)")
    joint_error = dynamics.constraint_error(model.structure, y[:n])
    if joint_error > max_length_error * max(float(model.structure.rod_length.max(initial=0.0)), 1.0):
        return (f"unstable: the joints and supports are violated by {joint_error:.3g} m within one "
                f"step at t = {t:.6g} s (step too large, or the motion is unstable)")
    total, scale = model.energy_balance(t, y)
    energy_scale[0] = max(energy_scale[0], scale)
    if total - energy0 > max_growth * max(energy_scale[0], 1e-300):
        return (f"unstable: energy grew by {total - energy0:.3g} J (scale {energy_scale[0]:.3g} J)"
                f" at t = {t:.6g} s")
    return None


def _progress_bar(t0: float, t_end: float):
    from tqdm import tqdm

    return tqdm(total=t_end - t0, unit="s", unit_scale=False, desc="simulating",
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.3g}/{total:.3g} s [{elapsed}<{remaining}]")


def _result(structure, recorder, status, message, integrator, counts, max_length_error,
            max_joint_error, wall_time, settings) -> SimulationResult:
    r = recorder.rows
    n = structure.n_coordinates
    y = np.array(r["y"])
    energy = np.array(r["energy"])
    names = ("kinetic", "elastic", "gravity", "dissipated", "external_work", "control_work")
    return SimulationResult(
        structure=structure,
        t=np.array(r["t"]),
        q=y[:, :n],
        qdot=y[:, n : 2 * n],
        node_position=np.array(r["p"]),
        node_velocity=np.array(r["v"]),
        tendon_length=np.array(r["length"]),
        tendon_tension=np.array(r["tension"]),
        energy={name: energy[:, k] for k, name in enumerate(names)},
        residual_acceleration=np.array(r["accel"]),
        status=status,
        message=message,
        nfev=integrator.total_nfev,
        max_rod_length_error=max_length_error,
        max_constraint_error=max_joint_error,
        wall_time=wall_time,
        settings=settings,
        **counts,
    )
