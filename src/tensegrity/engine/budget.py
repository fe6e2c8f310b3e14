"""What a run will cost, estimated before it starts from the structure alone (docs/simulation.md,
"Stiff structures"): the structure's highest rate (:func:`highest_rate`), the round-off floor of
its accelerations (:func:`acceleration_floor`), and from them the fewest steps an explicit method
needs and about how long they take (:func:`estimate`).

The constants are fitted to runs on the project's 2-core machine (2026-11-27, the numbers in
docs/simulation.md): the estimate is a lower bound on the steps (a run refused for it could not
have ended within its budget), the time a rough guide.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from tensegrity.engine.options import COMPILED_ADAPTIVE_METHODS, FIXED_STEP_METHODS, Options
from tensegrity.model.structure import Structure
from tensegrity.physics.coordinates import rod_damping_rates
from tensegrity.physics.dynamics import elastic_tensions, tendon_lengths

#: Explicit adaptive methods take at least this many steps per radian of the highest rate
#: (``t_end * highest_rate``): the fewest measured, DOP853 on an undamped prism at rest (0.32;
#: a damped shell settling 1.5, RK45 1.4, RK23 1.05, an undamped shell 16).
STEPS_PER_RADIAN = 0.3
#: ``"rk4"`` with ``dt * highest_rate`` above this is unstable (measured: 1.65 for an undamped
#: prism at rest, 0.3-0.5 for damped shells and prisms in motion).
RK4_STABLE = 2.0
#: ... and a step below this over it is suggested instead (a damped (3,1) shell fails at 0.3).
RK4_SAFE = 0.2
#: The residual accelerations of a run at rest stay at about this times
#: :func:`acceleration_floor` (measured 1.8-2.3); a steady-state run whose floor exceeds its
#: ``acceleration_tol`` cannot come to rest.
FLOOR_FACTOR = 2.3
#: At rest an adaptive step is at most about this times ``atol`` over
#: :func:`acceleration_floor` [s] (DOP853, (3,1) shells of 1e10-1e12 N/m: 0.66-0.75).
NOISE_STEP = 0.7
#: Seconds of one step [s]: a part per step and a part per member (rod or tendon), per method
#: (DOP853: 24 us at the (3,1) shell's 30 members, 435 us at the (10,10) shell's 1,180; rk4:
#: 4.5 and 44 us; scipy's methods step in Python: 90-430 us at (3,1)).
STEP_SECONDS = {"DOP853": (14e-6, 0.36e-6), "rk4": (4.2e-6, 0.034e-6)}
SCIPY_STEP_SECONDS = (150e-6, 0.36e-6)


@dataclasses.dataclass(frozen=True)
class RunEstimate:
    """The cost of a run, estimated before it starts.

    Attributes
    ----------
    least_steps : the fewest steps the run can take (a lower bound; ``"rk4"``: its steps).
    steps : about how many it takes: at rest, an adaptive run's steps are bound by the
        round-off of its accelerations against ``atol`` (:data:`NOISE_STEP`).
    step_seconds : about how long one step takes [s].
    rate : the structure's highest rate [1/s] (:func:`highest_rate`).
    settles : True if a steady-state run may come to rest before its end (then ``steps`` and
        ``least_steps`` bound a run that may stop much earlier).
    stable : False if ``"rk4"``'s ``dt`` is beyond its stability limit (the run blows up).
    """

    least_steps: float
    steps: float
    step_seconds: float
    rate: float
    settles: bool = False
    stable: bool = True

    @property
    def safe_dt(self) -> float:
        """A ``"rk4"`` step [s] well within the stability limit (:data:`RK4_SAFE`)."""
        return RK4_SAFE / self.rate


def _tendon_masses(structure: Structure) -> np.ndarray:
    """The reduced mass [kg] of each tendon's end nodes, shape (S,): ``m_a m_b / (m_a + m_b)``,
    the other end's mass for a tendon to an anchor (a massless node)."""
    m = structure.node_mass[structure.tendon_nodes]
    ma, mb = m[:, 0], m[:, 1]
    total = ma + mb
    both = np.divide(ma * mb, total, out=np.zeros_like(ma), where=(ma > 0) & (mb > 0))
    return np.where(ma == 0, mb, np.where(mb == 0, ma, both))


def highest_rate(structure: Structure) -> float:
    """A bound of the structure's highest rate [1/s] (angular frequency, or decay rate).

    Per tendon: ``sqrt(k / mu)``, ``mu`` the reduced mass of its end nodes (half a rod's mass
    each, or a point mass; an anchor infinitely heavy), or with its damping ``c`` beyond
    critical the overdamped rate ``(c + sqrt(c^2 - 4 k mu)) / (2 mu)``; per rod its
    mass-proportional damping rates (to ground and relative to the rigid-body motion).  The
    largest of these (0 for a structure with neither).
    Rods are rigid and tendons the only elastic members, so this is cheap; the true highest
    rate is within a small factor of it (several tendons at a node, the rods' rotation), which
    the constants of :func:`estimate` absorb.
    """
    mu = _tendon_masses(structure)
    k, c = structure.tendon_stiffness, structure.tendon_damping
    moving = mu > 0
    k, c, mu = k[moving], c[moving], mu[moving]
    over = c * c > 4 * k * mu
    rate = np.where(
        over,
        (c + np.sqrt(np.maximum(c * c - 4 * k * mu, 0.0))) / (2 * np.where(over, mu, 1.0)),
        np.sqrt(k / mu),
    )
    return float(max(rate.max(initial=0.0), _rod_rates(structure).max(initial=0.0)))


def _rod_rates(structure: Structure) -> np.ndarray:
    """Each rod's damping rate [1/s] (R,), to ground plus relative to the rigid motion."""
    alpha, beta = rod_damping_rates(structure)
    return alpha + beta


def acceleration_floor(structure: Structure) -> float:
    """The round-off of the nodes' accelerations [m/s^2] in the structure's initial state: the
    largest initial tendon tension over the lightest moving node, times the machine epsilon.
    At rest a run's residual accelerations stay near :data:`FLOOR_FACTOR` times this."""
    tension = elastic_tensions(structure, tendon_lengths(structure, structure.node_position))
    mass = structure.node_mass[structure.node_mass > 0]
    if not (tension.size and mass.size):
        return 0.0
    return float(np.finfo(float).eps * tension.max() / mass.min())


def estimate(
    structure: Structure,
    t_end: float,
    *,
    method: str = Options.method,
    dt: float | None = None,
    atol: float = Options.atol,
    steady_state: bool = False,
    acceleration_tol: float = Options.acceleration_tol,
) -> RunEstimate | None:
    """The steps a run of ``structure`` from 0 to ``t_end`` [s] takes, about how long one takes,
    and (``"rk4"``) whether its ``dt`` [s] is stable; None for an implicit method (its steps
    are not bound by the highest rate).

    Explicit adaptive methods take at least ``t_end * highest_rate * STEPS_PER_RADIAN`` steps;
    a damped structure comes to rest, where its steps are bound by the round-off of its
    accelerations: ``t_end * acceleration_floor / (NOISE_STEP * atol)`` (``atol`` the absolute
    tolerance).  ``"rk4"``: ``t_end / dt`` steps, stable while ``dt * highest_rate <=
    RK4_STABLE``.  A steady-state run ``settles`` if its :func:`acceleration_floor` times
    :data:`FLOOR_FACTOR` is below ``acceleration_tol`` [m/s^2].
    """
    if method not in (*COMPILED_ADAPTIVE_METHODS, "RK45", "RK23", *FIXED_STEP_METHODS):
        return None
    rate = highest_rate(structure)
    floor = acceleration_floor(structure)
    fixed, per_member = STEP_SECONDS.get(method, SCIPY_STEP_SECONDS)
    step_seconds = fixed + per_member * (structure.n_rods + structure.n_tendons)
    settles = steady_state and floor * FLOOR_FACTOR < acceleration_tol
    if method in FIXED_STEP_METHODS:
        assert dt is not None, "a fixed-step method needs dt"
        steps = math.ceil(t_end / dt - 1e-9)
        return RunEstimate(
            steps,
            steps,
            step_seconds,
            rate,
            settles,
            stable=dt * rate <= RK4_STABLE,
        )
    least = t_end * rate * STEPS_PER_RADIAN
    damped = bool(np.any(structure.tendon_damping > 0) or np.any(_rod_rates(structure) > 0))
    at_rest = t_end * floor / (NOISE_STEP * atol) if damped else 0.0
    return RunEstimate(least, max(least, at_rest), step_seconds, rate, settles)
