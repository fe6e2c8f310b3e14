"""Reduced coordinates that respect the rod-length constraints, and rigid-body motions.

Every rod ``r`` (end nodes ``a``, ``b``, length ``L``) is described by its centre ``c`` (3) and
its unit direction ``n`` (``p_a = c - (L/2) n``, ``p_b = c + (L/2) n``, so ``q1 = 2 c`` and
``q2 = L n`` of :mod:`tensegrity.physics.dynamics`).  About a *base* configuration ``(c0, n0)``
we use, per rod, the 5 numbers::

    x_r = [dc (3), phi (2)],   c = c0 + dc,   n = (n0 + E phi) / sqrt(1 + |phi|^2)

with ``E = [e1, e2]`` an orthonormal basis of the plane perpendicular to ``n0`` (the gnomonic
chart of the unit sphere: exact for any ``phi``, it covers the open hemisphere about ``n0``, and
at ``phi = 0`` the two angles are small rotations about ``e2`` and ``-e1``).  Stacked rod by rod,
``x`` has ``5R`` entries: the degrees of freedom of the structure (spin about a rod's own axis
is not one).  Every configuration built from ``x`` satisfies ``|q2| = L`` exactly.

The kinetic energy in these coordinates at ``phi = 0`` is ``x'^T M x' / 2`` with
``M = diag(m, m, m, m L^2/12, m L^2/12)`` per rod: :func:`mass_matrix`.

Point masses (nodes of no rod, ``Structure.point_mass_nodes``) follow the rods: 3 numbers each,
their displacement from the base (``M = diag(m, m, m)``), so ``x`` has ``5R + 3M`` entries.
Joints and supports are *not* eliminated from ``x``: they are the constraints
``g(x) = A q(x) - b = 0`` of :mod:`tensegrity.physics.constraints`, nonlinear in ``x`` through
the rod angles, with tangent ``G = A_n J(x)`` (:meth:`Chart.constraint_jacobian`).  A planar
structure is analysed as its 3-D form with every node held on the plane ``z = 0``
(:func:`spatial`).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, overload

import numpy as np

from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics
from tensegrity.physics.constraints import constraints_of

#: Rigid-body motions of a free structure in 3-D: 3 translations and 3 rotations.
N_RIGID = 6

#: Relative size below which a rigid-body motion counts as none (:func:`rigid_body_basis`).
RTOL_RIGID = 1e-10


def tangent_basis(direction: np.ndarray) -> np.ndarray:
    """Orthonormal ``E = [e1, e2]`` (..., 3, 2) perpendicular to unit vectors ``direction``
    (..., 3).

    Deterministic: ``e1`` is ``z x n`` normalized (``x x n`` when ``n`` is within 0.1 rad of z),
    ``e2 = n x e1``.
    """
    n = np.asarray(direction, dtype=float)
    z = np.broadcast_to([0.0, 0.0, 1.0], n.shape)
    x = np.broadcast_to([1.0, 0.0, 0.0], n.shape)
    near_z = np.abs(n[..., 2:3]) > np.cos(0.1)
    helper = np.where(near_z, x, z)
    e1 = np.cross(helper, n)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(n, e1)
    return np.stack([e1, e2], axis=-1)


@dataclasses.dataclass(frozen=True, eq=False)
class Chart:
    """The reduced coordinates about a base configuration (see the module docstring).

    Attributes
    ----------
    structure : Structure (3-D: a planar one is analysed as its :func:`spatial` form)
    centre : (R, 3) base rod centres ``c0`` [m].
    direction : (R, 3) base unit rod directions ``n0``.
    basis : (R, 3, 2) tangent bases ``E`` at ``n0``.
    point_mass : (M, 3) base positions of the point masses [m].
    """

    structure: Structure
    centre: np.ndarray
    direction: np.ndarray
    basis: np.ndarray
    point_mass: np.ndarray

    @classmethod
    def at(cls, structure: Structure, q: np.ndarray) -> Chart:
        """The chart based at the configuration ``q`` (n,) (``x = 0`` there)."""
        if structure.dim != 3:
            raise ValueError(
                "the analysis package: a planar structure is analysed in its 3-D form "
                "(tensegrity.analysis.coordinates.spatial)"
            )
        q = np.asarray(q, dtype=float)
        rods = dynamics.rod_coordinates(structure, q)
        centre = 0.5 * rods[:, 0]
        direction = rods[:, 1] / np.linalg.norm(rods[:, 1], axis=1, keepdims=True)
        point_mass = dynamics.point_mass_coordinates(structure, q)
        return cls(structure, centre.copy(), direction, tangent_basis(direction), point_mass.copy())

    @property
    def n_rod_coordinates(self) -> int:
        """``5 R``: the rods' part of ``x``."""
        return 5 * self.structure.n_rods

    @property
    def size(self) -> int:
        """``5 R + 3 M``."""
        return self.n_rod_coordinates + self.point_mass.size

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(dc (R, 3), phi (R, 2))`` views of the rods' part of ``x`` (5R + 3M,)."""
        rods = np.asarray(x, dtype=float)[: self.n_rod_coordinates].reshape(-1, 5)
        return rods[:, :3], rods[:, 3:]

    def _with_point_masses(self, rods: np.ndarray, point_mass: np.ndarray) -> np.ndarray:
        """``rods`` (R, k) flattened, followed by ``point_mass`` (M, 3) if there are any."""
        if not self.point_mass.size:
            return rods.reshape(-1)
        return np.concatenate([rods.reshape(-1), point_mass.reshape(-1)])

    def _point_part(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=float)[self.n_rod_coordinates :].reshape(-1, 3)

    def directions(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(c (R, 3), n (R, 3), s (R,))`` with ``s = sqrt(1 + |phi|^2)``."""
        dc, phi = self.split(x)
        s = np.sqrt(1.0 + np.sum(phi**2, axis=1))
        n = (self.direction + np.einsum("rij,rj->ri", self.basis, phi)) / s[:, None]
        return self.centre + dc, n, s

    def q(self, x: np.ndarray) -> np.ndarray:
        """Coordinates ``q`` (n,) of ``x``: ``q1 = 2 c``, ``q2 = L n`` (rod lengths exact), then
        the point masses' positions."""
        c, n, _ = self.directions(x)
        q = np.stack([2.0 * c, self.structure.rod_length[:, None] * n], axis=1)
        return self._with_point_masses(q, self.point_mass + self._point_part(x))

    def nodes(self, x: np.ndarray) -> np.ndarray:
        """Node positions (N, 3) of ``x``."""
        return dynamics.nodes_from_coordinates(self.structure, self.q(x))

    def x(self, q: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`q` (for rods within the open hemisphere about their base direction):
        ``dc = q1/2 - c0``, ``phi = E^T n / (n . n0)``; ``q`` may have leading (time) axes."""
        q = np.asarray(q, dtype=float)
        rods = dynamics.rod_coordinates(self.structure, q)
        n = rods[..., 1, :] / np.linalg.norm(rods[..., 1, :], axis=-1, keepdims=True)
        cos = np.sum(n * self.direction, axis=-1)
        if np.any(cos <= 0):
            r = int(np.argmin(cos)) % max(self.structure.n_rods, 1)
            raise ValueError(f"rods[{r}] turned by more than 90 degrees from the chart's base")
        phi = np.einsum("rij,...ri->...rj", self.basis, n) / cos[..., None]
        dc = 0.5 * rods[..., 0, :] - self.centre
        x = np.concatenate([dc, phi], axis=-1).reshape(*q.shape[:-1], self.n_rod_coordinates)
        if not self.point_mass.size:
            return x
        moved = dynamics.point_mass_coordinates(self.structure, q) - self.point_mass
        return np.concatenate([x, moved.reshape(*q.shape[:-1], -1)], axis=-1)

    def velocity_x(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """Rates ``x'`` (5R + 3M,) at a configuration *on the base* (``q`` with ``phi = 0``):
        ``dc' = q1'/2``, ``phi' = E^T q2' / L``, point masses ``x'``.  Elsewhere, first order in
        ``phi``."""
        qdot = np.asarray(qdot, dtype=float)
        rates = dynamics.rod_coordinates(self.structure, qdot)
        dphi = np.einsum("rij,ri->rj", self.basis, rates[:, 1]) / self.structure.rod_length[:, None]
        return self._with_point_masses(
            np.concatenate([0.5 * rates[:, 0], dphi], axis=1),
            dynamics.point_mass_coordinates(self.structure, qdot),
        )

    def velocity_q(self, xdot: np.ndarray) -> np.ndarray:
        """``q'`` (n,) of rates ``x'`` at the base (``x = 0``): ``q1' = 2 dc'``,
        ``q2' = L E phi'``."""
        dc, dphi = self.split(xdot)
        v2 = self.structure.rod_length[:, None] * np.einsum("rij,rj->ri", self.basis, dphi)
        return self._with_point_masses(np.stack([2.0 * dc, v2], axis=1), self._point_part(xdot))

    def node_jacobian(self, x: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``dp/dx`` per rod: ``(Jn (R, 3, 2), n (R, 3))`` with
        ``Jn = dn/dphi = (I - n n^T) E / s``.

        Node ``a`` moves by ``dc - (L/2) Jn dphi``, node ``b`` by ``dc + (L/2) Jn dphi``.
        """
        x = np.zeros(self.size) if x is None else x
        _, n, s = self.directions(x)
        proj = np.eye(3) - n[:, :, None] * n[:, None, :]
        return proj @ self.basis / s[:, None, None], n

    def jacobian_matrix(self, x: np.ndarray | None = None) -> np.ndarray:
        """Dense ``J = dp/dx`` (3N, 5R + 3M) with ``p`` flattened node by node (zero rows at
        anchors)."""
        s = self.structure
        jn, _ = self.node_jacobian(x)
        half = 0.5 * s.rod_length[:, None, None] * jn
        R = s.n_rods
        per_rod = np.zeros((s.n_nodes, 3, R, 5))
        r = np.arange(R)
        a, b = s.rod_nodes[:, 0], s.rod_nodes[:, 1]
        per_rod[a, :, r, :3] = np.eye(3)
        per_rod[b, :, r, :3] = np.eye(3)
        per_rod[a, :, r, 3:] = -half
        per_rod[b, :, r, 3:] = half
        J = per_rod.reshape(3 * s.n_nodes, 5 * R)
        if not self.point_mass.size:
            return J
        masses = s.point_mass_nodes
        P = np.zeros((s.n_nodes, 3, masses.size, 3))
        P[masses, :, np.arange(masses.size), :] = np.eye(3)
        return np.hstack([J, P.reshape(3 * s.n_nodes, 3 * masses.size)])

    def generalized_force(self, force: np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """``Q = J^T f`` (5R + 3M,) of nodal forces ``f`` (N, 3): per rod ``[f_a + f_b, (L/2)
        Jn^T (f_b - f_a)]``, then the force on each point mass."""
        s = self.structure
        jn, _ = self.node_jacobian(x)
        fa, fb = force[s.rod_nodes[:, 0]], force[s.rod_nodes[:, 1]]
        torque = 0.5 * s.rod_length[:, None] * np.einsum("rij,ri->rj", jn, fb - fa)
        return self._with_point_masses(
            np.concatenate([fa + fb, torque], axis=1), force[s.point_mass_nodes]
        )

    # ------------------------------------------------------------------ joints and supports
    @property
    def n_constraints(self) -> int:
        """Rows ``c`` of the joints and supports (0 without any)."""
        c = constraints_of(self.structure)
        return 0 if c is None else c.matrix.shape[0]

    def constraint_residual(self, x: np.ndarray) -> np.ndarray:
        """``g(x) = A q(x) - b`` [m], shape (c,)."""
        c = constraints_of(self.structure)
        return np.zeros(0) if c is None else c.residual(self.q(x))

    def constraint_jacobian(self, x: np.ndarray | None = None) -> np.ndarray:
        """``G = dg/dx = A_n J(x)`` (c, 5R + 3M), dense."""
        c = constraints_of(self.structure)
        if c is None:
            return np.zeros((0, self.size))
        return np.asarray(c.node_matrix @ self.jacobian_matrix(x))

    def reaction(
        self, generalized_force: np.ndarray, x: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(f_c (N, 3), Q + G^T lambda)``: the nodal forces ``f_c = A_n^T lambda`` [N] of the
        joints and supports that best balance the generalized forces ``Q`` (``lambda`` by least
        squares, minimum norm where the rows are dependent), and what they leave unbalanced."""
        s = self.structure
        c = constraints_of(s)
        if c is None or c.matrix.shape[0] == 0:  # (self.n_constraints == 0)
            return np.zeros((s.n_nodes, 3)), generalized_force
        G = self.constraint_jacobian(x)
        multiplier, *_ = np.linalg.lstsq(G.T, -generalized_force, rcond=None)
        force = (c.node_matrix_t @ multiplier).reshape(-1, 3)
        return force, generalized_force + G.T @ multiplier

    def retract(self, x: np.ndarray) -> np.ndarray:
        """``q`` (n,) of ``x`` moved onto the joints and supports (the closest configuration in
        the kinetic-energy metric,
        :meth:`tensegrity.physics.constraints.LinearConstraints.project`)."""
        q = self.q(x)
        c = constraints_of(self.structure)
        if c is None or c.matrix.shape[0] == 0:  # (self.n_constraints == 0)
            return q
        return c.project(q, np.zeros_like(q))[0]

    def admitted_motions(
        self, x: np.ndarray | None = None, rtol: float = 1e-10
    ) -> np.ndarray | None:
        """``Z`` (5R + 3M, k): an ``M``-orthonormal basis (``Z^T M Z = I``) of the motions the
        joints and supports admit, ``null(G)``; None without constraints (every motion)."""
        if self.n_constraints == 0:
            return None
        root = np.sqrt(mass_matrix(self.structure))
        G = self.constraint_jacobian(x) / root[None, :]
        _, sigma, vt = np.linalg.svd(G)
        rank = int(np.sum(sigma > rtol * (sigma[0] if sigma.size else 0.0)))
        return vt[rank:].T / root[:, None]


@functools.lru_cache(maxsize=32)
def spatial(structure: Structure) -> Structure:
    """The 3-D form of a structure: a 3-D structure itself; a planar one (nodes (N, 2)) with
    ``z = 0`` added and every node that is neither fixed nor on a line held on the plane
    ``z = 0`` (a node on a line keeps it, which holds ``z`` too).  Its motions are exactly the
    planar structure's (Theorem 18.1 is the same in the plane; ``tests/test_planar.py`` checks
    the two simulations against each other), and it is what the analysis package works on."""
    if structure.dim == 3:
        return structure
    held = ~structure.node_fixed
    held[structure.line_nodes] = False
    planes = np.flatnonzero(held)
    return structure.replace(
        node_position=spatial_vector(structure, structure.node_position),
        node_velocity=spatial_vector(structure, structure.node_velocity),
        plane_nodes=planes,
        plane_normal=np.tile([0.0, 0.0, 1.0], (planes.size, 1)),
        line_nodes=structure.line_nodes,
        line_direction=spatial_vector(structure, structure.line_direction),
    )


def has_supports(structure: Structure) -> bool:
    """True if some node is fixed or held on a plane or line: the supports then hold the
    structure against (some) rigid-body motion, and configurations are compared as they are,
    not after a rigid alignment."""
    return structure.is_supported


@overload
def spatial_vector(structure: Structure, value: np.ndarray) -> np.ndarray: ...
@overload
def spatial_vector(structure: Structure, value: None) -> None: ...
@overload
def spatial_vector(structure: Structure, value: np.ndarray | None) -> np.ndarray | None: ...
def spatial_vector(structure: Structure, value: np.ndarray | None) -> np.ndarray | None:
    """Vectors (..., d) of ``structure`` -- nodal forces or positions (N, d), a gravity vector
    (d,) -- in 3-D (``z = 0`` added to a planar structure's); None stays None."""
    if value is None or structure.dim == 3:
        return value
    value = np.asarray(value, dtype=float)
    return np.pad(value, [(0, 0)] * (value.ndim - 1) + [(0, 1)])


def spatial_coordinates(structure: Structure, q: np.ndarray, *, rates: bool = False) -> np.ndarray:
    """``q`` of :func:`spatial` ``(structure)`` from ``structure``'s ``q`` (leading axes allowed);
    with ``rates``, of rates or accelerations (anchors at rest)."""
    if structure.dim == 3:
        return q
    p = dynamics.nodes_from_coordinates(structure, np.asarray(q, dtype=float), rates=rates)
    return dynamics.coordinates_from_nodes(spatial(structure), spatial_vector(structure, p))


def planar_coordinates(structure: Structure, q: np.ndarray, *, rates: bool = False) -> np.ndarray:
    """Inverse of :func:`spatial_coordinates`: a planar ``structure``'s ``q`` from its 3-D
    form's."""
    if structure.dim == 3:
        return q
    p = dynamics.nodes_from_coordinates(spatial(structure), np.asarray(q, dtype=float), rates=rates)
    return dynamics.coordinates_from_nodes(structure, p[..., :2])


def configuration(structure: Structure, value: Any = None, *, name: str = "q") -> np.ndarray:
    """``q`` (n,) of a configuration given as node positions (N, d), as ``q`` (n,), or None
    (the structure's node positions); rods projected onto their lengths.  ``ValueError`` naming
    ``name`` for any other shape."""
    if value is None:
        return dynamics.coordinates_from_nodes(structure, structure.node_position)
    value = np.asarray(value, dtype=float)
    if value.shape == (structure.n_nodes, structure.dim):
        value = dynamics.coordinates_from_nodes(structure, value)
    if value.shape != (structure.n_coordinates,):
        raise ValueError(
            f"{name}: expected node positions ({structure.n_nodes}, {structure.dim}) or q "
            f"({structure.n_coordinates},), got shape {value.shape}"
        )
    q, _ = dynamics.project_to_constraints(structure, value, np.zeros_like(value))
    return q


def admitted_dof(structure: Structure, q: Any = None) -> int:
    """Degrees of freedom left by the joints and supports at the configuration ``q`` (default:
    the structure's layout): the dimension of the admitted motions ``null(G)``
    (:meth:`Chart.admitted_motions`) of the :func:`spatial` form, so in-plane ones for a planar
    structure.  ``Structure.n_dof`` without joints and supports.  Dense: for analysis sizes."""
    s3 = spatial(structure)
    chart = Chart.at(s3, spatial_coordinates(structure, configuration(structure, q)))
    motions = chart.admitted_motions()
    return chart.size if motions is None else motions.shape[1]


def mass_matrix(structure: Structure) -> np.ndarray:
    """Diagonal of ``M`` (5R + 3M,): ``m`` for the centre, ``m L^2 / 12`` for the two angles,
    then ``m`` (3 times) per point mass."""
    m, L = structure.rod_mass, structure.rod_length
    rods = np.column_stack([m, m, m, m * L**2 / 12, m * L**2 / 12]).reshape(-1)
    if not structure.point_mass_nodes.size:
        return rods
    return np.concatenate(
        [rods, np.repeat(structure.node_point_mass[structure.point_mass_nodes], 3)]
    )


def rigid_body_basis(chart: Chart) -> np.ndarray:
    """The infinitesimal rigid-body motions at the chart's base that the supports admit, as
    columns of ``x`` (5R + 3M, k).

    Translations ``dc = e_k``; rotations ``delta = a x (.)`` about the mass centre: ``dc = a x
    (c - c_m)``, ``phi = E^T (a x n)`` (a point mass moves by ``a x (p - c_m)``).  ``k = 6`` for
    a free structure unless its rods are all collinear; with supports only the combinations
    that keep every anchor still and satisfy ``G dx = 0`` (none for a fixed base, the three
    rotations about a single pinned node, the plane's three motions for a planar structure).
    The columns are made orthonormal in the mass metric (``B^T M B = I``).

    Whether a motion moves anything is decided against the structure's size, never against
    exact zero or the other candidates alone: a rotation that moves the mass by no more than
    round-off (about a line through the point masses and collinear rods: its size is
    ``sqrt(I)`` with ``I`` the moment of inertia about that line, at most round-off times
    ``sqrt(m_total) l``, ``l`` the largest node distance from the mass centre) is no motion,
    and a combination of unit-size motions that moves the mass by round-off is none either
    (a point mass pinned on the line of two anchors: the turn about that line the anchors
    admit moves nothing, so no rigid-body motion is left).
    """
    s = chart.structure
    mass = mass_matrix(s)
    weights = np.concatenate([s.rod_mass, s.node_point_mass[s.point_mass_nodes]])
    centre_of_mass = np.average(
        np.concatenate([chart.centre, chart.point_mass]), axis=0, weights=weights
    )
    columns = []
    for k in range(3):
        v = np.zeros((s.n_rods, 5))
        v[:, k] = 1.0
        columns.append(
            chart._with_point_masses(v, np.broadcast_to(np.eye(3)[k], chart.point_mass.shape))
        )
    for k in range(3):
        a = np.eye(3)[k]
        v = np.zeros((s.n_rods, 5))
        v[:, :3] = np.cross(a, chart.centre - centre_of_mass)
        v[:, 3:] = np.einsum("rij,ri->rj", chart.basis, np.cross(a, chart.direction))
        columns.append(chart._with_point_masses(v, np.cross(a, chart.point_mass - centre_of_mass)))
    rigid = np.column_stack(columns)
    scale = np.sqrt(np.sum(mass[:, None] * rigid**2, axis=0))  # each motion's size
    # A unit rotation about an axis through every mass (a point mass at the mass centre, rods
    # along the axis) moves nothing, but its column may hold the round-off of c - c_m and
    # p - c_m (of the equilibrium solver's last bits, or of c_m's): it is exactly no motion.
    # Translations have size sqrt(m_total), rotations at most sqrt(m_total) l.
    span = np.max(
        np.linalg.norm(chart.nodes(np.zeros(chart.size)) - centre_of_mass, axis=1), initial=0.0
    )
    still = scale <= RTOL_RIGID * np.sqrt(np.sum(weights)) * np.repeat([1.0, span], 3)
    rigid[:, still] = 0.0
    anchors = s.anchor_nodes
    if chart.n_constraints or anchors.size:
        # coefficients of the motions that move no anchor and keep the constraints
        arm = s.node_position[anchors] - centre_of_mass
        at_anchors = np.concatenate(
            [np.tile(np.eye(3), (anchors.size, 1)), -cross_matrix(arm).reshape(-1, 3)], axis=1
        )
        rows = np.vstack([chart.constraint_jacobian() @ rigid, at_anchors])
        scale[still] = 1.0  # motions that move nothing (above): only their anchors count
        _, sigma, vt = np.linalg.svd(rows / scale[None, :])
        rank = int(np.sum(sigma > RTOL_RIGID * max(sigma[0] if sigma.size else 0.0, 1.0)))
        # combinations (unit coefficients) of motions of unit size: a genuine admitted motion
        # has a size of order 1, one that moves the mass by round-off only is no motion (the
        # anchors' null space holds round-off in its translation part)
        rigid = rigid @ (vt[rank:].T / scale[:, None])
        return mass_orthonormal(rigid, mass, RTOL_RIGID, reference=1.0)
    return mass_orthonormal(rigid, mass, RTOL_RIGID)


def admitted_rigid_motions(chart: Chart, basis: np.ndarray | None) -> np.ndarray:
    """:func:`rigid_body_basis` in the coordinates ``eta`` of the admitted motions ``x = Z eta``
    (``basis`` = ``Z``, ``M``-orthonormal: ``eta = Z^T M x``); unchanged for ``Z`` = None."""
    rigid = rigid_body_basis(chart)
    if basis is None:
        return rigid
    return basis.T @ (mass_matrix(chart.structure)[:, None] * rigid)


def drop_roundoff(matrix: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """``matrix`` with the entries below ``rtol`` times its largest set to 0: in ``J Z`` and
    ``Z^T A_eq`` those are the round-off of ``G Z = 0`` (a fixed node's position, a tendon
    between two fixed nodes), which would otherwise pass for a tiny, real authority."""
    return np.where(np.abs(matrix) <= rtol * np.max(np.abs(matrix), initial=0.0), 0.0, matrix)


def cross_matrix(a: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[a]_x`` (..., 3, 3) of vectors (..., 3): ``[a]_x b = a x b``."""
    out = np.zeros((*a.shape, 3))
    out[..., 0, 1], out[..., 0, 2] = -a[..., 2], a[..., 1]
    out[..., 1, 0], out[..., 1, 2] = a[..., 2], -a[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -a[..., 1], a[..., 0]
    return out


def mass_orthonormal(
    vectors: np.ndarray, mass: np.ndarray, rtol: float = 1e-10, *, reference: float = 0.0
) -> np.ndarray:
    """An ``M``-orthonormal basis (``V^T diag(mass) V = I``) of the span of ``vectors``' columns.

    Directions whose mass-metric size is at most ``rtol`` times the largest of the columns'
    singular values and ``reference`` (the size a genuine column has) are dropped: without a
    ``reference``, columns that are all round-off would pass for a basis of their own."""
    root = np.sqrt(mass)
    u, sigma, _ = np.linalg.svd(root[:, None] * vectors, full_matrices=False)
    keep = sigma > rtol * max(sigma[0] if sigma.size else 0.0, reference)
    return u[:, keep] / root[:, None]


def mass_complement(basis: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """``M``-orthonormal basis (5R, 5R - k) of the ``M``-orthogonal complement of ``basis``."""
    root = np.sqrt(mass)
    scaled = root[:, None] * basis  # orthonormal columns in the Euclidean metric
    q, _ = np.linalg.qr(scaled, mode="complete")
    k = basis.shape[1]
    return q[:, k:] / root[:, None]


def align(p: np.ndarray, reference: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``p`` (..., N, 3) moved rigidly onto ``reference`` (N, 3): weighted Kabsch fit.

    The rotation and translation minimize ``sum w |R p + t - reference|^2``; the result satisfies
    Eckart's conditions with respect to ``reference`` (same weighted centroid, and
    ``sum w (reference - c) x (aligned - reference) = 0``): the gauge used throughout.
    """
    p = np.asarray(p, dtype=float)
    if p.ndim == 2:
        return kabsch(p, reference, weights)[0]
    flat = p.reshape(-1, *p.shape[-2:])
    return np.stack([kabsch(one, reference, weights)[0] for one in flat]).reshape(p.shape)


def kabsch(
    p: np.ndarray, reference: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted Kabsch fit of ``p`` (N, 3) onto ``reference``: ``(aligned, R)`` with
    ``aligned = (p - c) R + c_ref`` (``c``, ``c_ref`` the weighted centroids, ``R`` a rotation)."""
    w = np.asarray(weights, dtype=float) / np.sum(weights)
    c, c_ref = w @ p, w @ reference
    h = (w[:, None] * (p - c)).T @ (reference - c_ref)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    rotation = u @ np.diag([1.0, 1.0, d]) @ vt
    return (p - c) @ rotation + c_ref, rotation


def deformation(
    p: np.ndarray, reference: np.ndarray, weights: np.ndarray, *, rigid: bool = True
) -> np.ndarray:
    """RMS (weighted by ``weights``) node distance from ``reference`` after rigid alignment [m],
    shape (...,): the size of a deformation, blind to rigid-body motion.  ``rigid=False``: no
    alignment (a supported structure, whose rigid-body motion is a deformation too)."""
    aligned = align(p, reference, weights) if rigid else p
    w = np.asarray(weights, dtype=float) / np.sum(weights)
    return np.sqrt(np.sum(w * np.sum((aligned - reference) ** 2, axis=-1), axis=-1))
