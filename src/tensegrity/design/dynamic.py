"""The dynamic check: a structure under each load case applied suddenly (``docs/design.md``).

A static design (:func:`~tensegrity.design.sizing.size_members`) keeps every member within its
limits when the loads are applied slowly.  Applied suddenly -- a step load from rest at the
prestressed equilibrium -- a linear undamped system overshoots to twice its static response,
and a member sized to a utilisation of 1 reaches about 2.  :func:`dynamic_check` simulates the
structure under each load case from ``t = 0`` (:func:`tensegrity.simulate`, the case's nodal
forces and gravity held constant from the start) and computes
:func:`~tensegrity.design.utilisation.run_utilisation` over the run: the largest utilisation of
each member in motion, and whether any member exceeds its limits.

Damping: each tendon gets ``damping_ratio`` (default 2 %) of the critical damping of its own
axial vibration, ``c = zeta 2 sqrt(k mu)`` [N s/m] (``mu`` the reduced mass of its ends, as
:func:`tensegrity.physics.dynamics.artificial_damping` defines it), and the rods none (no damping
to ground).  The structure's own damping is replaced.  A few per cent of critical is typical of
bolted and cable structures; 0 gives the undamped bound.

Duration: ``periods`` (default 5) times the longest period of the structure's vibration modes at
the prestressed equilibrium (:func:`tensegrity.analysis.modes.modal_analysis`; modes of zero
frequency, rigid-body motions and unstiffened mechanisms, left out), sampled at a twentieth of
the shortest period (at most ``max_samples`` samples): the first overshoot, at half a period of
the modes the load excites, is inside the run.  A member's peak between two samples is missed
by at most the change over a twentieth of a period (about 1 % of the swing).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import modal_analysis
from tensegrity.design.materials import MemberProperties
from tensegrity.design.sizing import LoadCase
from tensegrity.design.utilisation import RunUtilisation, run_utilisation
from tensegrity.engine.simulate import simulate
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import artificial_damping

__all__ = ["DAMPING_RATIO", "DynamicCase", "dynamic_check", "suddenly_loaded"]

#: Default fraction of each tendon's critical damping.
DAMPING_RATIO = 0.02


class DynamicCase(NamedTuple):
    """One load case applied suddenly: its run's utilisation and how it was run."""

    name: str
    utilisation: RunUtilisation  #: every sample's and each member's largest, and when
    duration: float  #: [s]
    sample_dt: float  #: [s]
    message: str  #: how the run ended

    @property
    def largest(self) -> float:
        """The largest utilisation of any member in motion."""
        return self.utilisation.largest

    @property
    def fails(self) -> bool:
        """Whether a member exceeds its limits (a utilisation above 1) at some sample."""
        return self.largest > 1.0


def suddenly_loaded(structure: Structure, *, damping_ratio: float = DAMPING_RATIO) -> Structure:
    """``structure`` with the dynamic check's damping: ``damping_ratio`` of each tendon's
    critical damping (module docstring), no rod damping."""
    if not (math.isfinite(damping_ratio) and 0 <= damping_ratio < 1):
        raise ValueError(f"damping_ratio: must be in [0, 1), got {damping_ratio!r}")
    critical = artificial_damping(structure)
    return structure.replace(
        tendon_damping=damping_ratio * critical.tendon_damping,
        rod_damping=np.zeros(structure.n_rods),
    )


def _periods(structure: Structure) -> tuple[float, float]:
    """The longest and shortest periods [s] of ``structure``'s modes of nonzero frequency at its
    node positions (taken as the equilibrium)."""
    modes = modal_analysis(linearize(structure))
    omega2 = modes.omega_squared[modes.omega_squared > modes.zero_tol]
    if not omega2.size:
        raise ValueError("structure: no mode of nonzero frequency (nothing holds it)")
    return 2 * math.pi / math.sqrt(float(omega2.min())), 2 * math.pi / math.sqrt(
        float(omega2.max())
    )


def dynamic_check(
    structure: Structure,
    members: MemberProperties,
    load_cases: Sequence[LoadCase],
    *,
    damping_ratio: float = DAMPING_RATIO,
    periods: float = 5.0,
    duration: float | None = None,
    sample_dt: float | None = None,
    max_samples: int = 20_000,
    safety_factor: float = 1.0,
    strength_factor: float = 1.0,
) -> list[DynamicCase]:
    """Simulate ``structure`` (e.g. :attr:`Sizing.structure`: its geometry the prestressed
    equilibrium) from rest under each load case applied at ``t = 0`` and held, and compute the
    members' utilisation over each run.

    Parameters
    ----------
    structure : Structure
        At rest at its node positions without load; its damping is replaced (module docstring).
    members : MemberProperties
        Its members' materials and sections (:attr:`Sizing.members`).
    load_cases : sequence of LoadCase
        Nodal forces (N, dim) [N] and gravity (dim,) [m/s^2] of each case.
    damping_ratio : float
        Fraction of each tendon's critical damping, in [0, 1).
    periods : float
        The run's duration in longest periods of the structure's modes (unless ``duration``).
    duration, sample_dt : float, optional
        The run's duration and sample spacing [s]; default from the modes (module docstring).
    max_samples : int
        The most samples a run keeps (``sample_dt`` is raised to stay within it).
    safety_factor : float
        Divides the Euler load (>= 1).
    strength_factor : float
        Divides the yield strengths (>= 1): the sizing's, so that a member sized to its limit
        has a static utilisation of 1.

    Returns
    -------
    list of DynamicCase
        One per load case, in order.

    Raises
    ------
    ValueError
        A bad argument, a structure without rods or tendons (the damping is scaled with both),
        or one that nothing holds.
    """
    damped = suddenly_loaded(structure, damping_ratio=damping_ratio)
    if duration is None or sample_dt is None:
        longest, shortest = _periods(structure)
        duration = periods * longest if duration is None else duration
        sample_dt = shortest / 20 if sample_dt is None else sample_dt
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration: must be > 0, got {duration!r}")
    sample_dt = max(sample_dt, duration / max_samples)
    out = []
    for case in load_cases:
        force = None if case.force is None else np.asarray(case.force, dtype=float)
        gravity = None if case.gravity is None else np.asarray(case.gravity, dtype=float)
        result = simulate(
            damped,
            (0.0, duration),
            external_force=force,
            gravity=gravity,
            sample_dt=sample_dt,
        )
        if not result.success:
            raise ValueError(f"load case {case.name!r}: the run failed: {result.message}")
        u = run_utilisation(
            result,
            members,
            safety_factor=safety_factor,
            strength_factor=strength_factor,
            external_force=force,
        )
        out.append(DynamicCase(case.name, u, duration, sample_dt, result.message))
    return out
