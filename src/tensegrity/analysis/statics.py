"""Static forces and their analytic Jacobians in reduced coordinates
(:mod:`~tensegrity.analysis.coordinates`).

For a configuration ``x`` of a :class:`~tensegrity.analysis.coordinates.Chart`:

- ``Q(x) = J(x)^T f(p(x))`` (5R,): the generalized forces of the tendons, the external nodal
  forces ``w`` and gravity.  ``Q = 0`` is the static equilibrium of eq. 18.61,
  ``K_p(q) q = B(q) u + D(q) w``, written in coordinates that respect the rod lengths (it is
  exactly ``q'' = 0`` of Theorem 18.1 at ``q' = 0``).
- ``dQ/dx = -J^T K_node J + G``: the tangent stiffness ``K = -dQ/dx``.  ``K_node`` is the sum
  over taut tendons of ``k t t^T + (T / l) (I - t t^T)`` (material plus geometric stiffness of a
  tendon, ``t`` its unit vector); ``G`` is the geometric term of the rods' rotation (it makes a
  compressed rod destabilizing, ``-P L / 2`` per angle at ``phi = 0``).

Tendon law as in :mod:`tensegrity.physics.dynamics` (elastic part only: velocities are zero in
statics): ``T = k (l - Lbar)`` while ``l > Lbar``, else 0.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tensegrity.analysis.coordinates import Chart
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

#: A tendon whose stretch ``|l - Lbar|`` is at most this times ``Lbar`` (or ``l``) is "at the
#: threshold": no tension, but it stiffens as soon as it is stretched.
THRESHOLD_RTOL = 1e-9


class TendonState(NamedTuple):
    """Tendon quantities at a configuration (all shape (S,) unless stated)."""

    length: np.ndarray  #: ``l`` [m]
    direction: np.ndarray  #: unit vectors head minus tail (S, 3)
    tension: np.ndarray  #: ``k max(l - Lbar, 0)`` [N]
    taut: np.ndarray  #: bool, ``l > Lbar`` beyond the threshold tolerance
    at_threshold: np.ndarray  #: bool, ``|l - Lbar| <= THRESHOLD_RTOL max(l, Lbar)``


def tendon_state(structure: Structure, p: np.ndarray, rest_length: np.ndarray) -> TendonState:
    """Lengths, unit vectors, elastic tensions and taut/threshold flags at node positions ``p``."""
    t = dynamics.tendon_vectors(structure, p)
    length = np.linalg.norm(t, axis=-1)
    direction = t / length[:, None]
    stretch = length - rest_length
    at_threshold = np.abs(stretch) <= THRESHOLD_RTOL * np.maximum(length, rest_length)
    taut = (stretch > 0) & ~at_threshold
    tension = dynamics.elastic_tensions(structure, length, rest_length)
    return TendonState(length, direction, tension, taut, at_threshold)


def unit_tension_forces(structure: Structure, direction: np.ndarray) -> np.ndarray:
    """Nodal forces (N, 3, S) of a unit tension in each tendon: ``+t`` on the tail, ``-t`` on the
    head (each end is pulled toward the other)."""
    S = structure.n_tendons
    out = np.zeros((structure.n_nodes, 3, S))
    s = np.arange(S)
    out[structure.tendon_nodes[:, 0], :, s] += direction
    out[structure.tendon_nodes[:, 1], :, s] -= direction
    return out


def nodal_forces(
    structure: Structure,
    p: np.ndarray,
    tension: np.ndarray,
    direction: np.ndarray,
    external_force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
) -> np.ndarray:
    """Total static nodal forces (N, 3) [N]: tendons, external ``w`` and gravity."""
    force = -(structure.tendon_incidence_transpose @ (tension[:, None] * direction))
    if external_force is not None:
        force = force + np.asarray(external_force, dtype=float)
    if gravity is not None:
        force = force + structure.node_mass[:, None] * np.asarray(gravity, dtype=float)
    return np.asarray(force)


def node_stiffness(
    structure: Structure,
    tendons: TendonState,
    *,
    include_threshold: bool = True,
    damping: bool = False,
) -> np.ndarray:
    """Tendon stiffness on node displacements, dense (3N, 3N): ``-df/dp``.

    Per taut tendon ``k t t^T + (T/l)(I - t t^T)``; tendons at the threshold contribute their
    material part ``k t t^T`` if ``include_threshold`` (the stiffness they have as soon as they
    are stretched).  With ``damping=True`` the same assembly of ``c t t^T`` gives the tendon
    damping matrix on node velocities.
    """
    N = structure.n_nodes
    use = tendons.taut | (tendons.at_threshold & include_threshold)
    t = tendons.direction[use]
    outer = t[:, :, None] * t[:, None, :]
    if damping:
        block = structure.tendon_damping[use, None, None] * outer
    else:
        geometric = (tendons.tension[use] / tendons.length[use])[:, None, None]
        block = structure.tendon_stiffness[use, None, None] * outer + geometric * (
            np.eye(3) - outer
        )
    tail, head = structure.tendon_nodes[use, 0], structure.tendon_nodes[use, 1]
    K = np.zeros((N, N, 3, 3))
    np.add.at(K, (tail, tail), block)
    np.add.at(K, (head, head), block)
    np.add.at(K, (tail, head), -block)
    np.add.at(K, (head, tail), -block)
    return K.transpose(0, 2, 1, 3).reshape(3 * N, 3 * N)


class Statics(NamedTuple):
    """Generalized forces and related quantities at one configuration ``x`` of a chart."""

    q: np.ndarray  #: (6R,)
    p: np.ndarray  #: (N, 3)
    tendons: TendonState
    force: np.ndarray  #: total nodal forces (N, 3) [N]
    generalized_force: np.ndarray  #: ``Q`` (5R,) [N, N m]


def statics(
    chart: Chart,
    x: np.ndarray,
    rest_length: np.ndarray,
    external_force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
) -> Statics:
    """Generalized forces ``Q(x)`` and the tendon state at ``x``."""
    s = chart.structure
    q = chart.q(x)
    p = dynamics.nodes_from_coordinates(s, q)
    tendons = tendon_state(s, p, rest_length)
    force = nodal_forces(s, p, tendons.tension, tendons.direction, external_force, gravity)
    return Statics(q, p, tendons, force, chart.generalized_force(force, x))


def with_reactions(chart: Chart, st: Statics) -> Statics:
    """``st`` with the best reactions of the joints and supports (:meth:`Chart.reaction`) added to
    its nodal forces (unchanged without any): then :func:`force_jacobian` is the Jacobian of
    ``Q + G^T lambda`` at fixed ``lambda``, minus the Hessian of the Lagrangian -- the reactions
    enter the rods' geometric term as external nodal forces do."""
    if not chart.n_constraints:
        return st
    return st._replace(force=st.force + chart.reaction(st.generalized_force)[0])


def force_jacobian(chart: Chart, x: np.ndarray, st: Statics) -> np.ndarray:
    """Analytic ``dQ/dx`` (5R, 5R) at ``x`` (``st = statics(chart, x, ...)``)."""
    s = chart.structure
    J = chart.jacobian_matrix(x)
    K_node = node_stiffness(s, st.tendons, include_threshold=False)
    dQ = -J.T @ K_node @ J
    # Rotation term: g . dN_i/dphi_j, with N = dn/dphi = (I - n n^T) E / s.
    jn, n = chart.node_jacobian(x)
    _, phi = chart.split(x)
    sq = np.sqrt(1.0 + np.sum(phi**2, axis=1))
    fa, fb = st.force[s.rod_nodes[:, 0]], st.force[s.rod_nodes[:, 1]]
    g = 0.5 * s.rod_length[:, None] * (fb - fa)  # (R, 3)
    g_n = np.einsum("ri,ri->r", g, n)
    g_N = np.einsum("ri,rij->rj", g, jn)  # g . N_j
    n_e = np.einsum("ri,rij->rj", n, chart.basis)  # n . e_i
    N_e = np.einsum("rki,rkj->rij", chart.basis, jn)  # e_i . N_j
    G = (
        -(n_e[:, :, None] * g_N[:, None, :] + g_n[:, None, None] * N_e) / sq[:, None, None]
        - g_N[:, :, None] * phi[:, None, :] / sq[:, None, None] ** 2
    )
    for r in range(s.n_rods):
        dQ[5 * r + 3 : 5 * r + 5, 5 * r + 3 : 5 * r + 5] += G[r]
    return dQ


def equilibrium_matrix(
    chart: Chart, direction: np.ndarray, x: np.ndarray | None = None
) -> np.ndarray:
    """``A`` (5R, S): generalized force of a unit tension in each tendon, ``Q = A T + J^T w``."""
    s = chart.structure
    unit = unit_tension_forces(s, direction)  # (N, 3, S)
    J = chart.jacobian_matrix(x)
    return J.T @ unit.reshape(3 * s.n_nodes, s.n_tendons)


def rod_compression(structure: Structure, force: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Axial compression of each rod [N] (> 0 compressed) from the nodal forces on its ends:
    ``(f_a - f_b) . n / 2``, ``n`` (R, 3) the unit vector from ``a`` to ``b``.  ``force`` is
    (N, 3), or (N, 3, ...) for several force sets at once (result (R, ...))."""
    fa, fb = force[structure.rod_nodes[:, 0]], force[structure.rod_nodes[:, 1]]
    return 0.5 * np.einsum("rk...,rk->r...", fa - fb, direction)
