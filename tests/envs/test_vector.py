"""``gymnasium.make_vec`` on our ids: shapes, seeds, Gymnasium's autoreset, all three modes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs.vector import RoboGymVectorEnv

NAV = "RoboGymRay/NoObstacleNavigationMir100Sim-v0"
UR = "RoboGymRay/EndEffectorPositioningUR10Sim-v0"


@pytest.mark.parametrize("env_id", [NAV, UR])
def test_make_vec_batches_k_envs_seeded_like_single_ones(env_id: str) -> None:
    vec = gym.make_vec(env_id, num_envs=3)
    try:
        assert isinstance(vec, RoboGymVectorEnv) and vec.num_envs == 3
        single = gym.make(env_id)
        obs, _ = vec.reset(seed=11)
        assert obs.shape == (3, *single.observation_space.shape) and obs.dtype == np.float32
        for i in range(3):  # sub-env i is seeded 11 + i, as gymnasium's vector envs do
            np.testing.assert_array_equal(obs[i], single.reset(seed=11 + i)[0])
        single.close()
        obs, reward, terminated, truncated, _ = vec.step(vec.action_space.sample())
        assert obs.shape[0] == reward.shape[0] == terminated.shape[0] == truncated.shape[0] == 3
        assert vec.observation_space.contains(obs)
    finally:
        vec.close()


def test_autoreset_is_gymnasiums_next_step() -> None:
    vec = gym.make_vec(NAV, num_envs=2, max_steps=3)
    vec.reset(seed=0)
    zero = np.zeros((2, 2))
    for _ in range(2):
        _, _, terminated, truncated, _ = vec.step(zero)
        assert not (terminated | truncated).any()
    last, _, terminated, truncated, info = vec.step(zero)
    assert truncated.all() and not terminated.any()
    assert list(info["final_status"]) == ["max_steps_exceeded"] * 2
    # The next step resets the finished sub-envs: first observations, reward 0, no end.
    first, reward, terminated, truncated, _ = vec.step(zero)
    assert (reward == 0).all() and not (terminated | truncated).any()
    assert not np.array_equal(first, last)
    vec.close()


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_gymnasiums_own_vector_modes_still_work(mode: str) -> None:
    vec = gym.make_vec(NAV, num_envs=2, vectorization_mode=mode)
    try:
        obs, _ = vec.reset(seed=3)
        assert obs.shape == (2, 4)
        obs, *_ = vec.step(vec.action_space.sample())
        assert np.isfinite(obs).all()
    finally:
        vec.close()


def test_render_returns_one_frame_per_sub_env() -> None:
    vec = gym.make_vec(NAV, num_envs=2, render_mode="rgb_array")
    vec.reset(seed=0)
    frames = vec.render()
    assert len(frames) == 2 and frames[0].ndim == 3 and frames[0].dtype == np.uint8
    vec.close()
