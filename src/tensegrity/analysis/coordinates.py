"""Reduced coordinates that respect the rod-length constraints, and rigid-body motions.

Every rod ``r`` (end nodes ``a``, ``b``, length ``L``) is described by its centre ``c`` (3) and
its unit direction ``n`` (``p_a = c - (L/2) n``, ``p_b = c + (L/2) n``, so ``q1 = 2 c`` and
``q2 = L n`` of :mod:`tensegrity.dynamics`).  About a *base* configuration ``(c0, n0)`` we use,
per rod, the 5 numbers

    x_r = [dc (3), phi (2)],   c = c0 + dc,   n = (n0 + E phi) / sqrt(1 + |phi|^2)

with ``E = [e1, e2]`` an orthonormal basis of the plane perpendicular to ``n0`` (the gnomonic
chart of the unit sphere: exact for any ``phi``, it covers the open hemisphere about ``n0``, and
at ``phi = 0`` the two angles are small rotations about ``e2`` and ``-e1``).  Stacked rod by rod,
``x`` has ``5R`` entries: the degrees of freedom of the structure (spin about a rod's own axis
is not one).  Every configuration built from ``x`` satisfies ``|q2| = L`` exactly.

The kinetic energy in these coordinates at ``phi = 0`` is ``x'^T M x' / 2`` with
``M = diag(m, m, m, m L^2/12, m L^2/12)`` per rod: :func:`mass_matrix`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from tensegrity import dynamics
from tensegrity.structure import Structure

#: Rigid-body motions of a free structure in 3-D: 3 translations and 3 rotations.
N_RIGID = 6


def tangent_basis(direction: np.ndarray) -> np.ndarray:
    """Orthonormal ``E = [e1, e2]`` (..., 3, 2) perpendicular to unit vectors ``direction`` (..., 3).

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
    structure : Structure
    centre : (R, 3) base rod centres ``c0`` [m].
    direction : (R, 3) base unit rod directions ``n0``.
    basis : (R, 3, 2) tangent bases ``E`` at ``n0``.
    """

    structure: Structure
    centre: np.ndarray
    direction: np.ndarray
    basis: np.ndarray

    @classmethod
    def at(cls, structure: Structure, q: np.ndarray) -> Chart:
        """The chart based at the configuration ``q`` (6R,) (``x = 0`` there)."""
        structure.require_free_class1("the analysis package")
        rods = dynamics.rods_view(np.asarray(q, dtype=float))
        centre = 0.5 * rods[:, 0]
        direction = rods[:, 1] / np.linalg.norm(rods[:, 1], axis=1, keepdims=True)
        return cls(structure, centre.copy(), direction, tangent_basis(direction))

    @property
    def size(self) -> int:
        """``5 R``."""
        return 5 * self.structure.n_rods

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(dc (R, 3), phi (R, 2))`` views of ``x`` (5R,)."""
        rods = np.asarray(x, dtype=float).reshape(-1, 5)
        return rods[:, :3], rods[:, 3:]

    def directions(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(c (R, 3), n (R, 3), s (R,))`` with ``s = sqrt(1 + |phi|^2)``."""
        dc, phi = self.split(x)
        s = np.sqrt(1.0 + np.sum(phi**2, axis=1))
        n = (self.direction + np.einsum("rij,rj->ri", self.basis, phi)) / s[:, None]
        return self.centre + dc, n, s

    def q(self, x: np.ndarray) -> np.ndarray:
        """Coordinates ``q`` (6R,) of ``x``: ``q1 = 2 c``, ``q2 = L n`` (rod lengths exact)."""
        c, n, _ = self.directions(x)
        q = np.stack([2.0 * c, self.structure.rod_length[:, None] * n], axis=1)
        return q.reshape(-1)

    def nodes(self, x: np.ndarray) -> np.ndarray:
        """Node positions (N, 3) of ``x``."""
        return dynamics.nodes_from_coordinates(self.structure, self.q(x))

    def x(self, q: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`q` (for rods within the open hemisphere about their base direction):
        ``dc = q1/2 - c0``, ``phi = E^T n / (n . n0)``."""
        rods = dynamics.rods_view(np.asarray(q, dtype=float))
        n = rods[..., 1, :] / np.linalg.norm(rods[..., 1, :], axis=-1, keepdims=True)
        cos = np.sum(n * self.direction, axis=-1)
        if np.any(cos <= 0):
            r = int(np.argmin(cos))
            raise ValueError(f"rods[{r}] turned by more than 90 degrees from the chart's base")
        phi = np.einsum("rij,...ri->...rj", self.basis, n) / cos[..., None]
        dc = 0.5 * rods[..., 0, :] - self.centre
        return np.concatenate([dc, phi], axis=-1).reshape(*np.shape(q)[:-1], self.size)

    def velocity_x(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """Rates ``x'`` (5R,) at a configuration *on the base* (``q`` with ``phi = 0``):
        ``dc' = q1'/2``, ``phi' = E^T q2' / L``.  Elsewhere, first order in ``phi``."""
        rates = dynamics.rods_view(np.asarray(qdot, dtype=float))
        dphi = np.einsum("rij,ri->rj", self.basis, rates[:, 1]) / self.structure.rod_length[:, None]
        return np.concatenate([0.5 * rates[:, 0], dphi], axis=1).reshape(-1)

    def velocity_q(self, xdot: np.ndarray) -> np.ndarray:
        """``q'`` (6R,) of rates ``x'`` at the base (``x = 0``): ``q1' = 2 dc'``, ``q2' = L E phi'``."""
        dc, dphi = self.split(xdot)
        v2 = self.structure.rod_length[:, None] * np.einsum("rij,rj->ri", self.basis, dphi)
        return np.stack([2.0 * dc, v2], axis=1).reshape(-1)

    def node_jacobian(self, x: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``dp/dx`` per rod: ``(Jn (R, 3, 2), n (R, 3))`` with ``Jn = dn/dphi = (I - n n^T) E / s``.

        Node ``a`` moves by ``dc - (L/2) Jn dphi``, node ``b`` by ``dc + (L/2) Jn dphi``.
        """
        x = np.zeros(self.size) if x is None else x
        _, n, s = self.directions(x)
        proj = np.eye(3) - n[:, :, None] * n[:, None, :]
        return proj @ self.basis / s[:, None, None], n

    def jacobian_matrix(self, x: np.ndarray | None = None) -> np.ndarray:
        """Dense ``J = dp/dx`` (3N, 5R) with ``p`` flattened node by node."""
        s = self.structure
        jn, _ = self.node_jacobian(x)
        half = 0.5 * s.rod_length[:, None, None] * jn
        J = np.zeros((s.n_nodes, 3, s.n_rods, 5))
        r = np.arange(s.n_rods)
        a, b = s.rod_nodes[:, 0], s.rod_nodes[:, 1]
        J[a, :, r, :3] = np.eye(3)
        J[b, :, r, :3] = np.eye(3)
        J[a, :, r, 3:] = -half
        J[b, :, r, 3:] = half
        return J.reshape(3 * s.n_nodes, 5 * s.n_rods)

    def generalized_force(self, force: np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """``Q = J^T f`` (5R,) of nodal forces ``f`` (N, 3): ``[f_a + f_b, (L/2) Jn^T (f_b - f_a)]``."""
        s = self.structure
        jn, _ = self.node_jacobian(x)
        fa, fb = force[s.rod_nodes[:, 0]], force[s.rod_nodes[:, 1]]
        torque = 0.5 * s.rod_length[:, None] * np.einsum("rij,ri->rj", jn, fb - fa)
        return np.concatenate([fa + fb, torque], axis=1).reshape(-1)


def configuration(structure: Structure, value: Any = None, *, name: str = "q") -> np.ndarray:
    """``q`` (6R,) of a configuration given as node positions (N, 3), as ``q`` (6R,), or None
    (the structure's node positions); rods projected onto their lengths.  ``ValueError`` naming
    ``name`` for any other shape."""
    if value is None:
        return dynamics.coordinates_from_nodes(structure, structure.node_position)
    value = np.asarray(value, dtype=float)
    if value.shape == (structure.n_nodes, 3):
        value = dynamics.coordinates_from_nodes(structure, value)
    if value.shape != (structure.n_coordinates,):
        raise ValueError(f"{name}: expected node positions ({structure.n_nodes}, 3) or q "
                         f"({structure.n_coordinates},), got shape {value.shape}")
    q, _ = dynamics.project_to_constraints(structure, value, np.zeros_like(value))
    return q


def mass_matrix(structure: Structure) -> np.ndarray:
    """Diagonal of ``M`` (5R,): ``m`` for the centre, ``m L^2 / 12`` for the two angles."""
    m, L = structure.rod_mass, structure.rod_length
    return np.column_stack([m, m, m, m * L**2 / 12, m * L**2 / 12]).reshape(-1)


def rigid_body_basis(chart: Chart) -> np.ndarray:
    """The infinitesimal rigid-body motions at the chart's base as columns of ``x`` (5R, k).

    Translations ``dc = e_k``; rotations ``delta = a x (.)`` about the mass centre: ``dc = a x
    (c - c_m)``, ``phi = E^T (a x n)``.  ``k = 6`` unless the rods are all collinear; the columns
    are made orthonormal in the mass metric (``B^T M B = I``).
    """
    s = chart.structure
    centre_of_mass = np.average(chart.centre, axis=0, weights=s.rod_mass)
    columns = []
    for k in range(3):
        v = np.zeros((s.n_rods, 5))
        v[:, k] = 1.0
        columns.append(v.reshape(-1))
    for k in range(3):
        a = np.eye(3)[k]
        v = np.zeros((s.n_rods, 5))
        v[:, :3] = np.cross(a, chart.centre - centre_of_mass)
        v[:, 3:] = np.einsum("rij,ri->rj", chart.basis, np.cross(a, chart.direction))
        columns.append(v.reshape(-1))
    return mass_orthonormal(np.column_stack(columns), mass_matrix(s))


def mass_orthonormal(vectors: np.ndarray, mass: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """An ``M``-orthonormal basis (``V^T diag(mass) V = I``) of the span of ``vectors``' columns."""
    root = np.sqrt(mass)
    u, sigma, _ = np.linalg.svd(root[:, None] * vectors, full_matrices=False)
    keep = sigma > rtol * (sigma[0] if sigma.size else 0.0)
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


def kabsch(p: np.ndarray, reference: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted Kabsch fit of ``p`` (N, 3) onto ``reference``: ``(aligned, R)`` with
    ``aligned = (p - c) R + c_ref`` (``c``, ``c_ref`` the weighted centroids, ``R`` a rotation)."""
    w = np.asarray(weights, dtype=float) / np.sum(weights)
    c, c_ref = w @ p, w @ reference
    h = (w[:, None] * (p - c)).T @ (reference - c_ref)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    rotation = u @ np.diag([1.0, 1.0, d]) @ vt
    return (p - c) @ rotation + c_ref, rotation


def deformation(p: np.ndarray, reference: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """RMS (weighted by ``weights``) node distance from ``reference`` after rigid alignment [m],
    shape (...,): the size of a deformation, blind to rigid-body motion."""
    aligned = align(p, reference, weights)
    w = np.asarray(weights, dtype=float) / np.sum(weights)
    return np.sqrt(np.sum(w * np.sum((aligned - reference) ** 2, axis=-1), axis=-1))
