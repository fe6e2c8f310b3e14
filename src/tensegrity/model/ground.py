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
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

import numpy as np

#: A contact pair's modes: free (no force), slipping (kinetic friction), sticking (held).
FREE, SLIP, STICK = 0, 1, 2
#: Their names (``SimulationResult.contact_mode``).
CONTACT_MODES = {FREE: "free", SLIP: "slip", STICK: "stick"}

__all__ = ["Plane", "ground", "planes_of"]


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
        Its normal, pointing out of the solid (normalized; a zero vector is refused).
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
        object.__setattr__(self, "normal", normal / length)
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
