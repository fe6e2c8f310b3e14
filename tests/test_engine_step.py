"""``tensegrity.engine.step``: a user's own loop of :func:`step` follows ``simulate(method="rk4")``
(the same compiled RK4 step and projection), conserves energy without damping, keeps the rods'
lengths and fails clearly on a blow-up."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import class1_shell, simulate
from tensegrity.engine.step import StepError, make_model, step
from tensegrity.model.shell import class2_shell
from tensegrity.physics import dynamics


@pytest.mark.parametrize(
    "structure",
    [class1_shell(3, 1, damping=0.2), class2_shell(3, 2)],
    ids=["class 1", "class 2 (joints)"],
)
def test_a_loop_of_steps_follows_simulate_rk4(structure):
    gravity = [0.0, 0.0, -9.81]
    model = make_model(structure, gravity=gravity)
    state = dynamics.initial_state(structure)
    dt, n = 1e-3, 200
    for _ in range(n):
        state = step(model, state, dt)
    run = simulate(structure, (0.0, n * dt), method="rk4", dt=dt, sample_dt=n * dt, gravity=gravity)
    assert run.status == 0 and state.t == pytest.approx(n * dt)
    # simulate's last sample is the last step's end before its projection: equal to round-off
    np.testing.assert_allclose(state.q, run.q[-1], atol=1e-12)
    np.testing.assert_allclose(state.qdot, run.qdot[-1], atol=1e-10)
    assert np.max(np.abs(dynamics.rod_length_error(structure, state.q))) < 1e-13


def test_steps_conserve_energy_without_damping():
    shell = class1_shell(4, 2)
    model = make_model(shell)
    rng = np.random.default_rng(1)
    start = dynamics.initial_state(shell)
    q, qdot = dynamics.project_to_constraints(
        shell, start.q, 0.3 * rng.standard_normal(start.q.size)
    )
    state = dynamics.State(0.0, q, qdot)

    def energy(s):
        return (
            dynamics.kinetic_energy(shell, s.qdot).sum()
            + dynamics.elastic_energy(shell, dynamics.nodes_from_coordinates(shell, s.q)).sum()
        )

    e0 = energy(state)
    for _ in range(500):
        state = step(model, state, 2e-4)
    assert abs(energy(state) - e0) < 1e-6 * e0


def test_a_blow_up_and_a_bad_step_are_refused():
    shell = class1_shell(3, 1)
    model = make_model(shell)
    state = dynamics.initial_state(shell)
    moving = dynamics.State(0.0, state.q, 1e3 * np.ones_like(state.qdot))
    with pytest.raises(StepError, match="blew up"):
        step(model, moving, 0.5)
    with pytest.raises(ValueError, match="dt"):
        step(model, state, 0.0)


def test_a_state_made_by_hand_is_projected_first_on_request():
    shell = class1_shell(3, 1)
    model = make_model(shell)
    start = dynamics.initial_state(shell)
    rng = np.random.default_rng(2)
    rough = dynamics.State(
        0.0,
        start.q + 1e-4 * rng.standard_normal(start.q.size),
        0.1 * rng.standard_normal(start.q.size),
    )
    q, qdot = dynamics.project_to_constraints(shell, rough.q, rough.qdot)
    by_hand = step(model, rough, 1e-3, project=True)
    projected = step(model, dynamics.State(0.0, q, qdot), 1e-3)
    assert np.array_equal(by_hand.q, projected.q) and np.array_equal(by_hand.qdot, projected.qdot)
    assert np.max(np.abs(dynamics.rod_length_error(shell, by_hand.q))) < 1e-13
