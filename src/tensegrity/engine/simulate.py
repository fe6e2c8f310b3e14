"""Simulation of a structure (eq. 18.60): :func:`simulate` runs the engine
(:func:`tensegrity.engine.run`: compiled integration, slack-switch location, constraint
projection, energy bookkeeping, blow-up detection, steady-state stop) and returns the samples in
memory as a :class:`SimulationResult`.

The ODE state is ``y = [q, q', E_d, W_w, W_u]``: coordinates and rates followed by the energy
dissipated by damping, the work of the external forces ``w`` and the work of the control ``u``
(rest-length changes), all integrated with the motion so that the energy balance
``E_kin + E_el + E_grav + E_d - W_w - W_u = E(0)`` can be checked at every step.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.engine.feedback import LinearFeedback
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.options import DEFAULT_MAX_SAMPLES, DEFAULT_MAX_STEPS, Options
from tensegrity.engine.result import (
    STATUS_END,
    STATUS_FAILED,
    STATUS_STEADY,
    STATUS_STOPPED,
    MemorySink,
    SimulationResult,
)
from tensegrity.model.actuators import Actuators
from tensegrity.model.ground import Plane
from tensegrity.model.structure import Structure, require_structure
from tensegrity.physics.dynamics import State

if TYPE_CHECKING:
    from tensegrity.engine.loop import Controller, StopCondition

__all__ = [
    "STATUS_END",
    "STATUS_FAILED",
    "STATUS_STEADY",
    "STATUS_STOPPED",
    "SimulationResult",
    "options_and_inputs",
    "simulate",
]

TimeFunction = Callable[[float], np.ndarray]


def simulate(
    structure: Structure,
    t_span: tuple[float, float],
    *,
    initial: State | None = None,
    control: np.ndarray | TimeFunction | None = None,
    external_force: np.ndarray | TimeFunction | None = None,
    gravity: np.ndarray | None = None,
    ground: Plane | Sequence[Plane] | None = None,
    contact_radius: float = 0.0,
    controller: Controller | LinearFeedback | None = None,
    actuators: Actuators | None = None,
    stop: StopCondition | None = None,
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
    max_steps: int = DEFAULT_MAX_STEPS,
    max_samples: int = DEFAULT_MAX_SAMPLES,
    max_wall_time: float = math.inf,
    progress: bool = False,
    sensitivity: Sequence[Any] | None = None,
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
    ground : Plane or sequence of Plane, optional
        Rigid planes the rods' ends touch (:class:`tensegrity.model.ground.Plane`, e.g.
        ``ground()`` for ``z = 0``): a compliant normal law and Coulomb friction with exact
        sticking, onset, lift-off, stick and slip located as events (adaptive methods, a
        structure of rods and tendons).
    contact_radius : float
        Radius [m] of the rods' ends as contact points (spheres); default 0.
    controller : Controller, optional
        State feedback ``u = controller(t, q, qdot)`` held for ``controller.period`` [s] from
        ``t0`` on (zero-order hold; :class:`tensegrity.engine.loop.Feedback` makes one of a
        function); instead of ``control``.  Steps end at its update times.  A
        :class:`~tensegrity.engine.feedback.LinearFeedback` (``u = u_ref - K (y - y_ref)``) runs
        inside the compiled loop, with no Python call per update (DOP853; the other methods
        stop at its updates).  The commands held are in ``control_time``,
        ``control_command`` and ``control_applied`` of the result.
    actuators : Actuators, optional
        The actuated tendons (:func:`tensegrity.model.actuators.actuators`): a controller's
        commands go through their rest-length bounds, rate limits and lags; without them a
        command is held at once, only kept from making a rest length negative.
    stop : StopCondition, optional
        Called with every sample (a :class:`~tensegrity.engine.result.Samples` block of one
        row); the run stops at the first for which it returns a reason (a sentence), with
        status 2 and the message ``"stopped at t = ... s: <reason>"``; e.g.
        :func:`tensegrity.design.utilisation.stop_at_failure` for members over their limits.
    method : str
        An adaptive ``scipy.integrate`` method (``"DOP853"``, ``"RK45"``, ``"Radau"``, ...) with
        ``rtol``, ``atol``; or ``"rk4"``, fixed step ``dt`` [s].
    sample_dt : float, optional
        Output spacing [s]; default ``(t_end - t0) / 1000``.  The last sample is where the run
        ended.
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
    max_steps, max_samples : int
        Limits checked before work: a run that would take more than ``max_steps`` fixed steps
        (``"rk4"``) or make more than ``max_samples`` samples is refused (``ValueError`` naming
        the option); an adaptive run stops (status -1) once it has taken ``max_steps`` steps
        short of its end (defaults 10,000,000 each).
    max_wall_time : float
        A budget of wall-clock time [s]: a run still going after it stops (status -1, the
        message says where it stood), its samples so far kept.  Default: none.
    sensitivity : sequence of parameters, optional
        Integrate the derivatives of the trajectory with respect to these (each with a
        ``kind`` and ``members``, e.g. :func:`tensegrity.analysis.identification.parameter`'s;
        :func:`tensegrity.engine.sensitivity.prepare`) with the state, through the located
        events (:mod:`tensegrity.engine.sensitivity`); the result's ``q_sensitivity`` and
        ``qdot_sensitivity``.  DOP853 only, without a controller or actuators.

    Returns
    -------
    SimulationResult
        With ``status`` (-1 failed, 0 end reached, 1 steady state, 2 stopped by ``stop``) and
        ``message``.  A failed run keeps its samples up to the failure.
    """
    options, inputs = options_and_inputs(
        structure,
        control=control,
        external_force=external_force,
        gravity=gravity,
        ground=ground,
        contact_radius=contact_radius,
        actuators=actuators,
        method=method,
        rtol=rtol,
        atol=atol,
        dt=dt,
        sample_dt=sample_dt,
        locate_switches=locate_switches,
        steady_state=steady_state,
        velocity_tol=velocity_tol,
        acceleration_tol=acceleration_tol,
        projection_tol=projection_tol,
        max_rod_length_error=max_rod_length_error,
        max_energy_growth=max_energy_growth,
        max_steps=max_steps,
        max_samples=max_samples,
        max_wall_time=max_wall_time,
    )
    from tensegrity.engine.loop import run, time_span  # (compiled code: numba loads on use)

    sink = MemorySink()
    bar = ProgressBar(*time_span(t_span)) if progress else None
    try:
        summary = run(
            structure,
            t_span,
            initial=initial,
            inputs=inputs,
            options=options,
            sink=sink,
            progress=bar,
            controller=controller,
            stop=stop,
            sensitivity=sensitivity,
        )
    finally:
        if bar is not None:
            bar.close()
    return sink.result(structure, summary)


def options_and_inputs(
    structure: Structure,
    *,
    control: Any = None,
    external_force: Any = None,
    gravity: Any = None,
    ground: Any = None,
    contact_radius: Any = 0.0,
    actuators: Actuators | None = None,
    **options: Any,
) -> tuple[Options, Inputs]:
    """:func:`simulate`'s keyword options as the engine takes them: the :class:`Options` of the
    run and its :class:`Inputs` (``TypeError`` names an unknown option, or ``structure`` if it
    is not a :class:`Structure`)."""
    require_structure(structure)
    unknown = sorted(set(options) - {f.name for f in dataclasses.fields(Options)})
    if unknown:
        raise TypeError(f"unknown option {unknown[0]!r}")
    return Options(**options), Inputs(
        structure,
        control=control,
        external_force=external_force,
        gravity=gravity,
        ground=ground,
        contact_radius=contact_radius,
        actuators=actuators,
    )


class ProgressBar:
    """A ``tqdm`` bar over simulated time, called with the time reached."""

    def __init__(self, t0: float, t_end: float) -> None:
        from tqdm import tqdm

        self.t0 = float(t0)
        self.bar = tqdm(
            total=float(t_end) - self.t0,
            unit="s",
            unit_scale=False,
            desc="simulating",
            bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.3g}/{total:.3g} s "
            "[{elapsed}<{remaining}]",
        )

    def __call__(self, t: float) -> None:
        self.bar.update(t - self.t0 - self.bar.n)

    def close(self) -> None:
        self.bar.close()
