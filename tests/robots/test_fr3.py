"""The simulated Franka Research 3: the Panda's folder and kinematics with the FR3's own limits,
kept by its URDF, card, action and SetState checks, and launch commands (PyBullet DIRECT)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from robogym_ray.errors import ConfigError, InvalidActionError, InvalidStateError, UnknownRobotError
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.panda.card import CARDS
from robogym_ray.robots.panda.model import LIMITS, READY, urdf_path, urdf_text
from robogym_ray.robots.panda.robot import PandaArm
from robogym_ray.robots.panda.state import POSITION_KEYS
from robogym_ray.robots.registry import check_options, make_robot, robot_card
from robogym_ray.supervision.launch import parse_launch_cmd

FR3_MAX = (2.9007, 1.8361, 2.9007, -0.1169, 2.8763, 4.6216, 3.0508)
FR3_MIN = (-2.9007, -1.8361, -2.9007, -3.0770, -2.8763, 0.4398, -3.0508)
FR3_VELOCITY = (2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26)
"""Franka's "Limits for Franka Research 3" (q_max, q_min, dq_max), written out again here."""
ROBO_GYM_START = (-0.018, -0.76, 0.02, -2.342, 0.03, 1.541, 0.753)
PANDA_ONLY = (0.0, -0.5, 0.0, -2.0, 0.0, 0.2, 0.785)
"""Joint 6 at 0.2 rad: within the Panda's limits (from -0.0175), below the FR3's (0.4398)."""
FR3_ONLY = (0.0, -0.5, 0.0, -2.0, 0.0, 4.0, 0.785)
"""Joint 6 at 4.0 rad: within the FR3's limits (to 4.6216), above the Panda's (3.7525)."""


def _arm(model: str) -> PandaArm:
    robot = make_robot(model, seed=0, options={"action_mode": "abs_pos"})
    assert isinstance(robot, PandaArm) and robot.name == model
    return robot


def _goal(q) -> StateRequest:
    return StateRequest(state_dict=dict(zip(POSITION_KEYS, map(float, q), strict=True)))


def test_the_fr3_limits_are_frankas_table_and_read_only() -> None:
    fr3 = LIMITS["fr3"]
    np.testing.assert_array_equal(fr3.upper, FR3_MAX)
    np.testing.assert_array_equal(fr3.lower, FR3_MIN)
    np.testing.assert_array_equal(fr3.velocity, FR3_VELOCITY)
    with pytest.raises(ValueError, match="read-only"):
        fr3.lower[0] = 0.0
    for pose in (ROBO_GYM_START, READY):  # the tasks' start and Franka's ready pose suit both
        for limits in LIMITS.values():
            assert np.all(limits.lower <= pose) and np.all(pose <= limits.upper)


@pytest.mark.parametrize("model", sorted(LIMITS))
def test_each_models_urdf_carries_its_limits_in_a_file_of_its_own(model: str) -> None:
    joints = ET.fromstring(urdf_text(model)).findall("joint[@type='revolute']")
    limits = LIMITS[model]
    assert len(joints) == 7
    for i, joint in enumerate(joints):
        limit = joint.find("limit")
        assert limit is not None
        got = [float(limit.get(k, "nan")) for k in ("lower", "upper", "velocity")]
        assert got == [limits.lower[i], limits.upper[i], limits.velocity[i]]
    assert model in urdf_path(model).rsplit("/", 1)[-1]
    assert urdf_path("fr3") != urdf_path("panda")


def test_the_fr3_card_is_the_pandas_but_for_the_limits() -> None:
    fr3, panda = robot_card("fr3"), robot_card("panda")
    assert fr3 is CARDS["fr3"] and (fr3.name, fr3.family, fr3.kind) == ("fr3", "panda", "arm")
    assert fr3.limits.position_range == (FR3_MIN, FR3_MAX)
    assert fr3.limits.velocity == FR3_VELOCITY
    assert fr3.safety is not None and (fr3.safety.low, fr3.safety.high) == (FR3_MIN, FR3_MAX)
    for same in ("geometry", "state", "emulation", "factory", "option_parser"):
        assert getattr(fr3, same) == getattr(panda, same), same


def test_validate_action_refuses_outside_the_fr3s_limits() -> None:
    fr3, panda = _arm("fr3"), _arm("panda")
    try:
        panda.validate_action(np.array(PANDA_ONLY))
        with pytest.raises(
            InvalidActionError,
            match=r"action\[5\] \(panda_joint6, abs_pos\) = 0\.2 is outside "
            r"\[0\.439800, 4\.621600\] rad",
        ):
            fr3.validate_action(np.array(PANDA_ONLY))
        fr3.validate_action(np.array(FR3_ONLY))
        with pytest.raises(InvalidActionError, match=r"^FR3 action must have 7 values"):
            fr3.validate_action(np.zeros(6))
    finally:
        fr3.close()
        panda.close()


def test_set_state_refuses_a_goal_outside_the_fr3s_limits_that_the_panda_accepts() -> None:
    fr3, panda = _arm("fr3"), _arm("panda")
    try:
        panda.set_state(_goal(PANDA_ONLY))
        np.testing.assert_allclose(panda.joint_positions, PANDA_ONLY)
        fr3.set_state(_goal(READY))
        with pytest.raises(
            InvalidStateError, match=r"joint6_position .* = 0\.2 is outside \[0\.4398, 4\.6216\]"
        ):
            fr3.set_state(_goal(PANDA_ONLY))
        np.testing.assert_allclose(fr3.joint_positions, READY)  # refused: nothing moved
        fr3.set_state(_goal(FR3_ONLY))  # beyond the Panda's joint 6, within the FR3's
        np.testing.assert_allclose(fr3.joint_positions, FR3_ONLY)
        with pytest.raises(InvalidStateError, match="joint6"):
            panda.set_state(_goal(FR3_ONLY))
    finally:
        fr3.close()
        panda.close()


def test_the_fr3_moves_at_its_own_speed_limit() -> None:
    robot = make_robot("fr3", seed=0, options={"action_mode": "abs_pos", "action_cycle_rate": "10"})
    try:
        robot.set_state(_goal(READY))
        before = np.array(robot.joint_positions)
        robot.publish(np.array(READY) + 1.0)  # 1 rad away in every joint: too far for a tick
        robot.advance(0.01)
        speed = (np.array(robot.joint_positions) - before) / 0.01
        # Synchronised joints: the slowest joint's limit (2.62 rad/s) paces all of them.
        np.testing.assert_allclose(speed, 2.62, rtol=1e-9)
    finally:
        robot.close()


def test_the_robot_launch_argument_picks_the_arm() -> None:
    base = "roslaunch panda_robot_server panda_robot_server.launch         rs_mode:=1object"
    assert parse_launch_cmd(base).robot == "panda"  # robo-gym's commands: the Panda
    for model in ("panda", "fr3"):
        spec = parse_launch_cmd(f"{base}         robot:={model}")
        assert (spec.robot, spec.options) == (model, {"rs_mode": "1object"})
    with pytest.raises(UnknownRobotError, match=r"robot:=fr2 .*known: panda, fr3"):
        parse_launch_cmd(f"{base} robot:=fr2")


def test_bad_fr3_options_are_refused_naming_the_fr3() -> None:
    with pytest.raises(ConfigError, match="unknown FR3 action_mode 'abs_vel'"):
        check_options("fr3", None, {"action_mode": "abs_vel"})
    with pytest.raises(ConfigError, match="simulated FR3"):
        check_options("fr3", None, {"real_robot": "true"})
