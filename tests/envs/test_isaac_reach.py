"""robo-gym 2.1.0's Isaac Lab reach envs on our embedded UR10 and Panda servers: spaces equal to
2.1.0's, the observation piece by piece, the target sampling, rewards, ends and continuing."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs import ENV_IDS
from robogym_ray.errors import ConfigError
from robogym_ray.robots.server import start_robot_server
from robogym_ray.robots.ur.geometry import forward_kinematics
from tests.envs.conftest import check_env_warnings

UR, PANDA = "RoboGymRay/IsaacReachUR10Sim-v0", "RoboGymRay/IsaacReachPandaSim-v0"

# -- 2.1.0's numbers, as its source writes them (ur10.yaml, panda.yaml, the env classes) ------
TWO_PI, PI = 6.28318530718, 3.14159265359
UR10_MAX = np.array([TWO_PI, TWO_PI, PI, TWO_PI, TWO_PI, TWO_PI])
UR10_DEFAULT = np.array([0, -1.7120, 1.7120, 0, 0, 0])
PANDA_MIN = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
PANDA_MAX = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
PANDA_DEFAULT = np.array([0, -0.569, 0, -2.81, 0, 3.037, 0.741])
SCALE, TOLERANCE = 0.5, 0.1
"""``isaac_scale``; ``joint_position_tolerance_normalized`` times each joint's range."""


def expected_spaces(lo, hi, default, extra_lo=(), extra_hi=()):
    """IsaacReachObservationNode + LastActionObservationNode, IsaacReachActionNode."""
    act_lo, act_hi = (lo - default) / SCALE, (hi - default) / SCALE
    tol = TOLERANCE * np.abs(hi - lo)
    n = lo.size + len(extra_lo)
    low = [*(lo - tol - default), *extra_lo, *[-np.inf] * n, *[-np.inf] * 3, *[-1.0] * 4, *act_lo]
    high = [*(hi + tol - default), *extra_hi, *[np.inf] * n, *[np.inf] * 3, *[1.0] * 4, *act_hi]
    f32 = np.float32
    return (np.array(low, f32), np.array(high, f32)), (act_lo.astype(f32), act_hi.astype(f32))


EXPECTED = {
    UR: expected_spaces(-UR10_MAX, UR10_MAX, UR10_DEFAULT),
    PANDA: expected_spaces(PANDA_MIN, PANDA_MAX, PANDA_DEFAULT, (-1, -1), (1, 1)),
}
KNOWN_WARNINGS = ("symmetric and normalized", "is -infinity", "is infinity")
"""check_env's advice on 2.1.0's spaces themselves: unbounded velocities and positions, and
actions bounded by the joint limits (Isaac Lab's spaces), not [-1, 1]."""


def test_ids_are_registered_with_both_variants():
    for name in (UR, PANDA):
        assert name in ENV_IDS and name.replace("Sim-v0", "Rob-v0") in ENV_IDS


@pytest.mark.parametrize("env_id", [UR, PANDA])
def test_spaces_equal_robo_gym_2_1_0_and_check_env_is_clean(env_id):
    (obs_lo, obs_hi), (act_lo, act_hi) = EXPECTED[env_id]
    env = gym.make(env_id, disable_env_checker=True)
    try:
        assert env.observation_space.shape == ({UR: 25, PANDA: 32}[env_id],)
        np.testing.assert_array_equal(env.observation_space.low, obs_lo)
        np.testing.assert_array_equal(env.observation_space.high, obs_hi)
        np.testing.assert_array_equal(env.action_space.low, act_lo)
        np.testing.assert_array_equal(env.action_space.high, act_hi)
        assert check_env_warnings(env.unwrapped, KNOWN_WARNINGS) == []
    finally:
        env.close()


def test_launch_options_are_robo_gym_s():
    ur = gym.make(UR).unwrapped
    robot, scene, options = ur.server_spec()
    assert (robot, scene) == ("ur10", None)
    assert options["world_name"] == "isaactabletop_sphere50_no_collision.world"
    assert (options["ee_frame"], options["z"], options["rs_mode"]) == ("tool1", "0.0", "1object")
    assert (options["action_cycle_rate"], options["max_velocity_scale_factor"]) == ("30", "0.2")
    panda = gym.make(PANDA).unwrapped
    robot, _, options = panda.server_spec()
    assert robot == "panda" and options["world_name"] == ur.server_spec()[2]["world_name"]
    assert (options["z"], options["reference_frame"]) == ("0.0", "world")
    ur.close()
    panda.close()


@pytest.mark.parametrize("env_id", [UR, PANDA])
def test_a_seeded_episode_observes_the_robot_state_component_by_component(env_id):
    n, default = (6, UR10_DEFAULT) if env_id == UR else (7, PANDA_DEFAULT)
    extra = 0 if env_id == UR else 2
    env = gym.make(env_id, rs_state_to_info=True)
    try:
        obs, info = env.reset(seed=7)
        task = env.unwrapped
        # The target is 2.1.0's draw from the seed: x, y, z, roll, pitch, yaw in that order.
        rng = np.random.default_rng(7)
        pitch = math.pi / 2 if env_id == UR else math.pi
        xyz = [rng.uniform(0.35, 0.65), rng.uniform(-0.2, 0.2), rng.uniform(0.15, 0.5)]
        rpy = [rng.uniform(0.0, 0.0), rng.uniform(pitch, pitch), rng.uniform(-3.14, 3.14)]
        quat = Rotation.from_euler("xyz", rpy).as_quat()
        np.testing.assert_allclose(task.target_pose, [*xyz, *quat], atol=1e-12)
        action = np.zeros(n, np.float32)
        action[:3] = (0.2, -0.1, 0.1)
        for step in range(3):
            sd = info["rs_state"]
            joints = np.array([sd[k] for k in task.position_keys])
            velocities = np.array([sd[k] for k in task.velocity_keys])
            np.testing.assert_allclose(obs[:n], joints - default, atol=1e-5)
            np.testing.assert_array_equal(obs[n : n + extra], 0.0)  # the fingers
            np.testing.assert_allclose(obs[n + extra : 2 * n + extra], velocities, atol=1e-5)
            np.testing.assert_array_equal(obs[2 * n + extra : 2 * (n + extra)], 0.0)  # fingers
            command = obs[2 * (n + extra) : 2 * (n + extra) + 7]
            np.testing.assert_allclose(command[:3], xyz, atol=1e-6)
            np.testing.assert_allclose(command[3:], [quat[3], *quat[:3]], atol=1e-6)  # w first
            np.testing.assert_allclose([sd[f"object_0_to_ref_translation_{a}"] for a in "xyz"],
                                       xyz, atol=1e-6)  # fmt: skip
            np.testing.assert_array_equal(obs[-n:], action if step else 0.0)
            obs, reward, terminated, truncated, info = env.step(action)
            assert not (terminated or truncated)
        assert np.abs(obs[:3]).max() > 0.01  # the arm moved, toward default + 0.5 * action
        # The commanded orientation: pitch about y, then the random yaw about z.
        axis, down = ([1, 0, 0], [0, 0, -1]) if env_id == UR else ([0, 0, 1], [0, 0, -1])
        np.testing.assert_allclose(Rotation.from_quat(quat).apply(axis), down, atol=1e-9)
    finally:
        env.close()


def test_actions_are_offsets_from_the_default_pose():
    env = gym.make(UR)
    try:
        env.reset(seed=0)
        task = env.unwrapped
        action = np.array([0.4, -0.2, 0.3, 0.1, -0.5, 1.0], np.float32)
        np.testing.assert_allclose(task.joint_targets(action), UR10_DEFAULT + 0.5 * action)
        for _ in range(150):  # the controller closes in on the targets exponentially
            env.step(action)
        np.testing.assert_allclose(task.joints(task.client.get_state()),
                                   UR10_DEFAULT + 0.5 * action, atol=1e-3)  # fmt: skip
    finally:
        env.close()


def tool1_pose(q):
    xyz, quat = forward_kinematics("ur10", q)["tool1"]
    return [*xyz, *quat]


def test_success_at_2_cm_and_0_05_rad_then_the_next_episode_continues():
    env = gym.make(UR)
    try:
        hold = np.zeros(6, np.float32)
        # Within 0.02 m and 0.05 rad of where tool1 is: success at once, reward 2.
        near = np.array(tool1_pose(UR10_DEFAULT))
        near[0] += 0.015
        near[3:] = (Rotation.from_quat(near[3:]) * Rotation.from_euler("z", 0.04)).as_quat()
        env.reset(seed=0, options={"ee_target_pose": near})
        _, reward, terminated, _, info = env.step(hold)
        assert terminated and info["final_status"] == "success" and reward == 2.0
        assert info["dist_coord"] == pytest.approx(0.015, abs=1e-4)
        assert info["dist_rot"] == pytest.approx(0.04, abs=1e-4)
        # A rotation error of 0.06 rad is no success: -0.005 m^-1 and -0.05 rad^-1 per step.
        far = np.array(tool1_pose(UR10_DEFAULT))
        far[3:] = (Rotation.from_quat(far[3:]) * Rotation.from_euler("x", 0.06)).as_quat()
        offset = np.array([0.4, 0.0, 0.0, 0.0, 0.0, 0.0], np.float32)
        obs, _ = env.reset(seed=0, options={"ee_target_pose": far, "joint_positions": UR10_DEFAULT})
        _, reward, terminated, _, info = env.step(hold)
        assert not terminated
        assert reward == pytest.approx(-0.005 * info["dist_coord"] - 0.05 * info["dist_rot"])
        # Two more steps away from the default pose hit the step limit (not a collision): the
        # next episode starts where this one ended (continue_except_collision).
        env.unwrapped.max_episode_steps = 3
        env.step(offset)
        _, _, terminated, truncated, info = env.step(offset)
        assert truncated and info["final_status"] == "max_steps_exceeded"
        last = env.unwrapped.joints(env.unwrapped.client.get_state())
        obs, _ = env.reset()  # unseeded, as a rollout worker resets
        np.testing.assert_allclose(obs[:6], last - UR10_DEFAULT, atol=1e-4)
        assert obs[0] > 0.01
        # A seeded reset reproduces its episode: the default pose, whatever came before.
        env.step(offset)
        env.unwrapped.max_episode_steps = 1
        assert env.step(offset)[4]["final_status"] == "max_steps_exceeded"
        obs, _ = env.reset(seed=1)
        np.testing.assert_allclose(obs[:6], 0.0, atol=1e-5)
    finally:
        env.close()


def test_a_collision_ends_the_episode_and_the_next_starts_at_the_default_pose():
    env = gym.make(UR)
    try:
        # The upper arm pointing 0.5 rad down goes through Isaac Lab's table (top at the base).
        down = np.array([0.0, 0.5, 0.0, 0.0, 0.0, 0.0])
        env.reset(seed=0, options={"joint_positions": down})
        _, reward, terminated, _, info = env.step(env.unwrapped.action_for(down))
        assert terminated and info["final_status"] == "collision" and reward == -1.0
        obs, _ = env.reset(seed=0)
        np.testing.assert_allclose(obs[:6], 0.0, atol=1e-5)
    finally:
        env.close()


def test_panda_starts_at_the_default_pose_every_episode():
    env = gym.make(PANDA, max_steps=1)
    try:
        env.reset(seed=0)
        _, _, _, truncated, info = env.step(np.full(7, 0.3, np.float32))
        assert truncated and info["final_status"] == "max_steps_exceeded"
        obs, _ = env.reset(seed=0)
        np.testing.assert_allclose(obs[:9], 0.0, atol=1e-5)
    finally:
        env.close()


def test_make_vec_and_the_rob_variant_over_the_wire():
    vec = gym.make_vec(UR, num_envs=2)
    try:
        obs, _ = vec.reset(seed=0)
        assert obs.shape == (2, 25)
        obs, reward, *_ = vec.step(np.zeros((2, 6), np.float32))
        assert obs.shape == (2, 25) and reward.shape == (2,)
        assert not np.allclose(obs[0, 12:19], obs[1, 12:19])  # seeds 0 and 1: two targets
    finally:
        vec.close()
    robot, scene, options = gym.make(UR).unwrapped.server_spec()
    handle = start_robot_server(robot, scene=scene, options=options)
    env = gym.make(UR.replace("Sim-v0", "Rob-v0"), rs_address=str(handle.address))
    try:
        obs, _ = env.reset(seed=0)
        obs, _, terminated, _, info = env.step(np.zeros(6, np.float32))
        assert obs.shape == (25,) and not terminated and "dist_rot" in info
    finally:
        env.close()
        handle.stop(grace=0.0)


def test_bad_arguments_are_refused():
    with pytest.raises(ConfigError, match="fix_"):
        gym.make(UR, fix_wrist_3=True)
    with pytest.raises(ConfigError, match="isaac_scale"):
        gym.make(UR, isaac_scale=0.0)
    with pytest.raises(ConfigError, match="ee_target_pose"):
        gym.make(PANDA, ee_target_pose=[0.5, 0.0])
    with pytest.raises(ConfigError, match="random_joint_offset"):
        gym.make(PANDA, randomize_start=True)
    env = gym.make(UR, isaac_scale=0.25, ee_rotation_matters=False)
    assert env.action_space.high[0] == pytest.approx(TWO_PI / 0.25)
    env.close()
