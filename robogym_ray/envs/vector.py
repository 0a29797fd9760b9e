"""``gymnasium.make_vec(id, num_envs=K)`` for every RoboGymRay id: K envs in this process.

Each sub-env is ``gymnasium.make(id, **kwargs)`` with its robot core in this process (the
in-process default of ``envs/inprocess.py``), so a vector of K envs runs K simulations in one
process with no wire and no process hand-off. The vector env is Gymnasium's own ``SyncVectorEnv``
over those envs - its autoreset (``NEXT_STEP``: the step after an episode's last one resets that
sub-env and returns its first observation with reward 0), batching and ``render`` - because the
speed comes from the sub-envs, and Gymnasium's semantics are what users expect.

Sub-env ``i`` of ``reset(seed=s)`` is seeded ``s + i`` (Gymnasium's convention).
``vectorization_mode="sync"`` / ``"async"`` build Gymnasium's vector envs from the same ids as
usual (``"async"``: one process per sub-env, each with its own in-process core).
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
from gymnasium.vector import SyncVectorEnv


class RoboGymVectorEnv(SyncVectorEnv):
    """K sub-envs of one id, stepped in this process (see the module docstring).

    Args:
        env_id: the registered id of the sub-envs.
        num_envs: K.
        **kwargs: passed to every ``gymnasium.make(env_id, ...)`` (``provider=``,
            ``render_mode=``, ``max_episode_steps=`` ...).
    """

    def __init__(self, env_id: str, num_envs: int = 1, **kwargs: Any) -> None:
        if num_envs < 1:
            raise gym.error.Error(f"{env_id}: num_envs={num_envs}; expected >= 1")
        self.env_id = env_id
        make = functools.partial(gym.make, env_id, **kwargs)
        super().__init__([make] * num_envs)


def vector_entry_point(env_id: str) -> Any:
    """What ``gymnasium.register(vector_entry_point=...)`` takes for ``env_id``: gymnasium calls
    it with ``num_envs`` and the id's kwargs (it does not pass the id itself)."""
    return functools.partial(RoboGymVectorEnv, env_id)
