"""Sizing at the loaded, deformed equilibrium (``docs/design.md``, "Sizing at the loaded
equilibrium").

Tensegrity prisms, towers and shells are infinitesimal mechanisms stiffened by their prestress:
a load along a mechanism is carried only after the structure deforms, so the linear sizing of
:func:`~tensegrity.design.sizing.size_members` (equilibrium at the undeformed geometry) refuses
it.  :func:`size_at_equilibrium` sizes them where they carry the load:

1. The prestress: the self-stress of the given geometry with every tendon at least
   ``prestress`` [N] (the lightest, as :func:`size_members` finds it for the prestress alone).
   The geometry stays the unloaded equilibrium whatever the areas: each tendon's rest length is
   ``Lbar = l E A / (E A + T0)``.
2. For each load case, the equilibrium of the structure with the current areas under its
   prestress and the case's loads, by the nonlinear solver
   (:func:`~tensegrity.analysis.equilibrium.find_equilibrium`: rods of exact length, material and
   geometric stiffness), reached by load steps from the unloaded geometry, each step checked
   stable (:func:`~tensegrity.analysis.modes.modal_analysis`).  A load path that loses stability
   before the full load (a limit point: the structure would snap through) is refused, naming the
   case and the load factor reached.
3. The least areas that carry every case's forces there (yield and buckling with the strength and
   safety factors, :func:`~tensegrity.design.sizing.least_areas`).  Areas change the stiffness,
   the weight and so the equilibria: steps 2-3 are repeated until no area changes by more than
   ``rtol`` (a fully stressed design: each member above the least area is at utilisation 1 in
   its governing case).

Rods are rigid in the model: their areas change only the weight.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import scipy.optimize

from tensegrity.analysis.equilibrium import EquilibriumResult, find_equilibrium
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import RIGID, modal_analysis
from tensegrity.design.least_mass import Lightened, MassProblem, lighten
from tensegrity.design.materials import Material, per_member
from tensegrity.design.sizing import (
    LoadCase,
    Sizing,
    buckling_coefficient,
    checked_cases,
    equilibrium_rows,
    least_areas,
    nodal_equilibrium_matrix,
    size_members,
    sized_structure,
)
from tensegrity.design.utilisation import utilisation
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

__all__ = [
    "STATICS",
    "DesignLimitError",
    "LoadPathError",
    "ServiceabilityError",
    "follow_load",
    "largest_displacement",
    "lowest_frequency",
    "mechanism_count",
    "size",
    "size_at_equilibrium",
    "unheld_load",
]

#: The most a load step may move a node [rod lengths]: a longer jump is taken for a jump to
#: another branch of equilibria, and the step is halved.
MAX_STEP_MOVE = 0.05

#: The smallest load step [fraction of the case's load]: a path that needs a smaller one ends at
#: a limit point.
MIN_LOAD_STEP = 1e-3


class DesignLimitError(ValueError):
    """A design limit that larger members may cure: ``case`` (the load case at fault),
    ``governs`` (the name of the limit, for the report) and the sentence ``reason``; each kind
    rebuilds itself for another reason (:meth:`with_reason`)."""

    governs = "limit"

    def __init__(self, case: str, reason: str) -> None:
        self.case, self.reason = case, reason
        super().__init__(self.sentence(reason))

    def sentence(self, reason: str) -> str:
        """The one-line message for ``reason``."""
        return f"load case {self.case!r}: {reason}"

    def with_reason(self, reason: str) -> DesignLimitError:
        """The same limit for another ``reason``."""
        return DesignLimitError(self.case, reason)

    def beyond(self, factor: float) -> DesignLimitError:
        """The same limit, unmet even with the tendons ``factor`` times the area."""
        return self.with_reason(f"{self.reason} even with tendons {factor:.3g} times the area")


class LoadPathError(DesignLimitError):
    """A load case's path of equilibria ends before the full load: ``case`` (name), ``reached``
    (the last load factor in [0, 1) with a stable equilibrium) and the reason in the message."""

    governs = "stability"

    def __init__(self, case: str, reached: float, reason: str) -> None:
        self.reached = reached
        super().__init__(case, reason)

    def with_reason(self, reason: str) -> LoadPathError:
        return LoadPathError(self.case, self.reached, reason)

    def sentence(self, reason: str) -> str:
        where = "at its start" if self.reached == 0 else f"at {self.reached:.3g} of its load"
        return (
            f"load case {self.case!r}: {reason} {where} (a limit point, where the structure would "
            "snap through, or a mechanism the load moves and nothing stiffens); raise the "
            "prestress, or change the geometry"
        )


class ServiceabilityError(DesignLimitError):
    """A serviceability limit unmet: ``governs`` ``"displacement"`` (``max_displacement``) or
    ``"frequency"`` (``min_frequency``)."""

    def __init__(self, case: str, governs: str, reason: str) -> None:
        self.governs = governs
        super().__init__(case, reason)

    def with_reason(self, reason: str) -> ServiceabilityError:
        return ServiceabilityError(self.case, self.governs, reason)

    def sentence(self, reason: str) -> str:
        where = "the prestressed state" if self.case == "prestress" else f"load case {self.case!r}"
        return f"{where}: {reason}; raise the prestress, or relax the limit"


def _scaled(load: np.ndarray | None, factor: float) -> np.ndarray | None:
    return None if load is None else factor * load


def _stable(structure: Structure, eq: EquilibriumResult) -> bool:
    """No mode of negative stiffness about ``eq``: a mechanism the load does not move (zero
    stiffness, e.g. a node on a plane held by a slack tendon) is neutral, and at a limit point
    a stiffness passes through zero to negative."""
    return modal_analysis(linearize(structure, eq)).n_unstable == 0


def largest_displacement(structure: Structure, eq: EquilibriumResult) -> float:
    """The largest distance [m] of a node of ``eq`` from its place in ``structure``."""
    moved = np.linalg.norm(eq.node_position - structure.node_position, axis=-1)
    return float(np.max(moved, initial=0.0))


def lowest_frequency(structure: Structure, eq: EquilibriumResult | None = None) -> float:
    """The lowest natural frequency [Hz] of ``structure`` about the equilibrium ``eq`` (None:
    its node positions, unloaded): of the modes that are not rigid-body motions, so 0 for a
    mechanism (:func:`~tensegrity.analysis.modes.modal_analysis`)."""
    modes = modal_analysis(linearize(structure, eq))
    free = [f for f, kind in zip(modes.frequency_hz, modes.kind, strict=True) if kind != RIGID]
    return float(min(free, default=math.inf))


def follow_load(
    structure: Structure,
    case: LoadCase,
    *,
    start: np.ndarray | None = None,
    steps: int = 8,
) -> tuple[EquilibriumResult, int]:
    """The stable equilibrium of ``structure`` under ``case``'s loads on the path from its
    unloaded equilibrium (its node positions), and the number of load steps taken.

    From ``start`` (6R,) coordinates of a nearby loaded equilibrium (e.g. of the same structure
    with other areas) the full load is tried first.  Otherwise, or if that fails, the load grows
    from 0 in ``steps`` equal steps, each solved from the last (least squares, no descent: the
    nearest equilibrium; if that fails, as from tendons exactly at their rest length, after a
    descent of the potential energy) and accepted if it converged, is stable and moved no node
    more than :data:`MAX_STEP_MOVE` rod lengths; a rejected step is halved, and doubled again
    after a success.

    Raises
    ------
    LoadPathError
        If a step below :data:`MIN_LOAD_STEP` of the load is rejected (a limit point), or the
        unloaded structure is not at an equilibrium.  (Its stability is not asked: a structure
        without prestress may be stiffened by the load itself.)
    """
    length = float(np.mean(structure.rod_length)) if structure.n_rods else 1.0

    def solve(q: np.ndarray | None, factor: float) -> EquilibriumResult:
        found = None
        for descend in (False, True):  # the nearest root; else down the energy (a slack start)
            found = find_equilibrium(
                structure,
                q,
                external_force=_scaled(case.force, factor),
                gravity=_scaled(case.gravity, factor),
                descend=descend,
            )
            if found.converged:
                break
        assert found is not None
        return found

    if start is not None:
        eq = solve(start, 1.0)
        if eq.converged and _stable(structure, eq):
            return eq, 1
    unloaded = solve(None, 0.0)
    if not unloaded.converged:
        raise LoadPathError(case.name, 0.0, "the unloaded structure is not at an equilibrium")
    reached, step, last, taken = 0.0, 1.0 / steps, unloaded, 0
    while reached < 1.0:
        factor = min(1.0, reached + step)
        eq = solve(last.q, factor)
        taken += 1
        moved = float(np.max(np.linalg.norm(eq.node_position - last.node_position, axis=-1)))
        if eq.converged and moved <= MAX_STEP_MOVE * length and _stable(structure, eq):
            reached, last, step = factor, eq, 2 * step
            continue
        step /= 2
        if step < MIN_LOAD_STEP:
            reason = (
                "no stable equilibrium near the path" if eq.converged else "no equilibrium found"
            )
            raise LoadPathError(case.name, reached, reason)
    return last, taken


#: The most doublings of the tendons' areas tried against a limit point (:func:`_stiffened`).
MAX_DOUBLINGS = 20


#: After this many doublings without progress (:func:`_progress`) the stiffening gives up.
HOPELESS = 4


def _progress(first: DesignLimitError, last: DesignLimitError) -> bool:
    """Whether stiffening moved a limit: a load path that now reaches further, or another
    limit met (serviceability limits: always, their measure is not compared)."""
    if isinstance(first, LoadPathError) and isinstance(last, LoadPathError):
        return last.reached > first.reached
    return True


def _holds(acceptable: Callable[[np.ndarray], Any], area: np.ndarray) -> bool:
    """Whether members of areas ``area`` meet every limit :func:`_stiffened` cures."""
    try:
        acceptable(area)
    except DesignLimitError:
        return False
    return True


def _stiffened(
    acceptable: Callable[[np.ndarray], Any],
    area: np.ndarray,
    R: int,
    failure: DesignLimitError,
) -> tuple[np.ndarray, Any]:
    """The areas ``area`` (R + S,) with the tendons' scaled by the least factor (within
    ``2^(1/8)``: doublings, then three bisections of its logarithm) for which ``acceptable``
    raises no :class:`DesignLimitError` (every load path holds, and the serviceability limits
    are met), and its result for them; the last failure extended
    (:meth:`DesignLimitError.beyond`) if ``2^MAX_DOUBLINGS`` is not enough, or if a load path
    reaches no further after ``2^HOPELESS``."""

    def scaled(factor: float) -> np.ndarray:
        return np.concatenate([area[:R], factor * area[R:]])

    low, high, found = 1.0, 0.0, None
    first = failure
    for doubling in range(1, MAX_DOUBLINGS + 1):
        try:
            high, found = 2.0**doubling, acceptable(scaled(2.0**doubling))
            break
        except DesignLimitError as again:
            low, failure = 2.0**doubling, again
        if doubling == HOPELESS and not _progress(first, failure):
            break  # sixteen times the area moved the limit no further: more will not help
    if found is None:
        raise failure.beyond(low)
    for _ in range(3):
        middle = math.sqrt(low * high)
        try:
            high, found = middle, acceptable(scaled(middle))
        except DesignLimitError:
            low = middle
    return scaled(high), found


def size_at_equilibrium(
    structure: Structure,
    *,
    prestress: float | tuple[float, float] = 0.0,
    **options: Any,
) -> Sizing:
    """Members sized at each load case's loaded equilibrium (see the module docstring).

    ``prestress`` [N] is the smallest tendon tension of the prestressed state, or a range
    ``(low, high)`` in which the lightest design is found (Brent's bounded search on the
    logarithm of the prestress to a relative 2 %, each trial a sizing at that prestress, a
    trial that fails counted infinitely heavy): a higher prestress stiffens the structure's
    mechanisms (fewer limit points, smaller displacements, higher frequencies) and costs tendon
    area.  The search finds a local minimum of the mass over the range.  ``options``: as
    :func:`_size_at_prestress`.  The chosen prestress is ``Sizing.prestress``.
    """
    if not isinstance(prestress, tuple):
        return _size_at_prestress(structure, prestress=prestress, **options)
    low, high = (float(v) for v in prestress)
    if not (math.isfinite(low) and math.isfinite(high) and 0 < low < high):
        raise ValueError(f"prestress: a range must be 0 < low < high, got {prestress!r}")
    tried: dict[float, Sizing | ValueError] = {}

    def mass(log_prestress: float) -> float:
        level = float(np.exp(log_prestress))
        try:
            tried[level] = _size_at_prestress(structure, prestress=level, **options)
        except DesignLimitError as exc:
            tried[level] = exc
        found = tried[level]
        return found.total_mass if isinstance(found, Sizing) else math.inf

    with np.errstate(invalid="ignore"):  # Brent's parabola through an infinite trial
        scipy.optimize.minimize_scalar(
            mass, bounds=(math.log(low), math.log(high)), method="bounded", options={"xatol": 0.02}
        )
    for level in (low, high):  # the ends, which the bounded search does not evaluate
        mass(math.log(level))
    feasible = {level: z for level, z in tried.items() if isinstance(z, Sizing)}
    if not feasible:
        last = tried[max(tried)]
        raise ValueError(f"prestress: no level in [{low:g}, {high:g}] N works: {last}")
    best = min(feasible, key=lambda level: feasible[level].total_mass)
    chosen = feasible[best]
    return dataclasses.replace(
        chosen,
        message=f"{chosen.message}; prestress {best:.4g} N, the lightest of {len(tried)} "
        f"levels tried in [{low:g}, {high:g}] N",
    )


def _size_at_prestress(
    structure: Structure,
    *,
    rod_material: Material | Sequence[Material],
    tendon_material: Material | Sequence[Material],
    load_cases: Sequence[LoadCase],
    prestress: float = 0.0,
    wall_ratio: float | None = None,
    safety_factor: float = 1.0,
    strength_factor: float = 1.0,
    min_area: float = 1e-8,
    tendon_mass: bool = False,
    max_displacement: float | None = None,
    min_frequency: float | None = None,
    rtol: float = 1e-6,
    max_iterations: int = 50,
    load_steps: int = 8,
    least_mass: bool = False,
    stability_margin: float = 0.25,
) -> Sizing:
    """:func:`size_at_equilibrium` at one prestress (see the module docstring).

    Parameters as :func:`~tensegrity.design.sizing.size_members`; the structure's node positions
    are its unloaded, prestressed geometry.

    max_displacement : float, optional
        The largest displacement [m] of a node from the given geometry allowed in a load case.
    min_frequency : float, optional
        The lowest natural frequency [Hz] allowed, in the prestressed state and at each load
        case's equilibrium (:func:`lowest_frequency`).
    rtol : float
        Converged when no area changes by more than ``rtol`` (relative) from one iteration to
        the next.
    max_iterations : int
        The most sizing iterations (each solves every case's equilibrium).
    load_steps : int
        Load steps of the first path of each case (:func:`follow_load`).
    least_mass : bool
        From the fully stressed design, search the least mass under every limit
        (:func:`~tensegrity.design.least_mass.lighten`: a local minimum), then round its areas
        up until every member carries its forces and check every load path afresh.
    stability_margin : float
        With ``least_mass``: at every point of every load path, the lowest ``omega^2`` at least
        this fraction of the fully stressed design's (keeps the paths away from limit points).

    Returns
    -------
    Sizing
        With ``statics="equilibrium"``, each load case's equilibrium (``equilibria``) and
        largest node displacement from the geometry (``displacement``), and what governs each
        member's area.

    Raises
    ------
    ValueError
        One line: a bad argument, a prestress the geometry cannot hold, a case whose path
        reaches a limit point (:class:`LoadPathError`), or no convergence.
    """
    s = structure
    if not (isinstance(max_iterations, int) and max_iterations >= 1):
        raise ValueError(f"max_iterations: must be an integer >= 1, got {max_iterations!r}")
    if not (isinstance(load_steps, int) and load_steps >= 1):
        raise ValueError(f"load_steps: must be an integer >= 1, got {load_steps!r}")
    for name, value in (
        ("rtol", rtol),
        ("max_displacement", max_displacement),
        ("min_frequency", min_frequency),
        ("stability_margin", stability_margin),
    ):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be > 0, got {value!r}")
    if stability_margin > 1:
        raise ValueError(
            f"stability_margin: must be at most 1 (a fraction of the fully stressed design's "
            f"stiffness), got {stability_margin!r}"
        )
    if least_mass and s.dim != 3:
        raise ValueError("least_mass: only for a 3-D structure; size a planar one without it")
    cases = checked_cases(s, load_cases, prestress)
    loads = [c for c in cases if c.name != "prestress"]
    if not loads:
        raise ValueError("load_cases: give at least one load case to size at its equilibrium")
    rm = per_member(rod_material, s.n_rods, "rod_material", Material)
    tm = per_member(tendon_material, s.n_tendons, "tendon_material", Material)
    strength = np.array([m.yield_strength for m in (*rm, *tm)]) / strength_factor
    beta = buckling_coefficient(
        s.rod_length,
        np.array([m.youngs_modulus for m in rm]),
        wall_ratio=wall_ratio,
        safety_factor=safety_factor,
    )
    R, S = s.n_rods, s.n_tendons
    density = np.array([m.density for m in (*rm, *tm)])
    mass_per_area = density * np.concatenate(
        [s.rod_length, dynamics.tendon_lengths(s, s.node_position)]
    )

    def linear(cases: Sequence[LoadCase]) -> Sizing:
        return size_members(
            s,
            rod_material=rm,
            tendon_material=tm,
            load_cases=cases,
            prestress=prestress,
            wall_ratio=wall_ratio,
            safety_factor=safety_factor,
            strength_factor=strength_factor,
            min_area=min_area,
            tendon_mass=tendon_mass,
        )

    C0, T0 = np.zeros(R), np.zeros(S)
    first: Sizing | None = None
    if prestress > 0:
        first = linear(())
        C0, T0 = first.rod_compression[0], first.tendon_tension[0]
    # the first areas: the linear sizing's if it carries the loads, else the prestress's
    with contextlib.suppress(ValueError):
        first = linear(loads)
    area = (
        np.full(R + S, min_area)
        if first is None
        else np.concatenate([first.rod_area, first.tendon_area])
    )
    for case in loads:
        power = unheld_load(s, case)
        if power > 1e-9 * max(unheld_scale(s, case), 1e-300):
            raise ValueError(
                f"load case {case.name!r}: cannot be carried: the supports leave the structure "
                f"free to move under it ({power:.3g} N net along a rigid-body motion); fix "
                "nodes (e.g. --fixed-base) or balance the load"
            )
    names = [c.name for c in cases]
    starts: list[np.ndarray | None] = [None] * len(loads)

    def members_of(area: np.ndarray) -> tuple[Structure, Any]:
        """The structure of members of areas ``area`` (R + S,) [m^2], and its members."""
        return sized_structure(
            s,
            rod_material=rm,
            tendon_material=tm,
            rod_area=area[:R],
            tendon_area=area[R:],
            wall_ratio=wall_ratio,
            prestress_tension=T0,
            tendon_mass=tendon_mass,
        )

    def equilibria_at(area: np.ndarray) -> tuple[list[EquilibriumResult], Structure, Any]:
        """Each load case's equilibrium of the structure of members of areas ``area``."""
        sized, members = members_of(area)
        found = [
            follow_load(sized, case, start=starts[k], steps=load_steps)[0]
            for k, case in enumerate(loads)
        ]
        starts[:] = [eq.q for eq in found]
        return found, sized, members

    def acceptable(area: np.ndarray) -> tuple[list[EquilibriumResult], Structure, Any]:
        """:func:`equilibria_at` ``area``, checked against the serviceability limits."""
        found, sized, members = equilibria_at(area)
        for case, eq in zip(loads, found, strict=True):
            moved = largest_displacement(s, eq)
            if max_displacement is not None and moved > max_displacement:
                raise ServiceabilityError(
                    case.name,
                    "displacement",
                    f"largest displacement {moved:.4g} m > max_displacement {max_displacement:g} m",
                )
        if min_frequency is not None:
            states: list[EquilibriumResult | None] = [None] * (prestress > 0)
            for name, state in zip(names, states + list(found), strict=True):
                hz = lowest_frequency(sized, state)
                if hz < min_frequency:
                    raise ServiceabilityError(
                        name,
                        "frequency",
                        f"lowest natural frequency {hz:.4g} Hz < min_frequency "
                        f"{min_frequency:g} Hz",
                    )
        return found, sized, members

    held = np.asarray(s.node_fixed[s.rod_nodes].all(axis=1))  # rods between two fixed nodes

    def forces(found: list[EquilibriumResult]) -> tuple[np.ndarray, np.ndarray]:
        """Rod compressions (K, R) and tendon tensions (K, S) [N] of every case; a rod between
        two fixed nodes carries none (the supports take its load; its share is not
        determined), as in the linear sizing."""
        C = np.array(([C0] if prestress > 0 else []) + [eq.rod_compression for eq in found])
        T = np.array(([T0] if prestress > 0 else []) + [eq.tension for eq in found])
        C = C.reshape(-1, R)
        C[:, held] = 0.0
        return C, T.reshape(-1, S)

    def carried(found: list[EquilibriumResult]) -> np.ndarray:
        """The least areas (R + S,) [m^2] that carry the forces of the equilibria ``found``."""
        C, T = forces(found)
        return least_areas(C, T, strength=strength, beta=beta, min_area=min_area, cases=names).area

    floor = np.zeros(R + S)  # tendon areas below which a load path or a serviceability fails
    floor_limit: DesignLimitError | None = None
    message = f"stopped after {max_iterations} iterations (max_iterations): areas still change"
    for iteration in range(1, max_iterations + 1):
        try:
            equilibria, sized, members = acceptable(area)
        except DesignLimitError as failure:
            area, (equilibria, sized, members) = _stiffened(acceptable, area, R, failure)
            floor[R:], floor_limit = area[R:], failure
        C, T = forces(equilibria)
        least = least_areas(C, T, strength=strength, beta=beta, min_area=min_area, cases=names)
        target = np.maximum(least.area, floor)
        change = float(np.max(np.abs(target - area) / target, initial=0.0))
        if change <= rtol and np.any(floor > least.area) and _holds(acceptable, least.area):
            # the floor came from earlier areas, and the least areas now meet every limit
            floor[:], floor_limit = 0.0, None
            target, change = least.area, math.inf
        if change <= rtol:
            message = f"converged after {iteration} iterations (areas within {change:.2g})"
            break
        area = target
    else:  # pragma: no cover - the loop always breaks
        raise AssertionError
    if change > rtol:
        raise ValueError(
            f"sizing at the loaded equilibrium: {message} (the last change of an area: "
            f"{'a stiffening dropped' if math.isinf(change) else f'{change:.3g} relative'})"
        )
    # Round the areas up by rtol, so that the iteration's tolerance never shows as a utilisation
    # above 1 (areas that only grow: every limit still holds); the result is these areas' own
    # equilibria and forces.
    area = np.where(
        np.array(least.governs) == "min_area", area, np.maximum(area, target) * (1 + rtol)
    )
    limit = "" if floor_limit is None else floor_limit.governs
    limit_case = None if floor_limit is None else floor_limit.case
    if least_mass:
        problem = MassProblem(
            structure_at=lambda a: members_of(a)[0],
            geometry=s,
            loads=loads,
            strength=strength,
            beta=beta,
            held=held,
            mass_per_area=mass_per_area,
            lower=least_areas(
                C0[None],
                T0[None],
                strength=strength,
                beta=beta,
                min_area=min_area,
                cases=["prestress"],
            ).area,
            max_displacement=max_displacement,
            min_frequency=min_frequency,
            prestressed=prestress > 0,
            stability_margin=stability_margin,
        )
        area, lightened = _lightest(problem, area, acceptable, carried, starts, rtol)
        message = f"{message}; {lightened.summary()}"
        # a member above the area its forces need is held there by a limit of the whole
        limit, limit_case = "+".join(lightened.active) or "stiffness", None
    equilibria, sized, members = acceptable(area)
    C, T = forces(equilibria)
    if least_mass:
        least = least_areas(C, T, strength=strength, beta=beta, min_area=min_area, cases=names)
        floor = np.where(area > least.area * (1 + ABOVE), area, 0.0)
    stiffened = floor > least.area
    governs = tuple(limit if f else g for f, g in zip(stiffened, least.governs, strict=True))
    governing_case = tuple(
        limit_case if f else c for f, c in zip(stiffened, least.case, strict=True)
    )
    mass = mass_per_area * area
    moved = [largest_displacement(s, eq) for eq in equilibria]
    states: list[EquilibriumResult | None] = [None] * (prestress > 0)
    frequency = [lowest_frequency(sized, eq) for eq in states + list(equilibria)]
    return Sizing(
        structure=sized,
        members=members,
        cases=tuple(names),
        rod_area=area[:R],
        tendon_area=area[R:],
        rod_mass=mass[:R],
        tendon_mass=mass[R:],
        rod_compression=C,
        tendon_tension=T,
        utilisation=utilisation(
            s,
            members,
            tension=T,
            compression=C,
            safety_factor=safety_factor,
            strength_factor=strength_factor,
        ),
        iterations=iteration,
        message=message,
        statics="equilibrium",
        governs=governs,
        governing_case=governing_case,
        equilibria=tuple(equilibria),
        displacement=np.array(moved),
        frequency=np.array(frequency),
        prestress=prestress,
    )


#: A member whose area is this much (relative) above what its forces need is reported as set by
#: a limit of the whole structure (the least-mass design).
ABOVE = 1e-3

#: The most rounds of rounding a least-mass design's areas up to its forces.
MAX_ROUNDING = 10

#: The relative stiffenings of the tendons tried when a least-mass design misses a limit by
#: the search's tolerance.
BUMPS = (0.0, 1e-6, 1e-5, 1e-4, 1e-3)

#: Bisections of the step from the fully stressed to the least-mass design when the latter
#: fails its fresh check.
BACKTRACKS = 6


def _lightest(
    problem: MassProblem,
    start: np.ndarray,
    acceptable: Callable[[np.ndarray], Any],
    carried: Callable[[list[EquilibriumResult]], np.ndarray],
    starts: list[np.ndarray | None],
    rtol: float,
) -> tuple[np.ndarray, Lightened]:
    """The least-mass areas from the fully stressed ``start`` (:func:`lighten`), rounded up
    until every member carries its forces (areas over ``rtol`` above them) and checked afresh:
    every load path followed from its start (``starts`` reset), every limit met
    (``acceptable``).  If that fails, the largest part of the step from ``start`` (on the log
    areas, :data:`BACKTRACKS` bisections) that passes."""
    lightened = lighten(problem, start)

    def checked(area: np.ndarray) -> np.ndarray:
        for _ in range(MAX_ROUNDING):
            need = carried(acceptable(area)[0])
            if np.all(need <= area):
                break
            area = np.maximum(area, need * (1 + rtol))
        starts[:] = [None] * len(starts)
        need = carried(acceptable(area)[0])  # afresh: every path from its start
        if np.any(need > area):
            raise DesignLimitError(
                "least mass", "members do not carry the forces of their fresh load paths"
            )
        return area

    tendons = np.arange(start.size) >= problem.geometry.n_rods
    for bump in BUMPS:  # a limit met to the search's tolerance: the tendons a little stiffer
        try:
            area = checked(lightened.area * np.where(tendons, 1 + bump, 1.0))
        except DesignLimitError as failure:
            reason = failure
            continue
        return area, dataclasses.replace(
            lightened, area=area, mass=float(problem.mass_per_area @ area)
        )
    kept, low, high, best = 0.0, 0.0, 1.0, start
    for _ in range(BACKTRACKS):
        t = 0.5 * (low + high)
        try:
            best, kept, low = checked(start ** (1 - t) * lightened.area**t), t, t
        except DesignLimitError:
            high = t
    return best, dataclasses.replace(
        lightened,
        area=best,
        mass=float(problem.mass_per_area @ best),
        message=f"{lightened.message}; {kept:.3g} of the step kept (all of it fails: {reason})",
    )


def nodal_load(structure: Structure, case: LoadCase) -> np.ndarray:
    """``case``'s nodal forces (N, dim) [N]: its forces and the weight of the structure's masses
    (half of each rod's at each end, and the point masses)."""
    N, d = structure.node_position.shape
    load = np.zeros((N, d)) if case.force is None else case.force.copy()
    if case.gravity is not None:
        load += structure.node_mass[:, None] * case.gravity
    return load


def unheld_scale(structure: Structure, case: LoadCase) -> float:
    """The size of ``case``'s nodal loads [N] (the sum of their magnitudes) that
    :func:`unheld_load` is measured against."""
    return float(np.linalg.norm(nodal_load(structure, case), axis=1).sum())


def unheld_load(structure: Structure, case: LoadCase) -> float:
    """The largest power [W per m/s] of ``case``'s loads (its forces and the weight of the
    structure's masses) on a rigid-body motion the supports leave free (unit speed of the
    nodes, root mean square): 0 when the supports hold the structure against the load's net
    force and moment, > 0 when no equilibrium can exist."""
    p = structure.node_position
    N, d = p.shape
    load = nodal_load(structure, case)
    centre = p.mean(axis=0)
    fields = [np.tile(np.eye(d)[a], (N, 1)) for a in range(d)]  # translations
    for a, b in [(0, 1)] if d == 2 else [(1, 2), (2, 0), (0, 1)]:  # rotations
        field = np.zeros((N, d))
        field[:, a], field[:, b] = -(p[:, b] - centre[b]), p[:, a] - centre[a]
        fields.append(field)
    B = np.stack([f.ravel() for f in fields], axis=1)  # (N d, rigid motions)
    P = equilibrium_rows(structure).toarray()
    if P.shape[0]:
        Q, _ = np.linalg.qr(P.T)
        outside = B - Q @ (Q.T @ B)  # the part of each motion the supports forbid
    else:
        outside = B
    _, sv, vt = np.linalg.svd(outside)
    scale = max(float(np.linalg.norm(B, axis=0).max()), 1e-300)
    free = vt[np.count_nonzero(sv > 1e-9 * scale) :].T  # combinations the supports allow
    if free.size == 0:
        return 0.0
    U = B @ free
    U /= np.linalg.norm(U, axis=0) / math.sqrt(N)
    return float(np.max(np.abs(load.ravel() @ U)))


#: The ways :func:`size` finds the members' forces.
STATICS = ("auto", "linear", "equilibrium")


def mechanism_count(structure: Structure) -> int:
    """The number of independent infinitesimal mechanisms (and rigid-body motions the supports
    leave) of ``structure`` at its node positions: the load patterns no member forces balance
    there, ``rows - rank`` of the equilibrium matrix ``P H``
    (:func:`~tensegrity.design.sizing.equilibrium_rows`, ``nodal_equilibrium_matrix``)."""
    P = equilibrium_rows(structure)
    H = np.hstack(nodal_equilibrium_matrix(structure))
    PH = np.asarray(P @ H)
    if PH.size == 0:
        return int(PH.shape[0])
    sv = np.linalg.svd(PH, compute_uv=False)
    return int(PH.shape[0] - np.count_nonzero(sv > 1e-9 * sv[0]))


def size(structure: Structure, *, statics: str = "auto", **options: Any) -> Sizing:
    """Members sized under a prestress and load cases, by the linear sizing
    (:func:`~tensegrity.design.sizing.size_members`, ``statics="linear"``: equilibrium at the
    given geometry) or at each case's loaded equilibrium (:func:`size_at_equilibrium`,
    ``"equilibrium"``).  ``"auto"``: the linear sizing where it applies -- a structure without
    mechanisms (:func:`mechanism_count` 0: statically determinate or stiff), whose small
    deformation leaves its forces as they are -- and the loaded equilibrium otherwise (a
    mechanism, which only the prestress or the load stiffens: even a load the given geometry
    balances deforms it, and its forces change), or when a serviceability limit or a prestress
    range is asked for.  ``options``: the keywords of the chosen function."""
    if statics not in STATICS:
        raise ValueError(f"statics: expected one of {', '.join(STATICS)}, got {statics!r}")
    nonlinear = (
        "rtol",
        "load_steps",
        "max_displacement",
        "min_frequency",
        "least_mass",
        "stability_margin",
    )
    if statics == "auto":
        asked = isinstance(options.get("prestress"), tuple) or any(n in options for n in nonlinear)
        statics = "equilibrium" if asked or mechanism_count(structure) else "linear"
    if statics == "linear":
        if isinstance(options.get("prestress"), tuple):
            raise ValueError(
                "prestress: a range is searched only at the loaded equilibrium (linear sizing is "
                "lightest at the least prestress)"
            )
        for name in nonlinear:
            if name in options:
                raise ValueError(f"{name}: only for sizing at the loaded equilibrium")
        return size_members(structure, **options)
    return size_at_equilibrium(structure, **options)
