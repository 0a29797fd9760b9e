"""Values a client sends are checked against physically sensible ranges before anything changes.

Until 2026-11-23 a MiR100 target yaw of 1e5 was stored and echoed, UR object positions of 3e38 were
accepted, a ``triangle_wave`` of 1e-5 Hz precomputed ~670 MB, an ``action_cycle_rate`` of
0.001 Hz made each SendAction simulate 1,000 s. Every test goes through real gRPC on 127.0.0.1.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import grpc
import numpy as np
import pytest

from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.robots import objects
from robogym_ray.robots.server import ERROR_METADATA_KEY, RobotServerHandle, start_robot_server

FLOAT32_MAX = 3.4e38


def stub_for(address: str) -> pb_grpc.RobotServerStub:
    return pb_grpc.RobotServerStub(grpc.insecure_channel(address))


def set_state(stub: pb_grpc.RobotServerStub, msg: pb.State) -> tuple[bool, str]:
    reply, call = stub.SetState.with_call(msg, timeout=10)
    return reply.success, dict(call.trailing_metadata() or ()).get(ERROR_METADATA_KEY, "")


# -- MiR100 ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def mir() -> Iterator[RobotServerHandle]:
    handle = start_robot_server("mir100", scene="lab_6x8", seed=0)
    yield handle
    handle.stop()


def mir_state(target=(2.0, 0.0, 0.5), pose=(-1.0, -2.5, 0.3), cube_yaw=0.0) -> pb.State:
    state = np.zeros(1030, dtype=np.float32)
    state[0:3], state[3:6] = target, pose
    state[1021:1030] = [-2.0, 0.0, cube_yaw, 0.0, 0.5, 0.0, 2.0, -0.5, 0.0]
    return pb.State(state=state.tolist())


@pytest.mark.parametrize(
    ("msg", "field"),
    [
        (mir_state(target=(2.0, 0.0, 1e5)), "state[2] (target yaw)"),
        (mir_state(target=(2.0, 0.0, FLOAT32_MAX)), "state[2] (target yaw)"),
        (mir_state(target=(2.0, 0.0, -FLOAT32_MAX)), "state[2] (target yaw)"),
        (mir_state(pose=(0.0, 0.0, 1e5)), "state[5] (robot pose yaw)"),
        (mir_state(cube_yaw=FLOAT32_MAX), "state[1023] (obstacle_0 yaw)"),
    ],
    ids=["target-1e5", "target-float32-max", "target-minus-float32-max", "robot-1e5", "cube"],
)
def test_mir_set_state_refuses_an_unbounded_yaw(
    mir: RobotServerHandle, msg: pb.State, field: str
) -> None:
    stub = stub_for(mir.address)
    assert set_state(stub, mir_state()) == (True, "")
    before = list(stub.GetState(pb.Empty(), timeout=5).state)
    ok, error = set_state(stub, msg)
    assert not ok
    assert f"SetState: InvalidStateError: {field} = " in error
    assert f"[{-4 * math.pi:g}, {4 * math.pi:g}] rad" in error
    # Nothing was applied: the target is not echoed, the robot did not move.
    assert list(stub.GetState(pb.Empty(), timeout=5).state) == before
    assert stub.SendActionGetState(pb.Action(action=[0.1, 0.0]), timeout=5).success


@pytest.mark.parametrize("yaw", [-math.pi, math.pi, 2 * math.pi, -3.9 * math.pi])
def test_mir_set_state_keeps_accepting_ordinary_yaws(mir: RobotServerHandle, yaw: float) -> None:
    stub = stub_for(mir.address)
    assert set_state(stub, mir_state(target=(2.0, 0.0, yaw), pose=(0.0, -2.5, yaw))) == (True, "")
    state = stub.GetState(pb.Empty(), timeout=5).state
    assert np.isclose(state[2], yaw, atol=1e-5)  # the target is echoed as sent


# -- UR ----------------------------------------------------------------------------------------
JOINTS = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")
Q0 = (0.0, -2.5, 1.5, -1.5, -1.4, 0.0)


@pytest.fixture(scope="module")
def ur10() -> Iterator[RobotServerHandle]:
    handle = start_robot_server("ur10", scene="tabletop", seed=0, options={"rs_mode": "1object"})
    yield handle
    handle.stop()


def ur_state(function: str, q=Q0, **params: float) -> pb.State:
    return pb.State(
        state_dict={f"{j}_joint_position": v for j, v in zip(JOINTS, q, strict=True)},
        string_params={"object_0_function": function},
        float_params={f"object_0_{k}": v for k, v in params.items()},
    )


TRIANGLE = dict(x=0.12, y=0.34, z_amplitude=0.2, z_frequency=0.125, z_offset=0.4)
ABC = {f"{k}_{t}": 0.3 for t in "abc" for k in "xyz"}
ABC.update(hold_a=1.0, hold_b=1.0, hold_c=1.0, n_sampling_points_ab=10, n_sampling_points_bc=10)


@pytest.mark.parametrize(
    ("function", "params", "field", "allowed"),
    [
        ("fixed_position", dict(x=3e38, y=0.0, z=0.5), "object_0_x = 3e+38;", "[-10, 10] m"),
        ("fixed_position", dict(x=0.5, y=0.0, z=-11.0), "object_0_z = -11.0;", "[-10, 10] m"),
        (
            "triangle_wave",
            {**TRIANGLE, "z_frequency": 1e-5},
            "object_0_z_frequency = 1e-05;",
            "[0.00333333, 50] Hz",
        ),
        ("triangle_wave", {**TRIANGLE, "z_amplitude": 1e30}, "object_0_z_amplitude", "m"),
        ("interpolated_abc", {**ABC, "hold_b": 1e7}, "object_0_hold_b = 10000000.0;", "[0, 300] s"),
        (
            "interpolated_abc",
            {**ABC, "n_sampling_points_ab": 1e9},
            "object_0_n_sampling_points_ab",
            "[0, 30000] samples",
        ),
    ],
)
def test_ur_set_state_refuses_unbounded_object_parameters(
    ur10: RobotServerHandle,
    monkeypatch: pytest.MonkeyPatch,
    function: str,
    params: dict,
    field: str,
    allowed: str,
) -> None:
    stub = stub_for(ur10.address)
    assert set_state(stub, ur_state("fixed_position", x=0.5, y=0.3, z=0.6)) == (True, "")
    before = stub.GetState(pb.Empty(), timeout=5)
    # The server runs in this process: count the calls of the function's real sampler.
    names, sampler = objects.FUNCTIONS[function]
    sampled: list[dict] = []

    def counted(p: dict, rng: np.random.Generator) -> np.ndarray:
        sampled.append(p)
        return sampler(p, rng)

    monkeypatch.setitem(objects.FUNCTIONS, function, (names, counted))
    ok, error = set_state(stub, ur_state(function, q=(0.5, -2.0, 1.0, -1.0, -1.0, 0.5), **params))
    # Refused before any trajectory is sampled (1e-5 Hz took 3.1 s and ~670 MB).
    assert sampled == []
    assert not ok and field in error and allowed in error, error
    after = stub.GetState(pb.Empty(), timeout=5)
    assert dict(after.state_dict) == dict(before.state_dict)  # joints and object untouched
    assert stub.SendActionGetState(pb.Action(action=[0.0] * 6), timeout=5).success


def test_ur_set_state_keeps_accepting_robo_gym_trajectories(ur10: RobotServerHandle) -> None:
    """The values robo-gym's envs send (spec c.2.4) and the ends of every range are accepted."""
    stub = stub_for(ur10.address)
    assert set_state(stub, ur_state("triangle_wave", **TRIANGLE)) == (True, "")
    slowest = {**TRIANGLE, "z_frequency": 0.0034}  # a 294 s period: 29,411 samples
    assert set_state(stub, ur_state("triangle_wave", **slowest)) == (True, "")
    assert set_state(stub, ur_state("triangle_wave", **{**TRIANGLE, "z_frequency": 50.0})) == (
        True,
        "",
    )
    assert set_state(stub, ur_state("interpolated_abc", **{**ABC, "hold_a": 300.0})) == (True, "")
    assert set_state(stub, ur_state("fixed_position", x=-10.0, y=10.0, z=0.6)) == (True, "")


@pytest.mark.parametrize("rate", ["0.001", "0.5", "1e6", "-10"])
def test_ur_action_cycle_rate_out_of_range_is_refused_at_start(rate: str) -> None:
    with pytest.raises(ConfigError, match=r"action_cycle_rate = .*\[1, 1000\] Hz"):
        start_robot_server("ur10", options={"action_cycle_rate": rate})


@pytest.mark.parametrize("rate", ["1", "10", "25", "125"])
def test_ur_action_cycle_rate_in_range_is_served(rate: str) -> None:
    handle = start_robot_server("ur10", options={"action_cycle_rate": rate})
    try:
        assert stub_for(handle.address).SendAction(pb.Action(action=[0.0] * 6), timeout=30).success
        cfg = handle.core.robot.handler_config
        # One action cycle of 8 ms controller ticks: at most 1 s (125 ticks) of sim time per call.
        assert np.isclose(handle.core.sim_time, cfg.ticks_per_action * cfg.actuation_cycle)
        assert np.isclose(handle.core.sim_time, 1.0 / float(rate), atol=0.008)
    finally:
        handle.stop()
