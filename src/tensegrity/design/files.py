"""Structure files in the material form: members given by material and section.

The readable network form (YAML, TOML, or JSON with ``"format": "tensegrity-network"``;
``docs/networks.md``) gives each rod a ``mass`` [kg] and each tendon a ``stiffness`` [N/m].
In the material form a member (or ``defaults.rod`` / ``defaults.tendon``, for every member of
its kind) gives instead

- ``material``: a name of :data:`~tensegrity.design.materials.MATERIALS` (``steel``), or a
  mapping of its properties ``{name, youngs_modulus [Pa], density [kg/m^3], yield_strength
  [Pa], ultimate_strength [Pa] (default the yield strength), source}``;
- ``section``: ``{diameter: D}`` [m] (a solid round rod; for a tendon a cable), or
  ``{diameter: D, wall: t}`` [m] (a round tube);

and the top level may say ``tendon_mass: true`` (the tendons' own mass added to the nodes,
:func:`~tensegrity.design.materials.with_members`) and ``factors: {safety: gamma, strength:
s}`` (each >= 1, default 1: :class:`~tensegrity.design.materials.Factors`, the factors the
members' utilisation is computed with, as ``tensegrity design`` sized them; only in the
material form).  The structure is then built by
:meth:`MemberDesign.apply <tensegrity.design.materials.MemberDesign.apply>`: tendon stiffness
``E A / Lbar`` (``Lbar`` the rest length the file gives, or its prestrain's), rod mass
``rho A L``.  Every member is in one form: all of them in the material form, or none; a member
given both (``mass`` and a material, say) is an error naming it.

:func:`read_design` reads either form (and ``.npz``, numeric only) and returns the structure
with its :class:`~tensegrity.design.materials.MemberDesign` (None for the numeric form);
:func:`write_design` writes the material form back: reading it gives the same structure and
design.  A trajectory file of a run whose members have a design carries that document too
(:func:`tensegrity.io.trajectory.write_trajectory`'s ``material_form``);
:func:`trajectory_design` reads it back.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tensegrity.design.materials import (
    MATERIALS,
    Cable,
    Factors,
    HollowTube,
    Material,
    MemberDesign,
    Section,
    SolidRod,
    material,
)
from tensegrity.io.files import PathLike, file_error
from tensegrity.io.formats import (
    file_format,
    network_from_dict,
    network_to_dict,
    read_document,
    read_network,
    with_scene,
    write_document,
)
from tensegrity.io.trajectory import MATERIAL_FORM, read_trajectory_structure
from tensegrity.model.ground import Scene
from tensegrity.model.structure import Structure, check_keys, parse_number

__all__ = [
    "Designed",
    "design_from_dict",
    "design_to_dict",
    "read_design",
    "same_members",
    "trajectory_design",
    "write_design",
]

#: Keys of a material given as a mapping (``ultimate_strength``, ``name``, ``source`` optional).
MATERIAL_KEYS = (
    "name",
    "youngs_modulus",
    "density",
    "yield_strength",
    "ultimate_strength",
    "source",
)
#: Keys of the top level's ``factors`` (:class:`~tensegrity.design.materials.Factors`' fields).
FACTOR_KEYS = ("safety", "strength")
#: The numeric key each kind of member gives in the other form.
_NUMERIC = {"rod": "mass", "tendon": "stiffness"}


class Designed(NamedTuple):
    """A structure read from a file and the design of its members (None: the numeric form)."""

    structure: Structure
    design: MemberDesign | None


def read_design(path: PathLike, *, format: str | None = None) -> Designed:
    """Read a structure file in either form (by suffix, or ``format``): see the module
    docstring.  A ``.npz`` file or a JSON file of :meth:`Structure.to_dict` is the numeric form.

    Raises
    ------
    ValueError
        One line starting with the file name and naming the member or key at fault.
    """
    kind = file_format(path, format)
    if kind not in ("json", "yaml", "toml"):
        return Designed(read_network(path, format=kind), None)
    data = read_document(path, format=kind)
    if kind == "json" and not (isinstance(data, Mapping) and "format" in data):
        return Designed(read_network(path, format=kind), None)  # Structure.to_dict's form
    try:
        return design_from_dict(data)
    except ValueError as exc:
        raise file_error(path, str(exc)) from exc
    except (TypeError, KeyError, OverflowError) as exc:
        raise file_error(path, str(exc) or type(exc).__name__) from exc


def trajectory_design(path: PathLike) -> Designed:
    """The structure of a trajectory file and its members' design, from the material form the
    file carries (a run whose members have a design:
    :func:`tensegrity.io.trajectory.read_trajectory_structure`); the design is None for a file
    without one (a run without a design, or a file written before trajectories carried it).

    The structure is the trajectory's own (its exact numbers); the design's factors are those
    the run's utilisation was computed with.

    Raises
    ------
    ValueError
        One line starting with the file name: the trajectory's (missing, not a trajectory, ...,
        as :func:`~tensegrity.io.trajectory.read_trajectory`), or naming the attribute
        ``structure_material`` if it is not the material form of the trajectory's structure.
    """
    structure, form = read_trajectory_structure(path)
    if form is None:
        return Designed(structure, None)
    where = f"attribute {MATERIAL_FORM!r}"
    try:
        given = design_from_dict(form)
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        raise file_error(path, f"{where}: {str(exc) or type(exc).__name__}") from exc
    if given.design is None:
        raise file_error(path, f"{where}: gives no materials and sections")
    if not same_members(given.structure, structure):
        raise file_error(
            path, f"{where}: not the structure of the trajectory (other nodes, rods or tendons)"
        )
    return Designed(structure, given.design)


def same_members(one: Structure, other: Structure) -> bool:
    """Whether ``one`` and ``other`` have the same number of nodes and the same rods and
    tendons between the same nodes (what a design of one needs of the other)."""
    return (
        one.n_nodes == other.n_nodes
        and np.array_equal(one.rod_nodes, other.rod_nodes)
        and np.array_equal(one.tendon_nodes, other.tendon_nodes)
    )


def design_from_dict(data: Any) -> Designed:
    """The structure and member design of a readable-form document (either form)."""
    factors = data.get("factors") if isinstance(data, Mapping) else None
    if factors is not None:
        data = {key: value for key, value in data.items() if key != "factors"}
    numeric, given, tendon_mass = _split(data)
    structure = network_from_dict(numeric)
    if given is None:
        if factors is not None:
            raise ValueError(
                "factors: only with members by material and section (the material form: "
                "the factors divide their strengths)"
            )
        return Designed(structure, None)
    if not isinstance(tendon_mass, bool):
        raise ValueError(f"tendon_mass: expected true or false, got {tendon_mass!r:.80}")
    choice: dict[str, tuple[list[Material], list[Section]]] = {}
    for kind in ("rod", "tendon"):
        choice[kind] = _members_design(data, given, kind)
    design = MemberDesign(
        tuple(choice["rod"][0]),
        tuple(choice["rod"][1]),
        tuple(choice["tendon"][0]),
        tuple(choice["tendon"][1]),
        tendon_mass,
        _factors(factors),
    )
    return Designed(design.apply(structure), design)


def _factors(value: Any) -> Factors:
    """The file's ``factors``: ``{safety: gamma, strength: s}``, each >= 1 (default 1)."""
    if value is None:
        return Factors()
    if not isinstance(value, Mapping):
        raise ValueError(
            f"factors: expected a mapping {{safety: GAMMA, strength: S}}, got "
            f"{type(value).__name__}"
        )
    check_keys(value, FACTOR_KEYS, "factors")
    numbers = {key: parse_number(value[key], f"factors.{key}") for key in value}
    try:
        return Factors(**numbers)
    except ValueError as exc:
        raise ValueError(f"factors.{exc}") from None


def _split(data: Any) -> tuple[Any, dict[str, Any] | None, Any]:
    """``data`` without the material form's keys; those keys (``{"defaults": {kind: {...}},
    "rod": [{...} per rod], "tendon": [...]}``, None if there are none); ``tendon_mass``."""
    if not isinstance(data, Mapping):
        return data, None, False
    numeric = dict(data)
    given: dict[str, Any] = {"defaults": {}, "rod": [], "tendon": []}
    found = "tendon_mass" in numeric
    tendon_mass = numeric.pop("tendon_mass", False)

    def take(item: Any) -> tuple[Any, dict[str, Any]]:
        nonlocal found
        if not isinstance(item, Mapping):
            return item, {}
        keys = {key: item[key] for key in ("material", "section") if key in item}
        found = found or bool(keys)
        return {key: value for key, value in item.items() if key not in keys}, keys

    defaults = numeric.get("defaults")
    if isinstance(defaults, Mapping):
        defaults = dict(defaults)
        for kind in ("rod", "tendon"):
            if kind in defaults:
                defaults[kind], given["defaults"][kind] = take(defaults[kind])
        numeric["defaults"] = defaults
    for kind in ("rod", "tendon"):
        items = numeric.get(kind + "s")
        if isinstance(items, Sequence) and not isinstance(items, str):
            pairs = [take(item) for item in items]
            numeric[kind + "s"] = [item for item, _ in pairs]
            given[kind] = [keys for _, keys in pairs]
    return numeric, (given if found else None), tendon_mass


def _members_design(
    data: Mapping[str, Any], given: dict[str, Any], kind: str
) -> tuple[list[Material], list[Section]]:
    """The material and section of every member of ``kind`` (``"rod"``, ``"tendon"``): its own,
    else ``defaults``'; one-line errors naming the member."""
    default = given["defaults"].get(kind, {})
    defaults = data.get("defaults") or {}
    numeric_default = _NUMERIC[kind] in (defaults.get(kind) or {})
    materials: list[Material] = []
    sections: list[Section] = []
    for k, (item, own) in enumerate(zip(data[kind + "s"], given[kind], strict=True)):
        label = f"{kind}s[{k}]" + (f" ({item['name']!r})" if "name" in item else "")
        chosen = {key: own.get(key, default.get(key)) for key in ("material", "section")}
        numeric = _NUMERIC[kind] in item or numeric_default
        if numeric and any(value is not None for value in chosen.values()):
            where = "" if _NUMERIC[kind] in item else f" (under defaults.{kind})"
            raise ValueError(
                f"{label}: gives both {_NUMERIC[kind]}{where} and a material and section; "
                f"give one form: {_NUMERIC[kind]}, or material and section"
            )
        missing = [key for key, value in chosen.items() if value is None]
        if missing:
            raise ValueError(
                f"{label}: no {' and no '.join(missing)} (other members are given by material "
                f"and section: give every member both, its own or under defaults.{kind})"
            )
        origin = {key: label if key in own else f"defaults.{kind}" for key in chosen}
        materials.append(_material(chosen["material"], f"{origin['material']}.material"))
        sections.append(_section(chosen["section"], f"{origin['section']}.section", kind))
    return materials, sections


def _material(value: Any, where: str) -> Material:
    """A material of the file: a table name or a mapping of :data:`MATERIAL_KEYS`."""
    if isinstance(value, str):
        if value not in MATERIALS:
            raise ValueError(f"{where}: unknown {value!r}; one of {', '.join(sorted(MATERIALS))}")
        return material(value)
    if not isinstance(value, Mapping):
        raise ValueError(
            f"{where}: expected a material name or a mapping of its properties, got "
            f"{type(value).__name__}"
        )
    check_keys(value, MATERIAL_KEYS, where)
    numbers = {}
    for key in ("youngs_modulus", "density", "yield_strength", "ultimate_strength"):
        if key in value:
            numbers[key] = parse_number(value[key], f"{where}.{key}")
        elif key != "ultimate_strength":
            raise ValueError(f"{where}: missing key {key!r}")
    numbers.setdefault("ultimate_strength", numbers["yield_strength"])
    for key in ("name", "source"):
        if not isinstance(value.get(key, ""), str):
            raise ValueError(f"{where}.{key}: expected text, got {value[key]!r:.80}")
    try:
        return Material(name=value.get("name", "custom"), source=value.get("source", ""), **numbers)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _section(value: Any, where: str, kind: str) -> Section:
    """``{diameter}`` (a solid rod, or a tendon's cable) or ``{diameter, wall}`` (a tube) [m]."""
    if not isinstance(value, Mapping):
        raise ValueError(
            f"{where}: expected a mapping {{diameter: D}} or {{diameter: D, wall: t}} [m], got "
            f"{type(value).__name__}"
        )
    check_keys(value, ("diameter", "wall"), where)
    if "diameter" not in value:
        raise ValueError(f"{where}: missing key 'diameter'")
    diameter = parse_number(value["diameter"], f"{where}.diameter")
    try:
        if "wall" in value:
            return HollowTube(diameter, parse_number(value["wall"], f"{where}.wall"))
        return SolidRod(diameter) if kind == "rod" else Cable(diameter)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def design_to_dict(
    structure: Structure,
    design: MemberDesign,
    *,
    keep_joints: bool = False,
    scene: Scene | None = None,
) -> dict[str, Any]:
    """The material form of ``structure`` (built by ``design``, :meth:`MemberDesign.apply`):
    :func:`~tensegrity.io.formats.network_to_dict` with each rod's ``mass`` and tendon's
    ``stiffness`` replaced by its ``material`` and ``section`` (under ``defaults`` when shared),
    ``tendon_mass`` if set, and the point masses the file gives (less the tendons' share);
    ``scene`` (if given and not empty) last, under ``"scene"``.

    Raises
    ------
    ValueError
        ``structure``'s stiffness or rod masses are not those ``design`` makes (naming the
        first member): the material form would change them.

    ``design``'s factors are written under ``"factors"`` unless they are the default (1, 1).
    """
    base = design.without_tendon_mass(structure)
    built = design.apply(base)
    for kind, ours, theirs, names in (
        ("rods", built.rod_mass, structure.rod_mass, None),
        ("tendons", built.tendon_stiffness, structure.tendon_stiffness, structure.tendon_name),
    ):
        bad = np.flatnonzero(~np.isclose(ours, theirs, rtol=1e-12, atol=0.0))
        if bad.size:
            k = bad[0]
            what = "mass" if names is None else "stiffness"
            raise ValueError(
                f"{kind}[{k}]{'' if names is None else f' ({names[k]!r})'}: {what} "
                f"{theirs[k]:.17g} is not the design's {ours[k]:.17g}"
            )
    data = network_to_dict(base, keep_joints=keep_joints)
    defaults = data.pop("defaults")
    rods, tendons = data.pop("rods"), data.pop("tendons")
    if design.tendon_mass:
        data["tendon_mass"] = True
    if design.factors != Factors():
        data["factors"] = dataclasses.asdict(design.factors)
    for kind, items, materials, sections in (
        ("rod", rods, design.rod_material, design.rod_section),
        ("tendon", tendons, design.tendon_material, design.tendon_section),
    ):
        table = defaults.setdefault(kind, {})
        table.pop(_NUMERIC[kind], None)
        for item in items:
            item.pop(_NUMERIC[kind], None)
        for key, values, written in (
            ("material", materials, [_material_value(m) for m in materials]),
            ("section", sections, [_section_value(s) for s in sections]),
        ):
            if values and all(value == values[0] for value in values):
                table[key] = written[0]
            else:
                for item, value in zip(items, written, strict=True):
                    item[key] = value
        if not table:
            del defaults[kind]
    if defaults:
        data["defaults"] = defaults
    data["rods"], data["tendons"] = rods, tendons
    return with_scene(data, scene)


def _material_value(m: Material) -> str | dict[str, Any]:
    """A table material by name; any other by its properties."""
    if MATERIALS.get(m.name) == m:
        return m.name
    value = dataclasses.asdict(m)
    if not value["source"]:
        del value["source"]
    return value


def _section_value(section: Section) -> dict[str, float]:
    if isinstance(section, HollowTube):
        return {"diameter": section.outer_diameter, "wall": section.wall_thickness}
    return {"diameter": section.diameter}


def write_design(
    path: PathLike,
    structure: Structure,
    design: MemberDesign,
    *,
    format: str | None = None,
    keep_joints: bool = False,
    scene: Scene | None = None,
) -> Path:
    """Write ``structure`` in the material form (:func:`design_to_dict`) as YAML, TOML or JSON
    (by suffix, or ``format``), atomically; :func:`read_design` reads back the same structure
    and design, its factors too (a tendon's :class:`SolidRod` section is read back as the
    :class:`Cable` of its diameter: the same area); ``scene`` goes under the file's ``"scene"``
    key (:func:`tensegrity.io.formats.read_scene` reads it back)."""
    data = design_to_dict(structure, design, keep_joints=keep_joints, scene=scene)
    header = (
        f"# {len(data['nodes'])} nodes, {structure.n_rods} rods, {structure.n_tendons} tendons, "
        "members by material and section; SI units\n"
    )
    return write_document(path, data, format=format, header=header)
