"""Materials and cross-sections of members, and the structure they make.

A :class:`Material` is four numbers in SI units (Young's modulus, density, yield strength,
ultimate strength); :data:`MATERIALS` is a table of common ones, each value's source in
``docs/design.md``.  A section (:class:`SolidRod`, :class:`HollowTube`, :class:`Cable`) gives
the area ``A`` [m^2] and the second moment of area ``I`` [m^4] of a round member.

:func:`member_properties` gives every member of a structure its material and section
(:class:`MemberProperties`, arrays over members); :func:`with_members` builds the structure they
make: tendon stiffness ``k = E A / Lbar`` (``Lbar`` the rest length), rod mass ``m = rho A L``,
and optionally the tendons' own mass ``rho A Lbar``; :func:`member_table` lists the derived
numbers.

The model has no point mass at a rod's end (:class:`~tensegrity.model.structure.Structure`
puts a payload on a node of its own), so half a tendon's mass is added to the mass of the rod at
each end (at a point-mass node, to that point mass; at an anchor it is dropped): each rod's
total mass and its weight are right, while its mass stays uniform along the rod (its rotary
inertia is that of a uniform rod, ``m L^2 / 12``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, NamedTuple, TypeAlias

import numpy as np

from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import elastic_tensions, tendon_lengths

__all__ = [
    "MATERIALS",
    "Cable",
    "Factors",
    "HollowTube",
    "Material",
    "MemberDesign",
    "MemberProperties",
    "Section",
    "SolidRod",
    "material",
    "member_properties",
    "member_table",
    "parse_section",
    "per_member",
    "round_section",
    "with_members",
]


def _positive(value: float, where: str) -> float:
    """``value`` as a finite float > 0, or a one-line ``ValueError`` naming ``where``."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: must be a number, got {value!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise ValueError(f"{where}: must be > 0, got {value!r}")
    return x


def check_factor(value: Any, where: str) -> float:
    """``value`` as a finite float >= 1 (a safety or strength factor), or a one-line
    ``ValueError`` naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"{where}: must be a number >= 1, got {value!r:.80}")
    if not (math.isfinite(value) and value >= 1.0):
        raise ValueError(f"{where}: must be >= 1, got {value!r}")
    return float(value)


@dataclasses.dataclass(frozen=True)
class Factors:
    """The factors a design is checked with (``docs/design.md``), each finite and >= 1:
    ``safety`` (``gamma``) divides the rods' Euler load, ``strength`` the yield strengths of rods
    and tendons (not the tendons' ultimate strength: ``tendon_ultimate`` stays the raw ratio to
    the breaking stress)."""

    safety: float = 1.0
    strength: float = 1.0

    def __post_init__(self) -> None:
        for field in ("safety", "strength"):
            object.__setattr__(self, field, check_factor(getattr(self, field), field))


@dataclasses.dataclass(frozen=True)
class Material:
    """An isotropic, linear-elastic member material (SI units).

    Attributes
    ----------
    name : str
        A short name (the key of :data:`MATERIALS` for the table's materials).
    youngs_modulus : float
        ``E`` [Pa] (for a fibre or a composite: along the fibres).
    density : float
        ``rho`` [kg/m^3].
    yield_strength : float
        ``sigma_y`` [Pa]: the stress a member is designed to (a metal's 0.2 % proof stress; a
        fibre or a composite, linear to failure, has none: its design strength, see
        ``docs/design.md``).
    ultimate_strength : float
        ``sigma_u`` [Pa] >= ``yield_strength``: the stress at which a tendon breaks.
    source : str
        Where the numbers come from (one line).
    """

    name: str
    youngs_modulus: float
    density: float
    yield_strength: float
    ultimate_strength: float
    source: str = ""

    def __post_init__(self) -> None:
        for field in ("youngs_modulus", "density", "yield_strength", "ultimate_strength"):
            object.__setattr__(
                self, field, _positive(getattr(self, field), f"material {self.name!r}.{field}")
            )
        if self.ultimate_strength < self.yield_strength:
            raise ValueError(
                f"material {self.name!r}: ultimate_strength {self.ultimate_strength:g} Pa is "
                f"below yield_strength {self.yield_strength:g} Pa"
            )


#: Common member materials, typical values (sources and ranges in ``docs/design.md``).
MATERIALS: dict[str, Material] = {
    m.name: m
    for m in (
        Material(
            "steel", 210e9, 7850.0, 355e6, 510e6, "structural steel S355, EN 1993-1-1 Table 3.1"
        ),
        Material("stainless", 200e9, 8000.0, 220e6, 520e6, "austenitic 1.4401 (316), EN 1993-1-4"),
        Material("aluminium", 68.9e9, 2700.0, 276e6, 310e6, "6061-T6, ASM Handbook / MatWeb"),
        Material("titanium", 113.8e9, 4430.0, 880e6, 950e6, "Ti-6Al-4V annealed, ASM Handbook"),
        Material(
            "cfrp",
            135e9,
            1600.0,
            1200e6,
            2000e6,
            "unidirectional carbon/epoxy (T700-class, ~60 % fibre), typical pultruded rod",
        ),
        Material(
            "dyneema", 116e9, 970.0, 3.4e9, 3.4e9, "UHMWPE fibre Dyneema SK78, DSM fact sheet"
        ),
        Material("kevlar", 112e9, 1440.0, 3.0e9, 3.0e9, "Kevlar 49 yarn, DuPont technical guide"),
        Material("nylon", 2.7e9, 1140.0, 64e6, 85e6, "nylon 6,6 (bulk), Callister appendix B"),
    )
}


def material(name: str) -> Material:
    """The table's material called ``name`` (:data:`MATERIALS`), or a one-line ``ValueError``
    listing the names."""
    try:
        return MATERIALS[name]
    except KeyError:
        raise ValueError(
            f"material: unknown {name!r}; one of {', '.join(sorted(MATERIALS))}"
        ) from None


@dataclasses.dataclass(frozen=True)
class SolidRod:
    """A solid round bar of ``diameter`` [m]."""

    diameter: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "diameter", _positive(self.diameter, "solid rod diameter"))

    @property
    def area(self) -> float:
        """``pi d^2 / 4`` [m^2]."""
        return math.pi * self.diameter**2 / 4

    @property
    def second_moment(self) -> float:
        """``pi d^4 / 64`` [m^4]."""
        return math.pi * self.diameter**4 / 64

    def describe(self) -> str:
        return f"solid rod d = {self.diameter * 1e3:.4g} mm"


@dataclasses.dataclass(frozen=True)
class HollowTube:
    """A round tube of ``outer_diameter`` [m] and ``wall_thickness`` [m] (at most half the
    outer diameter: a solid bar)."""

    outer_diameter: float
    wall_thickness: float

    def __post_init__(self) -> None:
        D = _positive(self.outer_diameter, "tube outer_diameter")
        t = _positive(self.wall_thickness, "tube wall_thickness")
        if t > D / 2:
            raise ValueError(
                f"tube wall_thickness: {t:g} m is more than half the outer diameter {D:g} m"
            )
        object.__setattr__(self, "outer_diameter", D)
        object.__setattr__(self, "wall_thickness", t)

    @property
    def inner_diameter(self) -> float:
        """``D - 2 t`` [m]."""
        return self.outer_diameter - 2 * self.wall_thickness

    @property
    def area(self) -> float:
        """``pi (D^2 - d^2) / 4`` [m^2]."""
        return math.pi * (self.outer_diameter**2 - self.inner_diameter**2) / 4

    @property
    def second_moment(self) -> float:
        """``pi (D^4 - d^4) / 64`` [m^4]."""
        return math.pi * (self.outer_diameter**4 - self.inner_diameter**4) / 64

    def describe(self) -> str:
        return (
            f"tube D = {self.outer_diameter * 1e3:.4g} mm, t = {self.wall_thickness * 1e3:.4g} mm"
        )


@dataclasses.dataclass(frozen=True)
class Cable:
    """A cable (string) of ``diameter`` [m]: metal area ``pi d^2 / 4`` (a rope's nominal
    diameter overstates it; give the diameter of the load-bearing area).  No bending stiffness
    (``second_moment`` 0): a cable cannot be a rod."""

    diameter: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "diameter", _positive(self.diameter, "cable diameter"))

    @property
    def area(self) -> float:
        """``pi d^2 / 4`` [m^2]."""
        return math.pi * self.diameter**2 / 4

    @property
    def second_moment(self) -> float:
        """0 [m^4]: a cable does not carry compression."""
        return 0.0

    def describe(self) -> str:
        return f"cable d = {self.diameter * 1e3:.4g} mm"


Section: TypeAlias = SolidRod | HollowTube | Cable


def parse_section(text: str) -> Section:
    """A section from its command-line form: ``rod:D``, ``tube:D:T`` or ``cable:D``, lengths in
    millimetres (``rod:20``, ``tube:40:2``, ``cable:3``).

    Raises
    ------
    ValueError
        One line naming the form expected.
    """
    kind, *values = text.split(":")
    sizes = {"rod": 1, "tube": 2, "cable": 1}
    if kind not in sizes or len(values) != sizes[kind]:
        raise ValueError(
            f"section: expected rod:D, tube:D:T or cable:D (millimetres), got {text!r}"
        )
    try:
        mm = [float(v) * 1e-3 for v in values]
    except ValueError:
        raise ValueError(f"section: expected numbers (millimetres) in {text!r}") from None
    if kind == "rod":
        return SolidRod(mm[0])
    if kind == "tube":
        return HollowTube(mm[0], mm[1])
    return Cable(mm[0])


def round_section(area: float, *, wall_ratio: float | None = None) -> SolidRod | HollowTube:
    """The round rod section of area ``area`` [m^2]: a solid bar (``wall_ratio`` None) or a
    tube of wall thickness ``wall_ratio`` times its outer diameter (``0 < wall_ratio <= 1/2``;
    1/2 is the solid bar as a tube)."""
    if wall_ratio is None:
        return SolidRod(math.sqrt(4 * area / math.pi))
    xi = 1 - 2 * wall_ratio
    diameter = math.sqrt(4 * area / (math.pi * (1 - xi**2)))
    return HollowTube(diameter, wall_ratio * diameter)


class MemberProperties(NamedTuple):
    """Material and section numbers of every member, as arrays: rods (R,), tendons (S,)."""

    rod_modulus: np.ndarray  #: ``E`` [Pa]
    rod_density: np.ndarray  #: ``rho`` [kg/m^3]
    rod_yield: np.ndarray  #: ``sigma_y`` [Pa]
    rod_area: np.ndarray  #: ``A`` [m^2]
    rod_second_moment: np.ndarray  #: ``I`` [m^4]
    tendon_modulus: np.ndarray  #: [Pa]
    tendon_density: np.ndarray  #: [kg/m^3]
    tendon_yield: np.ndarray  #: [Pa]
    tendon_ultimate: np.ndarray  #: [Pa]
    tendon_area: np.ndarray  #: [m^2]
    rod_label: tuple[str, ...]  #: material and section of each rod, for tables
    tendon_label: tuple[str, ...]  #: material and section of each tendon


def per_member(value: Any, count: int, where: str, kind: type | tuple[type, ...]) -> list[Any]:
    """``value`` for every one of ``count`` members: one value (an instance of ``kind``), or a
    sequence of ``count`` of them; a one-line ``ValueError`` naming ``where`` otherwise."""
    items = [value] * count if isinstance(value, kind) else list(value)
    if len(items) != count:
        raise ValueError(f"{where}: expected one or {count} (one per member), got {len(items)}")
    for k, item in enumerate(items):
        if not isinstance(item, kind):
            names = "/".join(t.__name__ for t in (kind if isinstance(kind, tuple) else (kind,)))
            raise ValueError(f"{where}[{k}]: expected a {names}, got {type(item).__name__}")
    return items


def member_properties(
    structure: Structure,
    *,
    rod_material: Material | Sequence[Material],
    rod_section: Section | Sequence[Section],
    tendon_material: Material | Sequence[Material],
    tendon_section: Section | Sequence[Section],
) -> MemberProperties:
    """The material and section of every member of ``structure``: one for all rods (tendons),
    or a sequence of one per rod (tendon).

    Raises
    ------
    ValueError
        A sequence of the wrong length, or a rod whose section is a :class:`Cable`.
    """
    sections = (SolidRod, HollowTube, Cable)
    rm = per_member(rod_material, structure.n_rods, "rod_material", Material)
    rs = per_member(rod_section, structure.n_rods, "rod_section", sections)
    tm = per_member(tendon_material, structure.n_tendons, "tendon_material", Material)
    ts = per_member(tendon_section, structure.n_tendons, "tendon_section", sections)
    for r, section in enumerate(rs):
        if isinstance(section, Cable):
            raise ValueError(f"rod_section[{r}]: a cable cannot be a rod (no bending stiffness)")

    def numbers(items: list[Any], field: str) -> np.ndarray:
        return np.array([getattr(item, field) for item in items], dtype=float)

    return MemberProperties(
        rod_modulus=numbers(rm, "youngs_modulus"),
        rod_density=numbers(rm, "density"),
        rod_yield=numbers(rm, "yield_strength"),
        rod_area=numbers(rs, "area"),
        rod_second_moment=numbers(rs, "second_moment"),
        tendon_modulus=numbers(tm, "youngs_modulus"),
        tendon_density=numbers(tm, "density"),
        tendon_yield=numbers(tm, "yield_strength"),
        tendon_ultimate=numbers(tm, "ultimate_strength"),
        tendon_area=numbers(ts, "area"),
        rod_label=tuple(f"{m.name}, {s.describe()}" for m, s in zip(rm, rs, strict=True)),
        tendon_label=tuple(f"{m.name}, {s.describe()}" for m, s in zip(tm, ts, strict=True)),
    )


def tendon_stiffness(structure: Structure, members: MemberProperties) -> np.ndarray:
    """``E A / Lbar`` (S,) [N/m] with ``Lbar`` the structure's rest lengths; a one-line
    ``ValueError`` for a rest length of 0 (an infinitely stiff tendon)."""
    rest = structure.tendon_rest_length
    bad = np.flatnonzero(rest <= 0)
    if bad.size:
        s = bad[0]
        raise ValueError(
            f"tendons[{s}] ({structure.tendon_name[s]!r}).rest_length: must be > 0 for a "
            "stiffness E A / Lbar"
        )
    return np.asarray(members.tendon_modulus * members.tendon_area / rest)


def tendon_masses(structure: Structure, members: MemberProperties) -> np.ndarray:
    """``rho A Lbar`` (S,) [kg]: each tendon's own mass (at its rest length)."""
    return np.asarray(members.tendon_density * members.tendon_area * structure.tendon_rest_length)


def lumped_tendon_mass(structure: Structure, tendon_mass: np.ndarray) -> np.ndarray:
    """Where a tendon's mass (S,) [kg] goes, as an extra mass per node (N,) [kg]: half at each
    end (module docstring: a rod's share is added to that rod's mass)."""
    extra = np.zeros(structure.n_nodes)
    np.add.at(extra, structure.tendon_nodes[:, 0], tendon_mass / 2)
    np.add.at(extra, structure.tendon_nodes[:, 1], tendon_mass / 2)
    extra[structure.node_fixed] = 0.0  # an anchor (or a fixed rod end) holds it up
    return extra


def with_members(
    structure: Structure, members: MemberProperties, *, tendon_mass: bool = False
) -> Structure:
    """``structure`` with the stiffness and masses its members' materials and sections give.

    Tendon stiffness ``E A / Lbar`` [N/m], rod mass ``rho A L`` [kg]; with ``tendon_mass``,
    each tendon's mass ``rho A Lbar`` is added half to each end node: to the rod's mass there
    (see the module docstring), or to a point mass; dropped at fixed nodes.  Geometry, rest
    lengths, damping and supports are kept.
    """
    rod_mass = members.rod_density * members.rod_area * structure.rod_length
    point_mass = structure.node_point_mass.copy()
    if tendon_mass:
        extra = lumped_tendon_mass(structure, tendon_masses(structure, members))
        rod_mass = rod_mass + extra[structure.rod_nodes[:, 0]] + extra[structure.rod_nodes[:, 1]]
        free = structure.node_point_mass > 0
        point_mass[free] += extra[free]
    return structure.replace(
        tendon_stiffness=tendon_stiffness(structure, members),
        rod_mass=rod_mass,
        node_point_mass=point_mass,
    )


def member_table(structure: Structure, members: MemberProperties) -> list[dict[str, Any]]:
    """One row per member (rods, then tendons) of the numbers :func:`with_members` derives:
    ``member``, ``kind``, ``section``, ``length_m`` (rod length, tendon rest length),
    ``area_m2``, ``second_moment_m4`` (rods), ``stiffness_N_per_m`` (tendons: ``E A / Lbar``),
    ``mass_kg`` (``rho A L``)."""
    rows: list[dict[str, Any]] = []
    rod_mass = members.rod_density * members.rod_area * structure.rod_length
    for r in range(structure.n_rods):
        rows.append(
            dict(
                member=f"rod {r}",
                kind="rod",
                section=members.rod_label[r],
                length_m=float(structure.rod_length[r]),
                area_m2=float(members.rod_area[r]),
                second_moment_m4=float(members.rod_second_moment[r]),
                mass_kg=float(rod_mass[r]),
            )
        )
    stiffness = tendon_stiffness(structure, members)
    mass = tendon_masses(structure, members)
    for s in range(structure.n_tendons):
        rows.append(
            dict(
                member=structure.tendon_name[s],
                kind="tendon",
                section=members.tendon_label[s],
                length_m=float(structure.tendon_rest_length[s]),
                area_m2=float(members.tendon_area[s]),
                stiffness_N_per_m=float(stiffness[s]),
                mass_kg=float(mass[s]),
            )
        )
    return rows


@dataclasses.dataclass(frozen=True)
class MemberDesign:
    """The material and section of every member, as objects (what a structure file in the
    material form gives, ``docs/design.md``): tuples of one per rod (R,) and one per tendon
    (S,), whether the tendons' own mass is added to the nodes (:func:`with_members`), and the
    factors the members are checked with (:class:`Factors`: the file's ``factors``).

    :meth:`properties` gives the numbers (:class:`MemberProperties`) that
    :func:`~tensegrity.design.utilisation.utilisation` needs; :meth:`apply` the structure they
    make.
    """

    rod_material: tuple[Material, ...]
    rod_section: tuple[Section, ...]
    tendon_material: tuple[Material, ...]
    tendon_section: tuple[Section, ...]
    tendon_mass: bool = False
    factors: Factors = Factors()

    @classmethod
    def of(
        cls,
        structure: Structure,
        *,
        rod_material: Material | Sequence[Material],
        rod_section: Section | Sequence[Section],
        tendon_material: Material | Sequence[Material],
        tendon_section: Section | Sequence[Section],
        tendon_mass: bool = False,
        factors: Factors = Factors(),
    ) -> MemberDesign:
        """One material (section) for all rods (tendons) of ``structure``, or one per member;
        checked as :func:`member_properties` checks them."""
        if not isinstance(factors, Factors):
            raise TypeError(f"factors: expected a Factors, got {type(factors).__name__}")
        design = cls(
            tuple(per_member(rod_material, structure.n_rods, "rod_material", Material)),
            tuple(per_member(rod_section, structure.n_rods, "rod_section", _SECTIONS)),
            tuple(per_member(tendon_material, structure.n_tendons, "tendon_material", Material)),
            tuple(per_member(tendon_section, structure.n_tendons, "tendon_section", _SECTIONS)),
            tendon_mass,
            factors,
        )
        design.properties(structure)
        return design

    def properties(self, structure: Structure) -> MemberProperties:
        """:func:`member_properties` of these materials and sections for ``structure``."""
        return member_properties(
            structure,
            rod_material=self.rod_material,
            rod_section=self.rod_section,
            tendon_material=self.tendon_material,
            tendon_section=self.tendon_section,
        )

    def apply(self, structure: Structure, *, keep_tension: bool = False) -> Structure:
        """``structure`` with the stiffness ``E A / Lbar`` and masses ``rho A L`` of these
        members (:func:`with_members`, the tendons' mass too if :attr:`tendon_mass`).

        With ``keep_tension``, each taut tendon first gets the rest length
        ``Lbar = l E A / (E A + T)`` that keeps its tension ``T = k (l - Lbar)`` [N] at the
        structure's node positions (``l`` its length there) under the new stiffness: a
        prestressed structure keeps its prestress (its strain changes instead).  Slack
        tendons keep their rest length."""
        members = self.properties(structure)
        if keep_tension and structure.n_tendons:
            length = tendon_lengths(structure, structure.node_position)
            tension = elastic_tensions(structure, length)
            EA = members.tendon_modulus * members.tendon_area
            rest = np.where(tension > 0, length * EA / (EA + tension), structure.tendon_rest_length)
            structure = structure.replace(tendon_rest_length=rest)
        return with_members(structure, members, tendon_mass=self.tendon_mass)

    def without_tendon_mass(self, structure: Structure) -> Structure:
        """The inverse of :meth:`apply`'s lumping: ``structure``'s point masses less the
        tendons' share (the payloads a file gives); ``structure`` unchanged without
        :attr:`tendon_mass`."""
        if not self.tendon_mass or not structure.n_tendons:
            return structure
        extra = lumped_tendon_mass(structure, tendon_masses(structure, self.properties(structure)))
        free = structure.node_point_mass > 0
        point_mass = structure.node_point_mass.copy()
        point_mass[free] -= extra[free]
        return structure.replace(node_point_mass=point_mass)


_SECTIONS = (SolidRod, HollowTube, Cable)
