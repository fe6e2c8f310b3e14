"""Planar structures (issue 5): Theorem 18.1 in 2-D against the paper's Appendix A, Examples 1
and 2, the closed-form equilibrium of Example 2, and the same motion computed in 3-D with plane
constraints."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import Structure, artificial_damping, simulate
from tensegrity.model.planar import (
    EXAMPLE2_TENDONS,
    planar_rod,
    planar_two_rod,
    two_rod_equilibrium,
)
from tensegrity.physics import dynamics
from tensegrity.physics.constraints import constraints_of

I2, Z2 = np.eye(2), np.zeros((2, 2))


def cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The scalar cross product of planar vectors (..., 2)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def test_example1_accelerations_match_the_printed_matrix_form():
    """Example 1: ``q'' = diag(0, 0, -|q2'|^2/L^2 I) q + diag(I, [[q22^2, -q21 q22],
    [-q21 q22, q21^2]]) [g1; g2]`` with ``g1 = 2/m (f1 + f2)``, ``g2 = 6/(m L^2) (f2 - f1)``.
    (The printed diagonal has ``q^_21^2 + q^_22^2``: the hats are the dots of (18.A.17).)"""
    m, L = 1.7, 0.9
    s = planar_rod(mass=m, length=L, angle=0.4)
    rng = np.random.default_rng(3)
    q = dynamics.coordinates_from_nodes(s, s.node_position)
    q2 = q[2:]
    qdot = rng.normal(size=4)
    qdot[2:] -= (qdot[2:] @ q2) / L**2 * q2  # on the velocity constraint
    force = rng.normal(size=(2, 2))
    got = dynamics.accelerations(s, q, qdot, external_force=force)
    g1 = 2 / m * (force[0] + force[1])
    g2 = 6 / (m * L**2) * (force[1] - force[0])
    q21, q22 = q2
    printed = np.block([[I2, Z2], [Z2, np.array([[q22**2, -q21 * q22], [-q21 * q22, q21**2]])]])
    expected = np.concatenate(
        [np.zeros(2), -(qdot[2:] @ qdot[2:]) / L**2 * q2]
    ) + printed @ np.concatenate([g1, g2])
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)
    assert s.n_coordinates == 4 and s.n_dof == 3


def test_example2_topology_and_nodal_forces_match_eqs_18A20_to_18A22():
    s = planar_two_rod(angle=1.1, rest_length=[0.3, 0.35, 0.4, 0.45])
    rng = np.random.default_rng(4)
    p = s.node_position + 0.05 * rng.normal(size=(4, 2))  # a general quadrilateral
    q = dynamics.coordinates_from_nodes(s, p)
    # (18.A.22) with (18.A.21): l^d = [t1; t2; t3] = R q
    R = 0.5 * np.block([[I2, I2, -I2, I2], [I2, -I2, -I2, I2], [-I2, I2, I2, I2]])
    t = dynamics.tendon_vectors(s, p)
    names = [name for name, _, _ in EXAMPLE2_TENDONS]
    np.testing.assert_allclose(
        R @ q, t[[names.index(x) for x in ("t1", "t2", "t3")]].ravel(), atol=1e-15
    )
    # (18.A.21): q = Q l^o and its inverse, l^o = [rho; r1; r2; t5]
    Q = np.block(
        [[2 * I2, I2, Z2, Z2], [Z2, I2, Z2, Z2], [2 * I2, 2 * I2, -I2, 2 * I2], [Z2, Z2, I2, Z2]]
    )
    lo = np.concatenate([p[0], p[1] - p[0], p[3] - p[2], t[names.index("t5")]])
    np.testing.assert_allclose(Q @ lo, q, atol=1e-15)
    Qinv = 0.5 * np.block(
        [[I2, -I2, Z2, Z2], [Z2, 2 * I2, Z2, Z2], [Z2, Z2, Z2, 2 * I2], [-I2, -I2, I2, I2]]
    )
    np.testing.assert_allclose(Qinv @ q, lo, atol=1e-15)
    # (18.A.20): f_bar = B^o f^o + B^d f^d + W1 w, f_k = tension_k t_k / |t_k|
    w = rng.normal(size=(4, 2))
    tendons = dynamics.tendon_forces(s, p, np.zeros_like(p), s.tendon_rest_length)
    f = {name: tendons.tension[k] * tendons.direction[k] for k, name in enumerate(names)}
    Bo = np.vstack([I2, -I2, -I2, I2])
    Bd = np.block([[-I2, -I2, I2], [I2, -I2, I2], [I2, I2, -I2], [I2, I2, I2]])
    W1 = np.block([[I2, I2, Z2, Z2], [I2, -I2, Z2, Z2], [Z2, Z2, I2, I2], [Z2, Z2, I2, -I2]])
    printed = Bo @ f["t5"] + Bd @ np.concatenate([f["t1"], f["t2"], f["t3"]]) + W1 @ w.ravel()
    nodal = -(s.tendon_incidence_transpose @ (tendons.tension[:, None] * tendons.direction)) + w
    ours = np.concatenate(
        [nodal[0] + nodal[1], nodal[0] - nodal[1], nodal[2] + nodal[3], nodal[2] - nodal[3]]
    )
    np.testing.assert_allclose(ours, printed, atol=1e-12)
    assert np.all(tendons.tension > 0)


@pytest.mark.parametrize("rest_a, rest_b", [(0.3, 0.5), (0.4, 0.4), (0.45, 0.3)])
def test_example2_settles_at_the_closed_form_symmetric_equilibrium(rest_a, rest_b):
    """Damped from a perpendicular start, Example 2 comes to rest where
    :func:`two_rod_equilibrium` (derivation in its docstring and docs/constraints.md) says:
    rods crossing at their midpoints, sides ``a``, ``b`` with ``a/b = rest_a/rest_b``,
    ``a^2 + b^2 = (L1^2 + L2^2)/2``, equal force densities ``T/l`` in all four tendons."""
    k, lengths = 100.0, (1.0, 0.8)
    s = planar_two_rod(
        rod_length=lengths, stiffness=k, rest_length=[rest_b, rest_a, rest_b, rest_a]
    )
    r = simulate(
        artificial_damping(s),
        (0.0, 30.0),
        steady_state=True,
        velocity_tol=1e-8,
        acceleration_tol=1e-8,
    )
    assert r.status == 1, r.message
    expected = two_rod_equilibrium(lengths, k, rest_a, rest_b)
    p = r.node_position[-1]
    r1, r2 = p[1] - p[0], p[3] - p[2]
    np.testing.assert_allclose((p[0] + p[1]) / 2, (p[2] + p[3]) / 2, atol=1e-7)  # bisect
    lengths_now = r.tendon_length[-1]  # t1, t2, t3, t5
    np.testing.assert_allclose(lengths_now[[1, 3]], expected["a"], atol=1e-7)
    np.testing.assert_allclose(lengths_now[[0, 2]], expected["b"], atol=1e-7)
    assert r1 @ r2 / np.prod(lengths) == pytest.approx(expected["cos_phi"], abs=1e-7)
    np.testing.assert_allclose(r.tendon_tension[-1][[1, 3]], expected["tension_a"], rtol=1e-6)
    np.testing.assert_allclose(r.tendon_tension[-1][[0, 2]], expected["tension_b"], rtol=1e-6)
    # The tendons' pull at p1 is along rod 1 and balances its compression w L1.
    tendons = dynamics.tendon_forces(s, p, np.zeros_like(p), s.tendon_rest_length)
    pull = -(s.tendon_incidence_transpose @ (tendons.tension[:, None] * tendons.direction))
    assert pull[0] @ r1 / lengths[0] == pytest.approx(expected["compression_1"], rel=1e-6)
    assert abs(cross2(pull[0], r1)) < 1e-5
    assert pull[2] @ r2 / lengths[1] == pytest.approx(expected["compression_2"], rel=1e-6)


def test_two_rod_equilibrium_rejects_impossible_rest_lengths():
    with pytest.raises(ValueError, match="no taut point-symmetric equilibrium"):
        two_rod_equilibrium((1.0, 0.8), 100.0, 0.1, 0.9)
    with pytest.raises(ValueError, match="no taut point-symmetric equilibrium"):
        two_rod_equilibrium((1.0, 0.8), 100.0, 0.8, 0.8)


def lift(s: Structure) -> Structure:
    """The planar structure as a 3-D one in z = 0 with every node held on that plane."""
    z = np.zeros((s.n_nodes, 1))
    return s.replace(
        node_position=np.hstack([s.node_position, z]),
        node_velocity=np.hstack([s.node_velocity, z]),
        plane_nodes=np.arange(s.n_nodes),
        plane_normal=np.tile([0, 0, 1.0], (s.n_nodes, 1)),
        line_direction=None,
    )


def test_planar_motion_equals_3d_motion_held_on_a_plane():
    """Second formulation: 2-D Theorem 18.1 against the 3-D one with plane constraints (whose
    constraint forces supply what keeps the rods in the plane)."""
    s = planar_two_rod(angle=1.2, rest_length=0.3).replace(
        node_velocity=[[0.3, -0.2], [0.0, 0.5], [-0.4, 0.1], [0.2, 0.2]]
    )
    flat, lifted = (
        simulate(s, (0.0, 0.5), sample_dt=0.05),
        simulate(lift(s), (0.0, 0.5), sample_dt=0.05),
    )
    assert flat.status == lifted.status == 0
    np.testing.assert_allclose(lifted.node_position[..., :2], flat.node_position, atol=1e-8)
    assert np.max(np.abs(lifted.node_position[..., 2])) < 1e-12
    assert np.ptp(flat.total_energy) < 1e-8 * flat.energy["elastic"].max()


def test_planar_invariants_and_supports():
    """Undamped Example 2 keeps its energy, momentum and angular momentum; a planar rod pinned at
    a fixed node takes the support force ``m g / 4`` when released horizontally."""
    s = planar_two_rod(rest_length=0.3).replace(
        node_velocity=[[0.3, -0.2], [0.0, 0.5], [-0.4, 0.1], [0.2, 0.2]]
    )
    r = simulate(s, (0.0, 2.0), sample_dt=0.01)
    v, p, m = r.node_velocity, r.node_position, s.rod_mass[:, None]
    a, b = s.rod_nodes[:, 0], s.rod_nodes[:, 1]
    centre, centre_v = (p[:, a] + p[:, b]) / 2, (v[:, a] + v[:, b]) / 2
    momentum = np.sum(m * centre_v, axis=1)
    angular = np.sum(
        m[:, 0] * cross2(centre, centre_v)
        + m[:, 0] / 12 * cross2(p[:, b] - p[:, a], v[:, b] - v[:, a]),
        axis=1,
    )
    assert np.max(np.abs(momentum - momentum[0])) < 1e-9
    assert np.max(np.abs(angular - angular[0])) < 1e-9
    assert abs(angular[0]) > 0.01
    assert np.ptp(r.total_energy) < 1e-8 * r.energy["elastic"].max()

    mass, g = 2.0, 9.81
    pinned = planar_rod(mass=mass, length=1.5).replace(node_fixed=[True, False])
    state = dynamics.initial_state(pinned)
    ev = dynamics.evaluate(
        pinned,
        state.q,
        state.qdot,
        rest_length=pinned.tendon_rest_length,
        gravity=np.array([0.0, -g]),
    )
    np.testing.assert_allclose(ev.constraint_force[0], [0, mass * g / 4], atol=1e-9)


def test_planar_validation():
    s = planar_rod()
    with pytest.raises(
        ValueError, match=r"^plane_nodes: a planar structure has no plane constraints"
    ):
        s.replace(plane_nodes=[0], plane_normal=[[0, 1]])
    with pytest.raises(ValueError, match=r"^velocities: expected shape \(2, 2\)"):
        s.replace(node_velocity=np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"^gravity: expected 2 finite numbers"):
        simulate(s, (0, 1), gravity=[0, 0, -9.81])
    with pytest.raises(ValueError, match=r"^the compiled kernel: supports only free 3-D class 1"):
        from tensegrity.physics.kernel import pack

        pack(planar_two_rod())
    held = s.replace(line_nodes=[0], line_direction=[[1.0, 1.0]])
    assert constraints_of(held).matrix.shape[0] == 1
    assert Structure.from_dict(planar_two_rod().to_dict()).to_dict() == planar_two_rod().to_dict()
