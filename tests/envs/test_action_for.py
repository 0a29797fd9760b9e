"""``action_for``: the action that sends an arm task's joints to a given configuration."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.envs.arm_common import ArmTask
from robogym_ray.envs.registration import register_all

ARM_SIM_IDS = [
    i
    for i in register_all()
    if i.endswith("Sim-v0") and any(a in i for a in ("UR", "Panda", "FR3"))
]


@pytest.mark.parametrize("env_id", ARM_SIM_IDS)
def test_action_for_inverts_the_envs_own_map(env_id: str) -> None:
    env = gym.make(env_id)
    try:
        env.reset(seed=3)
        task = env.unwrapped
        assert isinstance(task, ArmTask)
        action = env.action_space.sample().astype(np.float64)
        targets = task.joint_targets(action)
        np.testing.assert_allclose(task.action_for(targets), action, atol=1e-5)
        # The fixed joints stay where the reset put them, whatever is asked of them.
        fixed = ~task.active
        np.testing.assert_allclose(targets[fixed], task.start_joints[fixed], atol=1e-12)
        with pytest.raises(ValueError, match="joints"):
            task.action_for(targets[:-1])
    finally:
        env.close()


def test_the_positioning_envs_wrist_1_is_not_joints_over_limits() -> None:
    env = gym.make("RoboGymRay/EndEffectorPositioningRoboGymUR10Sim-v0")
    try:
        env.reset(seed=0)
        task = env.unwrapped
        q = np.array([-2.14, -0.13, 0.63, -1.13, 1.63, 0.0])
        action = task.action_for(q)
        assert action[3] == pytest.approx((-1.13 + 3.48) / 3.79 * 2 - 1, abs=1e-6)
        np.testing.assert_allclose(task.joint_targets(action)[:5], q[:5], atol=1e-5)
    finally:
        env.close()
