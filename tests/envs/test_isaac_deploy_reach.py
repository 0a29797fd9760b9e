"""Isaac Lab 3's Isaac-Deploy-Reach-UR10e-v0 on our UR10e: spaces, the observation term by term
against the robot's state, the relative action streamed to the servo, the 4-s commands, the
keypoint reward, the 12-s episodes, the actuator randomisation, and the Rob variant on a robot
server over gRPC (and its refusal of a server that follows trajectories)."""

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

SIM, ROB = "RoboGymRay/IsaacDeployReachUR10eSim-v0", "RoboGymRay/IsaacDeployReachUR10eRob-v0"
PI = math.pi
DEFAULT = np.array([PI, -PI / 2, PI / 2, -PI / 2, -PI / 2, 0.0])


def base_pose(q: np.ndarray) -> tuple[np.ndarray, Rotation]:
    """wrist_3_link in UR's base frame (base_link turned pi about z), from our FK."""
    xyz, quat = forward_kinematics("ur10e", q)["wrist_3_link"]
    turn = Rotation.from_euler("z", PI)
    return turn.apply(xyz), turn * Rotation.from_quat(quat)


def keypoint_distance(pos_a, rot_a: Rotation, pos_b, rot_b: Rotation) -> float:
    """Isaac Lab's seven keypoints (origin, +-0.45 m on each axis), by rotation matrices."""
    pts = np.vstack([np.zeros(3), 0.45 * np.eye(3), -0.45 * np.eye(3)])
    a = pos_a + pts @ rot_a.as_matrix().T
    b = pos_b + pts @ rot_b.as_matrix().T
    return float(np.mean(np.sqrt(((a - b) ** 2).sum(axis=1))))


def test_ids_spaces_and_check_env() -> None:
    assert SIM in ENV_IDS and ROB in ENV_IDS
    env = gym.make(SIM)
    try:
        obs_space, act_space = env.observation_space, env.action_space
        assert obs_space.shape == (19,) and act_space.shape == (6,)
        limits = np.array([2 * PI, 2 * PI, PI, 2 * PI, 2 * PI, 2 * PI])
        widen = 0.1 * 2 * limits
        np.testing.assert_allclose(obs_space.low[:6], -limits - widen, rtol=1e-6)
        assert np.all(np.isinf(obs_space.high[6:15])) and np.all(obs_space.high[15:] == 1.0)
        # Isaac ROS clamps every action to [-1, 1].
        assert act_space.low.tolist() == [-1.0] * 6 and act_space.high.tolist() == [1.0] * 6
        assert env.unwrapped.server_spec()[2]["action_mode"] == "servo_pos"
        known = ("is -infinity", "is infinity")
        assert check_env_warnings(env.unwrapped, known) == []
    finally:
        env.close()


def test_observation_term_by_term_against_the_robots_state() -> None:
    envs = [gym.make(SIM, rs_state_to_info=True, isaac_quat_order=o) for o in ("xyzw", "wxyz")]
    try:
        (obs, _), (obs_wxyz, _) = (e.reset(seed=7) for e in envs)
        task = envs[0].unwrapped
        sd = task.last_rs_state
        joints = [
            sd[f"{k}_joint_position"]
            for k in ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")
        ]
        # Absolute joint positions, Isaac Lab's (= our env) order, within 0.125 rad of default.
        np.testing.assert_allclose(obs[:6], joints, atol=1e-6)
        assert 0 < np.max(np.abs(obs[:6] - DEFAULT)) <= 0.125 + 1e-6
        np.testing.assert_allclose(obs[6:12], 0.0, atol=1e-6)  # at rest after the reset
        x, y, z, qx, qy, qz, qw = task.target_pose
        np.testing.assert_allclose(obs[12:19], [x, y, z, qx, qy, qz, qw], atol=1e-6)
        np.testing.assert_allclose(obs_wxyz[12:19], [x, y, z, qw, qx, qy, qz], atol=1e-6)
        # The command is drawn in Isaac Lab's box of the base frame.
        assert 0.6375 <= x <= 1.1375 and -0.35 <= y <= -0.1 and 0.1 <= z <= 0.3
        # The server reports wrist_3_link in the base frame: our FK of the observed joints.
        pos, rot = base_pose(obs[:6].astype(np.float64))
        ee = np.array([sd[f"ee_to_ref_translation_{a}"] for a in "xyz"])
        ee_rot = Rotation.from_quat([sd[f"ee_to_ref_rotation_{a}"] for a in "xyzw"])
        np.testing.assert_allclose(ee, pos, atol=2e-4)
        assert (ee_rot * rot.inv()).magnitude() < 1e-3
    finally:
        for e in envs:
            e.close()


def test_relative_action_keypoint_reward_and_windows() -> None:
    env = gym.make(SIM, rs_state_to_info=True)
    try:
        obs, _ = env.reset(seed=3)
        task = env.unwrapped
        action = np.array([1.0, -1.0, 0.8, -0.8, 0.6, -0.6], dtype=np.float32)
        # The targets are the measured joints plus 0.0625 x action ...
        offset = 0.0625 * action.astype(np.float64)
        np.testing.assert_allclose(task.joint_targets(action), obs[:6] + offset, atol=1e-6)
        obs2, reward, *_, info = env.step(action)
        # ... which the servo moves every joint towards, each at its own PD pace.
        fraction = (obs2[:6] - obs[:6]) / offset
        assert fraction.min() > 0.01 and fraction.max() < 1.0
        pos, rot = base_pose(obs2[:6].astype(np.float64))
        goal = task.target_pose
        d = keypoint_distance(pos, rot, goal[:3], Rotation.from_quat(goal[3:]))
        with np.errstate(over="ignore"):  # exp(5000 d) is inf beyond 0.14 m: the term is 0
            kernels = sum(1 / (np.exp(a * d) + 1e-4 + np.exp(-a * d)) for a in (50, 300, 5000))
        cost = 0.005 * 2 * float(np.sum(action.astype(np.float64) ** 2))  # rate (from 0) + L2
        assert reward == pytest.approx((-1.5 * d + 1.5 * kernels - cost) / 60, abs=2e-5)
        assert info["dist_coord"] == pytest.approx(np.linalg.norm(pos - goal[:3]), abs=2e-4)
        commands, ends = [obs2[12:].copy()], []
        truncated, steps = False, 1
        while not truncated:
            obs2, _, terminated, truncated, info = env.step(np.zeros(6, np.float32))
            steps += 1
            assert not terminated  # only the time limit ends an episode
            if not np.array_equal(obs2[12:], commands[-1]):
                commands.append(obs2[12:].copy())
                ends.append(steps)
            if "window_position_error" in info:
                ends.append(-steps)
        assert steps == 720 and info["final_status"] == "max_steps_exceeded"
        # A new command after steps 240 and 480; each window's errors at its last step.
        assert ends == [240, -240, 480, -480, -720] and len(commands) == 3
    finally:
        env.close()


def test_a_command_reached_scores_the_top_reward() -> None:
    env = gym.make(SIM)
    try:
        obs, _ = env.reset(seed=1)
        pos, rot = base_pose(obs[:6].astype(np.float64))
        here = [*pos, *rot.as_quat()]
        obs, _ = env.reset(seed=1, options={"ee_target_pose": here})
        _, reward, *_, info = env.step(np.zeros(6, np.float32))
        assert info["dist_coord"] < 1e-3 and info["dist_rot"] < 1e-3
        top = 1.5 * 3 / (2 + 1e-4) / 60
        assert top - 2e-4 < reward <= top + 1e-9
    finally:
        env.close()


def test_bang_bang_actions_stay_inside_the_rewards_range_and_the_presets_support() -> None:
    """The worst step (actions at the bounds, sign flipped each step) lies inside
    step_reward_range, and the preset's support covers that range over the horizon, to within
    a unit."""
    from robogym_ray.envs.ur_deploy_reach import step_reward_range
    from robogym_ray.training.presets import TASKS

    env = gym.make(SIM)
    try:
        high = env.action_space.high.astype(np.float64)
        worst, best = step_reward_range(high)
        env.reset(seed=2)
        rewards = [env.step((-1) ** t * env.action_space.high)[1] for t in range(12)]
        assert all(worst <= r <= best for r in rewards), (worst, rewards, best)
        # Past the first step every step pays 5 |a|^2 (the bound's action part, 3 % of it).
        action_part = -0.005 * 5 * 6 / 60
        assert all(r - action_part < 0.95 * best for r in rewards[1:])
        d4pg = TASKS["isaac-deploy-reach-ur10e"].d4pg
        assert d4pg["v_min"] <= 100 * worst < d4pg["v_min"] + 1
        assert 100 * best <= d4pg["v_max"] < 100 * best + 1
    finally:
        env.close()


def test_actuator_randomisation_is_isaac_labs_and_sim_only() -> None:
    sim, rob = gym.make(SIM), gym.make(ROB, rs_address="127.0.0.1:1")
    try:
        # _prepare only draws (nothing is connected: Rob's address is never dialled)
        floats = sim.unwrapped._prepare({})[1]
        stiffness = [floats[f"servo_stiffness_scale_{j}"] for j in range(6)]
        damping = [floats[f"servo_damping_scale_{j}"] for j in range(6)]
        friction = [floats[f"servo_friction_{j}"] for j in range(6)]
        assert all(0.9 <= v <= 1.1 for v in stiffness) and len(set(stiffness)) == 6
        assert all(0.75 <= v <= 1.5 for v in damping) and all(0 <= v <= 0.1 for v in friction)
        assert rob.unwrapped._prepare({})[1] == {}  # a real arm's gains are its own
        off = gym.make(SIM, randomize_actuators=False)
        assert off.unwrapped._prepare({})[1] == {}
        off.close()
    finally:
        sim.close()
        rob.close()


def test_rob_variant_on_a_robot_server_and_bad_kwargs() -> None:
    robot, scene, options = gym.make(SIM).unwrapped.server_spec()
    handle = start_robot_server(robot, scene=scene, options=options, seed=0)
    trajectories = start_robot_server(robot, scene=scene, options={**options,
                                      "action_mode": "abs_pos"}, seed=0)  # fmt: skip
    try:
        env = gym.make(ROB, rs_address=handle.address)
        obs, _ = env.reset(seed=0)
        for _ in range(3):
            obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert obs.shape == (19,) and not (terminated or truncated)
        env.close()
        # A server that smears targets over trajectories is refused in one line.
        env = gym.make(ROB, rs_address=trajectories.address)
        with pytest.raises(ConfigError, match="action_mode abs_pos, this task needs servo_pos"):
            env.reset(seed=0)
        env.close()
    finally:
        handle.stop()
        trajectories.stop()
    with pytest.raises(ConfigError, match="isaac_quat_order"):
        gym.make(SIM, isaac_quat_order="wzyx")
    with pytest.raises(ConfigError, match="resampling_time"):
        gym.make(SIM, resampling_time=0.001)


def test_the_evaluator_and_train_summary_report_window_end_errors() -> None:
    """The deploy reach ends only by time: the evaluator scores it by its window-end errors
    (medians over its kept episodes, as ``evaluate`` does), and ``train``'s short summary shows
    them instead of 100 % timeouts."""
    from robogym_ray.experience.episodes import greedy_episode
    from robogym_ray.experience.evaluator import Evaluator
    from robogym_ray.experience.rollout import make_gym_env
    from robogym_ray.learner.config import D4PGConfig
    from robogym_ray.training.command import summary_text

    d4pg = D4PGConfig(policy_hidden=(16, 16), critic_hidden=(16, 16))
    evaluator = Evaluator(make_gym_env(SIM), d4pg, seed=1000)
    try:
        weights = {k: v.detach().numpy() for k, v in evaluator.actor.policy.state_dict().items()}
        stats = evaluator.evaluate(weights, 1, episodes=1)
        # the same episode again, through the one greedy-episode loop
        windows = greedy_episode(evaluator.env, evaluator._act, 1000).window_errors or []
    finally:
        evaluator.close()
    assert len(windows) == 3 and stats["eval_timeout_rate"] == 1.0
    assert stats["eval_window_position_error"] == np.median([w[0] for w in windows])
    assert stats["eval_window_rotation_error"] == np.median([w[1] for w in windows])
    summary = {
        "task": SIM, "ended": "completed", "wall_s": 60.0, "env_steps": 720, "episodes": 1,
        "learner_steps": 100, "restarts": {}, "dropped_steps": 0, "robot_errors": 0,
        "checkpoint": "runs/x/checkpoints/learner.pt", "logdir": "runs/x",
        "train/success_rate": 0.0, "train/collision_rate": 0.0, "train/timeout_rate": 1.0,
        **{f"eval/{k.removeprefix('eval_')}": v for k, v in stats.items()},
    }  # fmt: skip
    text = summary_text(summary)
    position = stats["eval_window_position_error"]
    assert f"window-end error median {position:.4f} m" in text
    assert "timeout" not in text and "training episodes" not in text
