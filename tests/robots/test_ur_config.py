"""UR launch options (spec b.4/b.5) -> URConfig, and the registry entries."""

from __future__ import annotations

import numpy as np
import pytest

from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.robots.registry import CARDS, make_robot
from robogym_ray.robots.ur.config import URConfig, parse_options
from robogym_ray.robots.ur.geometry import UR_MODELS, forward_kinematics


def _tokens(cmd: str) -> dict[str, str]:
    """Launch arguments of a robo-gym cmd string, as the server manager passes them."""
    return dict(t.split(":=", 1) for t in cmd.split() if ":=" in t)


EE_CMD = (
    "roslaunch ur_robot_server ur_robot_server.launch         world_name:=tabletop_sphere50_no_"
    "collision.world         reference_frame:=base_link         max_velocity_scale_factor:=0.1"
    "         action_cycle_rate:=10         rviz_gui:=true         gazebo_gui:=true         "
    "objects_controller:=true         rs_mode:=1object         n_objects:=1.0         object_0_"
    "model_name:=sphere50_no_collision         object_0_frame:=target ur_model:=ur10"
    " gui:=false server_port:=50052"
)
AVOID_CMD = (
    "roslaunch ur_robot_server ur_robot_server.launch world_name:=tabletop_sphere50.world "
    "reference_frame:=base_link max_velocity_scale_factor:=0.2 action_cycle_rate:=20 "
    "rviz_gui:=false gazebo_gui:=true objects_controller:=true rs_mode:=1moving2points "
    "n_objects:=1.0 object_0_model_name:=sphere50 object_0_frame:=target ur_model:=ur5"
)


def test_robo_gym_end_effector_cmd():
    cfg = parse_options("ur10", None, _tokens(EE_CMD))
    assert (cfg.scene, cfg.rs_mode, cfg.reference_frame) == (
        "tabletop_no_collision",
        "1object",
        "base_link",
    )
    assert cfg.max_velocity_scale_factor == 0.1
    assert cfg.action_cycle == pytest.approx(0.1)
    assert cfg.n_objects == 1 and cfg.objects_controller


def test_robo_gym_avoidance_cmd():
    cfg = parse_options("ur5", None, _tokens(AVOID_CMD))
    assert (cfg.scene, cfg.rs_mode, cfg.action_cycle) == ("tabletop", "1moving2points", 0.05)


def test_defaults():
    cfg = parse_options("ur10", None, {})
    assert cfg == URConfig(model="ur10")
    assert (cfg.scene, cfg.rs_mode, cfg.action_mode) == (
        "empty",
        "only_robot",
        "abs_pos",
    )  # as the launch file
    assert (cfg.action_cycle, cfg.actuation_cycle, cfg.repeat) == (0.04, 0.008, None)
    robot = make_robot("ur10")
    try:
        assert robot.handler_config.ticks_per_action == 5
    finally:
        robot.close()


def test_rs_mode_false_falls_back_to_target_mode():
    assert parse_options(
        "ur5", None, {"rs_mode": "false", "target_mode": "only_robot"}
    ).rs_mode == ("only_robot")


def test_scene_argument_and_world_name():
    assert parse_options("ur5", "tabletop", {}).scene == "tabletop"
    assert parse_options("ur5", "empty.world", {"world_name": "empty.world"}).scene == "empty"
    with pytest.raises(ConfigError, match="contradicts"):
        parse_options("ur5", "tabletop", {"world_name": "empty.world"})


@pytest.mark.parametrize(
    ("scene", "options", "error", "match"),
    [
        ("moon", {}, UnknownRobotError, "moon.*empty.world"),
        (None, {"world_name": "lab_6x8.world"}, UnknownRobotError, "lab_6x8"),
        (None, {"colour": "red"}, ConfigError, "unknown UR option 'colour'"),
        (None, {"rs_mode": "3objects"}, ConfigError, "rs_mode '3objects'"),
        (None, {"action_mode": "velocity"}, ConfigError, "action_mode"),
        (None, {"reference_frame": "world"}, ConfigError, "reference_frame"),
        (None, {"max_velocity_scale_factor": "fast"}, ConfigError, "not a number"),
        (None, {"max_velocity_scale_factor": "0"}, ConfigError, "positive"),
        (None, {"action_cycle_rate": "nan"}, ConfigError, "finite"),
        (None, {"action_cycle_rate": "500"}, ConfigError, "125 Hz"),
        (None, {"objects_controller": "maybe"}, ConfigError, "boolean"),
        (None, {"real_robot": "true"}, ConfigError, "real_robot"),
        (None, {"ur_model": "ur3"}, ConfigError, "contradicts"),
    ],
)
def test_bad_options(scene, options, error, match):
    with pytest.raises(error, match=match):
        parse_options("ur5", scene, options)


def test_unknown_model():
    with pytest.raises(UnknownRobotError, match="ur7"):
        URConfig(model="ur7")


@pytest.mark.parametrize("model", sorted(UR_MODELS))
def test_every_registered_model_builds_and_matches_numpy_fk(model):
    assert CARDS[model].factory == "robogym_ray.robots.ur.model:make_ur"
    robot = make_robot(model, options={"rs_mode": "1moving2points"})
    try:
        groups = robot.read_sensors()
        fk = forward_kinematics(model, np.zeros(6))
        np.testing.assert_allclose(groups["ee"][:3], fk["tool0"][0], atol=1e-5)
        np.testing.assert_allclose(groups["forearm"][:3], fk["forearm_link"][0], atol=1e-5)
        snap = robot.compose(groups)
        assert len(snap.state_dict) == 34 and len(snap.state) == 34
        assert snap.state_dict["in_collision"] == 0.0
    finally:
        robot.close()
