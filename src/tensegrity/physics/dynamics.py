"""Theorem 18.1 dynamics: explicit rod accelerations in end-point coordinates, tendon forces.

State per rod ``r`` with end nodes ``(a, b)`` (the paper's eq. 18.24)::

    q1 = p_a + p_b    (twice the mass centre)        q2 = p_b - p_a    (the rod vector, |q2| = L)

stacked rod by rod as ``q = [q1_0, q2_0, q1_1, q2_1, ...]`` (length ``6R``; for a shell this is
exactly the paper's ``q = [q_11, ..., q_n1, ..., q_nm]``), followed by the positions ``x`` of the
point masses (``Structure.point_mass_nodes``, 3 each; none in a class 1 structure).  Anchors
(fixed nodes of no rod) are not in ``q``.  Accelerations (eqs. 18.17, 18.20)::

    q1'' = (2/m) (f_a + f_b)
    q2'' = -(|q2'|^2 / L^2) q2 + (6 / (m L^2)) skew(q2)^2 (f_a - f_b)
    x''  = f / m                                   (a point mass)

plus, with joints and supports, the constraint forces of :mod:`tensegrity.physics.constraints`.

with ``f`` the total nodal forces: tendons (eqs. 18.39-18.40), external forces ``w`` and gravity.
No mass matrix is formed and no linear system is solved.  Every function is pure and vectorized
over rods and tendons; the ``q``-to-node maps also broadcast over leading (e.g. time) axes.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from tensegrity.model.structure import Structure
from tensegrity.physics.constraints import constraints_of
from tensegrity.physics.coordinates import (  # the coordinates are part of this reference's API
    coordinates_from_nodes,
    force_response,
    nodes_from_coordinates,
    point_mass_coordinates as point_mass_coordinates,
    rod_coordinates,
    rod_damping_acceleration,
    rod_damping_rates,
    rods_view as rods_view,
)


@dataclasses.dataclass(frozen=True, eq=False)
class State:
    """The time-varying state: time ``t`` [s], coordinates ``q`` (6R,) [m], rates ``qdot`` [m/s]."""

    t: float
    q: np.ndarray
    qdot: np.ndarray


def project_to_constraints(
    structure: Structure, q: np.ndarray, qdot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project onto the rod constraints: ``|q2| = L`` and ``q2 . q2' = 0`` for every rod, and
    onto the joints and supports (``A q = b``, ``A q' = 0``) if the structure has any.

    Returns new arrays ``(q, qdot)``.  Without joints and supports ``q1`` and ``q1'`` are
    unchanged; with them the projection is mass-weighted
    (:meth:`tensegrity.physics.constraints.LinearConstraints.project`).
    """
    constraints = constraints_of(structure)  # None without joints and supports
    if constraints is not None:
        return constraints.project(q, qdot)
    q, qdot = q.copy(), qdot.copy()
    q2, v2 = rod_coordinates(structure, q)[..., 1, :], rod_coordinates(structure, qdot)[..., 1, :]
    norm = np.linalg.norm(q2, axis=-1, keepdims=True)
    q2 *= structure.rod_length[:, None] / norm
    v2 -= np.sum(q2 * v2, axis=-1, keepdims=True) / structure.rod_length[:, None] ** 2 * q2
    return q, qdot


def rod_length_error(structure: Structure, q: np.ndarray) -> np.ndarray:
    """Relative rod-length error ``(|q2| - L) / L``, shape (..., R)."""
    q2 = rod_coordinates(structure, q)[..., 1, :]
    return np.linalg.norm(q2, axis=-1) / structure.rod_length - 1.0


def constraint_error(structure: Structure, q: np.ndarray) -> float:
    """Largest violation ``max |A q - b|`` [m] of the joints and supports (0 without any)."""
    constraints = constraints_of(structure)  # None without joints and supports
    if constraints is None:
        return 0.0
    return float(np.max(np.abs(constraints.residual(q)), initial=0.0))


def initial_state(structure: Structure, *, t: float = 0.0) -> State:
    """The state of the structure's node positions and velocities, projected onto the rod
    constraints (a velocity component that would stretch a rod is removed)."""
    q = coordinates_from_nodes(structure, structure.node_position)
    qdot = coordinates_from_nodes(structure, structure.node_velocity)
    q, qdot = project_to_constraints(structure, q, qdot)
    return State(t=float(t), q=q, qdot=qdot)


# --------------------------------------------------------------------------- tendons
def rest_lengths(structure: Structure, control: np.ndarray | None = None) -> np.ndarray:
    """Controlled rest lengths ``Lbar = L0 - u`` [m], shape (S,) (eq. 18.40).

    Raises
    ------
    ValueError
        If ``control`` has the wrong shape, is not finite, or makes some ``Lbar < 0``.
    """
    if control is None:
        return structure.tendon_rest_length
    u = np.asarray(control, dtype=float)
    if u.shape != (structure.n_tendons,):
        raise ValueError(f"control: expected shape ({structure.n_tendons},), got {u.shape}")
    if not np.all(np.isfinite(u)):
        raise ValueError("control: must be finite")
    rest = structure.tendon_rest_length - u
    bad = np.flatnonzero(rest < 0)
    if bad.size:
        s = bad[0]
        raise ValueError(
            f"control[{s}] ({structure.tendon_name[s]!r}): u = {u[s]} m makes the rest length "
            f"L0 - u = {rest[s]} m negative"
        )
    return rest


def tendon_vectors(structure: Structure, p: np.ndarray) -> np.ndarray:
    """Tendon vectors ``t = p_head - p_tail`` [m], shape (..., S, 3)."""
    return p[..., structure.tendon_nodes[:, 1], :] - p[..., structure.tendon_nodes[:, 0], :]


def tendon_lengths(structure: Structure, p: np.ndarray) -> np.ndarray:
    """Tendon lengths ``|t|`` [m], shape (..., S) (output ``y_l`` of eq. 18.60), from node
    positions ``p`` (..., N, dim): ``sqrt(t_x t_x + t_y t_y [+ t_z t_z])`` summed in that
    order, as the engine records them (``tensegrity.engine.compiled.tendon_lengths``), so that
    lengths computed from a file's ``q`` are bit for bit those of the run."""
    t = tendon_vectors(structure, p)
    squares = t[..., 0] * t[..., 0]
    for k in range(1, t.shape[-1]):
        squares = squares + t[..., k] * t[..., k]
    return np.sqrt(squares)


def elastic_tensions(
    structure: Structure, length: np.ndarray, rest_length: np.ndarray | None = None
) -> np.ndarray:
    """The tension law's elastic part ``k max(l - Lbar, 0)`` [N], shape (..., S) (eq. 18.40 with
    the slack rule): a taut tendon (``l > Lbar``) pulls with ``k (l - Lbar)``, a slack one not
    at all.  Every tension of the package outside the compiled kernel is this function.

    Parameters
    ----------
    structure : Structure
        The tendons' stiffnesses ``k`` [N/m], shape (S,), and their rest lengths ``L0`` [m].
    length : ndarray, shape (..., S)
        Tendon lengths ``l`` [m] (:func:`tendon_lengths`).
    rest_length : ndarray, shape (..., S), optional
        Rest lengths ``Lbar`` [m] (:func:`rest_lengths`); default ``L0``.
    """
    rest = structure.tendon_rest_length if rest_length is None else rest_length
    stretch = length - rest
    return np.where(stretch > 0, structure.tendon_stiffness * stretch, 0.0)


class TendonForces(NamedTuple):
    """Tendon quantities at one instant, each of shape (..., S) unless stated."""

    length: np.ndarray  #: ``|t|`` [m]
    length_rate: np.ndarray  #: ``d|t|/dt`` [m/s]
    direction: np.ndarray  #: ``t / |t|`` (..., S, 3); zero for a tendon of zero length
    tension: np.ndarray  #: total tension [N], >= 0
    elastic_tension: np.ndarray  #: ``k max(|t| - Lbar, 0)`` [N]


def tendon_forces(
    structure: Structure, p: np.ndarray, v: np.ndarray, rest_length: np.ndarray
) -> TendonForces:
    """Tendon tensions: ``T = max(k (l - Lbar) + c l', 0)`` while taut (``l > Lbar``), else 0.

    The elastic part is eq. 18.40 with the slack rule of the spec; the damping ``c l'`` acts only
    while taut, and a string never pushes (the sum is clipped at 0), so damping only dissipates.
    """
    t = tendon_vectors(structure, p)
    length = np.linalg.norm(t, axis=-1)
    direction = np.divide(t, length[..., None], out=np.zeros_like(t), where=length[..., None] > 0)
    length_rate = np.sum(direction * tendon_vectors(structure, v), axis=-1)
    taut = length - rest_length > 0
    elastic = elastic_tensions(structure, length, rest_length)
    tension = np.where(taut, np.maximum(elastic + structure.tendon_damping * length_rate, 0.0), 0.0)
    return TendonForces(length, length_rate, direction, tension, elastic)


def tendon_tensions(
    structure: Structure,
    p: np.ndarray,
    v: np.ndarray | None = None,
    *,
    control: np.ndarray | None = None,
) -> np.ndarray:
    """Tendon tensions [N], shape (..., S) (output ``y_f`` of eq. 18.60); damping needs ``v``."""
    v = np.zeros_like(p) if v is None else v
    return tendon_forces(structure, p, v, rest_lengths(structure, control)).tension


def _critical_rates(structure: Structure, what: str) -> tuple[np.ndarray, float]:
    """``(c, alpha)``: each tendon's critical damping ``c = 2 sqrt(k mu)`` [N s/m] (S,) and the
    rate ``alpha = 2 sqrt(k_mean / m_mean)`` [1/s] of :func:`artificial_damping`."""
    if not isinstance(structure, Structure):
        raise TypeError(f"structure: expected a Structure, got {type(structure).__name__}")
    if not (structure.n_rods and structure.n_tendons):
        raise ValueError(f"structure: {what} damping needs at least one rod and one tendon")
    m = structure.node_mass[structure.tendon_nodes]
    ma, mb = m[:, 0], m[:, 1]
    both = np.divide(ma * mb, ma + mb, out=np.zeros_like(ma), where=(ma > 0) & (mb > 0))
    reduced = np.where(ma == 0, mb, np.where(mb == 0, ma, both))
    rate = 2.0 * np.sqrt(structure.tendon_stiffness.mean() / structure.rod_mass.mean())
    return 2.0 * np.sqrt(structure.tendon_stiffness * reduced), float(rate)


def artificial_damping(structure: Structure) -> Structure:
    """The structure with the "artificial critical damping" of the paper's example (§18.5).

    The paper does not define it; ours has two parts (see ``docs/paper-notes.md``):

    - each tendon gets ``c = 2 sqrt(k mu)`` [N s/m], with ``mu = m_a m_b / (m_a + m_b)`` the
      reduced mass of its end nodes (half a rod's mass each): critical damping of the tendon's own
      axial vibration between two such point masses;
    - each rod gets mass-proportional damping *to ground* ``alpha = 2 sqrt(k_mean / m_mean)``
      [1/s] (``rod_damping``): critical damping of a rod of mean mass on a tendon of mean
      stiffness.  Tendon damping alone cannot remove the motion of a tensegrity's mechanisms
      (modes that change no tendon length to first order, stiffened only by prestress), so
      without this part a shell rocks for minutes.

    The second part drags the structure against the world frame: under gravity alone it falls
    at ``g / alpha`` instead of accelerating.  :func:`internal_damping` has the same rates but
    damps only deformation.

    An anchor (a fixed node of no rod) counts as infinitely heavy: a tendon to it gets the mass of
    its other end.  A point mass is its own mass; point masses get no mass-proportional damping.

    Raises
    ------
    TypeError
        If ``structure`` is not a :class:`Structure`.
    ValueError
        If the structure has no rod or no tendon (nothing to scale the damping with).
    """
    tendon, rate = _critical_rates(structure, "artificial")
    return structure.replace(
        tendon_damping=tendon,
        rod_damping=np.full(structure.n_rods, rate),
        rod_relative_damping=np.zeros(structure.n_rods),
    )


def internal_damping(structure: Structure) -> Structure:
    """The structure with critical *internal* damping: the default of ``tensegrity simulate``.

    The rates of :func:`artificial_damping`, acting on deformation only:

    - each tendon gets ``c = 2 sqrt(k mu)`` [N s/m] (as there);
    - each rod gets ``alpha = 2 sqrt(k_mean / m_mean)`` [1/s] of mass-proportional damping
      *relative to the structure's rigid-body motion* (``rod_relative_damping``;
      :func:`tensegrity.physics.coordinates.rigid_body_rates`).

    It conserves linear and angular momentum: a free structure falls at ``g`` and a spinning one
    keeps spinning while its deformation dies out.  A structure that starts at rest with no
    external force (the paper's example) has no rigid-body motion to keep, and moves exactly as
    with :func:`artificial_damping` (to round-off).  A structure held by supports is damped
    relative to the ground (:func:`tensegrity.physics.coordinates.rod_damping_rates`), as with
    :func:`artificial_damping`.

    Raises
    ------
    TypeError
        If ``structure`` is not a :class:`Structure`.
    ValueError
        If the structure has no rod or no tendon.
    """
    tendon, rate = _critical_rates(structure, "internal")
    return structure.replace(
        tendon_damping=tendon,
        rod_damping=np.zeros(structure.n_rods),
        rod_relative_damping=np.full(structure.n_rods, rate),
    )


def undamped(structure: Structure) -> Structure:
    """``structure`` without tendon or rod damping of any kind."""
    return structure.replace(
        tendon_damping=np.zeros(structure.n_tendons),
        rod_damping=np.zeros(structure.n_rods),
        rod_relative_damping=np.zeros(structure.n_rods),
    )


def describe_damping(structure: Structure) -> str:
    """One line naming the damping of ``structure`` as the equations apply it, e.g.
    ``"internal: tendons 0.707..1 N s/m, rods 40 1/s relative to the rigid-body motion"``."""
    alpha, beta = rod_damping_rates(structure)
    c = structure.tendon_damping
    parts = [
        *([f"tendons {_span(c)} N s/m"] if np.any(c) else []),
        *([f"rods {_span(beta)} 1/s relative to the rigid-body motion"] if np.any(beta) else []),
        *([f"rods {_span(alpha)} 1/s to ground"] if np.any(alpha) else []),
    ]
    if not parts:
        return "none"
    if np.any(structure.rod_damping):
        return "artificial (drags the structure against the world frame): " + ", ".join(parts)
    supported = " (the supports are the reference)" if np.any(alpha) else ""
    return f"internal{supported}: " + ", ".join(parts)


def _span(values: np.ndarray) -> str:
    """``"40"`` or ``"0.707..1"``: the range of the non-zero ``values``, 3 significant digits."""
    values = values[values != 0]
    low, high = f"{values.min():.3g}", f"{values.max():.3g}"
    return low if low == high else f"{low}..{high}"


#: The named kinds of damping (``tensegrity simulate --damping``); the first is the default.
DAMPING_KINDS = {"internal": internal_damping, "artificial": artificial_damping, "none": undamped}


# --------------------------------------------------------------------------- accelerations
#: Kinetic energy is ``sum m (|q1'|^2 / 8 + |q2'|^2 / 24)``; a rod's damping term ``a`` of ``q''``
#: (subtracted) then dissipates ``m (q1' . a1 / 4 + q2' . a2 / 12)``: these are the weights x 2.
_INERTIA_WEIGHT = np.array([[1 / 4], [1 / 12]])


class Evaluation(NamedTuple):
    """One evaluation of the equations of motion."""

    qddot: np.ndarray  #: accelerations (6R,) [m/s^2]
    tendons: TendonForces
    dissipated_power: float  #: power removed by tendon and rod damping [W], >= 0
    external_power: float  #: power delivered by the external nodal forces ``w`` [W]
    #: forces of the joints and supports on the nodes (N, 3) [N] (reactions at anchors), or None
    constraint_force: np.ndarray | None = None


def evaluate(
    structure: Structure,
    q: np.ndarray,
    qdot: np.ndarray,
    *,
    rest_length: np.ndarray,
    external_force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
) -> Evaluation:
    """Evaluate Theorem 18.1 for all rods (eqs. 18.17-18.20, 18.39-18.40).

    Parameters
    ----------
    q, qdot : ndarray, shape (6R,)
        Coordinates [m] and rates [m/s].
    rest_length : ndarray, shape (S,)
        Controlled rest lengths ``Lbar`` [m] (see :func:`rest_lengths`).
    external_force : ndarray, shape (N, 3), optional
        Nodal forces ``w`` [N].
    gravity : ndarray, shape (3,), optional
        Uniform gravitational acceleration [m/s^2]; each end node carries half the rod's weight.
    """
    p = nodes_from_coordinates(structure, q)
    v = nodes_from_coordinates(structure, qdot, rates=True)
    tendons = tendon_forces(structure, p, v, rest_length)
    # f = -C^T (T t_hat): the tail is pulled toward the head and the head toward the tail.
    force = -(structure.tendon_incidence_transpose @ (tendons.tension[:, None] * tendons.direction))
    external_power = 0.0
    if external_force is not None:
        force += external_force
        external_power = float(np.sum(external_force * v))
    if gravity is not None:
        force += structure.node_mass[:, None] * gravity

    rates = rod_coordinates(structure, qdot)
    qddot = force_response(structure, q, force, rates=rates)
    reaction = None
    constraints = constraints_of(structure)  # None without joints and supports
    if constraints is not None:
        reaction = constraints.constraint_force(q, qddot)
        qddot += force_response(structure, q, reaction)
    rod_damping = rod_damping_acceleration(structure, rod_coordinates(structure, q), rates)
    dissipated = float(
        np.sum((tendons.tension - tendons.elastic_tension) * tendons.length_rate)
        + np.sum(structure.rod_mass[:, None, None] * _INERTIA_WEIGHT * rates * rod_damping)
    )
    return Evaluation(qddot, tendons, dissipated, external_power, reaction)


def accelerations(
    structure: Structure,
    q: np.ndarray,
    qdot: np.ndarray,
    *,
    control: np.ndarray | None = None,
    external_force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
) -> np.ndarray:
    """``q''`` (6R,) [m/s^2] of eq. 18.59: ``q'' = -(K_r(q') + K_p(q)) q + B(q) u + D(q) w``.

    ``control`` is the rest-length change ``u`` (S,) [m]; see :func:`evaluate` for the rest.
    """
    return evaluate(
        structure,
        q,
        qdot,
        rest_length=rest_lengths(structure, control),
        external_force=external_force,
        gravity=gravity,
    ).qddot


# --------------------------------------------------------------------------- energy
def kinetic_energy(structure: Structure, qdot: np.ndarray) -> np.ndarray:
    """Kinetic energy [J] with each rod's true inertia, shape (...,):
    ``sum m/8 |q1'|^2 + m/24 |q2'|^2`` (translation of the centre plus rotation, ``I = m L^2/12``),
    plus ``m |x'|^2 / 2`` per point mass."""
    rates = rod_coordinates(structure, qdot)
    per_rod = structure.rod_mass * (
        np.sum(rates[..., 0, :] ** 2, axis=-1) / 8 + np.sum(rates[..., 1, :] ** 2, axis=-1) / 24
    )
    energy = per_rod.sum(axis=-1)
    if structure.point_mass_nodes.size:
        x_dot = point_mass_coordinates(structure, qdot)
        mass = structure.node_point_mass[structure.point_mass_nodes]
        energy = energy + 0.5 * np.sum(mass * np.sum(x_dot**2, axis=-1), axis=-1)
    return energy


def elastic_energy(
    structure: Structure, p: np.ndarray, rest_length: np.ndarray | None = None
) -> np.ndarray:
    """Elastic energy of the taut tendons ``sum k max(l - Lbar, 0)^2 / 2`` [J], shape (...,)."""
    rest = structure.tendon_rest_length if rest_length is None else rest_length
    stretch = np.maximum(tendon_lengths(structure, p) - rest, 0.0)
    return 0.5 * np.sum(structure.tendon_stiffness * stretch**2, axis=-1)


def gravity_energy(structure: Structure, q: np.ndarray, gravity: np.ndarray | None) -> np.ndarray:
    """Gravitational potential ``-sum m g . (q1/2)`` (rods) ``- sum m g . x`` (point masses) [J],
    shape (...,); zero without gravity."""
    if gravity is None:
        return np.zeros(q.shape[:-1])
    g = np.asarray(gravity, dtype=float)
    centre = 0.5 * rod_coordinates(structure, q)[..., 0, :]
    energy = -np.sum(structure.rod_mass * (centre @ g), axis=-1)
    if structure.point_mass_nodes.size:
        x = point_mass_coordinates(structure, q)
        energy = energy - np.sum(
            structure.node_point_mass[structure.point_mass_nodes] * (x @ g), axis=-1
        )
    return energy
