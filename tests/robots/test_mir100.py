"""The simulated MiR100 against real PyBullet (DIRECT), driven directly and through gRPC."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np
import pytest

from robogym_ray.errors import ConfigError, InvalidActionError, InvalidStateError, UnknownRobotError
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.mir100.lasers import BACK, FRONT
from robogym_ray.robots.mir100.model import Mir100Config, Mir100Robot, make_mir100
from robogym_ray.robots.mir100.scenes import OBSTACLES
from robogym_ray.robots.registry import make_robot

Pose = Sequence[float]
FAR = ((10.0, 10.0, 0.0), (11.0, 10.0, 0.0), (12.0, 10.0, 0.0))
"""Obstacle poses well outside the lab, so only the walls and the cube under test are seen."""


def full_state(target: Pose, pose: Pose, obstacles: Sequence[Pose] = FAR) -> np.ndarray:
    state = np.zeros(1030)
    state[0:3] = target
    state[3:6] = pose
    state[1021:1030] = np.ravel(obstacles)
    return state


def observe(robot: Mir100Robot) -> np.ndarray:
    return robot.compose(robot.read_sensors()).state


def drive(robot: Mir100Robot, v: float, w: float, cycles: int) -> list[np.ndarray]:
    """Publish once per 0.1 s tick, as the command handler does; returns each tick's state."""
    states = []
    for _ in range(cycles):
        robot.publish(robot.validate_action(np.array([v, w])))
        robot.advance(0.1)
        states.append(observe(robot))
    return states


def world_poses(robot: Mir100Robot) -> dict[str, tuple]:
    c = robot.world.client
    return {n: c.getBasePositionAndOrientation(u) for n, u in robot.world.bodies.items()}


def beam(angles: np.ndarray, robot_angle: float) -> int:
    """Index of the retained beam pointing closest to ``robot_angle`` (robot frame)."""
    diff = np.angle(np.exp(1j * (angles - robot_angle)))
    return int(np.argmin(np.abs(diff)))


@pytest.fixture(params=["boxes", "bullet"])
def lab(request: pytest.FixtureRequest) -> Iterator[Mir100Robot]:
    robot = Mir100Robot(Mir100Config(scene="lab_6x8", laser_caster=request.param), seed=0)
    yield robot
    robot.close()


@pytest.fixture
def empty() -> Iterator[Mir100Robot]:
    robot = Mir100Robot(Mir100Config(scene="empty"), seed=0)
    yield robot
    robot.close()


def test_set_state_is_read_back(lab: Mir100Robot) -> None:
    lab.set_state(StateRequest(state=full_state((1.0, -2.0, 0.0), (0.5, -1.5, 1.5 * math.pi))))
    state = observe(lab)
    assert state.shape == (1030,)
    np.testing.assert_allclose(state[0:3], [1.0, -2.0, 0.0])
    np.testing.assert_allclose(state[3:6], [0.5, -1.5, -0.5 * math.pi], atol=1e-12)
    np.testing.assert_array_equal(state[6:8], [0.0, 0.0])
    assert np.all((state[8:1020] >= 0.05) & (state[8:1020] <= 29.0))
    assert state[1020] == 0.0
    np.testing.assert_array_equal(state[1021:1030], np.zeros(9))  # write-only, as in ROS


def test_forward_twist_moves_along_heading(empty: Mir100Robot) -> None:
    yaw = 0.5
    empty.set_state(StateRequest(state=full_state((0, 0, 0), (1.0, 2.0, yaw))))
    states = drive(empty, 0.5, 0.0, 10)
    assert states[0][6] == pytest.approx(0.2)  # 2.0 m/s^2 for 0.1 s from rest
    # 1 s at 0.5 m/s minus the 0.25 s ramp's shortfall: 0.5 * 1.0 - 0.5 * 0.25 / 2.
    dx, dy = states[-1][3] - 1.0, states[-1][4] - 2.0
    assert dx * math.cos(yaw) + dy * math.sin(yaw) == pytest.approx(0.4375, abs=1e-6)
    assert -dx * math.sin(yaw) + dy * math.cos(yaw) == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(states[-1][5:8], [yaw, 0.5, 0.0], atol=1e-12)
    # No command in a tick = zero twist set-point: the base decelerates.
    empty.publish(None)
    empty.advance(0.1)
    assert observe(empty)[6] == pytest.approx(0.3)


def test_turning_and_limits(empty: Mir100Robot) -> None:
    empty.set_state(StateRequest(state=full_state((0, 0, 0), (0, 0, 3.0))))
    states = drive(empty, 5.0, -9.0, 20)  # beyond the limits: clipped, not refused
    assert states[-1][6] == pytest.approx(1.0)
    assert states[-1][7] == pytest.approx(-1.5)
    assert all(-math.pi < s[5] <= math.pi for s in states)


def _cube_reading(lab: Mir100Robot, robot_angle: float, scanner: str) -> tuple[float, float]:
    """(reading, expected) for a cube 2 m from the robot, on the beam of ``scanner`` that
    points along ``robot_angle``, with the robot at an arbitrary pose."""
    x0, y0, yaw = 0.3, -0.4, 0.7
    mount, offset = (FRONT, 8) if scanner == "front" else (BACK, 509)
    # Put the cube centre on the beam line, 2 m ahead of the scanner's origin.
    heading = yaw + robot_angle
    sx = x0 + mount.x * math.cos(yaw) - mount.y * math.sin(yaw)
    sy = y0 + mount.x * math.sin(yaw) + mount.y * math.cos(yaw)
    cube = (sx + 2.0 * math.cos(heading), sy + 2.0 * math.sin(heading), heading)
    lab.set_state(StateRequest(state=full_state((0, 0, 0), (x0, y0, yaw), (cube, *FAR[1:]))))
    index = beam(mount.robot_frame_angles(), robot_angle)
    return observe(lab)[offset + index], 2.0 - 0.25  # the cube faces the beam squarely


def test_front_scanner_sees_cube_ahead(lab: Mir100Robot) -> None:
    reading, expected = _cube_reading(lab, 0.0, "front")
    assert reading == pytest.approx(expected, abs=0.02)


def test_back_scanner_sees_cube_behind(lab: Mir100Robot) -> None:
    reading, expected = _cube_reading(lab, math.pi, "back")
    assert reading == pytest.approx(expected, abs=0.02)


def test_known_beam_indices() -> None:
    # Spec e.1: front beam 150 (raw 180) looks straight ahead, back beam 170 (raw 180) behind.
    assert FRONT.robot_frame_angles()[150] == pytest.approx(0.0, abs=1e-12)
    assert BACK.robot_frame_angles()[170] == pytest.approx(-math.pi, abs=1e-12)
    assert math.degrees(FRONT.robot_frame_angles()[0]) == pytest.approx(-75.0)
    assert math.degrees(BACK.robot_frame_angles()[-1]) == pytest.approx(-10.0)


def test_nothing_hit_reads_range_max(empty: Mir100Robot) -> None:
    np.testing.assert_array_equal(observe(empty)[8:1020], np.full(1012, 29.0))


def test_casters_agree() -> None:
    rng = np.random.default_rng(3)
    robots = [
        Mir100Robot(Mir100Config(scene="lab_6x8", laser_caster=c)) for c in ("boxes", "bullet")
    ]
    try:
        for _ in range(5):
            obstacles = [
                (rng.uniform(-2.4, 2.4), rng.uniform(-1, 1), rng.uniform(-3, 3)) for _ in range(3)
            ]
            pose = (rng.uniform(-2, 2), rng.choice([-2.6, 2.6]), rng.uniform(-3, 3))
            request = StateRequest(state=full_state((0, 0, 0), pose, obstacles))
            scans = []
            for robot in robots:
                robot.set_state(request)
                scans.append(observe(robot)[8:1020])
            # Bullet's ray/box cast is iterative: ~1 mm off at grazing angles, and a ray that
            # passes < 1 mm outside a cube corner may still "hit" it. The slab test is exact.
            diff = np.abs(scans[0] - scans[1])
            assert np.median(diff) < 1e-5
            assert np.count_nonzero(diff > 2e-3) <= 2, np.flatnonzero(diff > 2e-3)
    finally:
        for robot in robots:
            robot.close()


def test_wall_sets_collision_and_stops_robot(lab: Mir100Robot) -> None:
    lab.set_state(StateRequest(state=full_state((0, 0, 0), (2.0, 0.0, 0.0))))
    states = drive(lab, 0.5, 0.0, 20)
    flags = [s[1020] for s in states]
    assert flags[0] == 0.0 and flags[-1] == 1.0
    # Inner face of the east wall at x = -0.027 + 2.925 - 0.075; box front 0.4876 m ahead.
    front = states[-1][3] + 0.037646 + 0.45
    assert 2.823 - 0.011 <= front <= 2.823 + 1e-9
    assert states[-1][6] == pytest.approx(0.0, abs=0.021)  # stalled at the wall
    # Not latched: backing away clears it on the next tick.
    assert drive(lab, -0.3, 0.0, 1)[0][1020] == 0.0


def test_spawned_in_contact_can_drive_out(lab: Mir100Robot) -> None:
    cube = (1.0, 0.0, 0.0)  # near face at x = 0.75, box front at 0.7876: 0.038 m overlap
    lab.set_state(StateRequest(state=full_state((0, 0, 0), (0.3, 0.0, 0.0), (cube, *FAR[1:]))))
    assert observe(lab)[1020] == 0.0  # SetState clears the flag
    assert drive(lab, 0.0, 0.0, 1)[0][1020] == 1.0  # the bumper reports a standing contact
    assert drive(lab, 0.5, 0.0, 1)[0][3] == pytest.approx(0.3)  # cannot push in deeper
    out = drive(lab, -0.5, 0.0, 3)
    assert out[-1][3] < 0.28 and out[-1][1020] == 0.0


@pytest.mark.parametrize(
    ("state", "match"),
    [
        (np.zeros(5), "length 5"),
        (np.zeros(1029), "length 1029"),
        (np.array([0, 0, 0, 0, np.nan, 0.0]), r"state\[4\] \(robot pose y\) = nan"),
        (full_state((0, 0, 0), (0, 0, np.inf)), r"state\[5\]"),
        (full_state((60.0, 0, 0), (0, 0, 0)), r"state\[0\] \(target x\) = 60.0; expected within"),
        (full_state((0, 0, 0), (0, 0, 0), ((0, 0, 0), (0, -51, 0), (0, 0, 0))), r"state\[1025\]"),
    ],
)
def test_bad_state_is_refused_and_changes_nothing(
    lab: Mir100Robot, state: np.ndarray, match: str
) -> None:
    lab.set_state(StateRequest(state=full_state((1, 1, 0), (0.5, -1.0, 0.3))))
    drive(lab, 0.4, 0.2, 3)
    before, bodies = observe(lab), world_poses(lab)
    with pytest.raises(InvalidStateError, match=match):
        lab.set_state(StateRequest(state=state))
    np.testing.assert_array_equal(observe(lab), before)
    assert world_poses(lab) == bodies


@pytest.mark.parametrize(
    ("action", "match"),
    [
        ([0.1], "1 values; expected 2"),
        ([0.1, 0.2, 0.3], "3 values"),
        ([np.nan, 0], r"action\[0\] = nan"),
        ([0, np.inf], r"action\[1\] = inf"),
    ],
)
def test_bad_action_is_refused(empty: Mir100Robot, action: list[float], match: str) -> None:
    with pytest.raises(InvalidActionError, match=match):
        empty.validate_action(np.array(action, dtype=np.float64))


def test_obstacle_slots_ignored_without_cubes(empty: Mir100Robot) -> None:
    empty.set_state(StateRequest(state=full_state((1, 0, 0), (0, 0, 0), FAR)))
    assert set(OBSTACLES).isdisjoint(empty.world.bodies)
    empty.set_state(StateRequest(state=np.array([1.0, 0, 0, 0.5, 0.5, 0])))  # short form
    np.testing.assert_allclose(observe(empty)[3:6], [0.5, 0.5, 0.0])


def _noisy_run(seed: int) -> np.ndarray:
    robot = Mir100Robot(Mir100Config(scene="lab_6x8", laser_noise_sigma=0.01), seed=seed)
    try:
        robot.set_state(StateRequest(state=full_state((1, 1, 0), (-1.0, -2.5, 0.4))))
        return np.stack(drive(robot, 0.5, 0.3, 15))
    finally:
        robot.close()


def test_deterministic_for_a_seed() -> None:
    first, again, other = _noisy_run(7), _noisy_run(7), _noisy_run(8)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first[:, 8:1020], other[:, 8:1020])
    np.testing.assert_array_equal(first[:, :8], other[:, :8])  # noise only in the lasers


def test_factory_options() -> None:
    robot = make_robot(
        "mir100",
        options={
            "world_name": "lab_6x8.world",
            "robot_x": "1.5",
            "robot_yaw": "0.5",
            "gui": "true",
        },
    )
    try:
        assert robot.config.scene == "lab_6x8"
        np.testing.assert_allclose(observe(robot)[3:6], [1.5, 0.0, 0.5])
        assert robot.handler_config.action_cycle == 0.1
        assert robot.sensor_periods == {"f_scan": 0.08, "b_scan": 0.08}
    finally:
        robot.close()
    default = make_mir100("mir100", None, None, {})
    assert default.config.scene == "empty"  # as sim_robot_server.launch's world_name default
    default.close()


@pytest.mark.parametrize(
    ("scene", "options", "error", "match"),
    [
        ("moon", {}, UnknownRobotError, "known scenes: lab_6x8, empty"),
        (None, {"world_name": "moon.world"}, UnknownRobotError, "lab_6x8.world"),
        (None, {"speed": "2"}, ConfigError, "unknown MiR100 options"),
        (None, {"robot_x": "far"}, ConfigError, "robot_x"),
        (None, {"robot_y": "nan"}, ConfigError, "robot_y"),  # the option, not the field
        (None, {"robot_x": "1e9"}, ConfigError, "robot_x.*initial_pose"),
        ("empty", {"world_name": "lab_6x8.world"}, ConfigError, "contradicts"),
    ],
)
def test_factory_rejects(scene: str | None, options: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        make_mir100("mir100", scene, None, options)


def test_through_grpc() -> None:
    grpc = pytest.importorskip("grpc")
    server_mod = pytest.importorskip("robogym_ray.robots.server")
    from robogym_ray.protocol import robot_server_pb2 as pb
    from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc

    handle = server_mod.start_robot_server("mir100", options={"world_name": "lab_6x8.world"})
    try:
        with grpc.insecure_channel(handle.address) as channel:
            stub = pb_grpc.RobotServerStub(channel)
            sent = full_state((1.0, 2.0, 0.0), (0.0, -2.5, 0.0))
            assert stub.SetState(pb.State(state=sent.tolist())).success
            for _ in range(5):
                assert stub.SendAction(pb.Action(action=[0.5, 0.0])).success
            reply = stub.GetState(pb.Empty())
            assert reply.success and len(reply.state) == 1030
            assert reply.state[3] == pytest.approx(0.5 * 0.5 - 0.0625, abs=1e-5)
            assert not stub.SendAction(pb.Action(action=[float("nan"), 0.0])).success
    finally:
        handle.stop()
