"""robo-gym 2.1.0's new arm envs at our ServerManager, byte for byte (in-process servers, no Ray).

The ``cmd`` strings are what robo-gym v2.1.0 builds (``get_launch_cmd`` / the class ``cmd`` +
``" ur_model:=<m>"``) with the envs' defaults, sent by its client with ``gui=False``; the
SetState messages are what the envs' nodes compose on reset. The f-strings' backslash
continuations leave runs of 9 or 13 spaces between arguments (12 where IsaacReachPanda's
``action_mode:=...\\`` lacks its space), so the lengths are asserted too:

======================================  ==================================================
env (robo-gym v2.1.0 file)              cmd
======================================  ==================================================
IsaacReachURSim-v0 (ur10, the default)  ``envs/ur/ur_isaac_reach.py``: 545 chars
IsaacReachPandaSim-v0                   ``envs/panda/panda_isaac_reach.py``: 525 chars
EmptyEnvironment2URSim-v0 (ur5)         ``envs/ur/ur_base.py``: 284 chars
EndEffectorPositioning2URSim-v0 (ur10)  ``envs/ur/ur_ee_pos.py``: 493 chars (its rate is
                                        20.0: ``URBaseEnv2``'s default wins over its own 10.0)
AvoidanceRaad2022TestURSim-v0 (ur5)     ``envs/ur/ur_avoidance_raad.py``: 465 chars
======================================  ==================================================
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import grpc
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robogym_ray.protocol import robot_server_pb2 as rs
from robogym_ray.protocol import robot_server_pb2_grpc as rs_grpc
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.robots.panda.model import forward_kinematics as panda_fk
from robogym_ray.robots.panda.state import RS_MODE_KEYS as PANDA_KEYS
from robogym_ray.robots.server import ERROR_METADATA_KEY
from robogym_ray.robots.ur.geometry import ROS_FROM_ENV
from robogym_ray.robots.ur.geometry import forward_kinematics as ur_fk
from robogym_ray.robots.ur.state import POSITION_KEYS as UR_POSITION_KEYS
from robogym_ray.robots.ur.state import RS_MODE_KEYS as UR_KEYS

S9, S13 = " " * 9, " " * 13
_UR = "roslaunch ur_robot_server ur_robot_server.launch"
_GUIS = ["rviz_gui:=True", "gazebo_gui:=True"]
_OBJECT = ["n_objects:=1.0", "object_0_model_name:=sphere50_no_collision", "object_0_frame:=target"]
ISAAC_UR10 = S13.join(
    [_UR, *_GUIS, "world_name:=isaactabletop_sphere50_no_collision.world",
     "reference_frame:=base_link", "ee_frame:=tool1", "max_velocity_scale_factor:=0.2",
     "action_cycle_rate:=30.0", "objects_controller:=true", "rs_mode:=1object", *_OBJECT,
     "z:=0.0", "ur_model:=ur10"]
)  # fmt: skip
ISAAC_PANDA = (
    S13.join(["roslaunch panda_robot_server panda_robot_server.launch", *_GUIS,
              "world_name:=isaactabletop_sphere50_no_collision.world", "reference_frame:=world",
              "max_velocity_scale_factor:=0.2", "action_cycle_rate:=30.0",
              "objects_controller:=true", "rs_mode:=1object", "action_mode:=abs_pos"])
    + " " * 12 + S13.join([*_OBJECT, "z:=0.0 "])
)  # fmt: skip
EMPTY2_UR5 = S9.join(
    [_UR, *_GUIS, "world_name:=empty.world", "reference_frame:=base_link",
     "max_velocity_scale_factor:=0.2", "action_cycle_rate:=20.0", "rs_mode:=only_robot",
     "ur_model:=ur5"]
)  # fmt: skip
EE2_UR10 = S13.join(
    [_UR, *_GUIS, "world_name:=tabletop_sphere50_no_collision.world",
     "reference_frame:=base_link", "max_velocity_scale_factor:=0.1", "action_cycle_rate:=20.0",
     "objects_controller:=true", "rs_mode:=1object", *_OBJECT, "ur_model:=ur10"]
)  # fmt: skip
RAAD_TEST_UR5 = (
    S9.join([_UR, "world_name:=tabletop_sphere50.world", "reference_frame:=base_link",
             "max_velocity_scale_factor:=0.2", "action_cycle_rate:=20", "rviz_gui:=false",
             "gazebo_gui:=true", "objects_controller:=true", "rs_mode:=1moving2points",
             "n_objects:=1.0", "object_trajectory_file_name:=splines_ur5",
             "object_0_model_name:=sphere50", "object_0_frame:=target"])
    + " ur_model:=ur5"
)  # fmt: skip

ISAAC_UR_START = [0.0, -1.712, 1.712, 0.0, 0.0, 0.0]
ISAAC_PANDA_START = [0.0, -0.569, 0.0, -2.81, 0.0, 3.037, 0.741]
UR2_START = [0.0, -2.5, 1.5, 0.0, -1.4, 0.0]
RAAD_START = [-1.234, -1.854, -1.781, -1.069, 1.595, 0.0]
"""The first waypoint of robo-gym's trajectory_raad_2022.json (rounded), env order."""
TARGET = {"object_0_x": 0.5, "object_0_y": 0.1, "object_0_z": 0.3}
"""A target as IsaacReach draws them (x 0.35-0.65, y -0.2-0.2, z 0.15-0.5 m)."""
TOOL1_IN_TOOL0 = Rotation.from_euler("ZYX", [3.1415, -1.5707, 0.0])
"""robot-servers 2.1.0's ``static_transform_publisher 0 0 0 3.1415 -1.5707 0 tool0 tool1``
(yaw, pitch, roll), written again here."""
# ur10 tool0 pointing down at base_link (0.8, 0.164, +-0.03): over the demo table (x up to
# 1.035 m), beyond the tabletop (x up to 0.45 m); found with the numpy FK, checked below.
ABOVE = [0.0, -0.9007, 1.9111, -2.5812, -1.5708, 0.0]
BELOW = [0.0, -0.8104, 1.9047, -2.6651, -1.5708, 0.0]


@contextmanager
def robot_server(manager: Any, cmd: str) -> Iterator[Any]:
    """A robot server the manager started for ``cmd``; killed afterwards."""
    started = manager.StartNewServer(sm.RobotServer(cmd=cmd, gui=False), timeout=120)
    assert started.success, started.info
    channel = grpc.insecure_channel(f"127.0.0.1:{started.port}")
    try:
        yield rs_grpc.RobotServerStub(channel)
    finally:
        channel.close()
        assert manager.KillServer(sm.RobotServer(port=started.port), timeout=30).success


def _ur_reset(joints: list[float], keys: tuple[str, ...] = (), **params: Any) -> rs.State:
    """SetState as robo-gym's UR envs send it: ``keys`` with 0.0 (the avoidance envs send their
    whole composition), the six joint goals by name, and the object's params."""
    state_dict = dict.fromkeys(keys, 0.0) | dict(zip(UR_POSITION_KEYS, joints, strict=True))
    strings = {k: v for k, v in params.items() if isinstance(v, str)}
    floats = {k: float(v) for k, v in params.items() if not isinstance(v, str)}
    return rs.State(state_dict=state_dict, string_params=strings, float_params=floats)


def _xyz(sd: Any, frame: str) -> np.ndarray:
    return np.array([sd[f"{frame}_to_ref_translation_{a}"] for a in "xyz"])


def _quat(sd: Any, frame: str) -> np.ndarray:
    return np.array([sd[f"{frame}_to_ref_rotation_{a}"] for a in "xyzw"])


def test_the_commands_are_robo_gym_2_1_0s_byte_for_byte() -> None:
    lengths = [len(c) for c in (ISAAC_UR10, ISAAC_PANDA, EMPTY2_UR5, EE2_UR10, RAAD_TEST_UR5)]
    assert lengths == [545, 525, 284, 493, 465]


@pytest.mark.parametrize(
    ("cmd", "rs_mode", "start", "params"),
    [
        (ISAAC_UR10, "1object", ISAAC_UR_START, {"object_0_function": "fixed_position", **TARGET}),
        (EMPTY2_UR5, "only_robot", UR2_START, {}),
        (EE2_UR10, "1object", UR2_START, {"object_0_function": "fixed_position", **TARGET}),
    ],
    ids=["IsaacReachUR", "EmptyEnvironment2UR", "EndEffectorPositioning2UR"],
)
def test_modular_ur_envs_get_a_server_and_reset_it(
    inprocess_manager, cmd, rs_mode, start, params
) -> None:
    with robot_server(inprocess_manager, cmd) as robot:
        assert robot.SetState(_ur_reset(start, **params), timeout=20).success
        state = robot.GetState(rs.Empty(), timeout=20)
        sd = state.state_dict
        assert state.success and sorted(sd) == sorted(UR_KEYS[rs_mode])
        assert len(state.state) == len(UR_KEYS[rs_mode])
        np.testing.assert_allclose([sd[k] for k in UR_POSITION_KEYS], start, atol=1e-6)
        assert sd["in_collision"] == 0.0
        if params:
            np.testing.assert_allclose(_xyz(sd, "object_0"), list(TARGET.values()), atol=1e-6)
        # One step of the env: absolute targets in ROS order; the arm moves towards them.
        goal = np.array(start) + [0.0, 0.1, 0.0, 0.0, 0.0, 0.0]
        after = robot.SendActionGetState(rs.Action(action=goal[list(ROS_FROM_ENV)]), timeout=20)
        assert after.success and after.state_dict["shoulder_joint_position"] > start[1]


def test_isaac_reach_ur_reports_tool1_tool0_turned_by_the_launch_files_rotation(
    inprocess_manager,
) -> None:
    with robot_server(inprocess_manager, ISAAC_UR10) as robot:
        for joints in (ISAAC_UR_START, [0.3, -1.2, 1.0, -0.7, 0.9, 1.1]):
            assert robot.SetState(_ur_reset(joints), timeout=20).success
            sd = robot.GetState(rs.Empty(), timeout=20).state_dict
            tool0_xyz, tool0_quat = ur_fk("ur10", joints)["tool0"]
            np.testing.assert_allclose(_xyz(sd, "ee"), tool0_xyz, atol=1e-5)
            expected = Rotation.from_quat(tool0_quat) * TOOL1_IN_TOOL0
            error = Rotation.from_quat(_quat(sd, "ee")) * expected.inv()
            assert error.magnitude() < 1e-5


def _collides(robot: Any, joints: list[float]) -> bool:
    assert robot.SetState(_ur_reset(joints), timeout=20).success
    return robot.GetState(rs.Empty(), timeout=20).state_dict["in_collision"] == 1.0


def test_isaactabletop_puts_the_base_at_z_and_the_table_top_level_with_it(
    inprocess_manager,
) -> None:
    for joints, z in ((ABOVE, 0.03), (BELOW, -0.03)):
        xyz = ur_fk("ur10", joints)["tool0"][0]
        np.testing.assert_allclose(xyz[[0, 2]], [0.8, z], atol=1e-3)
    # z:=0.0 (as sent): the table top is at base_link height, 1.035 m long.
    with robot_server(inprocess_manager, ISAAC_UR10) as robot:
        assert not _collides(robot, ABOVE)
        assert _collides(robot, BELOW)
    # z:=0.5: the base 0.5 m above the table top; the same pose is free.
    with robot_server(inprocess_manager, ISAAC_UR10.replace("z:=0.0", "z:=0.5")) as robot:
        assert not _collides(robot, BELOW)
    # robo-gym's tabletop world (base_link 0.1 m up by default): that table ends at x = 0.45 m.
    with robot_server(inprocess_manager, EE2_UR10) as robot:
        assert not _collides(robot, BELOW)


def test_isaac_reach_panda_gets_a_server_on_the_demo_table(inprocess_manager) -> None:
    with robot_server(inprocess_manager, ISAAC_PANDA) as robot:
        goals = dict(zip(PANDA_KEYS["only_robot"][:7], ISAAC_PANDA_START, strict=True))
        reset = rs.State(state_dict=goals, string_params={"object_0_function": "fixed_position"})
        reset.float_params.update(TARGET)
        assert robot.SetState(reset, timeout=20).success
        state = robot.GetState(rs.Empty(), timeout=20)
        sd = state.state_dict
        assert state.success and sorted(sd) == sorted(PANDA_KEYS["1object"])
        assert len(state.state) == len(PANDA_KEYS["1object"]) and sd["in_collision"] == 0.0
        # reference_frame:=world: the Panda's base is the world origin (its launch file ignores
        # z), so the hand's pose is the forward kinematics itself.
        np.testing.assert_allclose(
            _xyz(sd, "ee"), panda_fk(ISAAC_PANDA_START)["panda_hand"][0], atol=1e-5
        )
        np.testing.assert_allclose(_xyz(sd, "object_0"), list(TARGET.values()), atol=1e-6)
        # The table top is at z = 0: the hand 0.04 m below it touches it.
        low = [0.0, 1.5, 0.0, -0.8, 0.0, 2.2, 0.785]
        assert panda_fk(low)["panda_hand"][0][2] < -0.03
        assert robot.SetState(
            rs.State(state_dict=dict(zip(goals, low, strict=True))), timeout=20
        ).success
        assert robot.GetState(rs.Empty(), timeout=20).state_dict["in_collision"] == 1.0


def _trajectory_reset(trajectory_id: float) -> rs.State:
    """AvoidanceRaad2022Test's SetState: the whole 1moving2points composition, the first
    waypoint, ``fixed_trajectory`` with ``ep_n % 50``."""
    return _ur_reset(
        RAAD_START,
        UR_KEYS["1moving2points"],
        object_0_function="fixed_trajectory",
        object_0_trajectory_id=trajectory_id,
    )


def _object_path(robot: Any, trajectory_id: float, steps: int = 20) -> np.ndarray:
    assert robot.SetState(_trajectory_reset(trajectory_id), timeout=20).success
    hold = np.array(RAAD_START)[list(ROS_FROM_ENV)]
    path = []
    for _ in range(steps):
        state = robot.SendActionGetState(rs.Action(action=hold), timeout=20)
        assert state.success
        path.append(_xyz(state.state_dict, "object_0"))
    return np.array(path)


def test_fixed_trajectory_is_the_same_for_the_same_id_on_every_server(inprocess_manager) -> None:
    with robot_server(inprocess_manager, RAAD_TEST_UR5) as first:
        path_7 = _object_path(first, 7.0)
        path_8 = _object_path(first, 8.0)
        again_7 = _object_path(first, 7.0)  # after another trajectory: the same again
    with robot_server(inprocess_manager, RAAD_TEST_UR5) as second:
        other_7 = _object_path(second, 7.0)
    np.testing.assert_array_equal(path_7, again_7)
    np.testing.assert_array_equal(path_7, other_7)
    assert np.abs(path_7 - path_8).max() > 0.05  # different ids, different trajectories
    # 20 steps at 20 Hz = 1 s = 100 samples of 8000-12000 per lap: the object moves on.
    assert len({tuple(p) for p in path_7}) == 20
    assert np.hypot(path_7[:, 0], path_7[:, 1]).min() > 0.2  # clear of the robot


@pytest.mark.parametrize("bad_id", [50.0, -1.0, 2.5])
def test_fixed_trajectory_ids_outside_0_to_49_are_refused(inprocess_manager, bad_id) -> None:
    with robot_server(inprocess_manager, RAAD_TEST_UR5) as robot:
        before = _object_path(robot, 3.0, steps=1)
        reply, call = robot.SetState.with_call(_trajectory_reset(bad_id), timeout=20)
        assert not reply.success
        assert "trajectory_id" in dict(call.trailing_metadata() or ()).get(ERROR_METADATA_KEY, "")
        # Nothing changed: the object still follows trajectory 3.
        state = robot.GetState(rs.Empty(), timeout=20)
        np.testing.assert_allclose(_xyz(state.state_dict, "object_0"), before[-1], atol=1e-6)
