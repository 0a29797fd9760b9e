"""An env that costs (nearly) nothing, with a robot task's shapes: for measuring the data path.

``RoboGymRayBench/Free-v0`` has navigation's spaces by default (20 observations, 2 actions) and
does no simulation: each step returns a fresh observation from its seeded generator and a reward
that depends on the action, so rollout workers, n-step windows, the object store and the learner's
replay do all of their work while the env does none (``benchmarks/scaling.py``).

## Spaces
Observation ``Box((obs_dim,), float32)``, unbounded; action ``Box((act_dim,), float32)`` in
[-1, 1].

## Reward
``-|a|^2 / act_dim`` plus standard-normal noise.

## Episode end
Truncated after ``episode_steps`` steps (``final_status`` "max_steps_exceeded"); never terminated.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from robogym_ray.errors import ConfigError

FREE_ENV_ID = "RoboGymRayBench/Free-v0"


class FreeEnv(gym.Env):
    """The data path's load without a simulation (module docstring)."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 - Gymnasium's convention

    def __init__(self, obs_dim: int = 20, act_dim: int = 2, episode_steps: int = 500) -> None:
        for name, value in (("obs_dim", obs_dim), ("act_dim", act_dim),
                            ("episode_steps", episode_steps)):  # fmt: skip
            if not (isinstance(value, int) and value >= 1):
                raise ConfigError(f"FreeEnv {name} must be an integer >= 1, got {value!r}")
        self.observation_space = spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (act_dim,), np.float32)
        self.episode_steps, self.t = episode_steps, 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.t = 0
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        a = np.asarray(action, dtype=np.float32)
        if a.shape != self.action_space.shape or not np.all(np.isfinite(a)):
            raise ConfigError(f"FreeEnv action must be {self.action_space.shape} finite, got {a!r}")
        self.t += 1
        reward = -float(np.dot(a, a)) / a.size + float(self.np_random.standard_normal())
        truncated = self.t >= self.episode_steps
        info = {"final_status": "max_steps_exceeded"} if truncated else {}
        return self._obs(), reward, False, truncated, info

    def _obs(self) -> np.ndarray:
        return self.np_random.standard_normal(self.observation_space.shape, dtype=np.float32)
