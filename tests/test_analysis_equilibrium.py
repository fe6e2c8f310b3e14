"""Equilibria (issue 4, step 1): coordinates, analytic Jacobians, and the two routes agreeing.

References independent of the code under test: central finite differences, the potential energy
of :mod:`tensegrity.physics.dynamics`, and Theorem 18.1's accelerations
(``dynamics.accelerations``).
"""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import class1_shell
from tensegrity.analysis.coordinates import Chart, align, deformation, mass_matrix
from tensegrity.analysis.equilibrium import (
    compare_equilibria,
    equilibrium_by_simulation,
    find_equilibrium,
)
from tensegrity.analysis.statics import force_jacobian, statics
from tensegrity.physics import dynamics

GRAVITY = np.array([0.0, 0.0, -9.81])


@pytest.fixture(scope="module")
def shell():
    return class1_shell(3, 1)


@pytest.fixture(scope="module")
def chart(shell):
    return Chart.at(shell, dynamics.coordinates_from_nodes(shell, shell.node_position))


def _random_x(chart, scale=0.1, seed=1):
    return np.random.default_rng(seed).normal(scale=scale, size=chart.size)


def test_reduced_coordinates_keep_rod_lengths_and_invert(shell, chart):
    x = _random_x(chart, scale=0.3)
    q = chart.q(x)
    assert np.max(np.abs(dynamics.rod_length_error(shell, q))) < 1e-15
    assert np.max(np.abs(chart.x(q) - x)) < 1e-14


def test_node_jacobian_matches_finite_differences(chart):
    x = _random_x(chart)
    h = 1e-6
    fd = np.column_stack(
        [
            (chart.nodes(x + h * e) - chart.nodes(x - h * e)).ravel() / (2 * h)
            for e in np.eye(chart.size)
        ]
    )
    assert np.max(np.abs(chart.jacobian_matrix(x) - fd)) < 1e-8


def test_generalized_forces_are_minus_the_energy_gradient(shell, chart):
    """Q = J^T f against -dV/dx by central differences, with tendons, external forces, gravity."""
    x = _random_x(chart)
    rest = shell.tendon_rest_length
    w = np.random.default_rng(2).normal(size=(shell.n_nodes, 3))

    def energy(x):
        p = chart.nodes(x)
        return (
            dynamics.elastic_energy(shell, p, rest)
            - np.sum(w * p)
            + dynamics.gravity_energy(shell, chart.q(x), GRAVITY)
        )

    h = 1e-6
    grad = np.array([(energy(x + h * e) - energy(x - h * e)) / (2 * h) for e in np.eye(chart.size)])
    Q = statics(chart, x, rest, w, GRAVITY).generalized_force
    assert np.max(np.abs(Q + grad)) < 1e-6 * np.max(np.abs(grad))


def test_force_jacobian_matches_finite_differences_with_slack_tendons(shell, chart):
    """The analytic dQ/dx (tendon material + geometric stiffness, rod rotation term) away from the
    kinks of the slack law, at a configuration where some tendons are slack."""
    rest = shell.tendon_rest_length.copy()
    x = _random_x(chart)
    lengths = statics(chart, x, rest).tendons.length
    rest[:6] = lengths[:6] + 0.05  # six tendons clearly slack
    st = statics(chart, x, rest)
    assert st.tendons.taut.sum() == shell.n_tendons - 6
    h = 1e-6
    fd = np.column_stack(
        [
            (
                statics(chart, x + h * e, rest).generalized_force
                - statics(chart, x - h * e, rest).generalized_force
            )
            / (2 * h)
            for e in np.eye(chart.size)
        ]
    )
    analytic = force_jacobian(chart, x, st)
    assert np.max(np.abs(analytic - fd)) < 1e-7 * np.max(np.abs(fd))


def test_generalized_forces_agree_with_theorem_18_1_accelerations(shell, chart):
    """At rest, M x'' from Theorem 18.1's q'' equals Q (M = diag(m, m, m, mL^2/12, mL^2/12))."""
    x = _random_x(chart, seed=3)
    moved = Chart.at(shell, chart.q(x))  # based at the configuration: phi = 0 there
    zero = np.zeros(moved.size)
    st = statics(moved, zero, shell.tendon_rest_length, None, GRAVITY)
    qddot = dynamics.accelerations(shell, st.q, np.zeros_like(st.q), gravity=GRAVITY)
    xddot = moved.velocity_x(st.q, qddot)
    assert np.max(np.abs(mass_matrix(shell) * xddot - st.generalized_force)) < 1e-10


@pytest.fixture(scope="module")
def both_routes(shell):
    return find_equilibrium(shell), equilibrium_by_simulation(shell)


def test_two_routes_agree_on_the_papers_example(shell, both_routes):
    """Least squares (from the cylinder layout) and damped simulation to rest find the same
    equilibrium: all 24 tendons at 31.64 N.  The simulation stops when node speeds are below
    1e-6 m/s and accelerations below 1e-6 m/s^2, i.e. within about v / omega_min = 1e-6 / 13.4
    = 8e-8 m of rest: hence the 1e-6 m and (k = 100 N/m) 1e-4 N bounds."""
    direct, simulated = both_routes
    assert direct.converged and simulated.converged
    assert direct.method == "least_squares" and simulated.method == "simulation"
    assert direct.residual_force < 1e-10 and direct.residual_acceleration < 1e-10
    assert not direct.slack.any() and not simulated.slack.any()
    np.testing.assert_allclose(direct.tension, 31.64, atol=0.005)
    assert np.ptp(direct.tension) < 1e-9
    agreement = compare_equilibria(direct, simulated)
    assert agreement["node_distance"] < 1e-6
    assert agreement["tension_difference"] < 1e-4
    assert np.max(np.abs(dynamics.rod_length_error(shell, direct.q))) < 1e-15


def test_newton_alone_returns_from_a_moved_and_deformed_start(shell, both_routes):
    """Least squares with the analytic Jacobian, no energy descent, from the equilibrium moved
    rigidly (rotation and translation) and deformed: it converges to the same tensions, and the
    result obeys Eckart's gauge with respect to its start."""
    direct, _ = both_routes
    rng = np.random.default_rng(4)
    angle = 0.3
    rot = np.array(
        [[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]]
    )
    moved = direct.node_position @ rot.T + np.array([0.2, -0.1, 0.5])
    chart = Chart.at(shell, dynamics.coordinates_from_nodes(shell, moved))
    start = chart.nodes(rng.normal(scale=0.02, size=chart.size))
    again = find_equilibrium(shell, start, descend=False)
    assert again.converged and again.residual_force < 1e-10
    np.testing.assert_allclose(again.tension, direct.tension, atol=1e-9)
    # Eckart: the result is its own best rigid fit to the start
    np.testing.assert_allclose(
        align(again.node_position, start, shell.node_mass), again.node_position, atol=1e-9
    )
    assert deformation(again.node_position, direct.node_position, shell.node_mass) < 1e-9


def test_least_squares_alone_can_land_on_a_saddle_and_reports_its_slack_tendons(shell):
    """Without the energy descent, least squares from the cylinder layout converges to the nearest
    root: an equilibrium with the three t6 tendons slack (unstable: see the modes tests)."""
    saddle = find_equilibrium(shell, descend=False)
    assert saddle.converged and saddle.residual_force < 1e-10
    assert saddle.slack_names == ["t6_1_1", "t6_2_1", "t6_3_1"]
    assert np.all(saddle.tension[saddle.slack] == 0)
    assert saddle.to_dict()["slack_tendons"] == saddle.slack_names


def test_equilibrium_with_control_and_balanced_external_forces(shell, both_routes):
    """With rest-length changes and self-balanced nodal forces, the solution satisfies Theorem
    18.1 at rest (q'' = 0) with those inputs."""
    direct, _ = both_routes
    u = np.linspace(-0.02, 0.03, shell.n_tendons)
    w = np.zeros((shell.n_nodes, 3))
    a, b = shell.rod_nodes[0]
    axis = direct.node_position[b] - direct.node_position[a]
    w[a], w[b] = -2.0 * axis, 2.0 * axis  # stretch rod 0: no net force, no net moment
    eq = find_equilibrium(shell, direct.node_position, control=u, external_force=w)
    assert eq.converged
    qddot = dynamics.accelerations(shell, eq.q, np.zeros_like(eq.q), control=u, external_force=w)
    assert np.max(np.abs(qddot)) < 1e-9
    np.testing.assert_allclose(eq.rest_length, shell.tendon_rest_length - u)


@pytest.mark.parametrize("given", [{}, "x", None])
def test_find_equilibrium_of_something_not_a_structure_is_a_type_error_naming_it(given):
    """At the call, naming the argument (before: ``AttributeError: 'str' object has no
    attribute 'dim'``)."""
    with pytest.raises(TypeError, match=r"^structure: expected a Structure, got "):
        find_equilibrium(given)
