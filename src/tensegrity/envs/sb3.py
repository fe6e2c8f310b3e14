"""Stable-Baselines3's ``VecEnv`` over the compiled vector environment
(:class:`~tensegrity.envs.vector.TensegrityVectorEnv`): every copy advanced in one compiled call,
with Stable-Baselines3's conventions (an ended episode resets in the same step, its last
observation in ``infos[i]["terminal_observation"]``, ``infos[i]["TimeLimit.truncated"]``).

Needs the optional extra ``rl`` (``pip install '.[rl]'``: Stable-Baselines3 and
PyTorch)::

    from stable_baselines3 import PPO
    from tensegrity.envs.sb3 import make_sb3

    env = make_sb3("tensegrity/ThreeBarCrawl-v0", 8, seed=0)
    PPO("MlpPolicy", env).learn(10_000)
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from tensegrity.envs.vector import TensegrityVectorEnv, make_vector

__all__ = ["TensegrityVecEnv", "make_sb3"]


class TensegrityVecEnv(VecEnv):
    """A :class:`stable_baselines3.common.vec_env.VecEnv` of the copies of ``vector``.

    Parameters
    ----------
    vector : TensegrityVectorEnv
        Made with ``autoreset_mode=AutoresetMode.SAME_STEP`` (:func:`make_sb3` does).

    Copy ``i`` of a reset after :meth:`seed` ``(s)`` is seeded ``s + i``, as
    Stable-Baselines3's own vector environments do; a step equals the vector environment's.
    """

    def __init__(self, vector: TensegrityVectorEnv) -> None:
        if not isinstance(vector, TensegrityVectorEnv):
            raise TypeError(f"vector: expected TensegrityVectorEnv, got {type(vector).__name__}")
        if vector.metadata["autoreset_mode"] != AutoresetMode.SAME_STEP:
            raise ValueError(
                "vector: needs autoreset_mode SAME_STEP (Stable-Baselines3 resets an ended "
                f"episode in the same step), got {vector.metadata['autoreset_mode']}"
            )
        self.vector = vector
        self._actions: np.ndarray | None = None
        super().__init__(
            vector.num_envs, vector.single_observation_space, vector.single_action_space
        )

    def reset(self) -> np.ndarray:
        """Reset every copy (with the seeds and options :meth:`seed` and
        :meth:`set_options` gave, once)."""
        options = self._options[0] or None
        observations, _ = self.vector.reset(seed=list(self._seeds), options=options)
        self.reset_infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return observations

    def step_async(self, actions: np.ndarray) -> None:
        """Keep ``actions`` (num_envs, A) for :meth:`step_wait`."""
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        """Advance every copy one control period: ``(observations, rewards, dones, infos)``."""
        if self._actions is None:
            raise RuntimeError("step_wait: call step_async first")
        actions, self._actions = self._actions, None
        observations, rewards, terminated, truncated, info = self.vector.step(actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for b in np.flatnonzero(dones):
            infos[b]["terminal_observation"] = info["final_obs"][b]
            infos[b]["TimeLimit.truncated"] = bool(truncated[b] and not terminated[b])
        if "failure" in info:
            for b in np.flatnonzero(info["_failure"]):
                infos[b]["failure"] = info["failure"][b]
        return observations, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        """Close the vector environment."""
        self.vector.close()

    def _copies(self, indices: int | Iterable[int] | None) -> list[Any]:
        return [self.vector.envs[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: int | Iterable[int] | None = None) -> list[Any]:
        """The attribute ``attr_name`` of the copies ``indices`` (default all)."""
        return [getattr(env, attr_name) for env in self._copies(indices)]

    def set_attr(
        self, attr_name: str, value: Any, indices: int | Iterable[int] | None = None
    ) -> None:
        """Set ``attr_name`` to ``value`` on the copies ``indices`` (default all)."""
        for env in self._copies(indices):
            setattr(env, attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: int | Iterable[int] | None = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Call ``method_name`` of the copies ``indices`` (default all)."""
        return [
            getattr(env, method_name)(*method_args, **method_kwargs)
            for env in self._copies(indices)
        ]

    def env_is_wrapped(
        self, wrapper_class: type, indices: int | Iterable[int] | None = None
    ) -> list[bool]:
        """The copies are not wrapped (the time limit is the vector environment's)."""
        return [False for _ in self._copies(indices)]


def make_sb3(
    env_id: str,
    num_envs: int,
    *,
    seed: int | None = None,
    max_episode_steps: int | None = None,
    **options: Any,
) -> TensegrityVecEnv:
    """Stable-Baselines3's vector environment of ``num_envs`` copies of the registered
    ``env_id`` (``"tensegrity/SixBarRoll-v0"``...), its episodes truncated after
    ``max_episode_steps`` (default: the registered limit), copy ``i`` seeded ``seed + i`` at
    the first reset; ``options`` go to the task's function (:mod:`tensegrity.envs.tasks`)."""
    vector = make_vector(
        env_id,
        num_envs,
        autoreset_mode=AutoresetMode.SAME_STEP,
        max_episode_steps=max_episode_steps,
        **options,
    )
    env = TensegrityVecEnv(vector)
    env.seed(seed)
    return env
