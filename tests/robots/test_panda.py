"""The simulated Panda in real PyBullet (DIRECT): kinematics, motion, contacts, SetState, input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robogym_ray.errors import ConfigError, InvalidActionError, InvalidStateError
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.command_handler import CommandHandler
from robogym_ray.robots.panda.card import CARD
from robogym_ray.robots.panda.model import DH, FLANGE_D, LOWER, READY, UPPER, forward_kinematics
from robogym_ray.robots.panda.robot import PandaArm
from robogym_ray.robots.panda.state import POSITION_KEYS, RS_MODE_KEYS
from robogym_ray.robots.registry import check_options, make_robot, robot_card
from robogym_ray.supervision.launch import parse_launch_cmd

ROBO_GYM_START = [-0.018, -0.76, 0.02, -2.342, 0.03, 1.541, 0.753]
SELF_COLLISION = [0.0, 0.0, 0.0, -3.0, 0.0, 1.0, 0.785]
"""Elbow folded, hand swung into the shoulder (hand ~0.25 m up, 0.08 m off the base axis)."""
GROUND_COLLISION = [0.0, 1.7, 0.0, -0.2, 0.0, 1.8, 0.785]
"""Leaning forward, stretched: the hand ends ~0.05 m above the floor, its body below it."""


def _robot(seed=0, **options: str) -> PandaArm:
    robot = make_robot("panda", seed=seed, options={"action_mode": "abs_pos", **options})
    assert isinstance(robot, PandaArm)
    return robot


@pytest.fixture
def panda():
    robot = _robot()
    yield robot
    robot.close()


def _goal(q) -> StateRequest:
    return StateRequest(state_dict=dict(zip(POSITION_KEYS, map(float, q), strict=True)))


def _act(robot: PandaArm, action, n: int = 1) -> None:
    """n SendActions the way the server runs them in sim time."""
    handler = CommandHandler(robot.handler_config, robot.publish)
    cfg = robot.handler_config
    for _ in range(n):
        handler.submit(robot.validate_action(np.asarray(action, dtype=np.float64)))
        for _ in range(cfg.ticks_per_action):
            handler.tick()
            robot.advance(cfg.actuation_cycle)


def _snapshot(robot: PandaArm):
    return robot.compose(robot.read_sensors())


# -- kinematics -------------------------------------------------------------------------------
def _dh_reference(q) -> np.ndarray:
    """Franka's DH table, written out again here (Craig's convention), flange pose as 4x4."""
    table = [  # a, d, alpha
        (0, 0.333, 0), (0, 0, -math.pi / 2), (0, 0.316, math.pi / 2), (0.0825, 0, math.pi / 2),
        (-0.0825, 0.384, -math.pi / 2), (0, 0, math.pi / 2), (0.088, 0, math.pi / 2),
        (0, 0.107, 0),
    ]  # fmt: skip
    t = np.eye(4)
    for (a, d, alpha), theta in zip(table, [*q, 0.0], strict=True):
        ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
        t = t @ np.array(
            [
                [ct, -st, 0, a],
                [st * ca, ct * ca, -sa, -d * sa],
                [st * sa, ct * sa, ca, d * ca],
                [0, 0, 0, 1],
            ]
        )
    return t


@pytest.mark.parametrize("q", [np.zeros(7), READY, ROBO_GYM_START, [0.5, -1, 1, -2, 1, 2, -1]])
def test_forward_kinematics_matches_the_dh_table(q):
    xyz, quat = forward_kinematics(q)["panda_link8"]
    ref = _dh_reference(q)
    np.testing.assert_allclose(xyz, ref[:3, 3], atol=1e-12)
    np.testing.assert_allclose(Rotation.from_quat(quat).as_matrix(), ref[:3, :3], atol=1e-12)


def test_published_reference_poses():
    # Zero pose: the flange 0.088 m forward at 0.333 + 0.316 + 0.384 - 0.107 = 0.926 m, z down.
    xyz, quat = forward_kinematics(np.zeros(7))["panda_link8"]
    np.testing.assert_allclose(xyz, [0.088, 0.0, 0.926], atol=1e-12)
    np.testing.assert_allclose(Rotation.from_quat(quat).apply([0, 0, 1]), [0, 0, -1], atol=1e-12)
    # Ready pose: libfranka's examples report O_T_EE (hand TCP, 0.1034 m beyond the flange)
    # at (0.307, 0, 0.487) m, pointing down; the flange is 0.1034 m higher.
    xyz, quat = forward_kinematics(READY)["panda_link8"]
    np.testing.assert_allclose(xyz, [0.307, 0.0, 0.487 + 0.1034], atol=1e-3)
    np.testing.assert_allclose(Rotation.from_quat(quat).apply([0, 0, 1]), [0, 0, -1], atol=1e-9)
    # The hand is the flange turned -45 deg about z.
    hand = Rotation.from_quat(forward_kinematics(READY)["panda_hand"][1])
    flange = Rotation.from_quat(quat)
    np.testing.assert_allclose((flange.inv() * hand).as_rotvec(), [0, 0, -math.pi / 4], atol=1e-9)


def test_pybullet_model_agrees_with_numpy_kinematics(panda):
    rng = np.random.default_rng(1)
    for q in [READY, *rng.uniform(LOWER, UPPER, (5, 7))]:
        panda.set_state(_goal(q))
        ee = panda.read_sensors(["ee"])["ee"]
        xyz, quat = forward_kinematics(q)["panda_hand"]
        np.testing.assert_allclose(ee[:3], xyz, atol=1e-6)
        assert abs(abs(np.dot(ee[3:], quat)) - 1.0) < 1e-6


# -- SetState / GetState ------------------------------------------------------------------------
@pytest.mark.parametrize("rs_mode", sorted(RS_MODE_KEYS))
def test_set_state_then_get_state_round_trip(rs_mode):
    robot = _robot(rs_mode=rs_mode, world_name="tabletop_sphere50_no_collision_no_gravity.world")
    try:
        target = {"object_0_x": 0.5, "object_0_y": -0.1, "object_0_z": 0.3}
        robot.set_state(
            StateRequest(
                state_dict=dict(zip(POSITION_KEYS, ROBO_GYM_START, strict=True)),
                string_params={"object_0_function": "fixed_position"},
                float_params=target,
            )
        )
        snap = _snapshot(robot)
        assert list(snap.state_dict) == list(RS_MODE_KEYS[rs_mode])
        assert len(snap.state) == {"only_robot": 29, "1object": 36}[rs_mode]
        got = [snap.state_dict[k] for k in POSITION_KEYS]
        np.testing.assert_allclose(got, ROBO_GYM_START, atol=1e-12)
        offset = 7 if rs_mode == "1object" else 0
        np.testing.assert_allclose(snap.state[offset : offset + 7], ROBO_GYM_START, atol=1e-12)
        assert snap.state_dict["in_collision"] == 0.0 and snap.state[-1] == 0.0
        xyz = [snap.state_dict[f"ee_to_ref_translation_{a}"] for a in "xyz"]
        np.testing.assert_allclose(xyz, forward_kinematics(ROBO_GYM_START)["panda_hand"][0])
        if rs_mode == "1object":
            np.testing.assert_allclose(snap.state[:3], [0.5, -0.1, 0.3])
    finally:
        robot.close()


def test_joint_targets_are_reached_at_the_speed_limit_within_limits():
    robot = _robot(max_velocity_scale_factor="0.2", action_cycle_rate="30")
    try:
        robot.set_state(_goal(READY))
        target = np.array([1.0, 0.5, -1.0, -1.5, 1.0, 2.5, 0.0])
        before = robot.joint_positions
        _act(robot, target)
        step = np.abs(robot.joint_positions - before)
        assert step.max() <= 0.2 * 2.61 / 30 + 1e-9  # no joint faster than its limit
        _act(robot, target, n=300)
        np.testing.assert_allclose(robot.joint_positions, target, atol=1e-9)
        # Beyond a limit: clipped, never outside.
        _act(robot, UPPER + 5e-5, n=300)
        assert np.all(robot.joint_positions <= UPPER) and np.all(robot.joint_positions >= LOWER)
    finally:
        robot.close()


def test_delta_pos_adds_to_the_position_once_per_action():
    robot = _robot(action_mode="delta_pos", action_cycle_rate="10")
    try:
        robot.set_state(_goal(READY))
        _act(robot, [0.05, 0, 0, 0, 0, 0, 0])
        assert robot.joint_positions[0] == pytest.approx(0.05)
    finally:
        robot.close()


# -- contacts ---------------------------------------------------------------------------------
@pytest.mark.parametrize("q", [READY, ROBO_GYM_START])
def test_usual_poses_are_collision_free(panda, q):
    panda.set_state(_goal(q))
    assert panda.read_sensors(["collision"])["collision"][0] == 0.0


@pytest.mark.parametrize("q", [SELF_COLLISION, GROUND_COLLISION])
def test_self_and_ground_contact_latch_until_set_state(panda, q):
    panda.set_state(_goal(READY))
    _act(panda, q, n=200)  # drive into the collision
    np.testing.assert_allclose(panda.joint_positions, q, atol=1e-9)
    assert _snapshot(panda).state_dict["in_collision"] == 1.0
    _act(panda, READY, n=200)  # out of it again: still latched
    assert _snapshot(panda).state_dict["in_collision"] == 1.0
    panda.set_state(_goal(READY))
    assert _snapshot(panda).state_dict["in_collision"] == 0.0


def test_the_table_counts_as_a_contact():
    robot = _robot(world_name="tabletop_sphere50_no_collision_no_gravity.world")
    try:
        robot.set_state(_goal([0.0, 1.2, 0.0, -0.5, 0.0, 2.0, 0.785]))  # hand 0.33 m up: free
        assert not robot.in_collision
        robot.set_state(_goal([0.0, 1.5, 0.0, -0.8, 0.0, 2.2, 0.785]))  # hand into the table
        assert robot.in_collision
    finally:
        robot.close()


# -- bad input --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("action", "match"),
    [
        ([0.0] * 6, "7 values"),
        ([0.0] * 8, "7 values"),
        ([0.0, 0.0, 0.0, -1.0, 0.0, 1.0, math.nan], r"action\[6\].*outside"),
        ([0.0, math.inf, 0.0, -1.0, 0.0, 1.0, 0.0], r"action\[1\]"),
        ([0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0], r"action\[3\] \(panda_joint4.*-3.071800, -0.069800"),
    ],
)
def test_bad_actions_are_refused(panda, action, match):
    with pytest.raises(InvalidActionError, match=match):
        panda.validate_action(np.array(action))


@pytest.mark.parametrize(
    ("state_dict", "match"),
    [
        ({k: 0.0 for k in POSITION_KEYS[:6]}, r"lacks \['joint7_position'\]"),
        ({**dict(zip(POSITION_KEYS, READY, strict=True)), "elbow_joint_position": 0.0}, "unknown"),
        ({**dict(zip(POSITION_KEYS, READY, strict=True)), "joint2_position": math.nan}, "joint2"),
        ({**dict(zip(POSITION_KEYS, READY, strict=True)), "joint6_position": 4.0}, "joint6"),
    ],
)
def test_bad_set_state_is_refused_and_changes_nothing(panda, state_dict, match):
    panda.set_state(_goal(GROUND_COLLISION))
    before = _snapshot(panda)
    with pytest.raises(InvalidStateError, match=match):
        panda.set_state(StateRequest(state_dict=state_dict))
    after = _snapshot(panda)
    np.testing.assert_array_equal(after.state, before.state)
    assert after.state_dict["in_collision"] == 1.0


@pytest.mark.parametrize(
    "options",
    [{"action_mode": "abs_vel"}, {"rs_mode": "1moving2points"}, {"ur_model": "ur5"},
     {"action_cycle_rate": "0"}, {"real_robot": "true"}, {"world_name": "lab_6x8.world"}],
)  # fmt: skip
def test_bad_options_are_refused_before_building(options):
    with pytest.raises(ConfigError):
        check_options("panda", None, options)


def test_card_matches_the_model():
    assert robot_card("panda") is CARD
    assert CARD.limits.position_range == (tuple(LOWER), tuple(UPPER))  # asymmetric
    assert CARD.safety is not None
    np.testing.assert_array_equal(CARD.safety.low, LOWER)
    np.testing.assert_array_equal(CARD.safety.high, UPPER)
    assert CARD.state.length == 29 and CARD.state.keys == RS_MODE_KEYS["only_robot"]
    assert CARD.geometry.dh == tuple(v for row in DH for v in row) + (FLANGE_D,)
    assert CARD.launch.launch_file == "panda_robot_server.launch"
    # franka_ros's ``robot`` argument picks the arm; robo-gym's commands leave it out: the Panda.
    assert (CARD.launch.model_argument, CARD.launch.default) == ("robot", True)
    cmd = "roslaunch panda_robot_server panda_robot_server.launch         rs_mode:=1object"
    spec = parse_launch_cmd(cmd)
    assert (spec.robot, spec.options) == ("panda", {"rs_mode": "1object"})


# -- emulated hardware --------------------------------------------------------------------------
FAR_GOAL = [q + d for q, d in zip(ROBO_GYM_START, (0.5, 0.3, 0.5, 0.3, 0.5, 0.3, 0.5), strict=True)]


def _move_over_grpc(emulation, cycles: int) -> np.ndarray:
    """Joint positions after ``cycles`` SendActionGetState towards a goal ~0.5 rad from
    robo-gym's start in every joint (too far to reach in that time)."""
    from robogym_ray.protocol import robot_server_pb2 as pb
    from robogym_ray.protocol.client import RobotServerClient
    from robogym_ray.robots.server import start_robot_server

    handle = start_robot_server(
        "panda", seed=0, options={"action_mode": "abs_pos"}, emulation=emulation
    )
    try:
        with RobotServerClient(handle.address) as client:
            client.set_state(
                pb.State(state_dict=dict(zip(POSITION_KEYS, ROBO_GYM_START, strict=True)))
            )
            for _ in range(cycles):
                reply = client.send_action_get_state(list(FAR_GOAL))
            assert len(reply.state) == CARD.state.length
            return np.array([reply.state_dict[k] for k in POSITION_KEYS])
    finally:
        handle.stop(0.0)


def test_the_emulated_panda_is_slower_and_noisy_over_grpc() -> None:
    """``robogym-ray serve --robot panda --emulate-hardware``: the card's hooks scale the speed
    limit and put seeded noise on the joint readings; the protocol stays robo-gym's."""
    from robogym_ray.robots.emulation import EmulationConfig

    quiet = {"joint_noise_sigma": 0.0, "latency_ticks": 0, "actuation_bias": 0.0}
    start = np.array(ROBO_GYM_START)
    plain = _move_over_grpc(None, 4) - start
    slow = _move_over_grpc(EmulationConfig(velocity_scale=0.5, **quiet), 4) - start
    # Half the speed limit: half the distance in the same cycles (the goal is far enough).
    np.testing.assert_allclose(slow, 0.5 * plain, atol=2e-3)
    noisy = _move_over_grpc(EmulationConfig(**{**quiet, "joint_noise_sigma": 0.01}), 4) - start
    assert 1e-4 < np.abs(noisy - plain).max() < 0.05
