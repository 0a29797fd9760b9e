"""RoboGymRayBench/Free-v0: the data path's load without a simulation (benchmarks/scaling.py)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import robogym_ray.envs  # noqa: F401 - registers the id
from robogym_ray.envs.free import FREE_ENV_ID
from robogym_ray.errors import ConfigError


def test_navigations_shapes_seeded_observations_and_truncation() -> None:
    env = gym.make(FREE_ENV_ID, episode_steps=3)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.observation_space.shape == (20,) and env.action_space.shape == (2,)
    a, _ = env.reset(seed=4)
    b, _ = env.reset(seed=4)
    np.testing.assert_array_equal(a, b)
    ends = [env.step(np.zeros(2, np.float32))[2:4] for _ in range(3)]
    assert ends == [(False, False), (False, False), (False, True)]


def test_bad_actions_and_settings_are_refused() -> None:
    env = gym.make(FREE_ENV_ID)
    env.reset(seed=0)
    for action in (np.zeros(3, np.float32), np.array([np.nan, 0], np.float32)):
        with pytest.raises(ConfigError, match="FreeEnv action"):
            env.step(action)
    with pytest.raises(ConfigError, match="obs_dim"):
        gym.make(FREE_ENV_ID, obs_dim=0)
