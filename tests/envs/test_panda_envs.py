"""robo-gym 2.1.0's Panda envs over our embedded Panda server: spaces, wire, rewards, ends; and
the same tasks on the FR3, which keep its joint limits."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs import ENV_IDS
from robogym_ray.envs.panda_tasks import DEFAULT_JOINTS, denormalize, normalize
from robogym_ray.errors import ConfigError
from robogym_ray.robots.panda.model import LIMITS, LOWER, UPPER, forward_kinematics

EMPTY, EE = "RoboGymRay/EmptyEnvironmentPandaSim-v0", "RoboGymRay/EndEffectorPositioningPandaSim-v0"
EMPTY_FR3 = "RoboGymRay/EmptyEnvironmentFR3Sim-v0"
EE_FR3 = "RoboGymRay/EndEffectorPositioningFR3Sim-v0"
REACH_FR3 = "RoboGymRay/IsaacReachFR3Sim-v0"
FOLDED = [0.0, 0.0, 0.0, -3.0, 0.0, 1.0, 0.785]
"""Hand folded into the shoulder: a self-collision."""


def test_ids_are_registered_with_both_variants():
    for name in (EMPTY, EE, EMPTY_FR3, EE_FR3, REACH_FR3):
        assert name in ENV_IDS and name.replace("Sim-v0", "Rob-v0") in ENV_IDS


@pytest.mark.parametrize("env_id", [EMPTY, EE])
def test_check_env(env_id):
    env = gym.make(env_id, disable_env_checker=True)
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


@pytest.mark.parametrize(("env_id", "obs", "act"), [(EMPTY, 14, 6), (EE, 29, 6)])
def test_robo_gym_shapes_and_a_rendered_frame(env_id, obs, act):
    env = gym.make(env_id, render_mode="rgb_array")
    try:
        first, _ = env.reset(seed=0)
        assert env.observation_space.shape == (obs,) and env.action_space.shape == (act,)
        assert first.shape == (obs,) and first.dtype == np.float32
        np.testing.assert_allclose(first[-14 if env_id == EMPTY else 3 :][:7],
                                   normalize(np.array(DEFAULT_JOINTS)), atol=1e-6)  # fmt: skip
        frame = env.render()
        assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8 and frame.std() > 0
    finally:
        env.close()


def test_normalisation_follows_the_asymmetric_limits():
    np.testing.assert_allclose(normalize(LOWER), -1.0)
    np.testing.assert_allclose(normalize(UPPER), 1.0)
    np.testing.assert_allclose(denormalize(np.zeros(7)), (LOWER + UPPER) / 2)
    np.testing.assert_allclose(denormalize(normalize(np.array(DEFAULT_JOINTS))), DEFAULT_JOINTS)
    np.testing.assert_allclose(normalize(UPPER + 1.0), 1.0)  # saturates like np.interp


def test_actions_move_the_active_joints_and_hold_the_fixed_one():
    env = gym.make(EMPTY)
    try:
        env.reset(seed=0)
        goal = np.array([0.1, -0.2, 0.1, -0.5, 0.2, 0.4, 0.0], dtype=np.float32)
        for _ in range(300):
            obs, reward, terminated, truncated, info = env.step(goal[:6])
        assert reward == 0.0 and not terminated
        q = [info["rs_state"][f"joint{i}_position"] for i in range(1, 8)]
        np.testing.assert_allclose(q[:6], denormalize(goal)[:6], atol=1e-6)
        assert q[6] == pytest.approx(DEFAULT_JOINTS[6])
        assert truncated and info["final_status"] == "success"  # 300 steps survived
    finally:
        env.close()


def test_empty_env_ends_on_a_collision():
    env = gym.make(EMPTY)
    try:
        env.reset(seed=0, options={"joint_positions": [*FOLDED[:6], DEFAULT_JOINTS[6]]})
        _, _, terminated, _, info = env.step(np.zeros(6, np.float32))
        assert terminated and info["final_status"] == "collision"
    finally:
        env.close()


@pytest.mark.parametrize(("env_id", "model"), [(EE, "panda"), (EE_FR3, "fr3")])
def test_ee_positioning_rewards_and_success(env_id, model):
    env = gym.make(env_id)
    try:
        # A target right at the start pose's hand: success at once, reward 2 (not added).
        hand = forward_kinematics(DEFAULT_JOINTS)["panda_hand"][0]
        obs, _ = env.reset(seed=0, options={"ee_target_pose": hand})
        np.testing.assert_allclose(obs[:3][0], 0.0, atol=1e-5)  # r of the target in the hand
        hold = normalize(np.array(DEFAULT_JOINTS), LIMITS[model])[:6].astype(np.float32)
        _, reward, terminated, _, info = env.step(hold)
        assert terminated and info["final_status"] == "success" and reward == 2.0
        # Far target: -0.005 * distance, observation carries target, hand and last action.
        far = np.array([0.6, 0.2, 0.2])
        obs, _ = env.reset(seed=0, options={"ee_target_pose": far})
        obs, reward, terminated, _, info = env.step(hold)
        assert not terminated
        assert reward == pytest.approx(-0.005 * np.linalg.norm(far - hand), rel=1e-4)
        np.testing.assert_allclose(obs[17:20], far, atol=1e-6)
        np.testing.assert_allclose(obs[20:23], hand, atol=1e-5)
        np.testing.assert_allclose(obs[23:], hold)
    finally:
        env.close()


@pytest.mark.parametrize(("env_id", "model"), [(EE, "panda"), (EE_FR3, "fr3")])
def test_ee_targets_lie_in_robo_gym_s_box(env_id, model):
    env = gym.make(env_id).unwrapped
    limits = LIMITS[model]
    try:
        for seed in range(5):
            env.reset(seed=seed, options={"randomize_start": True})
            assert np.all(env.target >= [0.35, -0.2, 0.15]) and np.all(
                env.target <= [0.65, 0.2, 0.5]
            )
            assert np.all(env.start_joints >= limits.lower)
            assert np.all(env.start_joints <= limits.upper)
    finally:
        env.close()


def test_ee_positioning_collision_is_minus_one():
    env = gym.make(EE)
    try:
        env.reset(seed=0, options={"joint_positions": FOLDED})
        _, reward, terminated, _, info = env.step(np.zeros(6, np.float32))
        assert terminated and info["final_status"] == "collision" and reward == -1.0
    finally:
        env.close()


def test_rob_variant_needs_an_address_and_fixed_joints_are_checked():
    with pytest.raises(ConfigError, match="rs_address"):
        gym.make("RoboGymRay/EmptyEnvironmentPandaRob-v0")
    with pytest.raises(ConfigError, match="fixed_joints"):
        gym.make(EMPTY, fixed_joints=("wrist_3",))
    env = gym.make(EMPTY, fixed_joints=())
    assert env.action_space.shape == (7,)
    env.close()


@pytest.mark.parametrize("env_id", [EMPTY_FR3, EE_FR3, REACH_FR3])
def test_fr3_envs_serve_the_fr3_and_act_within_its_limits(env_id):
    env = gym.make(env_id).unwrapped
    fr3 = LIMITS["fr3"]
    try:
        assert env.server_spec()[0] == "fr3" and env.panda_model == "fr3"
        np.testing.assert_array_equal((env.lower, env.upper), (fr3.lower, fr3.upper))
        obs, _ = env.reset(seed=0)
        assert np.all(fr3.lower <= env.start_joints) and np.all(env.start_joints <= fr3.upper)
        if env_id == REACH_FR3:  # joint_position + 0.5 * action, bounded by the FR3's limits
            np.testing.assert_allclose(env.action_space.high, (fr3.upper - env.start_joints) / 0.5)
            np.testing.assert_allclose(env.action_space.low, (fr3.lower - env.start_joints) / 0.5)
        else:  # -1 / +1: the FR3's lower / upper limit
            n = env.action_space.shape[0]
            np.testing.assert_allclose(env.joint_targets(np.full(n, -1.0))[:n], fr3.lower[:n])
            np.testing.assert_allclose(env.joint_targets(np.ones(n))[:n], fr3.upper[:n])
        _, _, terminated, _, _ = env.step(env.action_space.sample())
        assert not terminated
    finally:
        env.close()


def test_an_unknown_panda_model_is_refused():
    with pytest.raises(ConfigError, match="unknown panda_model 'fr2'.*'fr3'"):
        gym.make(EE, panda_model="fr2")
