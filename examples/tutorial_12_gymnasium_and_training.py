"""
A Gymnasium environment and a short training run
=================================================

The six-bar robot as a learning task: it stands on a face on the ground, its 24 cables are the
actions, and the reward is its centre's speed along a heading. The environment is a
`Gymnasium <https://gymnasium.farama.org>`_ one, stepped by the compiled engine (cables that
slacken, feet that touch down, stick and slip, all located as events); many copies step
together in one compiled call; and a learner from Stable-Baselines3 trains on them.
"""

# %%
# The environment
# ---------------
# Importing :mod:`tensegrity.envs` registers the tasks. An action is the cables' commanded
# rest lengths, scaled to ``[-1, 1]`` over each actuator's bounds (0: the robot as built);
# the actuators follow it through their rate limit and lag. The observation is the node
# positions and velocities and the cables' lengths.
import gymnasium
import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor

import tensegrity.envs  # noqa: F401 (registers the environments)
from tensegrity.envs.sb3 import make_sb3
from tensegrity.envs.vector import make_vector
from tensegrity.plots.figures import figure_structure, new_figure

env = gymnasium.make("tensegrity/SixBarRoll-v0")
observation, info = env.reset(seed=0)
print("observation", env.observation_space.shape, "| action", env.action_space.shape)
print(f"control period {env.unwrapped.control_period * 1e3:.0f} ms")

# %%
# An episode by hand
# ------------------
# A hand-written gait: the cables squeezed and released in a travelling wave. Every step
# advances the engine one control period; ``info`` says what the feet did.
period = env.unwrapped.control_period
phase = np.linspace(0.0, 2.0 * np.pi, env.action_space.shape[0], endpoint=False)
rewards = []
for k in range(100):
    action = 0.8 * np.sin(2.0 * np.pi * 2.0 * k * period + phase)
    observation, reward, terminated, truncated, info = env.step(action.astype(np.float32))
    rewards.append(reward)
    if terminated or truncated:
        break
print(f"{len(rewards)} steps, return {sum(rewards):.3f}")
gait = new_figure((7.0, 3.0))
ax = gait.subplots()
ax.plot(np.arange(len(rewards)) * period, rewards)
ax.set_xlabel("t [s]")
ax.set_ylabel("reward per step")

# %%
# Many copies at once
# -------------------
# :func:`~tensegrity.envs.vector.make_vector` gives a Gymnasium ``VectorEnv`` of copies of one
# environment: one compiled call advances all of them over a control period, and copy ``i`` is
# bit for bit the environment seeded ``seed + i``.
copies = make_vector("tensegrity/SixBarRoll-v0", 4)
observations, infos = copies.reset(seed=0)
copies.action_space.seed(0)
for _ in range(10):
    actions = copies.action_space.sample()
    observations, rewards_now, terminated, truncated, infos = copies.step(actions)
print("observations", observations.shape, "| rewards", np.round(rewards_now, 4))
copies.close()

# %%
# A short training run
# --------------------
# PPO from Stable-Baselines3 (the ``rl`` extra) on four copies through
# :func:`~tensegrity.envs.sb3.make_sb3`. The budget here is tiny, to show the loop rather than
# a trained robot: ``examples/train_six_bar.py`` is the whole script (learning curve, saved
# policy, a video of the roll), whose default budget teaches the robot to tumble along its
# heading (``docs/environments.md``).
vector = VecMonitor(make_sb3("tensegrity/SixBarRoll-v0", 4, seed=0, max_episode_steps=32))
agent = PPO("MlpPolicy", vector, n_steps=64, batch_size=128, seed=0, device="cpu", verbose=0)
agent.learn(512)
print(f"learned for {agent.num_timesteps} steps")

# %%
# The policy in a whole run
# -------------------------
# :meth:`~tensegrity.envs.base.TensegrityEnv.simulate` runs a policy in
# :func:`~tensegrity.engine.simulate.simulate` from a reset: the whole run (every sample's nodes,
# tensions, energies and contact modes), for the viewer, the videos and the files, ending each
# control period where :meth:`~tensegrity.envs.base.TensegrityEnv.step` would.
single = vector.venv.vector.envs[0]  # (copy 0's environment)
run = single.simulate(lambda obs: agent.predict(obs, deterministic=True)[0], 0.5, seed=0)
moved = run.node_position[-1].mean(axis=0) - run.node_position[0].mean(axis=0)
print(run.message, f"| the centre moved {1e3 * moved[0]:+.1f} mm in x", run.contact_counts)
robot = figure_structure(
    single.structure, run.node_position[-1], run.tendon_tension[-1], title="After 0.5 s"
)
