"""robo-gym 2.1.0's modular UR envs (EmptyEnvironment2UR, EndEffectorPositioning2UR) on our
embedded UR server: spaces equal to 2.1.0's, observations, rewards, ends, resets, kwargs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs import ENV_IDS
from robogym_ray.errors import ConfigError
from robogym_ray.robots.ur.geometry import forward_kinematics
from tests.envs.conftest import check_env_warnings

EMPTY5, EMPTY10 = "RoboGymRay/EmptyEnvironment2UR5Sim-v0", "RoboGymRay/EmptyEnvironment2UR10Sim-v0"
EE5, EE10 = (
    "RoboGymRay/EndEffectorPositioning2UR5Sim-v0",
    "RoboGymRay/EndEffectorPositioning2UR10Sim-v0",
)

# -- 2.1.0's numbers, as its source writes them (ur5.yaml / ur10.yaml, URBaseEnv2) ------------
TWO_PI, PI = 6.28318530718, 3.14159265359
LIMITS = np.array([TWO_PI, TWO_PI, PI, TWO_PI, TWO_PI, TWO_PI])
DEFAULT = np.array([0.0, -2.5, 1.5, 0.0, -1.4, 0.0])
OFFSET = np.array([1.5, 0.25, 0.5, 1.0, 0.4, 3.14])
WORKSPACE = {"ur5": (0.750, 0.200), "ur10": (1.300, 0.300)}
"""``workspace_area`` r, min_r (m)."""
INF = np.inf
JOINTS_LOW = [-1.1] * 6 + [-INF] * 6
"""ManipulatorObservationNode: positions within 1 + 0.1 normalised, free velocities."""
EXPECTED_OBS = {
    "empty": JOINTS_LOW,
    # ManipulatorEePosObservationNode (polar, joints, target, ee) + LastActionObservationNode.
    "ee": [-INF] * 3 + JOINTS_LOW + [-INF] * 3 + [-INF] * 3 + [-1.0] * 5,
    "ee+rotation": [-INF] * 3 + JOINTS_LOW + [-INF] * 3 + [-1.0] * 4 + [-INF] * 3 + [-1.0] * 4
    + [-1.0] * 5,
}  # fmt: skip
KNOWN_WARNINGS = ("is -infinity", "is infinity")
"""check_env's advice on 2.1.0's unbounded velocities and positions."""


def test_ids_are_registered_with_both_variants():
    for name in (EMPTY5, EMPTY10, EE5, EE10):
        assert name in ENV_IDS and name.replace("Sim-v0", "Rob-v0") in ENV_IDS


@pytest.mark.parametrize(
    ("env_id", "kwargs", "layout"),
    [(EMPTY5, {}, "empty"), (EE10, {}, "ee"), (EE5, {"ee_rotation_matters": True}, "ee+rotation")],
)
def test_spaces_equal_robo_gym_2_1_0_and_check_env_is_clean(env_id, kwargs, layout):
    env = gym.make(env_id, disable_env_checker=True, **kwargs)
    try:
        low = np.array(EXPECTED_OBS[layout], np.float32)
        assert env.observation_space.shape == ({"empty": 12, "ee": 26, "ee+rotation": 34}[layout],)
        np.testing.assert_array_equal(env.observation_space.low, low)
        np.testing.assert_array_equal(env.observation_space.high, -low)
        np.testing.assert_array_equal(env.action_space.low, -np.ones(5, np.float32))
        np.testing.assert_array_equal(env.action_space.high, np.ones(5, np.float32))
        assert check_env_warnings(env.unwrapped, KNOWN_WARNINGS) == []
    finally:
        env.close()


def test_launch_options_are_robo_gym_s():
    empty, ee = gym.make(EMPTY10).unwrapped, gym.make(EE5, action_rate=12.5).unwrapped
    assert empty.server_spec() == ("ur10", "empty", {
        "rs_mode": "only_robot", "reference_frame": "base_link",
        "max_velocity_scale_factor": "0.2", "action_cycle_rate": "20"})  # fmt: skip
    robot, scene, options = ee.server_spec()
    assert (robot, scene, options["rs_mode"]) == ("ur5", "tabletop_no_collision", "1object")
    assert options["object_0_model_name"] == "sphere50_no_collision"
    assert (options["max_velocity_scale_factor"], options["action_cycle_rate"]) == ("0.1", "12.5")
    assert empty.max_episode_steps == ee.max_episode_steps == 300
    empty.close()
    ee.close()


def state_of(info):
    sd = info["rs_state"]
    keys = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")
    q = np.array([sd[f"{k}_joint_position"] for k in keys])
    qd = np.array([sd[f"{k}_joint_velocity"] for k in keys])
    frame = {p: np.array([sd[f"{p}_to_ref_translation_{a}"] for a in "xyz"])
             for p in ("ee", "object_0") if f"{p}_to_ref_translation_x" in sd}  # fmt: skip
    quat = np.array([sd[f"ee_to_ref_rotation_{a}"] for a in "xyzw"])
    return q, qd, frame, quat


def test_empty_environment_observes_joints_fixes_wrist_3_and_survives_to_success():
    env = gym.make(EMPTY5, rs_state_to_info=True, max_steps=3)
    try:
        obs, info = env.reset(seed=0)
        action = np.array([0.1, -0.35, 0.2, -0.1, -0.2], np.float32)
        for _ in range(3):
            q, qd, _, _ = state_of(info)
            np.testing.assert_allclose(obs[:6], q / LIMITS, atol=1e-6)
            np.testing.assert_allclose(obs[6:], qd, atol=1e-5)
            assert q[5] == pytest.approx(0.0, abs=1e-9)  # wrist_3 held at its start
            obs, reward, terminated, truncated, info = env.step(action)
            assert reward == 0.0 and not terminated
        assert truncated and info["final_status"] == "success"
    finally:
        env.close()
    env = gym.make(EMPTY5)
    try:
        env.reset(seed=0, options={"joint_positions": [0.0, 1.0, 0.0, 0.0, 0.0, 0.0]})
        _, _, terminated, _, info = env.step(np.zeros(5, np.float32))
        assert terminated and info == {"final_status": "collision"}  # no rs_state by default
    finally:
        env.close()


def test_fix_joint_kwargs_keep_robo_gym_s_names():
    env = gym.make(
        EMPTY10, fix_wrist_3=False, fix_shoulder_pan=True, joint_position=[0.3, *DEFAULT[1:]]
    )
    try:
        assert env.action_space.shape == (5,)
        env.reset(seed=0)
        targets = env.unwrapped.joint_targets(np.ones(5))
        np.testing.assert_allclose(targets, [0.3, *LIMITS[1:]])  # shoulder_pan held at 0.3
    finally:
        env.close()
    for bad in ({"fix_base": True}, {"fixed_joints": ("wrist_3",)}, {"joint_position": [0.0] * 5}):
        with pytest.raises(ConfigError):
            gym.make(EMPTY10, **bad)


def workspace_target(seed, model):
    """2.1.0's ``get_random_workspace_pose_rpy`` draws from the env's seeded generator."""
    rng, (r_max, r_min) = np.random.default_rng(seed), WORKSPACE[model]
    while True:
        phi, cos_theta, u = rng.uniform(0, 2 * np.pi), rng.uniform(0, 1), rng.uniform(0, 1)
        r, sin_theta = r_max * np.cbrt(u), np.sqrt(1 - cos_theta**2)
        p = r * np.array([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta])
        if p[0] ** 2 + p[1] ** 2 > r_min**2:
            return p


@pytest.mark.parametrize(("env_id", "model"), [(EE5, "ur5"), (EE10, "ur10")])
def test_default_targets_lie_in_the_workspace_half_ball(env_id, model):
    env = gym.make(env_id)
    try:
        for seed in range(4):
            env.reset(seed=seed)
            pose = env.unwrapped.target_pose
            np.testing.assert_allclose(pose[:3], workspace_target(seed, model), atol=1e-12)
            np.testing.assert_array_equal(pose[3:], [0, 0, 0, 1])  # no rotation ranges
    finally:
        env.close()


def test_a_seeded_episode_observes_the_robot_state_component_by_component():
    env = gym.make(EE10, rs_state_to_info=True)
    try:
        obs, info = env.reset(seed=3)
        action = np.array([0.05, -0.38, 0.25, 0.0, -0.2], np.float32)
        for step in range(3):
            q, qd, frame, quat = state_of(info)
            local = Rotation.from_quat(quat).inv().apply(frame["object_0"] - frame["ee"])
            r = np.linalg.norm(local)
            polar = [r, np.arccos(local[2] / r), np.arctan2(local[1], local[0])]
            np.testing.assert_allclose(obs[:3], polar, atol=1e-5)
            np.testing.assert_allclose(obs[3:9], q / LIMITS, atol=1e-6)
            np.testing.assert_allclose(obs[9:15], qd, atol=1e-5)
            np.testing.assert_allclose(obs[15:18], frame["object_0"], atol=1e-6)
            np.testing.assert_allclose(obs[18:21], frame["ee"], atol=1e-6)
            np.testing.assert_array_equal(obs[21:], action if step else 0.0)
            obs, reward, terminated, _, info = env.step(action)
            q, _, frame, _ = state_of(info)
            distance = np.linalg.norm(frame["object_0"] - frame["ee"])
            assert not terminated and reward == pytest.approx(-0.005 * distance)
            assert info["dist_coord"] == pytest.approx(distance) and "dist_rot" not in info
    finally:
        env.close()


def tool0_pose(model, q):
    xyz, quat = forward_kinematics(model, q)["tool0"]
    return np.concatenate([xyz, quat])


def test_rotation_matters_observes_both_quaternions_and_decides_success():
    here = tool0_pose("ur5", DEFAULT)
    turned = here.copy()
    turned[3:] = (Rotation.from_quat(here[3:]) * Rotation.from_euler("y", 0.3)).as_quat()
    env = gym.make(EE5, ee_rotation_matters=True, rs_state_to_info=True)
    try:
        hold = (DEFAULT / LIMITS)[:5].astype(np.float32)
        obs, info = env.reset(seed=0, options={"ee_target_pose": turned})
        _, _, _, quat = state_of(info)
        np.testing.assert_allclose(obs[18:22], turned[3:], atol=1e-6)
        np.testing.assert_allclose(obs[25:29], quat, atol=1e-6)
        _, reward, terminated, _, info = env.step(hold)  # in place, turned by 0.3 rad: no success
        assert not terminated and info["dist_rot"] == pytest.approx(0.3, abs=1e-3)
        assert reward == pytest.approx(-0.005 * info["dist_coord"] - 0.05 * info["dist_rot"])
        env.reset(seed=0, options={"ee_target_pose": here})
        _, reward, terminated, _, info = env.step(hold)
        assert terminated and info["final_status"] == "success" and reward == 2.0
    finally:
        env.close()


def test_success_then_continue_on_success_and_the_step_limit():
    start = DEFAULT + [0.3, 0.1, 0.0, 0.0, 0.0, 0.0]
    env = gym.make(EE10, continue_on_success=True, joint_position=start, max_steps=2)
    try:
        hold = (start / LIMITS)[:5].astype(np.float32)
        env.reset(seed=0, options={"ee_target_pose": tool0_pose("ur10", start)[:3]})
        _, reward, terminated, _, info = env.step(hold + [0.002, 0, 0, 0, 0])
        assert terminated and info["final_status"] == "success" and reward == 2.0
        ended = env.unwrapped.joints(env.unwrapped.client.get_state())
        obs, _ = env.reset()  # unseeded: from where it ended, with a new target
        np.testing.assert_allclose(obs[3:9], ended / LIMITS, atol=1e-6)
        assert obs[3] != pytest.approx(start[0] / LIMITS[0], abs=1e-6)
        env.step(hold)
        _, _, terminated, truncated, info = env.step(hold)
        assert truncated and not terminated and info["final_status"] == "max_steps_exceeded"
        obs, _ = env.reset(seed=0)  # after the step limit: continue_on_success does not apply
        np.testing.assert_allclose(obs[3:9], start / LIMITS, atol=1e-6)
    finally:
        env.close()


def test_randomize_start_and_a_collision():
    env = gym.make(EE10, randomize_start=True)
    try:
        env.reset(seed=5)
        rng = np.random.default_rng(5)  # the offsets are drawn first, then the target
        np.testing.assert_allclose(env.unwrapped.start_joints,
                                   rng.uniform(DEFAULT - OFFSET, DEFAULT + OFFSET))  # fmt: skip
        env.reset(seed=0, options={"joint_positions": [0.0, 1.0, 0.0, 0.0, 0.0, 0.0]})
        _, reward, terminated, _, info = env.step(np.array([0, 1 / TWO_PI, 0, 0, 0], np.float32))
        assert terminated and info["final_status"] == "collision" and reward == -1.0
    finally:
        env.close()


def test_make_vec():
    vec = gym.make_vec(EE5, num_envs=2)
    try:
        obs, _ = vec.reset(seed=0)
        obs, reward, *_ = vec.step(np.zeros((2, 5), np.float32))
        assert obs.shape == (2, 26) and reward.shape == (2,)
        assert not np.allclose(obs[0, 15:18], obs[1, 15:18])
    finally:
        vec.close()
