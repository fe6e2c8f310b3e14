"""The generalized coordinates of Theorem 18.1 and the rods' response to nodal forces.

Per rod ``r`` with end nodes ``(a, b)`` (eq. 18.24): ``q1 = p_a + p_b`` and ``q2 = p_b - p_a``,
stacked rod by rod, then the point masses' positions.  :func:`force_response` is ``G(q) f``
(eqs. 18.17, 18.20), the rods' accelerations under nodal forces: it serves
:mod:`tensegrity.physics.dynamics` and the constraint solver of
:mod:`tensegrity.physics.constraints` alike.
"""

from __future__ import annotations

import numpy as np

from tensegrity.model.structure import Structure


# --------------------------------------------------------------------------- coordinates
def rods_view(q: np.ndarray, dim: int = 3) -> np.ndarray:
    """View ``q`` (..., 2 dim R) as (..., R, 2, dim): ``[..., r, 0]`` is ``q1``, ``[..., r, 1]``
    is ``q2``."""
    return q.reshape(*q.shape[:-1], -1, 2, dim)


def rod_coordinates(structure: Structure, q: np.ndarray) -> np.ndarray:
    """The rods' part of ``q`` (..., n) as (..., R, 2, dim), a view (point masses left out)."""
    if structure.is_free_class1:
        return q.reshape(*q.shape[:-1], -1, 2, 3)
    d = structure.dim
    return rods_view(q[..., : 2 * d * structure.n_rods], d)


def point_mass_coordinates(structure: Structure, q: np.ndarray) -> np.ndarray:
    """The point masses' part of ``q`` (..., n) as (..., M, dim), a view."""
    d = structure.dim
    return q[..., 2 * d * structure.n_rods :].reshape(*q.shape[:-1], -1, d)


def coordinates_from_nodes(structure: Structure, node_value: np.ndarray) -> np.ndarray:
    """``q`` (..., n) from node positions (..., N, 3): ``q1 = p_a + p_b``, ``q2 = p_b - p_a``,
    then the point masses' positions.

    Being linear, the same map takes node velocities to ``qdot``.
    """
    a, b = structure.rod_nodes[:, 0], structure.rod_nodes[:, 1]
    pa, pb = node_value[..., a, :], node_value[..., b, :]
    q = np.stack([pa + pb, pb - pa], axis=-2)  # (..., R, 2, dim)
    q = q.reshape(*q.shape[:-3], 2 * structure.dim * structure.n_rods)
    if structure.point_mass_nodes.size:
        x = node_value[..., structure.point_mass_nodes, :]
        q = np.concatenate([q, x.reshape(*x.shape[:-2], -1)], axis=-1)
    return q


def nodes_from_coordinates(
    structure: Structure, q: np.ndarray, *, rates: bool = False
) -> np.ndarray:
    """Node positions ``p = P q`` (eq. 18.26), shape (..., N, 3); anchors at their fixed
    positions.  With ``rates=True``, node velocities from ``qdot`` (anchors at rest)."""
    rods = rod_coordinates(structure, q)
    q1, q2 = rods[..., 0, :], rods[..., 1, :]
    p = np.empty((*q.shape[:-1], structure.n_nodes, structure.dim))
    p[..., structure.rod_nodes[:, 0], :] = 0.5 * (q1 - q2)
    p[..., structure.rod_nodes[:, 1], :] = 0.5 * (q1 + q2)
    if not structure.is_free_class1:
        p[..., structure.point_mass_nodes, :] = point_mass_coordinates(structure, q)
        anchors = structure.anchor_nodes
        p[..., anchors, :] = 0.0 if rates else structure.node_position[anchors]
    return p


def force_response(
    structure: Structure, q: np.ndarray, force: np.ndarray, *, rates: np.ndarray | None = None
) -> np.ndarray:
    """``q''`` (..., n) under the nodal forces ``force`` (..., N, 3) [N] (Theorem 18.1, eqs.
    18.17, 18.20; leading axes of ``force`` are batches)::

        q1'' = (2/m) (f_a + f_b),   q2'' = (6/(m L^2)) skew(q2)^2 (f_a - f_b),   x'' = f / m.

    Without ``rates`` this is ``G(q) f``, linear in ``f``.  With the rods' rates (R, 2, 3) (see
    :func:`rod_coordinates`) it is the full acceleration: plus the centripetal term
    ``-(|q2'|^2 / L^2) q2`` and the rod damping (:func:`rod_damping_acceleration`).
    """
    a, b = structure.rod_nodes[:, 0], structure.rod_nodes[:, 1]
    f_sum, f_diff = force[..., a, :] + force[..., b, :], force[..., a, :] - force[..., b, :]
    q2 = rod_coordinates(structure, q)[:, 1]
    m, L2 = structure.rod_mass[:, None], structure.rod_length[:, None] ** 2
    # skew(q2)^2 f = q2 (q2 . f) - |q2|^2 f
    skew2_f = (
        q2 * np.sum(q2 * f_diff, axis=-1, keepdims=True)
        - np.sum(q2 * q2, axis=-1, keepdims=True) * f_diff
    )
    qddot = np.empty((*f_sum.shape[:-1], 2, structure.dim))
    qddot[..., 0, :] = (2.0 / m) * f_sum
    if rates is None:
        qddot[..., 1, :] = (6.0 / (m * L2)) * skew2_f
    else:
        v2 = rates[:, 1]
        qddot[:, 1] = (
            -(np.sum(v2 * v2, axis=1, keepdims=True) / L2) * q2 + (6.0 / (m * L2)) * skew2_f
        )
        qddot -= rod_damping_acceleration(structure, rod_coordinates(structure, q), rates)
    qddot = qddot.reshape(*qddot.shape[:-3], -1)
    if structure.is_free_class1:
        return qddot
    masses = structure.point_mass_nodes
    point = force[..., masses, :] / structure.node_point_mass[masses, None]
    return np.concatenate([qddot, point.reshape(*point.shape[:-2], -1)], axis=-1)


# --------------------------------------------------------------------------- rod damping
def rod_damping_rates(structure: Structure) -> tuple[np.ndarray, np.ndarray]:
    """``(alpha, beta)`` (R,) [1/s]: the rods' mass-proportional damping rates to ground and
    relative to the rigid-body motion, as the equations of motion apply them.

    A structure held by supports (:attr:`Structure.is_supported`) has the ground for its rigid
    body: its relative damping acts to ground (``alpha + beta``, and ``beta = 0``).  (With a
    single pin the structure could still turn about it; that turn is damped too.)
    """
    if structure.is_supported:
        return structure.rod_damping + structure.rod_relative_damping, np.zeros(structure.n_rods)
    return structure.rod_damping, structure.rod_relative_damping


def rigid_body_rates(rods: np.ndarray, rates: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """The rates (R, 2, d) of the rigid-body motion that best fits the rods' motion.

    The fit minimises ``sum_r w_r integral |v - V - omega x (x - c)|^2 dm / m_r`` over the
    rods' mass elements: ``c`` and ``V`` are the ``w``-weighted mean of the rods' centres
    ``q1 / 2`` and of their velocities, ``omega = I^+ H`` with ``H = sum w ((x - c) x v + q2 x
    q2' / 12)`` and ``I = sum w (|x - c|^2 1 - (x - c)(x - c)^T + (|q2|^2 1 - q2 q2^T) / 12)``
    (a pseudo-inverse: rods on one line have no inertia about it, and no turn about it moves
    them).  The residual ``q' - rigid`` then carries no ``w``-weighted momentum or angular
    momentum.  Planar rods (d = 2) are fitted in the plane ``z = 0``.

    Parameters
    ----------
    rods, rates : ndarray, shape (R, 2, d)
        The rods' coordinates ``(q1, q2)`` [m] and rates [m/s] (:func:`rod_coordinates`).
    weight : ndarray, shape (R,)
        ``w >= 0`` [kg/s], e.g. ``beta m``; all zero gives zero rates.
    """
    d = rods.shape[-1]
    pad = ((0, 0), (0, 3 - d))
    centre, velocity = (np.pad(0.5 * x[:, 0], pad) for x in (rods, rates))
    q2, v2 = (np.pad(x[:, 1], pad) for x in (rods, rates))
    total = weight.sum()
    if not total > 0:
        return np.zeros_like(rates)
    c = weight @ centre / total
    V = weight @ velocity / total
    r = centre - c
    H = weight @ (np.cross(r, velocity) + np.cross(q2, v2) / 12)
    eye = np.eye(3)
    inertia = np.einsum(
        "r,rij->ij",
        weight,
        np.sum(r * r, axis=1)[:, None, None] * eye
        - r[:, :, None] * r[:, None, :]
        + (np.sum(q2 * q2, axis=1)[:, None, None] * eye - q2[:, :, None] * q2[:, None, :]) / 12,
    )
    omega = np.linalg.lstsq(inertia, H, rcond=1e-12)[0]
    rigid = np.stack([2.0 * (V + np.cross(omega, r)), np.cross(omega, q2)], axis=1)
    return rigid[..., :d]


def rod_damping_acceleration(
    structure: Structure, rods: np.ndarray, rates: np.ndarray
) -> np.ndarray:
    """The rods' damping term of ``q''`` (R, 2, d) [m/s^2], to be subtracted:
    ``alpha q' + beta (q' - rigid)`` (:func:`rod_damping_rates`, :func:`rigid_body_rates`),
    from the rods' coordinates and rates (R, 2, d).

    Both parts are tangent to the rod constraints (``q2 . q2' = 0`` and ``q2 . (omega x q2) =
    0``).  The force behind the relative part, ``-beta m (q' - rigid)`` in the mass metric,
    carries no momentum or angular momentum.
    """
    alpha, beta = rod_damping_rates(structure)
    term = alpha[:, None, None] * rates
    if np.any(beta):
        rigid = rigid_body_rates(rods, rates, beta * structure.rod_mass)
        term = term + beta[:, None, None] * (rates - rigid)
    return term
