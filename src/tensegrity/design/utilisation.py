"""Member utilisation: how close each member is to failing, at a state or over a run.

For the materials and sections of :func:`tensegrity.design.materials.member_properties`:

- a tendon's stress ``sigma = T / A`` against its yield strength divided by a strength factor
  ``s`` (``sigma / (sigma_y / s)``) and its ultimate strength (``sigma / sigma_u``, > 1: it
  breaks; not divided by ``s``: the raw ratio to breaking); a tendon with ``T = 0`` is slack;
- a rod's axial force ``C`` (> 0 compressed) against yield (``|C| / (A sigma_y / s)``) and, in
  compression, against the Euler load of a pinned-pinned bar divided by a safety factor
  ``gamma``: ``C / (pi^2 E I / (gamma L^2))``.

``gamma`` and ``s`` (each >= 1, default 1) are those of the sizing
(:func:`~tensegrity.design.sizing.size_members`): a member sized to its limit has utilisation 1.

A member *fails* when a utilisation exceeds 1.  The rods' axial forces are those the library
computes everywhere (:func:`tensegrity.analysis.statics.rod_compression`): half the difference of
the axial nodal forces on the rod's two ends, the forces of joints and supports included.  In
motion, the compression at a rigid rod's middle is less than that by the centrifugal part
``m omega^2 L / 8`` (``omega`` the rod's rate of turn), which is not subtracted: the
utilisation of a spinning rod errs on the safe side.  Lumped gravity (half the weight at each
end) adds nothing to it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from tensegrity.analysis.statics import nodal_forces, rod_compression
from tensegrity.design.materials import MemberProperties, check_factor
from tensegrity.model.structure import Structure
from tensegrity.physics.constraints import constraints_of
from tensegrity.physics.coordinates import force_response, nodes_from_coordinates, rod_coordinates
from tensegrity.physics.dynamics import tendon_vectors

if TYPE_CHECKING:
    from tensegrity.engine.result import Samples, SimulationResult

__all__ = [
    "Peak",
    "RunUtilisation",
    "TrajectoryUtilisation",
    "Utilisation",
    "euler_load",
    "failures",
    "peak",
    "rod_axial_forces",
    "run_utilisation",
    "stop_at_failure",
    "trajectory_utilisation",
    "utilisation",
]


class Utilisation(NamedTuple):
    """Utilisation of every member; arrays (..., S) for tendons and (..., R) for rods, with the
    leading axes of the forces given (e.g. samples)."""

    tendon_stress: np.ndarray  #: ``T / A`` [Pa]
    tendon_yield: np.ndarray  #: ``sigma / (sigma_y / s)``
    tendon_ultimate: np.ndarray  #: ``sigma / sigma_u``
    slack: np.ndarray  #: bool, ``T <= 0``
    rod_compression: np.ndarray  #: ``C`` [N], > 0 compressed
    rod_stress: np.ndarray  #: ``C / A`` [Pa], > 0 compressed
    rod_yield: np.ndarray  #: ``|C| / (A sigma_y / s)``
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
    ``pi^2 E I / L^2`` divided by ``safety_factor`` (>= 1)."""
    safety_factor = check_factor(safety_factor, "safety_factor")
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
    strength_factor: float = 1.0,
) -> Utilisation:
    """Utilisation of the members under tendon tensions (..., S) [N] and rod compressions
    (..., R) [N] (> 0 compressed), e.g. an equilibrium's ``tension`` and ``rod_compression``
    (:class:`~tensegrity.analysis.equilibrium.EquilibriumResult`), or a run's samples
    (:func:`run_utilisation`).  ``safety_factor`` (>= 1) divides the Euler load,
    ``strength_factor`` (>= 1) the yield strengths of rods and tendons (not the tendons'
    ultimate strength)."""
    strength = check_factor(strength_factor, "strength_factor")
    T = np.asarray(tension, dtype=float)
    C = np.asarray(compression, dtype=float)
    stress = T / members.tendon_area
    rod_stress = C / members.rod_area
    return Utilisation(
        tendon_stress=stress,
        tendon_yield=strength * stress / members.tendon_yield,
        tendon_ultimate=stress / members.tendon_ultimate,
        slack=T <= 0,
        rod_compression=C,
        rod_stress=rod_stress,
        rod_yield=strength * np.abs(rod_stress) / members.rod_yield,
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


def _forces_at(
    external_force: np.ndarray | Callable[[float], np.ndarray] | None,
) -> Callable[[float], np.ndarray | None]:
    """``external_force`` (constant, a function of time or None) as a function of time."""

    def at(t: float) -> np.ndarray | None:
        if external_force is None or not callable(external_force):
            return external_force
        return np.asarray(external_force(t), dtype=float)

    return at


def stop_at_failure(
    structure: Structure,
    members: MemberProperties,
    *,
    safety_factor: float = 1.0,
    strength_factor: float = 1.0,
    external_force: np.ndarray | Callable[[float], np.ndarray] | None = None,
    gravity: np.ndarray | None = None,
) -> Callable[[Samples], str | None]:
    """A stop condition for :func:`tensegrity.simulate` (``stop=``): the run stops at the first
    sample where a member's utilisation exceeds 1 (:func:`utilisation` of the sample's
    tensions and of :func:`rod_axial_forces`), the reason naming the member with the largest.
    ``external_force`` (N, dim) [N] (or ``w(t)``) and ``gravity`` (dim,) [m/s^2]: the run's,
    for the rods' forces; ``safety_factor`` and ``strength_factor``: :func:`utilisation`'s."""
    factors = {
        name: check_factor(value, name)
        for name, value in (("safety_factor", safety_factor), ("strength_factor", strength_factor))
    }
    force = _forces_at(external_force)
    g = None if gravity is None else np.asarray(gravity, dtype=float)

    def stop(sample: Samples) -> str | None:
        t, tension = float(sample.t[0]), sample.tendon_tension[0]
        compression = rod_axial_forces(
            structure, sample.q[0], tension, qdot=sample.qdot[0], external_force=force(t), gravity=g
        )
        u = utilisation(
            structure,
            members,
            tension=tension,
            compression=compression,
            **factors,
        )
        if u.largest <= 1.0:
            return None
        tendon, rod = u.tendon.max(initial=0.0), u.rod.max(initial=0.0)
        if tendon >= rod:
            name = structure.tendon_name[int(np.argmax(u.tendon))]
            return f"tendon {name!r} over its limits (utilisation {tendon:.3g}: yield)"
        r = int(np.argmax(u.rod))
        mode = "buckling" if u.rod_buckling[r] >= u.rod_yield[r] else "yield"
        return f"rod {r} over its limits (utilisation {rod:.3g}: {mode})"

    return stop


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
        return failures(structure, self)


def failures(structure: Structure, peaks: RunUtilisation | TrajectoryUtilisation) -> list[str]:
    """One line per member of ``structure`` whose peak utilisation (``peaks``) exceeded 1, with
    its time."""
    lines = [
        f"tendon {structure.tendon_name[s]!r}: utilisation {peaks.tendon_peak[s]:.3g} at "
        f"t = {peaks.tendon_peak_time[s]:.6g} s"
        for s in np.flatnonzero(peaks.tendon_peak > 1)
    ]
    lines += [
        f"rod {r}: utilisation {peaks.rod_peak[r]:.3g} at t = {peaks.rod_peak_time[r]:.6g} s"
        for r in np.flatnonzero(peaks.rod_peak > 1)
    ]
    return lines


def run_utilisation(
    result: SimulationResult,
    members: MemberProperties,
    *,
    safety_factor: float = 1.0,
    strength_factor: float = 1.0,
    external_force: np.ndarray | Callable[[float], np.ndarray] | None = None,
) -> RunUtilisation:
    """The utilisation of every member at every sample of a run, and each member's largest.

    Tendon stresses come from the run's recorded tensions (damping included); rod compressions
    from those tensions, the run's gravity (its ``settings``) and ``external_force`` (N, dim)
    [N] (constant, or a function ``w(t)`` such as a
    :class:`~tensegrity.model.loads.ForceTable`, as :func:`tensegrity.simulate` takes it; the
    run's own forces are not in the result: give them here), by :func:`rod_axial_forces` at
    each sample; ``safety_factor`` and ``strength_factor``: :func:`utilisation`'s.
    """
    s = result.structure
    g = result.settings.get("gravity")
    gravity = None if g is None else np.asarray(g, dtype=float)
    force = _forces_at(external_force)

    compression = np.array(
        [
            rod_axial_forces(s, q, T, qdot=qdot, external_force=force(t), gravity=gravity)
            for t, q, qdot, T in zip(
                result.t, result.q, result.qdot, result.tendon_tension, strict=True
            )
        ]
    ).reshape(len(result.t), s.n_rods)
    u = utilisation(
        s,
        members,
        tension=result.tendon_tension,
        compression=compression,
        safety_factor=safety_factor,
        strength_factor=strength_factor,
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


class Peak(NamedTuple):
    """The largest of a utilisation over members and samples: its value, the member (index)
    and the time [s]."""

    value: float
    member: int
    time: float


def peak(values: np.ndarray, t: np.ndarray) -> Peak | None:
    """The largest of ``values`` (T, M) (samples x members) at times ``t`` (T,) [s]; None
    without members or samples."""
    if values.size == 0:
        return None
    sample, member = np.unravel_index(int(np.argmax(values)), values.shape)
    return Peak(float(values[sample, member]), int(member), float(t[sample]))


#: :func:`trajectory_utilisation` finds rod forces at this many samples of a run at most.
ROD_SAMPLES = 2000
#: ... and reads at most this many bytes of tendon tensions (every sample when they fit).
TENSION_BYTES = 2**27


class TrajectoryUtilisation(NamedTuple):
    """The largest utilisation of each member over a run read from its trajectory file
    (:func:`trajectory_utilisation`): tendons from one sample in ``tendon_every``, rods from
    one in ``rod_every`` (and always the last)."""

    tendon_peak: np.ndarray  #: largest ``sigma / (sigma_y / s)`` of each tendon (S,)
    tendon_peak_time: np.ndarray  #: when (S,) [s]
    tendon_yield: Peak | None  #: the largest over tendons
    rod_peak: np.ndarray  #: largest governing utilisation of each rod (R,)
    rod_peak_time: np.ndarray  #: when (R,) [s]
    rod_yield: Peak | None  #: the largest ``|C| / (A sigma_y / s)`` over rods
    rod_buckling: Peak | None  #: the largest ``C / P_Euler`` over rods
    tendon_every: int
    rod_every: int

    @property
    def largest(self) -> float:
        """The largest utilisation of any member."""
        return float(max(self.tendon_peak.max(initial=0.0), self.rod_peak.max(initial=0.0)))

    def failures(self, structure: Structure) -> list[str]:
        """One line per member whose utilisation exceeded 1, with its peak and time."""
        return failures(structure, self)


def trajectory_utilisation(
    path: str | Path,
    members: MemberProperties,
    *,
    n_samples: int,
    safety_factor: float = 1.0,
    strength_factor: float = 1.0,
    external_force: np.ndarray | Callable[[float], np.ndarray] | None = None,
    rod_samples: int = ROD_SAMPLES,
    tension_bytes: int = TENSION_BYTES,
) -> TrajectoryUtilisation:
    """The largest utilisation of every member over the run in a trajectory file of
    ``n_samples`` samples, reading only what it needs: the tendon tensions (every sample, or
    one in k to stay within ``tension_bytes``) and, for the rods' forces (:func:`run_utilisation`,
    a solve per sample), one sample in k to stay within ``rod_samples``.  ``external_force``:
    the run's (the file does not hold it); ``safety_factor`` and ``strength_factor``:
    :func:`utilisation`'s.
    """
    from tensegrity.io.trajectory import read_dataset, read_trajectory

    run = read_trajectory(path, every=max(1, -(-n_samples // rod_samples)))
    rods = run_utilisation(
        run,
        members,
        safety_factor=safety_factor,
        strength_factor=strength_factor,
        external_force=external_force,
    )
    S = run.structure.n_tendons
    tendon_every = max(1, -(-n_samples * S * 8 // tension_bytes))
    t = read_dataset(path, "t", every=tendon_every)
    tension = read_dataset(path, "tendon_tension", every=tendon_every)
    tendon = utilisation(
        run.structure,
        members,
        tension=tension,
        compression=np.zeros((len(t), run.structure.n_rods)),
        strength_factor=strength_factor,
    ).tendon_yield
    at = np.argmax(tendon, axis=0) if S else np.zeros(0, dtype=int)
    return TrajectoryUtilisation(
        tendon_peak=np.max(tendon, axis=0, initial=0.0),
        tendon_peak_time=t[at],
        tendon_yield=peak(tendon, t),
        rod_peak=rods.rod_peak,
        rod_peak_time=rods.rod_peak_time,
        rod_yield=peak(rods.samples.rod_yield, rods.t),
        rod_buckling=peak(rods.samples.rod_buckling, rods.t),
        tendon_every=tendon_every,
        rod_every=max(1, -(-n_samples // rod_samples)),
    )
