"""One decision held for several env steps (action repeat), for training at a lower decision
rate than the env's own.

Why: where each step is short (the deploy reach streams a target every 1/60 s, relative to the
measured joints), one action changes the return by about a step's worth of tracking, and the
critic must read that difference under its own error (the action gap shrinks with the step,
Tallec, Blier and Ollivier 2019). Held for ``k`` steps, a decision's consequence is ``k`` times
larger. A policy so trained still answers every state, so it can be run at the env's own rate.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, SupportsFloat

import gymnasium as gym

from robogym_ray.errors import ConfigError


class ActionRepeat(gym.Wrapper):
    """Each ``step`` applies the action for ``repeat`` steps of ``env``, or until its episode
    ends: the observation is the last step's, the reward the sum of the steps' rewards
    (undiscounted: discount per decision in the learner), ``info`` the steps' infos merged, the
    later steps' keys over the earlier ones' (a command window's end errors and a final status
    reported inside the repeat survive it). Spaces, reset and render are ``env``'s.
    """

    def __init__(self, env: gym.Env, repeat: int) -> None:
        if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
            raise ConfigError(f"action repeat must be an int >= 1, got {repeat!r}")
        super().__init__(env)
        self.repeat = repeat

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        total, merged = 0.0, {}
        for _ in range(self.repeat):
            obs, reward, terminated, truncated, info = self.env.step(action)
            total += float(reward)
            merged.update(info)
            if terminated or truncated:
                break
        return obs, total, terminated, truncated, merged


def repeating(make_env: Callable[[], gym.Env], repeat: int) -> Callable[[], gym.Env]:
    """``make_env``'s envs wrapped in ``ActionRepeat`` (``make_env`` itself when ``repeat`` is
    1)."""
    if repeat == 1:
        return make_env

    def factory() -> gym.Env:
        return ActionRepeat(make_env(), repeat)

    return factory
