"""Planar structures of the paper's Appendix A: a single rod (Example 1) and the two crossed rods
held by four tendons (Example 2, eqs. 18.A.20-18.A.22).

A planar structure is a :class:`~tensegrity.model.structure.Structure` whose nodes have two
coordinates (``node_position`` of shape (N, 2)): ``q`` has ``4R`` entries (``q1 = p_a + p_b``,
``q2 = p_b - p_a`` in the plane) and Theorem 18.1 holds with the same formulas, ``skew(q2)^2``
being the 2x2 matrix ``q2 q2^T - |q2|^2 I`` printed in Example 1.  Each rod has 3 degrees of
freedom.

Example 2's nodes and tendons, read off (18.A.20)-(18.A.22) (``p1 = rho``, ``p2 = rho + r1``,
``p3 = rho_hat``, ``p4 = rho_hat + r2``; tendon vector head minus tail)::

    rod 1: p1 -> p2 (r1)        rod 2: p3 -> p4 (r2)
    t1 = p2 - p3   t2 = p1 - p3   t3 = p4 - p1   t5 = p4 - p2     (t4 = -t5, t6..t8 the same four)

so the tendons are the four sides of the quadrilateral ``p1 p3 p2 p4`` and the rods its diagonals.
Nodes are numbered ``p1..p4 -> 0..3``.
"""

from __future__ import annotations

import math

import numpy as np

from tensegrity.model.structure import Structure

#: Example 2's tendons as (name, tail, head), 0-based nodes (``p_k`` is node ``k - 1``).
EXAMPLE2_TENDONS = (("t1", 2, 1), ("t2", 2, 0), ("t3", 0, 3), ("t5", 1, 3))


def planar_rod(*, mass: float = 1.0, length: float = 1.0, angle: float = 0.0) -> Structure:
    """Example 1: one free planar rod [kg, m] from the origin at ``angle`` [rad] to the x axis."""
    tip = length * np.array([math.cos(angle), math.sin(angle)])
    return Structure(
        node_position=np.array([[0.0, 0.0], tip]),
        rod_nodes=[[0, 1]],
        rod_mass=[mass],
        rod_length=[length],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
    )


def planar_two_rod(
    *,
    rod_length: tuple[float, float] = (1.0, 0.8),
    rod_mass: tuple[float, float] = (1.0, 1.0),
    stiffness: float | tuple[float, float, float, float] = 100.0,
    rest_length: float | tuple[float, float, float, float] = 0.4,
    damping: float = 0.0,
    angle: float = math.pi / 2,
) -> Structure:
    """Example 2: two crossed planar rods and four tendons (t1, t2, t3, t5).

    The rods start crossing at their midpoints at ``angle`` [rad] to each other (rod 1 along x).
    ``stiffness`` [N/m] and ``rest_length`` [m] are one value for all tendons or four, in the
    order t1, t2, t3, t5; ``damping`` [N s/m] is the tendons'.  See
    :func:`two_rod_equilibrium` for the equilibrium.
    """
    L1, L2 = (float(x) for x in rod_length)
    r1 = np.array([L1, 0.0])
    r2 = L2 * np.array([math.cos(angle), math.sin(angle)])
    position = np.array([-r1 / 2, r1 / 2, -r2 / 2, r2 / 2])
    return Structure(
        node_position=position,
        rod_nodes=[[0, 1], [2, 3]],
        rod_mass=list(rod_mass),
        rod_length=[L1, L2],
        tendon_nodes=[(tail, head) for _, tail, head in EXAMPLE2_TENDONS],
        tendon_stiffness=np.broadcast_to(np.asarray(stiffness, dtype=float), (4,)),
        tendon_rest_length=np.broadcast_to(np.asarray(rest_length, dtype=float), (4,)),
        tendon_damping=np.full(4, float(damping)),
        tendon_name=tuple(name for name, _, _ in EXAMPLE2_TENDONS),
    )


def two_rod_equilibrium(
    rod_length: tuple[float, float], stiffness: float, rest_a: float, rest_b: float
) -> dict[str, float]:
    """The point-symmetric equilibrium of Example 2 with equal stiffness ``k`` [N/m], rest length
    ``rest_a`` [m] for t2, t5 and ``rest_b`` for t1, t3 (opposite sides of the quadrilateral).

    Derivation (``docs/constraints.md``).  With the rods crossing at their midpoints, ``p1, p2 =
    -+ r1/2`` and ``p3, p4 = -+ r2/2``; the sides are ``t2 = t5 = (r2 - r1)/2`` (length ``a``)
    and ``t1 = t3 = (r1 + r2)/2`` (length ``b``), so ``a^2 + b^2 = (L1^2 + L2^2)/2 = S``.  At
    ``p1`` the tendons pull with ``T_a (r1 - r2)/(2a) + T_b (r1 + r2)/(2b)``; a rod carries only
    axial force, so the ``r2`` component must vanish: ``T_a / a = T_b / b = w`` (equal force
    densities), i.e. ``k (1 - rest_a/a) = k (1 - rest_b/b)``, so ``a / b = rest_a / rest_b`` and

        a = rest_a sqrt(S / (rest_a^2 + rest_b^2)),   b = rest_b sqrt(S / (rest_a^2 + rest_b^2)),
        cos(phi) = (b^2 - a^2) / (L1 L2)   (phi: angle between r1 and r2),
        w = k (1 - sqrt((rest_a^2 + rest_b^2) / S)),   rod i compressed by  w L_i.

    Returns ``a``, ``b`` [m], ``cos_phi``, ``tension_a``, ``tension_b`` [N], ``compression_1``,
    ``compression_2`` [N].  Raises ``ValueError`` if no such equilibrium exists (``|cos phi| > 1``
    or slack tendons).
    """
    L1, L2 = rod_length
    S = (L1**2 + L2**2) / 2
    scale = math.sqrt(S / (rest_a**2 + rest_b**2))
    a, b = rest_a * scale, rest_b * scale
    cos_phi = (b**2 - a**2) / (L1 * L2)
    density = stiffness * (1 - 1 / scale)
    if abs(cos_phi) > 1 or density <= 0:
        raise ValueError(
            f"rest lengths ({rest_a}, {rest_b}): no taut point-symmetric equilibrium for rods "
            f"{rod_length} (cos phi = {cos_phi:.3g}, force density {density:.3g} N/m)"
        )
    return dict(
        a=a,
        b=b,
        cos_phi=cos_phi,
        tension_a=density * a,
        tension_b=density * b,
        compression_1=density * L1,
        compression_2=density * L2,
    )
