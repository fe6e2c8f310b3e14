"""The vector environment (tensegrity.envs.vector): copies stepped in one compiled call, each
equal to its own environment bit for bit; autoreset; a copy's failure ends its episode only."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from tensegrity.envs.tasks import three_bar_crawl
from tensegrity.envs.vector import TensegrityVectorEnv, make_vector


def _actions(rng, steps, B, A):
    return rng.uniform(-1.0, 1.0, size=(steps, B, A)).astype(np.float32)


def test_each_copy_is_its_own_environment_bit_for_bit():
    B, steps = 3, 6
    vector = TensegrityVectorEnv(three_bar_crawl, B)
    assert vector.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    actions = _actions(np.random.default_rng(5), steps, B, vector.single_action_space.shape[0])
    observations, _ = vector.reset(seed=10)
    assert vector.observation_space.contains(observations)
    rows = [observations]
    rewards = []
    for k in range(steps):
        obs, reward, terminated, truncated, _ = vector.step(actions[k])
        rows.append(obs)
        rewards.append(reward)
        assert not terminated.any() and not truncated.any()
    for b in range(B):
        single = three_bar_crawl()
        obs, _ = single.reset(seed=10 + b)
        assert np.array_equal(obs, rows[0][b])
        for k in range(steps):
            obs, reward, *_ = single.step(actions[k, b])
            assert np.array_equal(obs, rows[k + 1][b]), (b, k)
            assert reward == rewards[k][b]
    assert not np.array_equal(rows[-1][0], rows[-1][1])  # (the copies differ)


def test_an_ended_episode_is_reset_at_the_next_step():
    vector = TensegrityVectorEnv(three_bar_crawl, 2, max_episode_steps=2)
    A = vector.single_action_space.shape[0]
    vector.reset(seed=0)
    zero = np.zeros((2, A), np.float32)
    vector.step(zero)
    _, _, _, truncated, _ = vector.step(zero)
    assert truncated.all()
    obs, reward, terminated, truncated, _ = vector.step(np.ones((2, A), np.float32))
    assert not truncated.any() and not terminated.any() and np.all(reward == 0)
    single = three_bar_crawl()
    single.reset(seed=0)
    single.step(zero[0])
    single.step(zero[0])
    again, _ = single.reset()  # (no seed: its generator goes on)
    assert np.array_equal(obs[0], again)


def test_a_copy_that_fails_ends_its_own_episode_only():
    fragile = itertools.cycle([{}, {"engine": {"max_rod_length_error": 1e-300}}])
    vector = TensegrityVectorEnv(lambda: three_bar_crawl(**next(fragile)), 2)
    vector.reset(seed=0)
    A = vector.single_action_space.shape[0]
    _, _, terminated, _, info = vector.step(np.zeros((2, A), np.float32))
    assert terminated.tolist() == [False, True]
    assert info["_failure"].tolist() == [False, True]
    assert "rod's length error" in info["failure"][1]


def test_bad_actions_and_sizes_are_named():
    vector = TensegrityVectorEnv(three_bar_crawl, 2)
    vector.reset(seed=0)
    with pytest.raises(ValueError, match=r"^actions: expected shape \(2, 9\)"):
        vector.step(np.zeros((3, 9)))
    with pytest.raises(ValueError, match="num_envs"):
        TensegrityVectorEnv(three_bar_crawl, 0)


def test_make_vector_uses_the_registered_limit():
    vector = make_vector("tensegrity/ThreeBarCrawl-v0", 2)
    assert vector.max_episode_steps == 500 and vector.num_envs == 2
    with pytest.raises(ValueError, match="env_id"):
        make_vector("CartPole-v1", 2)


def test_an_environment_observes_through_its_sensors():
    """Markers without noise but with a bias read the nodes shifted by it; the tension sensor
    reads the engine's sample; noisy sensors repeat with the seed and change with another."""
    from gymnasium.utils.env_checker import check_env

    from tensegrity.engine.sensors import Sensor

    exact = [
        Sensor("position", nodes=[0, 1], bias=0.5),
        Sensor("tension", tendons=[0, 3]),
        Sensor("contact"),
    ]
    env = three_bar_crawl(sensors=exact)
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=1)
    obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
    channels = env.observation_channels
    assert len(channels) == obs.size == env.observation_space.shape[0]
    sample = env.live.sample()
    assert np.allclose(obs[:6], sample.node_position[0, :2].ravel() + 0.5, atol=1e-6)
    assert np.allclose(obs[6:8], sample.tendon_tension[0, [0, 3]], rtol=1e-6)
    noisy = [Sensor("position", nodes=[0, 1], noise=0.01), Sensor("length", tendons=[0])]

    def run(seed):
        env = three_bar_crawl(sensors=noisy)
        rows = [env.reset(seed=seed)[0]]
        rows += [env.step(np.full(9, 0.5, np.float32))[0] for _ in range(3)]
        return np.array(rows)

    assert np.array_equal(run(4), run(4)) and not np.array_equal(run(4), run(5))
