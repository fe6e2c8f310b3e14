"""Member utilisation: how close each member is to failing, at a state or over a run.

For the materials and sections of :func:`tensegrity.design.materials.member_properties`:

- a tendon's stress ``sigma = T / A`` against its yield strength (``sigma / sigma_y``) and its
  ultimate strength (``sigma / sigma_u``, > 1: it breaks); a tendon with ``T = 0`` is slack;
- a rod's axial force ``C`` (> 0 compressed) against yield (``|C| / (A sigma_y)``) and, in
  compression, against the Euler load of a pinned-pinned bar divided by a safety factor
  ``gamma``: ``C / (pi^2 E I / (gamma L^2))``.

A member *fails* when a utilisation exceeds 1.  The rods' axial forces are those the library
computes everywhere (:func:`tensegrity.analysis.statics.rod_compression`): half the difference of
the axial nodal forces on the rod's two ends, the forces of joints and supports included.  In
motion, the compression at a rigid rod's middle is less than that by the centrifugal part
``m omega^2 L / 8`` (``omega`` the rod's rate of turn), which is not subtracted: the
utilisation of a spinning rod errs on the safe side.  Lumped gravity (half the weight at each
end) adds nothing to it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from tensegrity.analysis.statics import nodal_forces, rod_compression
from tensegrity.design.materials import MemberProperties
from tensegrity.model.structure import Structure
from tensegrity.physics.constraints import constraints_of
from tensegrity.physics.coordinates import force_response, nodes_from_coordinates, rod_coordinates
from tensegrity.physics.dynamics import tendon_vectors

if TYPE_CHECKING:
    from tensegrity.engine.result import SimulationResult

__all__ = [
    "RunUtilisation",
    "Utilisation",
    "euler_load",
    "rod_axial_forces",
    "run_utilisation",
    "utilisation",
]


class Utilisation(NamedTuple):
    """Utilisation of every member; arrays (..., S) for tendons and (..., R) for rods, with the
    leading axes of the forces given (e.g. samples)."""

    tendon_stress: np.ndarray  #: ``T / A`` [Pa]
    tendon_yield: np.ndarray  #: ``sigma / sigma_y``
    tendon_ultimate: np.ndarray  #: ``sigma / sigma_u``
    slack: np.ndarray  #: bool, ``T <= 0``
    rod_compression: np.ndarray  #: ``C`` [N], > 0 compressed
    rod_stress: np.ndarray  #: ``C / A`` [Pa], > 0 compressed
    rod_yield: np.ndarray  #: ``|C| / (A sigma_y)``
    rod_buckling: np.ndarray  #: ``max(C, 0) / (pi^2 E I / (gamma L^2))``

    @property
    def tendon(self) -> np.ndarray:
        """The governing utilisation of each tendon: yield (..., S)."""
        return self.tendon_yield

    @property
    def rod(self) -> np.ndarray:
        """The governing utilisation of each rod: the larger of yield and buckling (..., R)."""
        return np.maximum(self.rod_yield, self.rod_buckling)

    @property
    def largest(self) -> float:
        """The largest utilisation of any member (0 without members)."""
        return float(max(self.tendon.max(initial=0.0), self.rod.max(initial=0.0)))


def euler_load(
    structure: Structure, members: MemberProperties, *, safety_factor: float = 1.0
) -> np.ndarray:
    """Allowed compression of each rod (R,) [N]: the pinned-pinned Euler load
    ``pi^2 E I / L^2`` divided by ``safety_factor``."""
    if not safety_factor >= 1.0:
        raise ValueError(f"safety_factor: must be >= 1, got {safety_factor!r}")
    return np.asarray(
        np.pi**2
        * members.rod_modulus
        * members.rod_second_moment
        / (safety_factor * structure.rod_length**2)
    )


def utilisation(
    structure: Structure,
    members: MemberProperties,
    *,
    tension: np.ndarray,
    compression: np.ndarray,
    safety_factor: float = 1.0,
) -> Utilisation:
    """Utilisation of the members under tendon tensions (..., S) [N] and rod compressions
    (..., R) [N] (> 0 compressed), e.g. an equilibrium's ``tension`` and ``rod_compression``
    (:class:`~tensegrity.analysis.equilibrium.EquilibriumResult`), or a run's samples
    (:func:`run_utilisation`).  ``safety_factor`` (>= 1) divides the Euler load."""
    T = np.asarray(tension, dtype=float)
    C = np.asarray(compression, dtype=float)
    stress = T / members.tendon_area
    rod_stress = C / members.rod_area
    return Utilisation(
        tendon_stress=stress,
        tendon_yield=stress / members.tendon_yield,
        tendon_ultimate=stress / members.tendon_ultimate,
        slack=T <= 0,
        rod_compression=C,
        rod_stress=rod_stress,
        rod_yield=np.abs(rod_stress) / members.rod_yield,
        rod_buckling=np.maximum(C, 0.0)
        / euler_load(structure, members, safety_factor=safety_factor),
    )


def rod_axial_forces(
    structure: Structure,
    q: np.ndarray,
    tension: np.ndarray,
    *,
    qdot: np.ndarray | None = None,
    external_force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
) -> np.ndarray:
    """Axial compression of each rod (R,) [N] (> 0 compressed) at coordinates ``q`` under
    tendon tensions (S,) [N], external nodal forces (N, dim) [N] and gravity (dim,) [m/s^2]:
    the library's
    :func:`~tensegrity.analysis.statics.rod_compression` of the nodal forces, plus the forces
    of the joints and supports there (as :func:`tensegrity.physics.dynamics.evaluate` finds
    them, from the accelerations at rates ``qdot``)."""
    p = nodes_from_coordinates(structure, q)
    t = tendon_vectors(structure, p)
    length = np.linalg.norm(t, axis=-1)
    direction = np.divide(t, length[:, None], out=np.zeros_like(t), where=length[:, None] > 0)
    force = nodal_forces(structure, p, tension, direction, external_force, gravity)
    constraints = constraints_of(structure)
    if constraints is not None:
        rates = None if qdot is None else rod_coordinates(structure, qdot)
        qddot = force_response(structure, q, force, rates=rates)
        force = force + constraints.constraint_force(q, qddot)
    rod = p[structure.rod_nodes[:, 1]] - p[structure.rod_nodes[:, 0]]
    return rod_compression(structure, force, rod / structure.rod_length[:, None])


class RunUtilisation(NamedTuple):
    """The utilisation of every member over a run (:func:`run_utilisation`)."""

    samples: Utilisation  #: at every sample, (T, S) and (T, R)
    t: np.ndarray  #: sample times (T,) [s]
    tendon_peak: np.ndarray  #: largest governing utilisation of each tendon (S,)
    tendon_peak_time: np.ndarray  #: when (S,) [s]
    rod_peak: np.ndarray  #: largest governing utilisation of each rod (R,)
    rod_peak_time: np.ndarray  #: when (R,) [s]

    @property
    def largest(self) -> float:
        """The largest utilisation of any member at any sample."""
        return float(max(self.tendon_peak.max(initial=0.0), self.rod_peak.max(initial=0.0)))

    def failures(self, structure: Structure) -> list[str]:
        """One line per member whose utilisation exceeded 1, with its peak and time."""
        lines = [
            f"tendon {structure.tendon_name[s]!r}: utilisation {self.tendon_peak[s]:.3g} at "
            f"t = {self.tendon_peak_time[s]:.6g} s"
            for s in np.flatnonzero(self.tendon_peak > 1)
        ]
        lines += [
            f"rod {r}: utilisation {self.rod_peak[r]:.3g} at t = {self.rod_peak_time[r]:.6g} s"
            for r in np.flatnonzero(self.rod_peak > 1)
        ]
        return lines


def run_utilisation(
    result: SimulationResult,
    members: MemberProperties,
    *,
    safety_factor: float = 1.0,
    external_force: np.ndarray | None = None,
) -> RunUtilisation:
    """The utilisation of every member at every sample of a run, and each member's largest.

    Tendon stresses come from the run's recorded tensions (damping included); rod compressions
    from those tensions, the run's gravity (its ``settings``) and ``external_force`` (N, dim)
    [N] (constant; the run's own forces are not in the result: give them here), by
    :func:`rod_axial_forces` at each sample.
    """
    s = result.structure
    g = result.settings.get("gravity")
    gravity = None if g is None else np.asarray(g, dtype=float)
    compression = np.array(
        [
            rod_axial_forces(s, q, T, qdot=qdot, external_force=external_force, gravity=gravity)
            for q, qdot, T in zip(result.q, result.qdot, result.tendon_tension, strict=True)
        ]
    ).reshape(len(result.t), s.n_rods)
    u = utilisation(
        s,
        members,
        tension=result.tendon_tension,
        compression=compression,
        safety_factor=safety_factor,
    )
    tendon_at, rod_at = np.argmax(u.tendon, axis=0), np.argmax(u.rod, axis=0)
    return RunUtilisation(
        samples=u,
        t=result.t,
        tendon_peak=np.max(u.tendon, axis=0, initial=0.0),
        tendon_peak_time=result.t[tendon_at],
        rod_peak=np.max(u.rod, axis=0, initial=0.0),
        rod_peak_time=result.t[rod_at],
    )
