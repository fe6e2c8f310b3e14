"""The least mass at the loaded equilibrium (``docs/design.md``, "Least mass").

The fully stressed design of :func:`~tensegrity.design.loaded.size_at_equilibrium` meets every
limit, and for a statically determinate structure it is the lightest.  For a statically
indeterminate one it is not: a lighter tendon sheds force to its neighbours, and a limit on
the displacement, the frequency or the stability is met by a uniform stiffening where a few
members would do.  :func:`lighten` starts from a design that meets every limit and finds a
local minimum of the mass by SLSQP (``scipy.optimize.minimize``) on the logarithms of the areas:

1. At given areas, each load case's equilibria along its load path (the load factors
   :data:`PATH`, each solved from the last, as :func:`~tensegrity.design.loaded.follow_load`
   does) and the constraints ``g(a) >= 0``, each scaled to order 1: yield and buckling of every
   member in every case; the largest displacement and the lowest natural frequency where they
   are limited; and a stability margin: at every point of every path, the lowest ``omega^2``
   (the stiffness of the softest mode, over its mass) at least ``stability_margin`` times the
   starting design's there, so that no path comes near a limit point.
2. Their derivatives with respect to the log areas, semi-analytically: the equilibria's by the
   implicit function theorem (:func:`~tensegrity.analysis.equilibrium.equilibrium_sensitivity`,
   one factorisation for all areas), the constraints' by central differences along them.
3. SLSQP from the starting design, the areas between the least the prestress needs and
   :data:`MAX_GROWTH` times their start; a trial design whose load path fails counts as
   violating every constraint.  The lightest design visited that violates no constraint by
   more than :data:`FEASIBLE` is the result.

The result is a local minimum (the problem is not convex).  A constraint met to
:data:`FEASIBLE` may still be missed by that much: the caller rounds the areas up and checks the
design afresh (:func:`~tensegrity.design.loaded.size_at_equilibrium`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np
import scipy.optimize

from tensegrity.analysis.equilibrium import (
    EquilibriumResult,
    equilibrium_sensitivity,
    find_equilibrium,
    make_result,
)
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import RIGID, modal_analysis
from tensegrity.design.sizing import LoadCase
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

__all__ = ["PATH", "Lightened", "MassProblem", "lighten"]

#: The load factors at which each load path is solved and its stability margin kept.
PATH = (0.25, 0.5, 0.75, 1.0)

#: The step [log area] of the central differences of the constraints and the residual.
STEP = 1e-6

#: The most a node may move from one path point to the next [rod lengths] (a longer jump is
#: another branch of equilibria: the design is refused).
MAX_PATH_MOVE = 0.25


@dataclasses.dataclass(frozen=True, eq=False)
class MassProblem:
    """What :func:`lighten` minimises and under which limits.

    Attributes
    ----------
    structure_at : the structure of members of areas ``a`` (R + S,) [m^2], rods first (its
        stiffness, rest lengths and masses; the geometry is the unloaded equilibrium).
    geometry : the given, unloaded structure (its node positions are the displacement's
        reference).
    loads : the load cases (not the prestress).
    strength : (R + S,) the design yield strengths [Pa] (over the strength factor).
    beta : (R,) the buckling coefficients [m^2 / sqrt(N)]: a rod's area must be at least
        ``beta sqrt(C)``.
    held : (R,) rods between two fixed nodes (no force of their own: not constrained).
    mass_per_area : (R + S,) ``rho L`` [kg/m^2]: the mass is ``mass_per_area @ a``.
    lower : (R + S,) the least areas [m^2] (the smallest area, and what the prestress needs).
    max_displacement : [m] or None.  min_frequency : [Hz] or None, under each case and, if
        ``prestressed``, in the prestressed state.
    stability_margin : the least ``omega^2`` at a path point, as a fraction of the starting
        design's.
    """

    structure_at: Callable[[np.ndarray], Structure]
    geometry: Structure
    loads: Sequence[LoadCase]
    strength: np.ndarray
    beta: np.ndarray
    held: np.ndarray
    mass_per_area: np.ndarray
    lower: np.ndarray
    max_displacement: float | None = None
    min_frequency: float | None = None
    prestressed: bool = True
    stability_margin: float = 0.25


@dataclasses.dataclass(frozen=True)
class Lightened:
    """The result of :func:`lighten`: ``area`` (R + S,) [m^2], ``mass`` [kg] (of ``area``),
    ``start_mass`` [kg], ``iterations`` (SLSQP's), ``message``, and ``active``: the limits
    other than a member's own strength that are met with equality (within
    :data:`ACTIVE_TOL`) by the search's lightest design (``"displacement"``, ``"frequency"``,
    ``"stability"``)."""

    area: np.ndarray
    mass: float
    start_mass: float
    iterations: int
    message: str
    active: tuple[str, ...]

    def summary(self) -> str:
        """One line: the masses, the iterations and how it ended."""
        return (
            f"least mass {self.start_mass:.4g} -> {self.mass:.4g} kg in {self.iterations} "
            f"iterations ({self.message})"
        )


class _PathError(Exception):
    """A load path with no stable equilibrium near it at some design."""


def _lowest_omega2(structure: Structure, eq: EquilibriumResult) -> float:
    """The lowest ``omega^2`` [1/s^2] of the modes about ``eq`` that are not rigid-body
    motions (negative: unstable)."""
    modes = modal_analysis(linearize(structure, eq))
    free = modes.omega_squared[[kind != RIGID for kind in modes.kind]]
    return float(np.min(free, initial=math.inf))


@dataclasses.dataclass(frozen=True, eq=False)
class _Design:
    """One design's structure, path equilibria (per case, per :data:`PATH` factor; the
    prestressed state first when a frequency is limited) and constraint values."""

    area: np.ndarray
    structure: Structure
    equilibria: list[list[EquilibriumResult]]
    values: np.ndarray
    kinds: tuple[str, ...]


class _Constraints:
    """The constraints of a :class:`MassProblem` (see the module docstring) and their
    derivatives, with the stability margin referred to the starting design."""

    def __init__(self, problem: MassProblem, start: np.ndarray) -> None:
        self.problem = problem
        self.reference: list[np.ndarray] | None = None
        first = self.design(start, None)
        self.reference = [
            np.array([_lowest_omega2(first.structure, eq) for eq in path])
            for path in first.equilibria
        ]
        self.start = self.measured(start, first.structure, first.equilibria)  # with stability

    @property
    def prestressed(self) -> bool:
        """Whether the prestressed state is a path point (its frequency is limited)."""
        return self.problem.min_frequency is not None and self.problem.prestressed

    def paths(self, structure: Structure, warm: _Design | None) -> list[list[EquilibriumResult]]:
        """Each case's equilibria at the :data:`PATH` factors, each solved from the last (or
        from ``warm``'s at the same factor)."""
        p = self.problem
        length = float(np.mean(p.geometry.rod_length)) if p.geometry.n_rods else 1.0
        found = []
        for k, case in enumerate(p.loads):
            path: list[EquilibriumResult] = []
            q = structure.node_position
            for j, factor in enumerate(PATH):
                start = q if warm is None else warm.equilibria[k][j + self.prestressed].q
                eq = find_equilibrium(
                    structure,
                    start,
                    external_force=None if case.force is None else factor * case.force,
                    gravity=None if case.gravity is None else factor * case.gravity,
                    descend=False,
                )
                last = path[-1].node_position if path else p.geometry.node_position
                jump = float(np.max(np.linalg.norm(eq.node_position - last, axis=1)))
                if not eq.converged or jump > MAX_PATH_MOVE * length:
                    raise _PathError(case.name)
                path.append(eq)
                q = eq.q
            found.append(path)
        if self.prestressed:
            unloaded = make_result(
                structure,
                dynamics.coordinates_from_nodes(structure, structure.node_position),
                None,
                converged=True,
                method="given",
                message="the prestressed geometry",
                nfev=0,
            )
            found = [[unloaded, *path] for path in found]
        return found

    def measure(
        self, area: np.ndarray, structure: Structure, eq: EquilibriumResult, case: int, point: int
    ) -> tuple[np.ndarray, tuple[str, ...]]:
        """The constraint values at one path point of one case of the structure of areas
        ``area``, and their kinds."""
        p, R = self.problem, self.problem.geometry.n_rods
        values: list[np.ndarray] = []
        kinds: list[str] = []

        def add(kind: str, value: np.ndarray | float) -> None:
            values.append(np.atleast_1d(value))
            kinds.extend([kind] * values[-1].size)

        final = point == len(PATH) - 1 + self.prestressed
        if self.prestressed and point == 0 and case > 0:  # the prestressed state: once
            return np.zeros(0), ()
        if final:
            C = np.where(p.held, 0.0, eq.rod_compression)
            add("tension", 1.0 - eq.tension / (p.strength[R:] * area[R:]))
            add("yield", 1.0 - np.abs(C) / (p.strength[:R] * area[:R]))
            add("buckling", 1.0 - p.beta**2 * np.maximum(C, 0.0) / area[:R] ** 2)
            if p.max_displacement is not None:
                free = ~p.geometry.node_fixed
                moved = np.linalg.norm(eq.node_position - p.geometry.node_position, axis=1)
                add("displacement", 1.0 - moved[free] / p.max_displacement)
        omega2 = _lowest_omega2(structure, eq)
        if p.min_frequency is not None and (final or (self.prestressed and point == 0)):
            add("frequency", omega2 / (2 * math.pi * p.min_frequency) ** 2 - 1.0)
        if self.reference is not None and self.reference[case][point] > 0:
            add("stability", omega2 / self.reference[case][point] - p.stability_margin)
        return np.concatenate([np.zeros(0), *values]), tuple(kinds)

    def design(self, area: np.ndarray, warm: _Design | None) -> _Design:
        """The design of areas ``area`` (the equilibria solved; :class:`_PathError` if a
        path fails)."""
        structure = self.problem.structure_at(area)
        return self.measured(area, structure, self.paths(structure, warm))

    def measured(
        self, area: np.ndarray, structure: Structure, paths: list[list[EquilibriumResult]]
    ) -> _Design:
        """The design of areas ``area`` (its ``structure``) with its path equilibria ``paths``
        solved: the constraint values at every point."""
        values: list[np.ndarray] = []
        kinds: list[str] = []
        for k, path in enumerate(paths):
            for j, eq in enumerate(path):
                v, kind = self.measure(area, structure, eq, k, j)
                values.append(v)
                kinds.extend(kind)
        return _Design(area, structure, paths, np.concatenate(values), tuple(kinds))

    def gradient(self, design: _Design) -> np.ndarray:
        """``d values / d log a`` (constraints, R + S) at ``design``."""
        z = np.log(design.area)
        eye = np.eye(z.size)
        areas = [(np.exp(z - STEP * e), np.exp(z + STEP * e)) for e in eye]
        perturbed = [
            (self.problem.structure_at(lo), self.problem.structure_at(hi)) for lo, hi in areas
        ]
        rows = []
        for k, path in enumerate(design.equilibria):
            for j, eq in enumerate(path):
                if self.prestressed and j == 0 and k > 0:
                    continue  # the prestressed state's constraints are case 0's
                if self.prestressed and j == 0:  # the geometry: only the structure changes
                    moves = [(eq.q, eq.q)] * z.size
                else:
                    sens = equilibrium_sensitivity(eq, perturbed, STEP)
                    moves = [
                        (sens.configuration(-STEP * e), sens.configuration(STEP * e)) for e in eye
                    ]
                columns = []
                for (a_lo, a_hi), (s_lo, s_hi), (q_lo, q_hi) in zip(
                    areas, perturbed, moves, strict=True
                ):
                    high = self.measure(a_hi, s_hi, _at(s_hi, eq, q_hi), k, j)[0]
                    low = self.measure(a_lo, s_lo, _at(s_lo, eq, q_lo), k, j)[0]
                    columns.append((high - low) / (2 * STEP))
                rows.append(np.stack(columns, axis=1))
        return np.vstack(rows)


def _at(structure: Structure, eq: EquilibriumResult, q: np.ndarray) -> EquilibriumResult:
    """The state ``q`` of ``structure`` under ``eq``'s loads, as an equilibrium record."""
    return make_result(
        structure,
        q,
        None,
        external_force=eq.external_force,
        gravity=eq.gravity,
        converged=True,
        method="sensitivity",
        message="moved to first order",
        nfev=0,
    )


#: SLSQP's tolerance on the relative mass.
FTOL = 1e-10

#: The most an area may grow from the starting design's.
MAX_GROWTH = 100.0

#: The largest violation of a (scaled) constraint of a design :func:`lighten` returns.
FEASIBLE = 1e-6

#: Constraint values down to this are taken as met with equality (``Lightened.active``).
ACTIVE_TOL = 1e-3

#: The kinds of constraint that are not a member's own strength.
SYSTEM_LIMITS = ("displacement", "frequency", "stability")


def lighten(
    problem: MassProblem,
    start: np.ndarray,
    *,
    max_iterations: int = 100,
) -> Lightened:
    """A local minimum of the mass from the areas ``start`` (R + S,) [m^2], which must meet
    every limit of ``problem`` (see the module docstring for the method).

    Parameters
    ----------
    max_iterations : int
        The most SLSQP iterations.

    Raises
    ------
    ValueError
        If a load path of the starting design fails (it is not a design that meets every limit).
    """
    try:
        constraints = _Constraints(problem, np.asarray(start, dtype=float))
    except _PathError as path:
        raise ValueError(
            f"load case {path.args[0]!r}: the starting design's load path fails"
        ) from None
    weight = problem.mass_per_area
    m0 = float(weight @ start)
    n = constraints.start.values.size
    seen = {constraints.start.area.tobytes(): constraints.start}
    last = [constraints.start]
    counts = {"designs": 0, "gradients": 0}

    failed: set[bytes] = set()

    def design(z: np.ndarray) -> _Design | None:
        area = np.exp(z)
        key = area.tobytes()
        if key in failed:
            return None
        if key not in seen:
            counts["designs"] += 1
            try:
                seen[key] = last[0] = constraints.design(area, last[0])
            except _PathError:
                failed.add(key)
                return None
        return seen[key]

    def values(z: np.ndarray) -> np.ndarray:
        found = design(z)
        return np.full(n, -1.0) if found is None else found.values

    def jacobian(z: np.ndarray) -> np.ndarray:
        found = design(z)
        counts["gradients"] += 1
        return constraints.gradient(last[0] if found is None else found)

    z0 = np.log(start)
    fit = scipy.optimize.minimize(
        lambda z: float(weight @ np.exp(z)) / m0,
        z0,
        jac=lambda z: weight * np.exp(z) / m0,
        method="SLSQP",
        bounds=list(zip(np.log(problem.lower), z0 + math.log(MAX_GROWTH), strict=True)),
        constraints=[{"type": "ineq", "fun": values, "jac": jacobian}],
        options={"maxiter": max_iterations, "ftol": FTOL},
    )
    feasible = [d for d in seen.values() if _violation(d) <= FEASIBLE]
    current = min(feasible, key=lambda d: float(weight @ d.area), default=constraints.start)
    iterations = int(fit.nit)
    message = (
        f"SLSQP: {fit.message}; {counts['designs']} designs and {counts['gradients']} "
        "gradients evaluated"
    )
    active = tuple(
        kind
        for kind in SYSTEM_LIMITS
        if any(
            k == kind and v <= ACTIVE_TOL
            for k, v in zip(current.kinds, current.values, strict=True)
        )
    )
    return Lightened(
        area=current.area,
        mass=float(weight @ current.area),
        start_mass=m0,
        iterations=iterations,
        message=message,
        active=active,
    )


def _violation(design: _Design) -> float:
    """The largest violation of a constraint (0 when every one is met)."""
    return max(0.0, -float(np.min(design.values, initial=0.0)))
