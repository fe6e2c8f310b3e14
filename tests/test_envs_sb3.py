"""Stable-Baselines3's VecEnv over the compiled vector environment (tensegrity.envs.sb3): the
same-step reset with the last observation in ``terminal_observation``, the time limit marked,
each copy its own environment bit for bit, and a learner that runs on it."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

pytest.importorskip("stable_baselines3")

from tensegrity.envs.sb3 import TensegrityVecEnv, make_sb3
from tensegrity.envs.tasks import three_bar_crawl
from tensegrity.envs.vector import TensegrityVectorEnv


def test_an_ended_episode_resets_in_the_same_step_as_stable_baselines3_expects():
    B, steps = 2, 5
    vector = TensegrityVectorEnv(
        three_bar_crawl, B, max_episode_steps=2, autoreset_mode=AutoresetMode.SAME_STEP
    )
    env = TensegrityVecEnv(vector)
    env.seed(7)
    A = env.action_space.shape[0]
    actions = np.random.default_rng(3).uniform(-1, 1, (steps, B, A)).astype(np.float32)
    rows, dones, infos = [env.reset()], [], []
    for k in range(steps):
        obs, reward, done, info = env.step(actions[k])
        assert reward.dtype == np.float32 and obs.shape == (B, env.observation_space.shape[0])
        rows.append(obs)
        dones.append(done)
        infos.append(info)
    assert [d.tolist() for d in dones] == [[False] * B, [True] * B] * 2 + [[False] * B]
    for b in range(B):
        single = three_bar_crawl()
        obs, _ = single.reset(seed=7 + b)
        assert np.array_equal(obs, rows[0][b])
        for k in range(steps):
            obs, reward, *_ = single.step(actions[k, b])
            if dones[k][b]:
                assert np.array_equal(infos[k][b]["terminal_observation"], obs), (b, k)
                assert infos[k][b]["TimeLimit.truncated"] is True
                obs, _ = single.reset()  # (no seed: its generator goes on)
            else:
                assert "terminal_observation" not in infos[k][b]
            assert np.array_equal(obs, rows[k + 1][b]), (b, k)


def test_the_adapter_needs_the_same_step_reset():
    with pytest.raises(ValueError, match="vector: needs autoreset_mode SAME_STEP"):
        TensegrityVecEnv(TensegrityVectorEnv(three_bar_crawl, 1))
    with pytest.raises(TypeError, match="vector: expected TensegrityVectorEnv"):
        TensegrityVecEnv(three_bar_crawl())  # type: ignore[arg-type]


def test_attributes_and_methods_reach_the_copies():
    env = make_sb3("tensegrity/ThreeBarCrawl-v0", 2, seed=0)
    assert env.get_attr("control_period") == [0.02, 0.02]
    env.set_attr("reset_noise", 0.5, indices=[1])
    assert env.get_attr("reset_noise") == [0.0, 0.5]
    assert env.env_method("command", np.zeros(9), indices=0)[0].shape == (9,)
    assert env.env_is_wrapped(object) == [False, False]


def test_proximal_policy_optimisation_learns_on_it():
    from stable_baselines3 import PPO

    env = make_sb3("tensegrity/ThreeBarCrawl-v0", 2, seed=0)
    model = PPO("MlpPolicy", env, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu")
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(32)
    assert model.num_timesteps == 32
    changed = [
        not np.array_equal(a.numpy(), p.detach().numpy())
        for a, p in zip(before, model.policy.parameters(), strict=True)
    ]
    assert any(changed)


def test_the_training_example_runs_and_writes_its_curve_policy_and_roll(tmp_path):
    """``examples/train_six_bar.py`` on a small budget (its default is 100,000 steps)."""
    import subprocess
    import sys
    from pathlib import Path

    from PIL import Image
    from stable_baselines3 import PPO

    from tensegrity.io.trajectory import read_trajectory

    script = Path(__file__).parents[1] / "examples" / "train_six_bar.py"
    argv = ["--steps", "2048", "--copies", "4", "--episode", "40", "--out", str(tmp_path)]
    done = subprocess.run(
        [sys.executable, str(script), *argv], capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr
    assert "learned for 2,048 steps; 48 episodes ended" in done.stdout
    with Image.open(tmp_path / "learning_curve.png") as curve:
        assert curve.size[0] > 500
    model = PPO.load(tmp_path / "policy.zip", device="cpu")
    assert model.observation_space.shape == (12 * 6 + 24,)
    run = read_trajectory(tmp_path / "roll.h5")
    assert run.success and run.t[-1] == pytest.approx(40 * 0.02)
    with Image.open(tmp_path / "roll.gif") as roll:
        assert roll.n_frames > 10
