"""robo-gym 2.1.0's Panda envs at our ServerManager, byte for byte (in-process servers, no Ray).

The two ``cmd`` strings are what ``EmptyEnvironmentPandaSim-v0`` and
``EndEffectorPositioningPandaSim-v0`` build in ``get_launch_cmd`` (backslash continuations leave
runs of 9 spaces, 8 before ``n_objects``; a trailing space after ``object_0_frame:=target``),
sent by ``ManagedClient`` with ``gui=False``. The SetState messages are what their action and
reward nodes compose in ``_get_initial_state_msg``.
"""

from __future__ import annotations

import grpc
import numpy as np
import pytest

from robogym_ray.protocol import robot_server_pb2 as rs
from robogym_ray.protocol import robot_server_pb2_grpc as rs_grpc
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.robots.panda.model import forward_kinematics
from robogym_ray.robots.panda.state import RS_MODE_KEYS

SP = " " * 9
_COMMON = (
    "roslaunch panda_robot_server panda_robot_server.launch"
    + SP + "rviz_gui:=True" + SP + "gazebo_gui:=True"
)  # fmt: skip
EMPTY_CMD = (
    _COMMON + SP + "world_name:=empty_no_gravity.world" + SP + "reference_frame:=world"
    + SP + "max_velocity_scale_factor:=0.2" + SP + "action_cycle_rate:=30.0"
    + SP + "rs_mode:=only_robot" + SP + "action_mode:=abs_pos"
)  # fmt: skip
EE_CMD = (
    _COMMON + SP + "world_name:=tabletop_sphere50_no_collision_no_gravity.world"
    + SP + "reference_frame:=world" + SP + "max_velocity_scale_factor:=0.2"
    + SP + "action_cycle_rate:=30.0" + SP + "objects_controller:=true" + SP + "rs_mode:=1object"
    + SP + "action_mode:=abs_pos" + " " * 8 + "n_objects:=1.0"
    + SP + "object_0_model_name:=sphere50_no_collision" + SP + "object_0_frame:=target "
)  # fmt: skip
START = [-0.018, -0.76, 0.02, -2.342, 0.03, 1.541, 0.753]
"""robo-gym 2.1.0's default Panda joint positions (what SetState carries)."""


def _positions(sd) -> list[float]:
    return [sd[f"joint{i}_position"] for i in range(1, 8)]


@pytest.mark.parametrize(
    ("cmd", "rs_mode", "length"), [(EMPTY_CMD, "only_robot", 304), (EE_CMD, "1object", 464)]
)
def test_robo_gym_2_1_panda_envs_start_drive_and_kill_a_panda(
    inprocess_manager, cmd, rs_mode, length
):
    assert len(cmd) == length  # the exact strings robo-gym 2.1.0 sends
    started = inprocess_manager.StartNewServer(sm.RobotServer(cmd=cmd, gui=False), timeout=120)
    assert started.success, started.info
    channel = grpc.insecure_channel(f"127.0.0.1:{started.port}")
    robot = rs_grpc.RobotServerStub(channel)
    try:
        # SetState as ManipulatorActionNode (+ ManipulatorEePosRewardNode) composes it.
        request = rs.State(state_dict={f"joint{i + 1}_position": q for i, q in enumerate(START)})
        if rs_mode == "1object":
            request.string_params["object_0_function"] = "fixed_position"
            request.float_params.update({"object_0_x": 0.5, "object_0_y": 0.1, "object_0_z": 0.3})
        assert robot.SetState(request, timeout=20).success
        state = robot.GetState(rs.Empty(), timeout=20)
        assert state.success and set(state.state_dict) == set(RS_MODE_KEYS[rs_mode])
        assert len(state.state) == len(RS_MODE_KEYS[rs_mode])
        np.testing.assert_allclose(_positions(state.state_dict), START, atol=1e-6)
        hand = forward_kinematics(START)["panda_hand"][0]
        ee = [state.state_dict[f"ee_to_ref_translation_{a}"] for a in "xyz"]
        np.testing.assert_allclose(ee, hand, atol=1e-5)
        assert state.state_dict["in_collision"] == 0.0
        if rs_mode == "1object":
            target = [state.state_dict[f"object_0_to_ref_translation_{a}"] for a in "xyz"]
            np.testing.assert_allclose(target, [0.5, 0.1, 0.3], atol=1e-6)
            np.testing.assert_allclose(state.state[:3], [0.5, 0.1, 0.3], atol=1e-6)
        # One abs_pos action (7 joint targets, rad) at 30 Hz with speeds at 0.2 of the limits.
        goal = np.array(START) + 0.5
        after = robot.SendActionGetState(rs.Action(action=goal.tolist()), timeout=20)
        moved = np.array(_positions(after.state_dict)) - START
        assert after.success and np.all(moved > 0)
        assert np.all(moved <= 0.2 * np.array([2.175] * 4 + [2.61] * 3) / 30 + 1e-6)
        # A bad action is refused with a reason, and the arm stays where it was.
        bad = robot.SendActionGetState(rs.Action(action=[0.0] * 6), timeout=20)
        assert not bad.success
        still = robot.GetState(rs.Empty(), timeout=20)
        np.testing.assert_allclose(_positions(still.state_dict), _positions(after.state_dict))
    finally:
        channel.close()
    assert inprocess_manager.KillServer(sm.RobotServer(port=started.port), timeout=30).success
