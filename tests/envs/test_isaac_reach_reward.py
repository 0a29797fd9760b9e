"""The UR10 reach on Isaac Lab's own MDP (``IsaacReachIsaacRewardUR10Sim-v0``): the spaces, server
and Isaac Lab terms of ``IsaacReachUR10Sim-v0``; Isaac Lab's reward by hand; a new command every
4 s; 12-s episodes ended by nothing else; Isaac Lab's reset; and its preset's critic support."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs import ENV_IDS
from tests.envs.conftest import check_env_warnings
from tests.envs.test_isaac_reach import KNOWN_WARNINGS

SIM, ROB = (
    "RoboGymRay/IsaacReachIsaacRewardUR10Sim-v0",
    "RoboGymRay/IsaacReachIsaacRewardUR10Rob-v0",
)
ORIGINAL = "RoboGymRay/IsaacReachUR10Sim-v0"
ROTATION_TANH = "RoboGymRay/IsaacReachRotationTanhUR10Sim-v0"
FINE_TANH = "RoboGymRay/IsaacReachFineTanhUR10Sim-v0"
DEFAULT = np.array([0.0, -1.712, 1.712, 0.0, 0.0, 0.0])


def isaac_lab_reward(
    position: float, rotation: float, change, velocity, tanh_weight=0.0, fine_weight=0.0
) -> float:
    """Isaac Lab's five reach terms times their weights and the step dt of 2 x 1/60 s; with
    ``tanh_weight``, the rotation variant's sixth, ``tanh_weight (1 - tanh(rotation / 0.25))``;
    with ``fine_weight``, the fine variant's two more at stds 0.02 m and 0.05 rad."""
    terms = [
        tanh_weight * (1.0 - math.tanh(rotation / 0.25)),
        fine_weight * (1.0 - math.tanh(position / 0.02)),
        fine_weight * (1.0 - math.tanh(rotation / 0.05)),
        -0.2 * position,
        0.1 * (1.0 - math.tanh(position / 0.1)),
        -0.1 * rotation,
        -1e-4 * float(np.sum(np.square(change))),
        -1e-4 * float(np.sum(np.square(velocity))),
    ]
    return sum(terms) * 2 / 60


def angle(quat_a, quat_b) -> float:
    """The shortest rotation between two unit quaternions (x-y-z-w): 2 acos |<a, b>|."""
    return 2.0 * math.acos(min(1.0, abs(float(np.dot(quat_a, quat_b)))))


def ee_pose(sd) -> tuple[np.ndarray, np.ndarray]:
    pos = np.array([sd[f"ee_to_ref_translation_{a}"] for a in "xyz"])
    quat = np.array([sd[f"ee_to_ref_rotation_{a}"] for a in "xyzw"])
    return pos, quat / np.linalg.norm(quat)


def test_the_reward_function_on_hand_computed_values() -> None:
    from robogym_ray.envs.isaac_reach_reward import reward_per_second

    # d 0.1 m, 0.5 rad, the action changed by (1, -1, 0...), one joint at 0.5 rad/s:
    # -0.02 + 0.1 (1 - tanh 1) - 0.05 - 1e-4 x 2 - 1e-4 x 0.25
    change, velocity = np.array([1.0, -1.0, 0, 0, 0, 0]), np.array([0.5, 0, 0, 0, 0, 0])
    assert reward_per_second(0.1, 0.5, change, velocity) == pytest.approx(-0.0463844156)
    # 5 cm off, on the orientation, still: -0.01 + 0.1 (1 - tanh 0.5)
    assert reward_per_second(0.05, 0.0, np.zeros(6), np.zeros(6)) == pytest.approx(0.0437882843)
    assert reward_per_second(0.0, 0.0, np.zeros(6), np.zeros(6)) == pytest.approx(0.1)


def test_ids_spaces_server_and_isaac_terms_are_isaac_reach_ur10s() -> None:
    assert SIM in ENV_IDS and ROB in ENV_IDS
    env, original = gym.make(SIM), gym.make(ORIGINAL)
    try:
        for space in ("observation_space", "action_space"):
            ours, theirs = getattr(env, space), getattr(original, space)
            assert ours.dtype == theirs.dtype and ours.shape == theirs.shape
            np.testing.assert_array_equal(ours.low, theirs.low)
            np.testing.assert_array_equal(ours.high, theirs.high)
        assert env.unwrapped.server_spec() == original.unwrapped.server_spec()
        assert env.unwrapped.isaac_io() == original.unwrapped.isaac_io()
        assert check_env_warnings(env.unwrapped, KNOWN_WARNINGS) == []
    finally:
        env.close()
        original.close()


@pytest.mark.parametrize(
    ("env_id", "tanh_weight", "fine_weight"),
    [(SIM, 0.0, 0.0), (ROTATION_TANH, 0.1, 0.0), (FINE_TANH, 0.1, 0.1)],
)
def test_a_step_scores_tool1_against_the_command_by_isaac_labs_formula(
    env_id: str, tanh_weight: float, fine_weight: float
) -> None:
    env = gym.make(env_id, rs_state_to_info=True)
    try:
        env.reset(seed=5, options={"joint_positions": DEFAULT})
        task = env.unwrapped
        pos, quat = ee_pose(task.last_rs_state)
        # A command 10 cm from tool1, turned 0.3 rad about z from it.
        turned = Rotation.from_rotvec([0.0, 0.0, 0.3]) * Rotation.from_quat(quat)
        goal = np.array([*(pos + [0.06, 0.0, 0.08]), *turned.as_quat()])
        obs, _ = env.reset(seed=5, options={"joint_positions": DEFAULT, "ee_target_pose": goal})
        np.testing.assert_allclose(obs[:6], 0.0, atol=1e-6)  # the option wins over the draw
        actions = [np.full(6, 0.2, np.float32), np.array([0.2, -0.4, 0, 0.1, 0, 0.3], np.float32)]
        previous = np.zeros(6)
        for action in actions:
            obs, reward, terminated, truncated, info = env.step(action)
            sd = info["rs_state"]
            here, quat_here = ee_pose(sd)
            position = float(np.linalg.norm(here - goal[:3]))
            rotation = angle(quat_here, goal[3:])
            velocity = [sd[k] for k in task.velocity_keys]
            change = action - previous
            expected = isaac_lab_reward(
                position, rotation, change, velocity, tanh_weight, fine_weight
            )
            assert reward == pytest.approx(expected, abs=1e-6)
            assert info["dist_coord"] == pytest.approx(position, abs=1e-6)
            assert info["dist_rot"] == pytest.approx(rotation, abs=1e-5)
            assert np.abs(velocity).max() > 0.01 and not (terminated or truncated)
            previous = action.astype(np.float64)
        # On the command, the arm still, the action unchanged: the top reward, the tanh terms.
        env.reset(seed=5, options={"joint_positions": DEFAULT, "ee_target_pose": [*pos, *quat]})
        _, reward, *_ = env.step(np.zeros(6, np.float32))
        top = (0.1 + tanh_weight + 2 * fine_weight) / 30
        assert top - 1e-5 < reward <= top
    finally:
        env.close()


def test_a_new_command_every_120_steps_and_only_time_ends_an_episode() -> None:
    env = gym.make(SIM)
    try:
        obs, _ = env.reset(seed=3)
        commands, ends, steps, truncated = [obs[12:19].copy()], [], 0, False
        while not truncated:
            obs, _, terminated, truncated, info = env.step(np.zeros(6, np.float32))
            steps += 1
            assert not terminated
            if not np.array_equal(obs[12:19], commands[-1]):
                commands.append(obs[12:19].copy())
                ends.append(steps)
            if "window_position_error" in info:
                ends.append(-steps)
                assert info["window_position_error"] == info["dist_coord"]
        # 4 s x 30 actions per second: new commands after steps 120 and 240 (the observation
        # shows the next), each window's errors at its last step; 12 s = 360 steps.
        assert steps == 360 and info["final_status"] == "max_steps_exceeded"
        assert ends == [120, -120, 240, -240, -360] and len(commands) == 3
        for command in commands:  # IsaacReach's draw: the box, pitch pi/2 (w-x-y-z in the obs)
            assert 0.35 <= command[0] <= 0.65 and 0.15 <= command[2] <= 0.5
        # A collision (the forearm in the table) ends nothing; IsaacReachUR10Sim-v0 ends there.
        into_table = np.array([0.0, 0.0, 1.5, 0.0, 0.0, 0.0])
        env.reset(seed=3, options={"joint_positions": into_table})
        action = ((into_table - DEFAULT) / 0.5).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        assert info["in_collision"] and not (terminated or truncated)
        original = gym.make(ORIGINAL)
        original.reset(seed=3, options={"joint_positions": into_table})
        assert original.step(action)[4]["final_status"] == "collision"
        original.close()
    finally:
        env.close()


def test_every_reset_draws_isaac_labs_start_and_none_continues() -> None:
    env = gym.make(SIM)
    try:
        starts = []
        for seed in (1, None, None):
            obs, _ = env.reset(seed=seed)
            starts.append(obs[:6].copy())  # positions relative to the default pose
            for _ in range(30):
                env.step(np.zeros(6, np.float32))
        for start in starts:
            # Isaac Lab's reset_joints_by_scale (0.75, 1.25): the zero joints stay at zero.
            np.testing.assert_array_equal(start[[0, 3, 4, 5]], 0.0)
            assert np.all(np.abs(start[1:3]) <= 0.25 * 1.712 + 1e-6)
        assert len({tuple(s.round(6)) for s in starts}) == 3
    finally:
        env.close()


def test_bang_bang_steps_stay_inside_the_reward_range_and_the_presets_support() -> None:
    from robogym_ray.envs.ur_isaac_reach_reward import return_range
    from robogym_ray.training.presets import TASKS

    worst, best = (v / 100 for v in return_range())
    env = gym.make(SIM)
    try:
        env.reset(seed=2)
        low, high = env.action_space.low, env.action_space.high
        rewards = [env.step(high if t % 2 else low)[1] for t in range(12)]
        assert all(worst <= r <= best for r in rewards), (worst, rewards, best)
        # Past the first step every step pays the action's full swing, 1e-4 x 3316, and gains
        # at most the tanh term's 0.1 (per second).
        swing = float(np.sum(np.square(high.astype(np.float64) - low)))
        assert swing == pytest.approx(3316.2, abs=0.1)
        assert all(r <= (0.1 - 1e-4 * swing) / 30 for r in rewards[1:])
    finally:
        env.close()
    preset = TASKS["isaac-reach-ur10-isaac-reward"]
    assert preset.env_id == SIM
    assert (preset.d4pg["v_min"], preset.d4pg["v_max"]) == (-4.0, 1.0)
    assert preset.d4pg["v_min"] <= 100 * worst < preset.d4pg["v_min"] + 1
    assert 100 * best <= preset.d4pg["v_max"] < 100 * best + 1


@pytest.mark.parametrize(
    ("env_id", "preset_name", "added", "support"),
    [
        (ROTATION_TANH, "isaac-reach-ur10-rotation-tanh", 0.1, (-4.0, 1.0)),
        (FINE_TANH, "isaac-reach-ur10-fine-tanh", 0.3, (-4.0, 2.0)),
    ],
)
def test_the_tanh_variants_range_and_support(
    env_id: str, preset_name: str, added: float, support: tuple[float, float]
) -> None:
    from robogym_ray.envs.ur_isaac_reach_reward import return_range
    from robogym_ray.training.presets import TASKS

    env = gym.make(env_id)
    try:
        (worst, best), (tanh_worst, tanh_best) = (
            return_range(),
            return_range(0.99, type(env.unwrapped)),
        )
        # The terms are >= 0: the worst stays, the best gains their weights over the horizon.
        assert tanh_worst == worst and tanh_best == pytest.approx(best + added / 30 * 100)
        env.reset(seed=2)
        low, high = env.action_space.low, env.action_space.high
        rewards = [env.step(high if t % 2 else low)[1] for t in range(12)]
        assert all(tanh_worst / 100 <= r <= tanh_best / 100 for r in rewards), rewards
    finally:
        env.close()
    preset = TASKS[preset_name]
    assert preset.env_id == env_id
    assert (preset.d4pg["v_min"], preset.d4pg["v_max"]) == support
    assert tanh_best <= preset.d4pg["v_max"] < tanh_best + 1
