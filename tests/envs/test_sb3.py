"""Stable-Baselines3 runs on the paper's navigation env (the envs are plain Gymnasium envs)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray  # noqa: F401

sb3 = pytest.importorskip("stable_baselines3")


def test_td3_500_steps_on_obstacle_avoidance():
    env = gym.make("RoboGymRay/ObstacleAvoidanceMir100Sim-v0")
    try:
        noise = sb3.common.noise.NormalActionNoise(np.zeros(2), 0.1 * np.ones(2))
        model = sb3.TD3(
            "MlpPolicy",
            env,
            action_noise=noise,
            learning_starts=100,
            batch_size=64,
            train_freq=4,
            gradient_steps=1,
            policy_kwargs={"net_arch": [64, 64]},
            seed=0,
            device="cpu",
        )
        model.learn(total_timesteps=500)
        assert model.num_timesteps == 500
        action, _ = model.predict(env.reset(seed=1)[0], deterministic=True)
        assert action.shape == (2,)
    finally:
        env.close()
