"""Rigid planes the nodes of a structure touch: the ground, an incline, a wall (:class:`Plane`).

A plane is the half-space boundary ``n . (x - point) = 0`` with ``n`` its unit normal, pointing
out of the solid.  Contact points are the rods' end nodes, as spheres of radius ``r`` (the run's
``contact_radius``): a point penetrates a plane by ``delta = r - n . (x - point)`` [m].

The normal law is the linear spring-damper (Kelvin-Voigt) of ``stiffness`` ``k`` [N/m] and
``damping`` ``c`` [N s/m]: while in contact the plane pushes with ``F_n = k delta + c delta'``,
and the contact ends where that force would pull (``F_n = 0``), so the force is continuous at
both ends of a contact.  Its coefficient of restitution for a point of mass ``m`` is
:meth:`Plane.restitution` (closed form, Schwager and Poeschel 2007).  Chosen over Hunt-Crossley
for that closed form and because a linear law keeps the stiffness a user sets the one the
frequencies follow; over a rigid law with restitution because a compliant contact needs no
impulses (the Zeno case of a bouncing rod ends in resting contact after finitely many bounces,
each contact lasting ``pi / omega``).

Friction is Coulomb's with a static coefficient ``friction`` and a kinetic one
``kinetic_friction`` (default the static one): a sticking point holds its tangential position
exactly (a constraint force, like a support's) while that force stays within ``friction * F_n``,
and slides with the force ``kinetic_friction * F_n`` against its sliding velocity otherwise.
The engine locates onset, lift-off, stick and slip as events (:mod:`tensegrity.engine.events`).

A :class:`Scene` is what a structure file carries beside the structure (its ``scene`` key,
``docs/simulation.md``, "Ground contact"): the planes, the contact radius and gravity of a run,
read and written by :mod:`tensegrity.io.formats` (:func:`~tensegrity.io.formats.read_scene`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from tensegrity.model.loads import gravity_vector
from tensegrity.model.structure import check_keys, parse_number, parse_vector

#: A contact pair's modes: free (no force), slipping (kinetic friction), sticking (held).
FREE, SLIP, STICK = 0, 1, 2
#: Their names (``SimulationResult.contact_mode``).
CONTACT_MODES = {FREE: "free", SLIP: "slip", STICK: "stick"}

__all__ = ["Plane", "Scene", "ground", "planes_of"]


def _vector(value: Any, name: str) -> np.ndarray:
    try:
        vector = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected 3 numbers, got {value!r:.60}") from None
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise ValueError(f"{name}: expected 3 finite numbers, got {value!r:.60}")
    return vector


def _number(value: Any, name: str, *, low: float, strict: bool) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    number = float(value) if ok else math.nan
    if not (math.isfinite(number) and (number > low if strict else number >= low)):
        bound = f"> {low:g}" if strict else f">= {low:g}"
        raise ValueError(f"{name}: must be a finite number {bound}, got {value!r}")
    return number


@dataclasses.dataclass(frozen=True)
class Plane:
    """A rigid plane with a compliant normal law and Coulomb friction (SI units).

    Attributes
    ----------
    point : (3,) array
        A point of the plane [m].
    normal : (3,) array
        Its normal, pointing out of the solid (normalized, unless of unit length to round-off
        already; a zero vector is refused).
    friction : float
        Static friction coefficient ``mu_s >= 0``.
    kinetic_friction : float, optional
        Kinetic friction coefficient ``0 <= mu_k <= mu_s``; default ``mu_s``.
    stiffness : float
        Normal stiffness ``k`` [N/m] of the contact spring, > 0.
    damping : float
        Normal damping ``c`` [N s/m] of the contact, >= 0.
    """

    point: Any = (0.0, 0.0, 0.0)
    normal: Any = (0.0, 0.0, 1.0)
    friction: float = 0.5
    kinetic_friction: float | None = None
    stiffness: float = 1e5
    damping: float = 100.0

    def __post_init__(self) -> None:
        normal = _vector(self.normal, "normal")
        length = float(np.linalg.norm(normal))
        if not length > 0:
            raise ValueError(f"normal: must not be zero, got {self.normal!r:.60}")
        object.__setattr__(self, "point", _vector(self.point, "point"))
        # (a normal of unit length to round-off is kept as it is, so that a plane made again
        # from its own fields, as a file is read back, is the same plane bit for bit)
        unit = abs(length - 1.0) <= 4.0 * np.finfo(float).eps
        object.__setattr__(self, "normal", normal if unit else normal / length)
        mu_s = _number(self.friction, "friction", low=0.0, strict=False)
        object.__setattr__(self, "friction", mu_s)
        mu_k = mu_s if self.kinetic_friction is None else self.kinetic_friction
        mu_k = _number(mu_k, "kinetic_friction", low=0.0, strict=False)
        if mu_k > mu_s:
            raise ValueError(f"kinetic_friction: must not exceed friction ({mu_s:g}), got {mu_k:g}")
        object.__setattr__(self, "kinetic_friction", mu_k)
        object.__setattr__(
            self, "stiffness", _number(self.stiffness, "stiffness", low=0.0, strict=True)
        )
        object.__setattr__(self, "damping", _number(self.damping, "damping", low=0.0, strict=False))

    def settings(self) -> dict[str, Any]:
        """The plane's fields as plain numbers and lists (a run's settings record)."""
        return {
            "point": self.point.tolist(),
            "normal": self.normal.tolist(),
            "friction": self.friction,
            "kinetic_friction": self.kinetic_friction,
            "stiffness": self.stiffness,
            "damping": self.damping,
        }

    def tangents(self) -> np.ndarray:
        """Two unit vectors (2, 3) spanning the plane, orthogonal to each other and to
        ``normal``."""
        n = self.normal
        helper = np.eye(3)[int(np.argmin(np.abs(n)))]
        t1 = np.cross(n, helper)
        t1 /= np.linalg.norm(t1)
        return np.array([t1, np.cross(n, t1)])

    def restitution(self, mass: float) -> float:
        """Coefficient of restitution of a point of ``mass`` [kg] hitting the plane along its
        normal (no gravity): the exit speed over the entry speed of the law ``m delta'' = -k
        delta - c delta'`` from ``delta = 0`` until the force ``k delta + c delta'`` is 0
        (Schwager and Poeschel, Phys. Rev. E 75, 2007).  Raises ``ValueError`` for damping at
        or above ``sqrt(2 k m)`` (the contact then ends at rest)."""
        omega0_sq = self.stiffness / mass
        beta = self.damping / (2.0 * mass)
        if not beta * beta < omega0_sq / 2.0:
            raise ValueError(
                f"damping: {self.damping:g} N s/m is too large for a restitution at mass "
                f"{mass:g} kg (needs < {math.sqrt(2 * self.stiffness * mass):.3g})"
            )
        omega = math.sqrt(omega0_sq - beta * beta)
        # contact ends at omega t = pi - atan(2 beta omega / (omega^2 - beta^2))
        end = (math.pi - math.atan2(2.0 * beta * omega, omega * omega - beta * beta)) / omega
        phase = omega * end
        return -math.exp(-beta * end) * (math.cos(phase) - beta / omega * math.sin(phase))


def ground(height: float = 0.0, **options: Any) -> Plane:
    """The horizontal plane ``z = height`` [m], normal ``+z``; ``options`` as :class:`Plane`'s."""
    return Plane(point=(0.0, 0.0, _number(height, "height", low=-math.inf, strict=True)), **options)


def planes_of(value: Any) -> tuple[Plane, ...]:
    """``simulate``'s ``ground``: a :class:`Plane` or several, as a tuple (``TypeError`` naming
    ``ground`` for anything else)."""
    if isinstance(value, Plane):
        return (value,)
    items = list(value) if isinstance(value, Iterable) and not isinstance(value, str) else None
    if not items or not all(isinstance(plane, Plane) for plane in items):
        raise TypeError(
            f"ground: expected a Plane or a sequence of Planes (tensegrity.Plane), got "
            f"{type(value).__name__}"
        )
    return tuple(items)


#: The keys of a plane in a file's ``scene.planes``: :class:`Plane`'s fields.
PLANE_KEYS = tuple(field.name for field in dataclasses.fields(Plane))
#: The keys of a file's ``scene``.
SCENE_KEYS = ("planes", "contact_radius", "gravity")


@dataclasses.dataclass(frozen=True, eq=False)
class Scene:
    """What a run puts around a structure: the planes its rods' ends touch, their contact
    radius and gravity (``simulate``'s ``ground``, ``contact_radius`` and ``gravity``).

    A structure file carries one under its ``scene`` key (:meth:`to_dict`, :meth:`from_dict`);
    the structure itself (:class:`~tensegrity.model.structure.Structure`) stays topology and
    parameters.  ``simulate(structure, t_span, **scene.simulate_options())`` runs in it.

    Attributes
    ----------
    planes : tuple of Plane
        The planes (none: free space).
    contact_radius : float
        Radius [m] of the rods' ends as contact spheres, >= 0.
    gravity : (d,) array or None
        Uniform gravity [m/s^2] (``d = 3``, or 2 for a planar structure); None: none.
    """

    planes: tuple[Plane, ...] = ()
    contact_radius: float = 0.0
    gravity: Any = None

    def __post_init__(self) -> None:
        planes = self.planes
        if not (isinstance(planes, (list, tuple)) and not planes):
            try:
                planes = planes_of(planes)
            except TypeError as exc:
                raise TypeError(str(exc).replace("ground:", "planes:", 1)) from None
        object.__setattr__(self, "planes", tuple(planes))
        radius = _number(self.contact_radius, "contact_radius", low=0.0, strict=False)
        object.__setattr__(self, "contact_radius", radius)
        if self.gravity is not None:
            try:
                gravity = np.array(self.gravity, dtype=float)
            except (TypeError, ValueError):
                gravity = np.full(0, np.nan)
            if gravity.shape not in ((2,), (3,)) or not np.all(np.isfinite(gravity)):
                raise ValueError(
                    f"gravity: expected 3 (or 2: planar) finite numbers [m/s^2], got "
                    f"{self.gravity!r:.60}"
                )
            gravity.setflags(write=False)
            object.__setattr__(self, "gravity", gravity)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scene):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(repr(self.to_dict()))

    def simulate_options(self) -> dict[str, Any]:
        """``simulate``'s ``ground`` (None without planes), ``contact_radius`` and
        ``gravity``."""
        return {
            "ground": self.planes or None,
            "contact_radius": self.contact_radius,
            "gravity": self.gravity,
        }

    def to_dict(self) -> dict[str, Any]:
        """The file's ``scene``: ``{"planes": [{point, normal, friction, kinetic_friction,
        stiffness, damping}, ...], "contact_radius": r, "gravity": [gx, gy, gz]}`` (``gravity``
        only when set); :meth:`from_dict` reads it back equal."""
        data: dict[str, Any] = {
            "planes": [plane.settings() for plane in self.planes],
            "contact_radius": self.contact_radius,
        }
        if self.gravity is not None:
            data["gravity"] = self.gravity.tolist()
        return data

    @classmethod
    def from_dict(cls, data: Any, *, dim: int = 3) -> Scene:
        """The scene of a file's ``scene`` key (a mapping of :data:`SCENE_KEYS`, each
        optional; a plane's keys those of :class:`Plane`, each optional, with its defaults),
        for a structure of dimension ``dim`` (3, or 2: planar; gravity has ``dim`` numbers, or
        is one number ``g`` down the last axis).

        Raises
        ------
        ValueError
            One line naming the key: ``scene.planes[1].normal: must not be zero, got [0, 0,
            0]``, ``scene.planes[0].friction: expected a number, got 'x'``, ...
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"scene: expected a mapping, got {type(data).__name__}")
        check_keys(data, SCENE_KEYS, "scene")
        planes = data.get("planes", [])
        if not isinstance(planes, Sequence) or isinstance(planes, str):
            raise ValueError(f"scene.planes: expected a list, got {type(planes).__name__}")
        radius = data.get("contact_radius", 0.0)
        gravity: Any = data.get("gravity")
        if isinstance(gravity, Sequence) and not isinstance(gravity, str):
            gravity = parse_vector(gravity, "scene.gravity", dim)
        elif gravity is not None:
            gravity = gravity_vector(parse_number(gravity, "scene.gravity"), dim)
        planes = tuple(_plane(item, f"scene.planes[{k}]") for k, item in enumerate(planes))
        try:
            return cls(planes, parse_number(radius, "scene.contact_radius"), gravity)
        except ValueError as exc:
            raise ValueError(f"scene.{exc}") from None


def _plane(item: Any, where: str) -> Plane:
    """The :class:`Plane` of one item of a file's ``scene.planes``; errors naming the key."""
    if not isinstance(item, Mapping):
        raise ValueError(f"{where}: expected a mapping, got {type(item).__name__}")
    check_keys(item, PLANE_KEYS, where)
    fields: dict[str, Any] = {
        key: parse_vector(value, f"{where}.{key}", 3)
        if key in ("point", "normal")
        else parse_number(value, f"{where}.{key}")
        for key, value in item.items()
        if not (key == "kinetic_friction" and value is None)
    }
    try:
        return Plane(**fields)
    except ValueError as exc:
        raise ValueError(f"{where}.{exc}") from None
