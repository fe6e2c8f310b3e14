"""Teach the six-bar robot to roll with Stable-Baselines3 on the compiled vector environment.

``tensegrity/SixBarRoll-v0`` (``docs/environments.md``): the robot stands on a face on the
ground, 24 cables actuated (rest lengths within 40% of their own, 0.1 m/s at most behind a 20 ms
lag), rewarded with its centre of mass's speed along the heading.  PPO learns on ``--copies``
copies stepped together in one compiled call a period (``tensegrity.envs.sb3.make_sb3``).  The
script writes to ``--out`` (default ``train-six-bar``):

- ``learning_curve.png``: the episodes' returns against the environment steps taken;
- ``policy.zip``: the trained agent (``PPO.load``);
- ``roll.gif``: the learned policy driving the robot for one episode, run in
  :func:`tensegrity.simulate` (``TensegrityEnv.simulate``), with its cables and contacts;
- ``roll.h5``: that run's trajectory (``tensegrity view --trajectory roll.h5``).

Needs the optional extra: ``pip install '.[rl]'``.  The default budget (100,000
steps; 41 minutes on a 2-core machine shared with other work) taught the policy to move the
robot's centre 0.705 m along the heading in an episode of 2 s, tumbling it from tip to tip
(``docs/environments.md``); CI runs it with ``--steps 2048`` so that it does not go stale.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecMonitor

import tensegrity.envs  # noqa: F401 (registers the environments)
from tensegrity.envs.sb3 import make_sb3
from tensegrity.io.trajectory import write_trajectory
from tensegrity.plots import animate

ENV_ID = "tensegrity/SixBarRoll-v0"


class Returns(BaseCallback):
    """Collects each finished episode's return and the environment steps taken by then."""

    def __init__(self) -> None:
        super().__init__()
        self.steps: list[int] = []
        self.returns: list[float] = []

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "episode" in info:
                self.steps.append(self.num_timesteps)
                self.returns.append(float(info["episode"]["r"]))
        return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="environment steps to learn")
    parser.add_argument("--copies", type=int, default=8, help="copies stepped together")
    parser.add_argument("--episode", type=int, default=100, help="steps per episode (20 ms each)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("train-six-bar"), help="output folder")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    env = VecMonitor(make_sb3(ENV_ID, args.copies, seed=args.seed, max_episode_steps=args.episode))
    rollout = max(8, min(128, args.steps // args.copies))
    model = PPO(
        "MlpPolicy",
        env,
        n_steps=rollout,
        batch_size=min(256, rollout * args.copies),
        learning_rate=3e-4,
        gamma=0.99,
        seed=args.seed,
        device="cpu",
        verbose=0,
    )
    returns = Returns()
    model.learn(args.steps, callback=returns)
    model.save(args.out / "policy.zip")
    print(f"learned for {model.num_timesteps:,} steps; {len(returns.returns)} episodes ended")

    figure, axes = plt.subplots(figsize=(6, 3.5), layout="constrained")
    axes.plot(returns.steps, returns.returns, ".", alpha=0.4, label="episode")
    if len(returns.returns) >= args.copies:
        window = np.ones(args.copies) / args.copies
        axes.plot(
            returns.steps[args.copies - 1 :],
            np.convolve(returns.returns, window, mode="valid"),
            label=f"mean of {args.copies}",
        )
    axes.set_xlabel("environment steps")
    axes.set_ylabel(f"return over {args.episode} steps")
    axes.set_title(f"PPO on {ENV_ID}")
    axes.legend()
    figure.savefig(args.out / "learning_curve.png", dpi=120)
    print(f"wrote {args.out / 'learning_curve.png'}")

    single = env.venv.vector.envs[0]  # (the environment of copy 0, not wrapped)
    run = single.simulate(
        lambda observation: model.predict(observation, deterministic=True)[0],
        args.episode * single.control_period,
        seed=args.seed,
    )
    moved = run.node_position[-1].mean(axis=0) - run.node_position[0].mean(axis=0)
    print(f"the learned policy moved its centre {moved[0]:+.3f} m in x, {moved[1]:+.3f} m in y")
    write_trajectory(args.out / "roll.h5", run)
    animate(run, args.out / "roll.gif", fps=25)
    print(f"wrote {args.out / 'roll.gif'}")


if __name__ == "__main__":
    main()
