"""The UR's ``servo_pos`` action mode: streamed joint targets tracked by a PD servo (Isaac Lab's
UR10e gains) within the UR's speed and acceleration limits, in real PyBullet and over gRPC."""

from __future__ import annotations

import numpy as np
import pytest

from robogym_ray.errors import InvalidStateError
from robogym_ray.protocol.client import RobotServerClient
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.command_handler import CommandHandler
from robogym_ray.robots.registry import make_robot
from robogym_ray.robots.server import start_robot_server
from robogym_ray.robots.ur.geometry import ROS_FROM_ENV, UR_MODELS
from robogym_ray.robots.ur.model import URArm
from robogym_ray.robots.ur.servo import DAMPING, MAX_ACCELERATION, STIFFNESS
from robogym_ray.robots.ur.state import POSITION_KEYS

ROS = list(ROS_FROM_ENV)
START = np.array([np.pi, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])
VMAX = np.asarray(UR_MODELS["ur10e"].max_velocity)


def _servo(**floats: float) -> URArm:
    robot = make_robot("ur10e", seed=0, options={"action_mode": "servo_pos",
                                                 "action_cycle_rate": "60"})  # fmt: skip
    assert isinstance(robot, URArm)
    goal = dict(zip(POSITION_KEYS, map(float, START), strict=True))
    robot.set_state(StateRequest(state_dict=goal, float_params=floats))
    return robot


def _run(robot: URArm, handler: CommandHandler, target_env: np.ndarray | None) -> np.ndarray:
    """One 60-Hz action (``None``: none sent, the slot stays empty); the joints after it."""
    cfg = robot.handler_config
    if target_env is not None:
        handler.submit(robot.validate_action(np.asarray(target_env)[ROS]))
    for _ in range(cfg.ticks_per_action):
        handler.tick()
        robot.advance(cfg.actuation_cycle)
    return robot.read_sensors(["joints"])["joints"]


def test_relative_targets_move_each_joint_at_the_pd_pace_within_the_limits() -> None:
    robot = _servo()
    try:
        handler = CommandHandler(robot.handler_config, robot.publish)
        # Two physics steps of 1/120 s per 60-Hz action, Isaac Lab's decimation.
        assert robot.handler_config.ticks_per_action == 2
        assert robot.handler_config.actuation_cycle == pytest.approx(1 / 120)
        q, velocities = START.copy(), []
        for _ in range(90):  # the deploy task's command at |action| = 1: measured + 0.0625
            joints = _run(robot, handler, q + 0.0625 * np.array([1, -1, 1, -1, 1, -1]))
            velocities.append(joints[6:])
            q = joints[:6]
        v = np.abs(np.array(velocities))
        assert np.all(v <= VMAX + 1e-9)
        accel = np.abs(np.diff(np.array(velocities), axis=0)) * 60
        assert np.all(accel <= MAX_ACCELERATION + 1e-6)
        # Steady motion: the PD force balances, so v = stiffness / damping x the lag behind
        # the target, which is 0.0625 when each action sets it and shrinks over its two steps.
        ratio = v[-1] / (STIFFNESS / DAMPING * 0.0625)
        assert np.all((ratio > 0.75) & (ratio < 0.95)), ratio
    finally:
        robot.close()


def test_a_held_target_is_reached_and_an_empty_slot_holds_the_arm() -> None:
    robot = _servo()
    try:
        handler = CommandHandler(robot.handler_config, robot.publish)
        goal = START + np.array([0.1, -0.1, 0.05, 0.2, -0.2, 0.3])
        for _ in range(120):  # 2 s of the same absolute target
            joints = _run(robot, handler, goal)
        np.testing.assert_allclose(joints[:6], goal, atol=1e-4)
        handler.submit(robot.validate_action((goal + 0.5)[ROS]))
        handler.tick()  # one step towards a far target, then nothing more is sent
        robot.advance(robot.handler_config.actuation_cycle)
        for _ in range(60):
            joints = _run(robot, handler, None)
        # Stopped: braked to rest within the acceleration limit, near where the command ended.
        np.testing.assert_allclose(joints[6:], 0.0, atol=1e-6)
        assert np.all(np.abs(joints[:6] - goal) < 0.01)
    finally:
        robot.close()


def test_set_state_sets_the_episodes_gains_and_refuses_bad_ones() -> None:
    robot = _servo(servo_stiffness_scale_0=1.1, servo_damping_scale_3=0.75, servo_friction_5=0.1)
    try:
        servo = robot._controller
        assert servo.stiffness[0] == pytest.approx(1.1 * STIFFNESS[0])
        assert servo.damping[3] == pytest.approx(0.75 * DAMPING[3])
        assert servo.friction.tolist() == [0.0] * 5 + [0.1]
        goal = dict(zip(POSITION_KEYS, map(float, START), strict=True))
        for floats, match in (
            ({"servo_stiffness_scale_6": 1.0}, "unknown SetState float params"),
            ({"servo_damping_scale_0": -1.0}, r"servo_damping_scale_0 = -1"),
        ):
            with pytest.raises(InvalidStateError, match=match):
                robot.set_state(StateRequest(state_dict=goal, float_params=floats))
        assert servo.stiffness[0] == pytest.approx(1.1 * STIFFNESS[0])  # unchanged by refusals
        robot.set_state(StateRequest(state_dict=goal))  # none given: nominal again
        np.testing.assert_allclose(servo.stiffness, STIFFNESS)
    finally:
        robot.close()
    trajectory = make_robot("ur10e", seed=0, options={})
    try:
        goal = dict(zip(POSITION_KEYS, map(float, START), strict=True))
        with pytest.raises(InvalidStateError, match="need action_mode servo_pos; this arm runs"):
            trajectory.set_state(
                StateRequest(state_dict=goal, float_params={"servo_friction_0": 0.05})
            )
    finally:
        trajectory.close()


def test_get_arguments_reports_the_mode_and_the_default_stays_robo_gyms() -> None:
    handles = [
        start_robot_server("ur10e", options=options, seed=0)
        for options in ({"action_mode": "servo_pos", "action_cycle_rate": "60"}, {})
    ]
    try:
        answers = []
        for handle in handles:
            client = RobotServerClient(handle.address)
            args = client.get_arguments()
            assert args is not None
            answers.append((args.action_mode, round(args.action_cycle_rate, 3)))
            client.close()
        assert answers == [("servo_pos", 60.0), ("abs_pos", 25.0)]
    finally:
        for handle in handles:
            handle.stop()
