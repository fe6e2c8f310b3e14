"""Many copies of an environment stepped together (:class:`TensegrityVectorEnv`): one compiled
call of the engine advances every copy over a control period
(:class:`~tensegrity.engine.live.LiveBatch`), each exactly as its own environment's
:meth:`~tensegrity.envs.base.TensegrityEnv.step` would; the actions' scaling, the observations,
rewards and episode ends are each copy's own.

A :class:`gymnasium.vector.VectorEnv` whose ``metadata["autoreset_mode"]`` is ``NEXT_STEP``
(Gymnasium's default: the step after a copy's episode ended resets that copy, its action
ignored, its reward 0) or ``SAME_STEP`` (the step that ends an episode resets the copy and
returns its first observation, the last one in ``info["final_obs"]``, as Stable-Baselines3
expects: :mod:`tensegrity.envs.sb3`).  Copy ``i`` seeded ``seed + i`` at the first reset
(``seed`` a number), or ``seed[i]`` (a list).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from tensegrity.engine.live import LiveBatch
from tensegrity.envs.base import TensegrityEnv

__all__ = ["TensegrityVectorEnv", "make_vector"]


class TensegrityVectorEnv(VectorEnv):
    """``num_envs`` copies of the environment ``make()`` makes, stepped together.

    Parameters
    ----------
    make : callable
        Makes one copy (a :class:`~tensegrity.envs.base.TensegrityEnv`, e.g.
        ``tensegrity.envs.tasks.six_bar_roll``); every copy must be of one structure.
    num_envs : int
        The copies (>= 1).
    max_episode_steps : int, optional
        Episodes are truncated after this many steps (default: none).
    autoreset_mode : gymnasium.vector.AutoresetMode
        ``NEXT_STEP`` (default) or ``SAME_STEP``; in ``metadata["autoreset_mode"]``.
    """

    def __init__(
        self,
        make: Callable[[], TensegrityEnv],
        num_envs: int,
        *,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode = AutoresetMode.NEXT_STEP,
    ) -> None:
        if autoreset_mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(
                f"autoreset_mode: must be NEXT_STEP or SAME_STEP, got {autoreset_mode!r}"
            )
        self.metadata = {"autoreset_mode": autoreset_mode}
        if not (isinstance(num_envs, int) and num_envs >= 1):
            raise ValueError(f"num_envs: must be a whole number >= 1, got {num_envs!r}")
        if max_episode_steps is not None and not (
            isinstance(max_episode_steps, int) and max_episode_steps >= 1
        ):
            raise ValueError(
                f"max_episode_steps: must be a whole number >= 1, got {max_episode_steps!r}"
            )
        self.envs = [make() for _ in range(num_envs)]
        for b, env in enumerate(self.envs):
            if not isinstance(env, TensegrityEnv):
                raise TypeError(
                    f"make: returned {type(env).__name__} for copy {b}, not a TensegrityEnv"
                )
        first = self.envs[0]
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        self.control_period = first.control_period
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(first.observation_space, num_envs)
        self.action_space = batch_space(first.action_space, num_envs)
        self.batch = LiveBatch([env.live for env in self.envs])
        self._steps = np.zeros(num_envs, np.int64)
        self._ended = np.zeros(num_envs, bool)

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every copy: copy ``i`` with ``seed + i`` (or ``seed[i]``)."""
        super().reset(seed=seed if isinstance(seed, int) or seed is None else None)
        if seed is None or isinstance(seed, int):
            seeds: Sequence[int | None] = [
                None if seed is None else seed + i for i in range(self.num_envs)
            ]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: expected {self.num_envs} seeds, got {len(seeds)}")
        observations = [
            env.reset(seed=s, options=options)[0] for env, s in zip(self.envs, seeds, strict=True)
        ]
        self._steps[:] = 0
        self._ended[:] = False
        return np.stack(observations), {}

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Advance every copy one control period in one compiled call (a copy whose episode
        ended at the last step is reset instead).  ``ValueError`` naming ``actions`` for a
        wrong shape."""
        actions = np.asarray(actions)
        if actions.shape != self.action_space.shape:
            raise ValueError(
                f"actions: expected shape {self.action_space.shape}, got {actions.shape}"
            )
        B = self.num_envs
        observations = np.zeros((B, self.envs[0].observation_size), np.float32)
        rewards, terminated, truncated = np.zeros(B), np.zeros(B, bool), np.zeros(B, bool)
        failures: dict[int, str] = {}
        stepping = np.flatnonzero(~self._ended)
        for b in np.flatnonzero(self._ended):
            observations[b] = self.envs[b].reset()[0]
            self._steps[b] = 0
        commands = [self.envs[b].command(actions[b]) for b in stepping]
        outcomes = self.batch.advance(commands, self.control_period, which=stepping.tolist())
        for b, outcome in zip(stepping, outcomes, strict=True):
            obs, rewards[b], terminated[b], _, said = self.envs[b].outcome(outcome)
            observations[b] = obs
            if "failure" in said:
                failures[int(b)] = said["failure"]
            self._steps[b] += 1
        if self.max_episode_steps is not None:
            truncated[stepping] = self._steps[stepping] >= self.max_episode_steps
        ended = terminated | truncated
        info: dict[str, Any] = {}
        if failures:
            info["failure"] = np.array([failures.get(b, "") for b in range(B)], dtype=object)
            info["_failure"] = np.array([b in failures for b in range(B)])
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP:
            info["final_obs"] = np.array([None] * B, dtype=object)
            info["_final_obs"] = ended.copy()
            for b in np.flatnonzero(ended):
                info["final_obs"][b] = observations[b].copy()
                observations[b] = self.envs[b].reset()[0]
                self._steps[b] = 0
        else:
            self._ended = ended
        return observations, rewards, terminated, truncated, info


def make_vector(
    env_id: str,
    num_envs: int,
    *,
    autoreset_mode: AutoresetMode = AutoresetMode.NEXT_STEP,
    max_episode_steps: int | None = None,
    **options: Any,
) -> TensegrityVectorEnv:
    """The vector environment of ``num_envs`` copies of the registered ``env_id``
    (``"tensegrity/SixBarRoll-v0"``...), its episodes truncated after ``max_episode_steps``
    (default: the registered limit); ``options`` go to the task's function
    (:mod:`tensegrity.envs.tasks`)."""
    spec = gymnasium.spec(env_id)
    entry = spec.entry_point
    if not isinstance(entry, str):
        raise ValueError(f"env_id: {env_id!r} is not one of tensegrity's environments")
    module, name = entry.split(":")
    if module != "tensegrity.envs.tasks":
        raise ValueError(f"env_id: {env_id!r} is not one of tensegrity's environments")
    from tensegrity.envs import tasks

    function = getattr(tasks, name)
    return TensegrityVectorEnv(
        lambda: function(**{**spec.kwargs, **options}),
        num_envs,
        max_episode_steps=max_episode_steps or spec.max_episode_steps,
        autoreset_mode=autoreset_mode,
    )
