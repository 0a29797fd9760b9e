"""The simulated UR arm in real PyBullet (DIRECT): motion, preemption, collisions, SetState."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robogym_ray.errors import InvalidActionError, InvalidStateError
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.command_handler import CommandHandler
from robogym_ray.robots.registry import make_robot
from robogym_ray.robots.ur.controller import MIN_DURATION
from robogym_ray.robots.ur.geometry import POSITION_LIMITS, ROS_FROM_ENV, UR_MODELS
from robogym_ray.robots.ur.model import URArm
from robogym_ray.robots.ur.state import ALL_KEYS, POSITION_KEYS, RS_MODE_KEYS

EE_RESET = np.array([0.0, -2.5, 1.5, -1.5, -1.4, 0.0])
ROS = list(ROS_FROM_ENV)
FIXED = {"object_0_function": "fixed_position"}


def _robot(model="ur10", seed=0, **options: str) -> URArm:
    robot = make_robot(model, seed=seed, options=options)
    assert isinstance(robot, URArm)
    return robot


@pytest.fixture
def ur10():
    robot = _robot(world_name="tabletop_sphere50.world", rs_mode="1moving2points")
    yield robot
    robot.close()


def _goal(q, **extra) -> StateRequest:
    return StateRequest(state_dict=dict(zip(POSITION_KEYS, map(float, q), strict=True)), **extra)


def _state(robot: URArm):
    return robot.compose(robot.read_sensors())


def _act(robot: URArm, handler: CommandHandler, action_ros, n: int = 1) -> None:
    """n SendActions the way the server runs them in sim time."""
    cfg = robot.handler_config
    for _ in range(n):
        handler.submit(robot.validate_action(np.asarray(action_ros, dtype=np.float64)))
        for _ in range(cfg.ticks_per_action):
            handler.tick()
            robot.advance(cfg.actuation_cycle)


def _joints(robot: URArm) -> np.ndarray:
    return robot.read_sensors(["joints"])["joints"]


@pytest.mark.parametrize("rs_mode", sorted(RS_MODE_KEYS))
def test_set_state_then_state_has_the_goal_and_exact_keys(rs_mode):
    robot = _robot("ur5", rs_mode=rs_mode, world_name="tabletop_sphere50_no_collision.world")
    try:
        # robo-gym sends its whole composition with zeros besides the joint goals.
        request = {k: 0.0 for k in RS_MODE_KEYS[rs_mode]}
        request.update(zip(POSITION_KEYS, EE_RESET, strict=True))
        robot.set_state(
            StateRequest(
                state_dict=request,
                string_params=FIXED,
                float_params={"object_0_x": 0.3, "object_0_y": 0.2, "object_0_z": 0.4},
            )
        )
        snap = _state(robot)
        assert set(snap.state_dict) == set(RS_MODE_KEYS[rs_mode])
        assert len(snap.state) == len(RS_MODE_KEYS[rs_mode])
        got = [snap.state_dict[k] for k in POSITION_KEYS]
        np.testing.assert_allclose(got, EE_RESET, atol=1e-3)
        assert snap.state_dict["in_collision"] == 0.0
        quat = [snap.state_dict[f"ee_to_ref_rotation_{c}"] for c in "xyzw"]
        assert np.isclose(np.linalg.norm(quat), 1.0)
        np.testing.assert_allclose(
            [snap.state_dict[f"ee_to_ref_translation_{c}"] for c in "xyz"],
            (-0.0069, 0.1231, 0.7009),
            atol=1e-3,
        )
        n_obj = 7 * sum(f"object_{i}_to_ref_rotation_w" in snap.state_dict for i in range(2))
        flat_pos = snap.state[n_obj : n_obj + 6]
        np.testing.assert_allclose(flat_pos, EE_RESET[ROS], atol=1e-3)  # ROS order
        if n_obj:
            np.testing.assert_allclose(snap.state[:7], (0.3, 0.2, 0.4, 0, 0, 0, 1))
    finally:
        robot.close()


def test_abs_targets_reach_the_goal_without_passing_limits(ur10):
    ur10.set_state(_goal(EE_RESET))
    handler = CommandHandler(ur10.handler_config, ur10.publish)
    target = EE_RESET + np.array([0.6, 0.3, -0.4, 0.5, -0.2, 1.0])
    start_err = np.abs(target - EE_RESET)
    _act(ur10, handler, target[ROS], n=1)
    err = np.abs(target - _joints(ur10)[:6])
    assert np.all(err < start_err)  # every joint moved toward the target
    # Synchronised: all joints covered the same fraction of their way.
    fraction = 1 - err / start_err
    np.testing.assert_allclose(fraction, fraction[0], rtol=1e-6)
    _act(ur10, handler, target[ROS], n=150)
    np.testing.assert_allclose(_joints(ur10)[:6], target, atol=1e-3)
    assert ur10.in_collision is False


def test_one_action_moves_at_most_vmax_times_the_cycle():
    robot = _robot("ur10", rs_mode="only_robot", max_velocity_scale_factor="0.2")
    try:
        robot.set_state(_goal(EE_RESET))
        handler = CommandHandler(robot.handler_config, robot.publish)
        vmax = 0.2 * np.asarray(UR_MODELS["ur10"].max_velocity)
        target = EE_RESET + np.array([2.0, 0.01, 0.0, 0.0, 0.0, 0.0])  # far: velocity-limited
        _act(robot, handler, target[ROS])
        step = _joints(robot)[:6] - EE_RESET
        assert step[0] == pytest.approx(vmax[0] * robot.config.action_cycle, rel=1e-6)
        # Short moves last at least MIN_DURATION (spec c.2.5): delta * T / 0.5 s per action.
        robot.set_state(_goal(EE_RESET))
        _act(robot, handler, (EE_RESET + 0.01)[ROS])
        moved = _joints(robot)[0] - EE_RESET[0]
        dt, ticks = robot.config.actuation_cycle, robot.handler_config.ticks_per_action
        assert moved == pytest.approx(0.01 * (1 - (1 - dt / MIN_DURATION) ** ticks), rel=1e-6)
    finally:
        robot.close()


def test_targets_beyond_a_limit_are_clipped(ur10):
    ur10.set_state(_goal([0.0, -1.5, 3.0, -1.5, -1.4, 0.0]))
    handler = CommandHandler(ur10.handler_config, ur10.publish)
    target = np.array([0.0, -1.5, np.pi + 5e-5, -1.5, -1.4, 0.0])  # within the 1e-4 slack
    for _ in range(100):
        _act(ur10, handler, target[ROS])
        assert abs(_joints(ur10)[2]) <= np.pi
    assert _joints(ur10)[2] == pytest.approx(np.pi, abs=1e-3)


def test_preempt_stops_the_arm(ur10):
    ur10.set_state(_goal(EE_RESET))
    handler = CommandHandler(ur10.handler_config, ur10.publish)
    _act(ur10, handler, (EE_RESET + 1.0)[ROS])
    moving = _joints(ur10)
    assert np.all(np.abs(moving[6:]) > 0)
    for _ in range(20):  # the slot is empty: every tick publishes None
        handler.tick()
        ur10.advance(ur10.handler_config.actuation_cycle)
    held = _joints(ur10)
    np.testing.assert_array_equal(held[:6], moving[:6])
    np.testing.assert_array_equal(held[6:], 0.0)


def test_delta_pos_adds_to_the_current_position_once_per_action():
    robot = _robot("ur5", rs_mode="only_robot", action_mode="delta_pos")
    try:
        robot.set_state(_goal(EE_RESET))
        handler = CommandHandler(robot.handler_config, robot.publish)
        delta = np.array([0.0, 0.0, 0.2, 0.0, 0.0, 0.0])  # ROS index 2 = shoulder_pan
        _act(robot, handler, delta)
        pan = _joints(robot)[0]
        assert 0.0 < pan < 0.2
        dt, ticks = robot.config.actuation_cycle, robot.handler_config.ticks_per_action
        assert pan == pytest.approx(0.2 * (1 - (1 - dt / MIN_DURATION) ** ticks), rel=1e-6)
        _act(robot, handler, np.zeros(6), n=10)  # zero deltas hold the pose
        assert _joints(robot)[0] == pytest.approx(pan)
    finally:
        robot.close()


def test_self_collision_latches_until_set_state(ur10):
    ur10.set_state(_goal([0.0, -1.57, 3.0, 0.0, 0.0, 0.0]))  # elbow folded onto the arm
    assert _state(ur10).state_dict["in_collision"] == 1.0
    ur10.set_state(_goal(EE_RESET))
    assert _state(ur10).state_dict["in_collision"] == 0.0


def test_ground_contact_latches_and_set_state_clears():
    robot = _robot("ur5", rs_mode="only_robot", world_name="empty.world")
    try:
        start = np.array([0.0, -0.3, 0.0, 0.0, 0.0, 0.0])
        robot.set_state(_goal(start))
        assert not robot.in_collision
        handler = CommandHandler(robot.handler_config, robot.publish)
        down = start + [0.0, 0.8, 0.0, 0.0, 0.0, 0.0]  # lift > 0 swings the arm into the floor
        _act(robot, handler, down[ROS], n=60)
        assert robot.in_collision
        _act(robot, handler, start[ROS], n=100)  # back in the air: still latched
        assert _state(robot).state_dict["in_collision"] == 1.0
        robot.set_state(_goal(start))
        assert _state(robot).state_dict["in_collision"] == 0.0
    finally:
        robot.close()


@pytest.mark.parametrize(
    ("world", "expected"),
    [("tabletop_sphere50.world", 1.0), ("tabletop_sphere50_no_collision.world", 0.0)],
)
def test_object_sphere_collides_only_in_its_world(world, expected):
    robot = _robot("ur5", world_name=world, rs_mode="1object")
    try:
        ee = _state(robot).state_dict
        at_ee = {f"object_0_{c}": ee[f"ee_to_ref_translation_{c}"] for c in "xyz"}
        robot.set_state(_goal(np.zeros(6), string_params=FIXED, float_params=at_ee))
        assert _state(robot).state_dict["in_collision"] == expected
    finally:
        robot.close()


def test_moving_object_follows_its_triangle_wave_in_sim_time(ur10):
    params = {
        "object_0_x": 0.12,
        "object_0_y": 0.34,
        "object_0_z_amplitude": 0.2,
        "object_0_z_frequency": 0.125,
        "object_0_z_offset": 0.5,
    }
    ur10.set_state(
        _goal(EE_RESET, string_params={"object_0_function": "triangle_wave"}, float_params=params)
    )
    assert _state(ur10).state_dict["object_0_to_ref_translation_z"] == pytest.approx(0.3)
    for _ in range(250):  # 250 ticks x 8 ms = 2 s = a quarter period
        ur10.advance(0.008)
    snap = _state(ur10).state_dict
    assert snap["object_0_to_ref_translation_z"] == pytest.approx(0.5)
    assert (snap["object_0_to_ref_translation_x"], snap["object_0_to_ref_translation_y"]) == (
        pytest.approx(0.12),
        pytest.approx(0.34),
    )
    # A SetState without object_0_function restarts the same trajectory from its first sample.
    ur10.set_state(_goal(EE_RESET))
    assert _state(ur10).state_dict["object_0_to_ref_translation_z"] == pytest.approx(0.3)


def test_base_reference_frame_negates_x_and_y():
    link, base = (
        _robot("ur5", rs_mode="1object"),
        _robot("ur5", rs_mode="1object", reference_frame="base"),
    )
    try:
        obj = {"object_0_x": 0.3, "object_0_y": 0.2, "object_0_z": 0.4}
        for robot in (link, base):
            robot.set_state(_goal(EE_RESET, string_params=FIXED, float_params=obj))
        a, b = link.read_sensors(), base.read_sensors()
        np.testing.assert_allclose(b["ee"][:3], a["ee"][:3] * [-1, -1, 1], atol=1e-9)
        rz = Rotation.from_euler("z", np.pi)
        expected = (rz * Rotation.from_quat(a["ee"][3:])).as_matrix()
        np.testing.assert_allclose(Rotation.from_quat(b["ee"][3:]).as_matrix(), expected, atol=1e-6)
        # Object params are read in the reference frame and reported back unchanged.
        np.testing.assert_allclose(b["object_0"], (0.3, 0.2, 0.4, 0, 0, 0, 1))
        pos = base._world.client.getBasePositionAndOrientation(base._object_uids[0])[0]
        np.testing.assert_allclose(pos, (-0.3, -0.2, 0.5), atol=1e-6)
    finally:
        link.close()
        base.close()


def test_set_state_falls_back_to_the_flat_state_in_ros_order(ur10):
    flat = np.zeros(12)
    flat[6:12] = EE_RESET[ROS]
    ur10.set_state(StateRequest(state=flat))
    np.testing.assert_allclose(_joints(ur10)[:6], EE_RESET)


def test_set_state_accepts_keys_of_any_mode():
    robot = _robot("ur5", rs_mode="only_robot")
    try:
        request = {k: 0.0 for k in ALL_KEYS}  # 41 keys sent to a 20-key server
        robot.set_state(StateRequest(state_dict=request))
        assert len(_state(robot).state_dict) == 20
    finally:
        robot.close()


@pytest.mark.parametrize(
    ("action", "match"),
    [
        (np.zeros(5), "6 values"),
        ([0, 0, np.nan, 0, 0, 0], r"action\[2\] \(shoulder_pan_joint"),
        ([3.2, 0, 0, 0, 0, 0], r"action\[0\] \(elbow_joint.*3.2.*\[-3.141593, 3.141593\]"),
        ([0, 0, 0, 0, 0, -6.3], r"action\[5\] \(wrist_3_joint"),
    ],
)
def test_bad_actions_raise_typed_errors(ur10, action, match):
    with pytest.raises(InvalidActionError, match=match):
        ur10.validate_action(np.asarray(action, dtype=np.float64))
    full = np.array([np.pi, -2 * np.pi, 2 * np.pi, 0, 0, 0], dtype=np.float32)  # float32 rounding
    assert ur10.validate_action(full.astype(np.float64)).shape == (6,)


BAD_REQUESTS = [
    (_goal(EE_RESET).state_dict | {"foo": 1.0}, {}, {}, "unknown UR state_dict keys.*foo"),
    (_goal([0, 0, np.nan, 0, 0, 0]).state_dict, {}, {}, "elbow_joint_position"),
    (_goal([0, 0, 3.2, 0, 0, 0]).state_dict, {}, {}, r"elbow_joint.*3.2"),
    ({"base_joint_position": 0.0}, {}, {}, "lacks"),
    (_goal(EE_RESET).state_dict, {"object_0_function": "spiral"}, {}, "spiral"),
    (_goal(EE_RESET).state_dict, FIXED, {"object_0_x": 0.1}, "object_0_y"),
]


@pytest.mark.parametrize(("state_dict", "strings", "floats", "match"), BAD_REQUESTS)
def test_bad_set_state_raises_and_changes_nothing(state_dict, strings, floats, match):
    robot, twin = (_robot("ur5", seed=5, rs_mode="1moving2points") for _ in range(2))
    spline = {"object_0_function": "3d_spline"}
    spline_params = {
        "object_0_x_min": -1,
        "object_0_x_max": 1,
        "object_0_y_min": -1,
        "object_0_y_max": 1,
        "object_0_z_min": 0.1,
        "object_0_z_max": 1,
        "object_0_n_points": 6,
        "object_0_n_sampling_points": 500,
    }
    try:
        for r in (robot, twin):
            r.set_state(_goal([0.1, -1.0, 1.0, 0.0, 0.5, 0.0]))
            r.advance(0.1)
        before = _state(robot)
        with pytest.raises(InvalidStateError, match=match):
            robot.set_state(
                StateRequest(state_dict=state_dict, string_params=strings, float_params=floats)
            )
        after = _state(robot)
        np.testing.assert_array_equal(after.state, before.state)
        assert after.state_dict == before.state_dict
        # The RNG was not consumed either: the next random trajectory is the twin's.
        for r in (robot, twin):
            r.set_state(_goal(EE_RESET, string_params=spline, float_params=spline_params))
            r.advance(1.0)
        np.testing.assert_array_equal(_state(robot).state, _state(twin).state)
    finally:
        robot.close()
        twin.close()


def test_same_seed_same_run():
    runs = []
    for _ in range(2):
        robot = _robot(
            "ur10", seed=11, rs_mode="1moving2points", world_name="tabletop_sphere50.world"
        )
        handler = CommandHandler(robot.handler_config, robot.publish)
        params = {
            "object_0_x_min": -1.0,
            "object_0_x_max": 1.0,
            "object_0_y_min": -1.0,
            "object_0_y_max": 1.0,
            "object_0_z_min": 0.1,
            "object_0_z_max": 1.0,
            "object_0_n_points": 10,
            "object_0_n_sampling_points": 2000,
        }
        robot.set_state(
            _goal(
                EE_RESET,
                string_params={"object_0_function": "3d_spline_ur5_workspace"},
                float_params=params,
            )
        )
        rng = np.random.default_rng(3)
        states = []
        for _ in range(30):
            _act(robot, handler, (EE_RESET + rng.uniform(-0.3, 0.3, 6))[ROS])
            states.append(_state(robot).state)
        runs.append(np.array(states))
        robot.close()
    np.testing.assert_array_equal(runs[0], runs[1])


def test_positions_stay_within_limits_under_random_actions():
    robot = _robot("ur3", rs_mode="only_robot", world_name="empty.world")
    try:
        handler = CommandHandler(robot.handler_config, robot.publish)
        rng = np.random.default_rng(0)
        for _ in range(200):
            _act(robot, handler, rng.uniform(-1, 1, 6) * POSITION_LIMITS[ROS])
            assert np.all(np.abs(_joints(robot)[:6]) <= POSITION_LIMITS)
    finally:
        robot.close()
