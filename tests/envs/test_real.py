"""Rob variants against a ``robogym-ray serve`` subprocess (a server the env did not start)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import robogym_ray  # noqa: F401
from robogym_ray.protocol.client import RobotServerClient


def test_mir_rob_env_end_to_end(serve_subprocess):
    address = serve_subprocess("mir100", "--scene", "lab_6x8", "--seed", "0")
    with RobotServerClient(address) as probe:
        before = np.array(probe.get_state().state[3:6])
    env = gym.make("RoboGymRay/ObstacleAvoidanceMir100Rob-v0", rs_address=address)
    try:
        obs, info = env.reset(seed=0)
        assert obs.shape == (20,) and info["server"] == address
        state = env.unwrapped.client.get_state().state
        np.testing.assert_allclose(state[3:6], before, atol=1e-4)  # starts where it stood
        assert np.all(np.asarray(state[1021:1030]) == 0.0)  # no cubes sent to a real robot
        for _ in range(10):
            obs, reward, terminated, truncated, info = env.step(np.array([0.5, 0.0], np.float32))
            assert np.isfinite(reward)
            if terminated or truncated:
                break
        assert env.unwrapped.restarts == 0
    finally:
        env.close()
    with RobotServerClient(address) as probe:  # closing the env leaves the server running
        assert len(probe.get_state().state) == 1030


def test_ur10_rob_env_end_to_end(serve_subprocess):
    address = serve_subprocess(
        "ur10",
        "--scene",
        "empty",
        "--option",
        "rs_mode=1object",
        "reference_frame=base_link",
        "max_velocity_scale_factor=0.1",
        "action_cycle_rate=10",
    )
    env = gym.make("RoboGymRay/EndEffectorPositioningUR10Rob-v0", rs_address=address)
    try:
        obs, _ = env.reset(seed=0)
        assert obs.shape == (15,)
        for _ in range(5):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert obs.shape == (15,) and np.isfinite(reward) and "distance" in info
    finally:
        env.close()
