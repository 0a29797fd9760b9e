"""The robot server through real gRPC on 127.0.0.1: semantics, bad input, token, pacing, CLI."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import grpc
import numpy as np
import pytest

from robogym_ray import children
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.robots.server import (
    ERROR_METADATA_KEY,
    TOKEN_METADATA_KEY,
    RobotServerHandle,
    start_robot_server,
)


def stub_for(address: str) -> pb_grpc.RobotServerStub:
    return pb_grpc.RobotServerStub(grpc.insecure_channel(address))


def error_of(call: grpc.Call) -> str:
    return dict(call.trailing_metadata() or ()).get(ERROR_METADATA_KEY, "")


@pytest.fixture
def mir() -> Iterator[RobotServerHandle]:
    handle = start_robot_server("mir100", scene="lab_6x8", seed=0)
    yield handle
    handle.stop()


def mir_state(target=(2.0, 0.0, 0.0), pose=(-1.0, -2.5, 0.3)) -> pb.State:
    state = np.zeros(1030, dtype=np.float32)
    state[0:3], state[3:6] = target, pose
    state[1021:1030] = [-2.0, 0.0, 0.0, 0.0, 0.5, 0.0, 2.0, -0.5, 0.0]
    return pb.State(state=state.tolist())


def test_get_state_works_before_any_set_state(mir: RobotServerHandle) -> None:
    """robo-gym's manager probes readiness with GetState and needs len(state) > 1."""
    msg = stub_for(mir.address).GetState(pb.Empty(), timeout=5)
    assert msg.success and len(msg.state) == 1030


def test_set_state_then_get_state_returns_the_pose(mir: RobotServerHandle) -> None:
    stub = stub_for(mir.address)
    assert stub.SetState(mir_state(), timeout=5).success
    msg = stub.GetState(pb.Empty(), timeout=5)
    assert np.allclose(msg.state[0:3], [2.0, 0.0, 0.0], atol=1e-6)  # target echoed
    assert np.allclose(msg.state[3:6], [-1.0, -2.5, 0.3], atol=1e-5)
    assert np.allclose(msg.state[6:8], 0.0)


def test_forward_twist_moves_mir_along_its_heading(mir: RobotServerHandle) -> None:
    stub = stub_for(mir.address)
    stub.SetState(mir_state(pose=(0.0, -2.5, 0.5)), timeout=5)
    for _ in range(20):  # 2 s at 0.5 m/s, from rest with 2 m/s^2 acceleration
        msg = stub.SendActionGetState(pb.Action(action=[0.5, 0.0]), timeout=5)
    x, y, yaw = msg.state[3:6]
    travelled = np.hypot(x, y + 2.5)
    assert 0.85 < travelled < 1.0
    assert np.isclose(np.arctan2(y + 2.5, x), 0.5, atol=1e-3)  # along the heading
    assert np.isclose(yaw, 0.5, atol=1e-4)
    assert np.isclose(msg.state[6], 0.5, atol=1e-6)


def test_send_action_takes_one_action_cycle_of_sim_time(mir: RobotServerHandle) -> None:
    stub = stub_for(mir.address)
    before = mir.core.sim_time
    assert stub.SendAction(pb.Action(action=[0.1, 0.1]), timeout=5).success
    assert np.isclose(mir.core.sim_time - before, 0.1)


@pytest.mark.parametrize(
    "action, expected",
    [
        ([0.1], "expected 2"),
        ([float("nan"), 0.0], "nan"),
        ([0.0, float("inf")], "inf"),
    ],
)
def test_bad_action_fails_the_call_and_changes_nothing(
    mir: RobotServerHandle, action: list[float], expected: str
) -> None:
    stub = stub_for(mir.address)
    stub.SetState(mir_state(), timeout=5)
    before = list(stub.GetState(pb.Empty(), timeout=5).state)
    time_before = mir.core.sim_time
    reply, call = stub.SendActionGetState.with_call(pb.Action(action=action), timeout=5)
    assert not reply.success
    assert expected in error_of(call).lower() and "SendActionGetState" in error_of(call)
    assert expected in reply.string_params["error"].lower()
    ok, call = stub.SendAction.with_call(pb.Action(action=action), timeout=5)
    assert not ok.success and error_of(call)
    assert list(stub.GetState(pb.Empty(), timeout=5).state) == before
    assert mir.core.sim_time == time_before
    # ... and the server keeps serving normally.
    assert stub.SendActionGetState(pb.Action(action=[0.1, 0.0]), timeout=5).success


@pytest.mark.parametrize(
    "state, expected",
    [
        ([1.0, 2.0], "length"),
        ([0.0] * 3 + [float("nan"), 0.0, 0.0], "nan"),
        ([0.0] * 3 + [1e6, 0.0, 0.0], "3"),
    ],
)
def test_bad_state_fails_the_call_and_changes_nothing(
    mir: RobotServerHandle, state: list[float], expected: str
) -> None:
    stub = stub_for(mir.address)
    stub.SetState(mir_state(), timeout=5)
    before = list(stub.GetState(pb.Empty(), timeout=5).state)
    reply, call = stub.SetState.with_call(pb.State(state=state), timeout=5)
    assert not reply.success and expected in error_of(call).lower()
    assert list(stub.GetState(pb.Empty(), timeout=5).state) == before


def test_concurrent_clients_get_consistent_states(mir: RobotServerHandle) -> None:
    """Four threads hammer the server; every reply is a complete, finite 1030-value state."""
    from concurrent.futures import ThreadPoolExecutor

    stub = stub_for(mir.address)
    stub.SetState(mir_state(), timeout=5)

    def worker(i: int) -> list[int]:
        lengths = []
        for _ in range(25):
            if i % 2:
                msg = stub.SendActionGetState(pb.Action(action=[0.2, 0.1]), timeout=10)
            else:
                msg = stub.GetState(pb.Empty(), timeout=10)
            assert msg.success and np.all(np.isfinite(msg.state))
            lengths.append(len(msg.state))
        return lengths

    with ThreadPoolExecutor(4) as pool:
        assert all(n == 1030 for lengths in pool.map(worker, range(4)) for n in lengths)
    assert mir.core.calls["action"] == 50


def test_token_is_required_when_set() -> None:
    handle = start_robot_server("mir100", scene="empty", token="s3cret")
    try:
        stub = stub_for(handle.address)
        with pytest.raises(grpc.RpcError) as info:
            stub.GetState(pb.Empty(), timeout=5)
        assert info.value.code() == grpc.StatusCode.UNAUTHENTICATED
        msg = stub.GetState(pb.Empty(), timeout=5, metadata=((TOKEN_METADATA_KEY, "s3cret"),))
        assert msg.success
    finally:
        handle.stop()


def test_real_time_pacing_publishes_at_the_actuation_rate() -> None:
    """With pacing on, the handler ticks at the controller's rate against the wall clock."""
    handle = start_robot_server("mir100", scene="empty", real_time=True, options={})
    try:
        stub = stub_for(handle.address)
        handler = handle.core.handler
        start_ticks, start = handler.published + handler.stops, time.monotonic()
        t0 = time.monotonic()
        stub.SendAction(pb.Action(action=[0.3, 0.0]), timeout=5)
        assert time.monotonic() - t0 >= 0.09  # SendAction returns after one action cycle
        time.sleep(1.0)
        rate = (handler.published + handler.stops - start_ticks) / (time.monotonic() - start)
        assert 6.0 <= rate <= 11.0  # 10 Hz actuation; loose for a loaded 2-core machine
        assert handler.published >= 1 and handler.stops >= 5  # empty slot -> zero twist
        assert np.isclose(stub.GetState(pb.Empty(), timeout=5).state[6], 0.0, atol=1e-6)
    finally:
        handle.stop()


def test_serve_cli_prints_address_and_stops_on_sigterm() -> None:
    proc = children.popen(
        [sys.executable, "-m", "robogym_ray.cli", "serve", "--robot", "mir100", "--port", "0"],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        line = proc.stdout.readline().strip()
        assert line.startswith("listening on 127.0.0.1:"), line
        address = line.removeprefix("listening on ")
        assert stub_for(address).GetState(pb.Empty(), timeout=10).success
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()


def test_serve_cli_rejects_an_unknown_robot() -> None:
    out = children.run(
        [sys.executable, "-m", "robogym_ray.cli", "serve", "--robot", "ur99"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 2 and "ur99" in out.stderr and "mir100" in out.stderr


# -- UR10 through gRPC -------------------------------------------------------------------------
JOINTS = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")


def ur_reset(stub: pb_grpc.RobotServerStub, q_env: list[float]) -> None:
    """SetState as robo-gym's EndEffectorPositioning env sends it (27 keys, joint goals)."""
    keys = {f"{j}_joint_position": q for j, q in zip(JOINTS, q_env, strict=True)}
    keys.update({f"{j}_joint_velocity": 0.0 for j in JOINTS})
    keys.update(
        {
            f"ee_to_ref_{a}": 0.0
            for a in (
                "translation_x",
                "translation_y",
                "translation_z",
                "rotation_x",
                "rotation_y",
                "rotation_z",
                "rotation_w",
            )
        }
    )
    keys["in_collision"] = 0.0
    msg = pb.State(
        state_dict=keys,
        string_params={"object_0_function": "fixed_position"},
        float_params={"object_0_x": 0.5, "object_0_y": 0.3, "object_0_z": 0.6},
    )
    assert stub.SetState(msg, timeout=10).success


def joints_of(msg: pb.State) -> np.ndarray:
    return np.array([msg.state_dict[f"{j}_joint_position"] for j in JOINTS])


@pytest.fixture
def ur10() -> Iterator[RobotServerHandle]:
    handle = start_robot_server("ur10", scene="tabletop", seed=0, options={"rs_mode": "1object"})
    yield handle
    handle.stop()


def test_ur10_set_state_is_read_back(ur10: RobotServerHandle) -> None:
    stub = stub_for(ur10.address)
    q = [0.0, -2.5, 1.5, -1.5, -1.4, 0.0]
    ur_reset(stub, q)
    msg = stub.GetState(pb.Empty(), timeout=5)
    assert msg.success and len(msg.state_dict) == 27 and len(msg.state) == 27
    assert np.allclose(joints_of(msg), q, atol=1e-4)
    ee = [msg.state_dict[f"ee_to_ref_translation_{a}"] for a in "xyz"]
    assert np.allclose(ee, (-0.0391, 0.1796, 1.0135), atol=2e-3)  # golden FK value, spec e.2
    assert msg.state_dict["in_collision"] == 0.0


def test_ur10_joint_targets_are_reached_and_limits_hold(ur10: RobotServerHandle) -> None:
    stub = stub_for(ur10.address)
    ur_reset(stub, [0.0, -2.5, 1.5, -1.5, -1.4, 0.0])
    goal_env = np.array([0.6, -2.2, 1.2, -1.2, -1.6, 0.4])
    ros = [goal_env[2], goal_env[1], goal_env[0], *goal_env[3:]]  # robo-gym sends ROS order
    for _ in range(150):  # 6 s of sim time at 40 ms per action
        msg = stub.SendActionGetState(pb.Action(action=ros), timeout=5)
    assert np.allclose(joints_of(msg), goal_env, atol=0.01)
    assert msg.state_dict["in_collision"] == 0.0
    # A target beyond the elbow's +-pi limit (allowed by the wire range check for the other
    # joints at 2*pi) never drives the joint past its limit.
    beyond = [3.1415, -2.2, 0.6, -1.2, -1.6, 6.28]
    for _ in range(300):
        msg = stub.SendActionGetState(pb.Action(action=beyond), timeout=5)
        q = joints_of(msg)
        assert abs(q[2]) <= np.pi + 1e-6 and abs(q[5]) <= 2 * np.pi + 1e-6


def test_ur10_out_of_range_action_is_refused(ur10: RobotServerHandle) -> None:
    stub = stub_for(ur10.address)
    reply, call = stub.SendActionGetState.with_call(
        pb.Action(action=[0.0, 0.0, 0.0, 0.0, 0.0, 99.0]), timeout=5
    )
    assert not reply.success and "wrist_3" in error_of(call)
    assert stub.GetState(pb.Empty(), timeout=5).success


# A library user's way to serve: start, then wait in the main thread until Ctrl-C.
WAITING_CHILD = """
import signal
from robogym_ray.robots.server import start_robot_server

# Ctrl-C as in a terminal: a parent started in the background may have left SIGINT ignored.
signal.signal(signal.SIGINT, signal.default_int_handler)
handle = start_robot_server("mir100")
print(handle.address, flush=True)
try:
    handle.wait()
except KeyboardInterrupt:
    print("connected" if handle.core.robot.world.client.isConnected() else "closed", flush=True)
"""


def test_wait_returns_whether_the_server_stopped() -> None:
    handle = start_robot_server("mir100")
    try:
        assert handle.wait(timeout=0.05) is False  # still serving
    finally:
        handle.stop()
    assert handle.wait(timeout=5) is True


def test_ctrl_c_in_wait_stops_the_server_and_closes_the_robot() -> None:
    proc = children.popen([sys.executable, "-c", WAITING_CHILD], stdout=subprocess.PIPE, text=True)
    try:
        address = proc.stdout.readline().strip()
        assert stub_for(address).GetState(pb.Empty(), timeout=10).success
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
        assert (proc.returncode, out) == (0, "closed\n")  # closed before Ctrl-C went on
        with pytest.raises(grpc.RpcError) as failed:
            stub_for(address).GetState(pb.Empty(), timeout=2)
        assert failed.value.code() == grpc.StatusCode.UNAVAILABLE
    finally:
        if proc.poll() is None:
            proc.kill()
