"""robo-gym 2.1.0's new arm launch options and object function, on the robot side.

The end-effector frame (``ee_frame``) and base height (``z``) each arm accepts come from its
card; the worlds from ``robots/scenes.py``; ``fixed_trajectory`` from ``robots/objects.py``.
(The same through robo-gym's exact launch commands and our ServerManager:
``tests/compat/test_robo_gym_2_1_arms.py``.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robogym_ray.errors import ConfigError, InvalidStateError
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.objects import FIXED_TRAJECTORIES, SAMPLE_RATE, build_trajectory
from robogym_ray.robots.registry import CARDS, check_options, make_robot
from robogym_ray.robots.scenes import WORLDS
from robogym_ray.robots.ur.config import parse_options
from robogym_ray.robots.ur.geometry import UR_MODELS, forward_kinematics
from robogym_ray.robots.ur.state import POSITION_KEYS

ARMS = sorted(name for name, card in CARDS.items() if card.kind == "arm")


@pytest.mark.parametrize("name", ARMS)
def test_every_arm_accepts_the_frames_and_base_height_its_card_declares(name) -> None:
    geometry = CARDS[name].geometry
    for frame in geometry.ee_frames:
        check_options(name, options={"ee_frame": frame})
    with pytest.raises(ConfigError, match="ee_frame"):
        check_options(name, options={"ee_frame": "flange_of_dreams"})
    if geometry.base_height_option is not None:
        check_options(name, options={geometry.base_height_option: "0.0"})
        with pytest.raises(ConfigError, match=geometry.base_height_option):
            check_options(name, options={geometry.base_height_option: "nan"})
    for world in WORLDS:  # the shared simulation_objects worlds
        check_options(name, options={"world_name": world})


def test_ur_base_height_defaults_to_the_launch_files_and_is_range_checked() -> None:
    assert parse_options("ur10", None, {}).base_height == 0.1
    assert parse_options("ur10", None, {"z": "0.0"}).base_height == 0.0
    for bad in ("3e38", "-5", "high"):
        with pytest.raises(ConfigError, match="z"):
            parse_options("ur10", None, {"z": bad})


@pytest.mark.parametrize("model", sorted(UR_MODELS))
def test_tool1_is_tool0_turned_by_isaacs_fixed_rotation(model) -> None:
    turn = Rotation.from_euler("ZYX", [3.1415, -1.5707, 0.0])  # yaw, pitch, roll of the tf
    q = [0.4, -1.3, 1.1, -0.6, 0.8, 0.2]
    frames = forward_kinematics(model, q)
    np.testing.assert_allclose(frames["tool1"][0], frames["tool0"][0], atol=1e-12)
    expected = Rotation.from_quat(frames["tool0"][1]) * turn
    assert (Rotation.from_quat(frames["tool1"][1]) * expected.inv()).magnitude() < 1e-9
    # PyBullet's tool1 link agrees with the numpy chain, at any base height.
    robot = make_robot(model, options={"ee_frame": "tool1", "z": "0.0"})
    try:
        robot.set_state(_ur_goal(q))
        ee = robot.read_sensors(["ee"])["ee"]
        np.testing.assert_allclose(ee[:3], frames["tool1"][0], atol=1e-6)
        assert abs(abs(np.dot(ee[3:], frames["tool1"][1])) - 1.0) < 1e-6
    finally:
        robot.close()


def _ur_goal(q: list[float]) -> StateRequest:
    return StateRequest(state_dict=dict(zip(POSITION_KEYS, q, strict=True)))


# -- fixed_trajectory ---------------------------------------------------------------------------
def _fixed(trajectory_id: float, seed: int = 0):
    return build_trajectory(
        0,
        {"object_0_function": "fixed_trajectory"},
        {"object_0_trajectory_id": trajectory_id},
        np.random.default_rng(seed),
    )


def test_the_50_fixed_trajectories_are_fixed_distinct_and_clear_of_the_robot() -> None:
    firsts = set()
    for k in range(FIXED_TRAJECTORIES):
        s = _fixed(float(k), seed=k).samples
        # Drawn from the id alone: the server's RNG does not matter.
        np.testing.assert_array_equal(s, _fixed(float(k), seed=k + 1000).samples)
        assert 80.0 <= len(s) / SAMPLE_RATE <= 120.0  # one lap, as AvoidanceRaad2022's splines
        # robo-gym's 3d_spline_ur5_workspace limits: > 0.2 m from the z axis and
        # > 0.35 m from the base; closed (the last sample is the first).
        assert np.hypot(s[:, 0], s[:, 1]).min() > 0.2
        assert np.linalg.norm(s, axis=1).min() > 0.35
        np.testing.assert_allclose(s[-1], s[0], atol=1e-9)
        firsts.add(tuple(np.round(s[0], 6)))
    assert len(firsts) == FIXED_TRAJECTORIES


def test_fixed_trajectories_stay_the_same_across_releases() -> None:
    # Pinned: a NumPy or SciPy change that alters the trajectories fails here, not silently in
    # a comparison of policies evaluated on "the same" 50 test episodes.
    zero = _fixed(0.0).samples
    assert len(zero) == 8989
    np.testing.assert_allclose(zero[0], [0.76313494, 0.64499674, 0.1090837], atol=1e-7)
    np.testing.assert_allclose(zero[1234], [-0.50703983, 0.80402199, 0.58745071], atol=1e-7)
    last = _fixed(49.0).samples
    assert len(last) == 11905
    np.testing.assert_allclose(last[0], [0.79692856, 0.6025036, 0.5502602], atol=1e-7)


@pytest.mark.parametrize("bad", [-1.0, 50.0, 2.5, math.nan, math.inf])
def test_fixed_trajectory_ids_outside_0_to_49_are_refused(bad) -> None:
    with pytest.raises(InvalidStateError, match="trajectory_id"):
        _fixed(bad)
