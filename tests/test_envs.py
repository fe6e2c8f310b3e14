"""A run advanced by its caller (engine.live.Live) against simulate(), and the Gymnasium
environments (tensegrity.envs): the checkers, determinism, actions, engine failures."""

from __future__ import annotations

import subprocess
import sys

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import tensegrity.envs
from tensegrity.design.catalogue import six_bar_robot
from tensegrity.design.rolling import stand_on_face
from tensegrity.engine.live import EngineError, Live
from tensegrity.engine.loop import Feedback
from tensegrity.engine.simulate import simulate
from tensegrity.envs.tasks import three_bar_crawl
from tensegrity.model.ground import ground
from tensegrity.physics.dynamics import initial_state

SCENE = dict(
    gravity=(0.0, 0.0, -9.81),
    ground=ground(friction=0.8, kinetic_friction=0.6),
    contact_radius=0.01,
)


@pytest.fixture(scope="module")
def robot():
    """The six-bar robot standing on its face f--- on the ground."""
    return stand_on_face(six_bar_robot(damping=1.0), (0, 4, 8), contact_radius=0.01)


def _control(robot, k: int) -> np.ndarray:
    """A control (S,) [m] that pulls in three cables of the robot by k cm."""
    u = np.zeros(robot.n_tendons)
    u[[0, 5, 10]] = 0.01 * k
    return u


# ---------------------------------------------------------------------------- Live
def test_live_stretch_equals_simulate_with_the_control_held(robot):
    """One stretch with the robot on the ground (contacts made, events located) ends where
    simulate() with the same constant control ends, to the integration tolerance."""
    live = Live(robot, **SCENE)
    live.reset(initial_state(robot))
    u = _control(robot, 8)
    state = live.advance(u, 0.3)
    result = simulate(robot, (0.0, 0.3), control=u, **SCENE)
    assert result.status == 0 and live.t == 0.3
    assert live.nswitches > 0  # (the contacts' events were located)
    np.testing.assert_allclose(state.q, result.q[-1], rtol=0, atol=1e-8)
    np.testing.assert_allclose(state.qdot, result.qdot[-1], rtol=0, atol=1e-7)
    # the control mattered: without it the robot ends elsewhere
    assert np.abs(simulate(robot, (0.0, 0.3), **SCENE).q[-1] - state.q).max() > 1e-3


def test_live_stretches_equal_simulate_with_a_controller(robot):
    """Stretches of 20 ms with changing controls equal simulate() with a controller that
    returns the same controls at the same times (the run loop's zero-order hold)."""
    period, controls = 0.02, [_control(robot, k) for k in (0, 5, 10, 3, 8, 0)]
    live = Live(robot, **SCENE)
    live.reset(initial_state(robot))
    for u in controls:
        state = live.advance(u, period)

    def law(t, q, qdot):
        return controls[round(t / period)]

    t_end = period * len(controls)
    result = simulate(robot, (0.0, t_end), controller=Feedback(law, period), **SCENE)
    assert result.status == 0
    assert live.t == pytest.approx(t_end, rel=1e-12)
    np.testing.assert_allclose(state.q, result.q[-1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(state.qdot, result.qdot[-1], rtol=0, atol=1e-9)


def test_live_failure_is_an_engine_failure_until_reset(robot):
    live = Live(robot, max_rod_length_error=1e-300, **SCENE)
    with pytest.raises(EngineError, match="reset"):
        live.advance(np.zeros(robot.n_tendons), 0.01)  # (no state yet)
    live.reset(initial_state(robot))
    with pytest.raises(EngineError, match="rod's length error") as failure:
        live.advance(np.zeros(robot.n_tendons), 0.01)
    assert 0.0 <= failure.value.t <= 0.01
    with pytest.raises(EngineError, match="rod's length error"):
        live.advance(np.zeros(robot.n_tendons), 0.01)


def test_live_refuses_a_bad_control(robot):
    live = Live(robot, **SCENE)
    live.reset(initial_state(robot))
    with pytest.raises(
        ValueError, match=r"^control: got shape \(3,\) at t = 0 s; expected \(24,\)"
    ):
        live.advance(np.zeros(3), 0.01)
    too_short = np.full(robot.n_tendons, 10.0)
    with pytest.raises(ValueError, match=r"^control\[0\]: rest length"):
        live.advance(too_short, 0.01)
    with pytest.raises(ValueError, match="duration"):
        live.advance(np.zeros(robot.n_tendons), 0.0)
    live.advance(np.zeros(robot.n_tendons), 0.01)  # (the last good control still holds)
    np.testing.assert_array_equal(live.control, 0.0)


# ---------------------------------------------------------------------------- environments
@pytest.mark.parametrize("env_id", sorted(tensegrity.envs.ENVIRONMENTS))
def test_registered_environment_passes_gymnasium_check_env(env_id):
    env = gymnasium.make(env_id)
    assert env.spec.max_episode_steps == tensegrity.envs.ENVIRONMENTS[env_id][1]
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", sorted(tensegrity.envs.ENVIRONMENTS))
def test_registered_environment_passes_stable_baselines3_check_env(env_id):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3_checker.check_env(gymnasium.make(env_id).unwrapped, warn=True)


def test_environments_are_found_by_the_module_prefix_without_import():
    """gymnasium 1.4 loads no plugins: the id with its module prefix imports the package."""
    code = (
        "import gymnasium, sys; assert 'tensegrity.envs' not in sys.modules; "
        "env = gymnasium.make('tensegrity.envs:tensegrity/ThreeBarCrawl-v0'); "
        "print(env.spec.id)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    assert out.stdout.strip() == "tensegrity/ThreeBarCrawl-v0"


def _rollout(env, seed: int, actions: np.ndarray) -> list[np.ndarray]:
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, reward, *_ = env.step(a)
        out.extend([obs, np.array([reward])])
    return out


@pytest.fixture(scope="module")
def crawler():
    return three_bar_crawl(reset_noise=0.05)


def test_same_seed_and_actions_give_the_same_trajectory_bit_for_bit(crawler):
    actions = np.random.default_rng(7).uniform(-1, 1, (4, crawler.action_space.shape[0]))
    first = _rollout(crawler, 3, actions)
    other = three_bar_crawl(reset_noise=0.05)  # (a second environment, too)
    for again in (_rollout(crawler, 3, actions), _rollout(other, 3, actions)):
        assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    different = _rollout(crawler, 4, actions)
    assert not np.array_equal(first[0], different[0])  # the seed perturbs the start


def test_reset_is_reproducible_from_the_seed(crawler):
    a, _ = crawler.reset(seed=11)
    crawler.step(crawler.action_space.sample())
    b, _ = crawler.reset(seed=11)
    np.testing.assert_array_equal(a, b)
    c, _ = crawler.reset(seed=12)
    assert not np.array_equal(a, c)


def test_observation_holds_nodes_velocities_and_cable_lengths(crawler):
    obs, _ = crawler.reset(seed=0)
    s = crawler.structure
    N = s.n_nodes
    assert obs.dtype == np.float32 and obs.shape == (6 * N + crawler.actuators.size,)
    np.testing.assert_allclose(obs[: 3 * N].reshape(N, 3), s.node_position, atol=1e-6)
    lengths = np.linalg.norm(np.diff(s.node_position[s.tendon_nodes], axis=1)[:, 0], axis=1)
    np.testing.assert_allclose(obs[6 * N :], lengths[crawler.actuators.tendons], rtol=1e-6)


def test_action_scale_clip_and_shape(crawler):
    s, act = crawler.structure, crawler.actuators
    rest = s.tendon_rest_length[act.tendons]
    A = act.size
    np.testing.assert_allclose(crawler.command(np.ones(A)), rest - act.min_rest_length)
    np.testing.assert_allclose(crawler.command(-np.ones(A)), rest - act.max_rest_length)
    np.testing.assert_allclose(crawler.command(np.zeros(A)), 0.0, atol=1e-15)
    np.testing.assert_array_equal(crawler.command(np.full(A, 3.0)), crawler.command(np.ones(A)))
    crawler.reset(seed=0)
    far = crawler.step(np.full(A, -7.0))[0]
    crawler.reset(seed=0)
    np.testing.assert_array_equal(far, crawler.step(-np.ones(A))[0])
    with pytest.raises(ValueError, match=r"^action: expected shape"):
        crawler.step(np.zeros(A + 1))
    with pytest.raises(ValueError, match=r"^action: must be finite"):
        crawler.step(np.full(A, np.nan))


def test_engine_blow_up_ends_the_episode_with_the_reason():
    env = three_bar_crawl(engine=dict(max_rod_length_error=1e-300))
    obs, _ = env.reset(seed=0)
    after, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
    assert terminated and not truncated and reward == 0.0
    assert "unstable: a rod's length error" in info["failure"]
    np.testing.assert_array_equal(after, obs)  # the last good observation
    assert env.step(np.zeros(env.action_space.shape))[2]  # and again, not an exception


def test_a_policy_run_in_simulate_passes_through_the_states_the_steps_give():
    """``env.simulate(policy, duration)`` (the whole run, for animations and files) is at the
    end of each control period where stepping the environment with the same policy is."""
    env = three_bar_crawl(reset_noise=0.01)
    A, size = env.action_space.shape[0], env.observation_size
    gain = np.random.default_rng(2).normal(scale=0.5, size=(A, size)).astype(np.float32)

    def policy(observation):
        return np.tanh(gain @ (observation - first))

    first, _ = env.reset(seed=4)
    nodes = [first[: 3 * env.structure.n_nodes]]
    observation = first
    for _ in range(8):
        observation, *_ = env.step(policy(observation))
        nodes.append(observation[: 3 * env.structure.n_nodes])
    result = env.simulate(policy, 8 * env.control_period, seed=4)
    assert result.success, result.message
    np.testing.assert_allclose(result.t, env.control_period * np.arange(9), rtol=0, atol=1e-12)
    ran = result.node_position.reshape(9, -1).astype(np.float32)
    np.testing.assert_allclose(ran, np.array(nodes), rtol=0, atol=1e-6)
    assert np.abs(ran[-1] - ran[0]).max() > 1e-3  # (the policy moved it)
    assert np.ptp(result.control_applied, axis=0).max() > 0.01


def test_an_environment_with_sensors_is_not_run_in_simulate():
    from tensegrity.engine.sensors import Sensor

    env = three_bar_crawl(sensors=[Sensor("length", tendons=[0])])
    with pytest.raises(ValueError, match="simulate: an environment with sensors"):
        env.simulate(lambda obs: np.zeros(9), 0.1)
