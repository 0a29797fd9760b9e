"""UR task details: wire order, target sampling, success, the substitute RAAD trajectory."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import robogym_ray  # noqa: F401
from robogym_ray.envs.ur_avoidance import RAAD_SEGMENTS, RAAD_START, raad_reference_trajectory
from robogym_ray.envs.ur_common import KEYS, normalize_joints, to_ros
from robogym_ray.envs.ur_tasks import PAPER_RADIUS_SCALE, sample_target
from robogym_ray.robots.ur.geometry import UR_MODELS


def test_key_sets_match_the_spec():
    assert [len(KEYS[m]) for m in ("only_robot", "1object", "1moving2points")] == [20, 27, 34]


def test_ros_order_swaps_base_and_elbow():
    np.testing.assert_array_equal(to_ros(np.arange(6)), [2, 1, 0, 3, 4, 5])


@pytest.mark.parametrize("model", ["ur3", "ur5", "ur10", "ur16e"])
def test_targets_avoid_singular_regions(model):
    spec = UR_MODELS[model]
    rng = np.random.default_rng(0)
    radius = spec.workspace_r * PAPER_RADIUS_SCALE
    pts = np.array([sample_target(rng, spec, radius) for _ in range(500)])
    assert np.all(np.linalg.norm(pts, axis=1) <= radius) and np.all(pts[:, 2] >= 0)
    assert np.all(np.hypot(pts[:, 0], pts[:, 1]) >= spec.workspace_min_r)
    if model == "ur10":
        assert radius == pytest.approx(1.2)


def test_paper_ee_env_sends_ros_order_and_reaches_success():
    env = gym.make("RoboGymRay/EndEffectorPositioningUR10Sim-v0")
    try:
        env.reset(seed=0)
        u = env.unwrapped
        ee = np.array([u.last_rs_state[f"ee_to_ref_translation_{a}"] for a in "xyz"])
        joints = u.joints(u.client.get_state())
        # A target where the end effector already is: holding still succeeds at once.
        env.reset(seed=0, options={"joint_positions": joints, "ee_target_pose": ee})
        obs, reward, terminated, _, info = env.step(normalize_joints(joints).astype(np.float32))
        assert terminated and info["final_status"] == "success" and reward > 50
        np.testing.assert_allclose(obs[:3], _spherical(ee), atol=1e-5)
    finally:
        env.close()


def _spherical(v: np.ndarray) -> np.ndarray:
    r = np.linalg.norm(v)
    return np.array([r, np.arccos(v[2] / r), np.arctan2(v[1], v[0])])


def test_raad_substitute_trajectory_is_smooth_and_loops():
    segments = raad_reference_trajectory()
    assert tuple(len(s) for s in segments) == RAAD_SEGMENTS
    np.testing.assert_allclose(segments[0][0], RAAD_START)
    np.testing.assert_allclose(segments[-1][-1], RAAD_START)
    for a, b in zip(segments, segments[1:], strict=False):
        np.testing.assert_allclose(a[-1], b[0])
    assert max(np.abs(np.diff(s, axis=0)).max() for s in segments) < 0.02
