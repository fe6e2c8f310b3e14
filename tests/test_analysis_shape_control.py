"""Shape control of a (4,2) shell (step 5): shorten by 20%, twist back, open and closed loop."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import class1_shell
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.shape_control import (
    Bounds,
    closed_loop,
    height_twist,
    node_outputs,
    quasi_static,
    sensitivities,
    shell_rings,
)
from tensegrity.physics import dynamics

BOUNDS = Bounds(min_rest_length=0.05, max_change=0.25, min_tension=1.0)


@pytest.fixture(scope="module")
def setup():
    s = class1_shell(4, 2)
    eq = find_equilibrium(s)
    bottom, top = shell_rings(4, 2)
    return s, eq, height_twist(eq.node_position, bottom, top)


@pytest.fixture(scope="module")
def plan(setup):
    s, eq, output = setup
    h0 = output.value(eq.node_position)[0]
    return quasi_static(
        s,
        output,
        [
            {"targets": (0.8 * h0, None), "actuators": "t1_*"},  # shorten with t1 only: it twists
            (0.8 * h0, 0.0),
        ],  # twist back with every tendon
        start=eq,
        steps=[4, 2],
        bounds=BOUNDS,
        tolerance=[1e-6, 1e-6],
    )


def test_output_jacobians_match_finite_differences(setup):
    s, eq, output = setup
    p = eq.node_position + np.random.default_rng(0).normal(scale=0.01, size=eq.node_position.shape)
    h = 1e-6
    for out in (output, node_outputs(s, [3, 7], "xz")):
        fd = np.column_stack(
            [
                (out.value(p + h * e.reshape(p.shape)) - out.value(p - h * e.reshape(p.shape)))
                / (2 * h)
                for e in np.eye(p.size)
            ]
        )
        assert np.max(np.abs(out.jacobian(p) - fd)) < 1e-8


def test_equilibrium_sensitivities_match_re_solved_equilibria(setup):
    """dy/du and dT/du from the tangent stiffness against equilibria re-solved at u +- h."""
    s, eq, output = setup
    dydu, dTdu, _ = sensitivities(eq, output, eq.node_position)
    h = 1e-6
    for k in (0, 17, 60):
        u = np.zeros(s.n_tendons)
        u[k] = h
        plus = find_equilibrium(s, eq.q, control=u, gauge_reference=eq.node_position)
        minus = find_equilibrium(s, eq.q, control=-u, gauge_reference=eq.node_position)
        fd_y = (output.value(plus.node_position) - output.value(minus.node_position)) / (2 * h)
        fd_T = (plus.tension - minus.tension) / (2 * h)
        np.testing.assert_allclose(dydu[:, k], fd_y, rtol=1e-5, atol=1e-8)
        np.testing.assert_allclose(dTdu[:, k], fd_T, rtol=1e-5, atol=1e-4)


def test_quasi_static_sequence_reaches_the_targets_within_bounds(setup, plan):
    s, eq, output = setup
    h0 = output.value(eq.node_position)[0]
    assert plan.reached, plan.message
    assert plan.outputs[-1, 0] == pytest.approx(0.8 * h0, abs=1e-6)
    assert abs(plan.outputs[-1, 1]) <= 1e-6
    # shortening with t1 alone twisted the shell; the second phase took the twist back out
    assert np.min(plan.outputs[:, 1]) < -0.05
    for e in plan.equilibria:
        assert e.converged and not e.slack.any()
        assert e.tension.min() >= BOUNDS.min_tension - 1e-9
        assert e.rest_length.min() >= BOUNDS.min_rest_length - 1e-12
        assert np.abs(e.control).max() <= BOUNDS.max_change + 1e-12
    # phase 1 moved only the t1 tendons
    moved = np.flatnonzero(np.abs(plan.control[plan.phase == 0][-1]) > 0)
    assert all(s.tendon_name[i].startswith("t1_") for i in moved)


def test_closed_loop_lqr_reaches_the_targets_on_the_nonlinear_model(setup, plan):
    """The plan played in 2 s per phase with LQR feedback, simulated on Theorem 18.1 with the
    slack law: targets within 1e-6 (m, rad) after 4 s of settling, no tendon slack at any
    sample (every 0.02 s), rest lengths within bounds."""
    s, _, _ = setup
    result = closed_loop(plan, move_time=2.0, settle_time=4.0)
    assert result.reached, result.message
    assert np.all(np.abs(result.final_error) <= 1e-6)
    assert result.min_tension > 0 and np.all(result.tension > 0)
    assert result.min_rest_length >= BOUNDS.min_rest_length - 1e-12
    assert result.max_rod_length_error < 1e-8
    # it followed the plan on the way, not only at the end
    assert np.max(np.abs(result.outputs - result.reference_outputs)) < 0.01
    # at the end it is at rest at the plan's final equilibrium
    final_speed = np.abs(dynamics.nodes_from_coordinates(s, result.qdot[-1])).max()
    assert final_speed < 1e-5
