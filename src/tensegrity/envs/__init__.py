"""Gymnasium environments (``docs/environments.md``): the base environment
(:class:`~tensegrity.envs.base.TensegrityEnv`) and the tasks of :mod:`tensegrity.envs.tasks`,
registered here as ``tensegrity/<Task>-v0`` for ``gymnasium.make`` (after ``import
tensegrity.envs``, or by the id ``"tensegrity.envs:tensegrity/<Task>-v0"``, which imports it).
"""

from __future__ import annotations

import gymnasium

from tensegrity.envs.base import Motion, Task, TensegrityEnv

__all__ = ["ENVIRONMENTS", "Motion", "Task", "TensegrityEnv"]

#: The registered environments: id -> (the function of :mod:`tensegrity.envs.tasks` that
#: builds it, steps per episode).
ENVIRONMENTS = {
    "tensegrity/SixBarRoll-v0": ("six_bar_roll", 500),
    "tensegrity/ThreeBarCrawl-v0": ("three_bar_crawl", 500),
    "tensegrity/ShellShape-v0": ("shell_shape", 250),
    "tensegrity/PayloadHold-v0": ("payload_hold", 500),
}

for _id, (_function, _steps) in ENVIRONMENTS.items():
    gymnasium.register(
        id=_id, entry_point=f"tensegrity.envs.tasks:{_function}", max_episode_steps=_steps
    )
