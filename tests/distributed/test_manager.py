"""robo-gym's ServerManager protocol against the supervisor, driven the way robo-gym drives it.

The client below is built from our generated stubs but follows robo-gym 2.0.1's
``server_manager.client.Client`` (spec b.2-b.6): port scan in ascending order with
VerifyConnection (20 s deadline), StartNewServer with the env's exact ``cmd``, then the robot
server at ``<manager ip>:<port>``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from typing import Any

import grpc
import pytest

from robogym_ray import children
from robogym_ray.protocol import robot_server_pb2 as rs
from robogym_ray.protocol import robot_server_pb2_grpc as rs_grpc
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from tests.distributed.conftest import free_port

ray = pytest.importorskip("ray")
pytestmark = [pytest.mark.ray, pytest.mark.usefixtures("ray_cluster")]

SP = " " * 9  # robo-gym's backslash-continuation runs (spec b.4)
MIR100_CMD = "roslaunch mir100_robot_server sim_robot_server.launch world_name:=lab_6x8.world"
UR10_CMD = (
    "roslaunch ur_robot_server ur_robot_server.launch"
    + SP
    + "world_name:=tabletop_sphere50_no_collision.world"
    + SP
    + "reference_frame:=base_link"
    + SP
    + "max_velocity_scale_factor:=0.1"
    + SP
    + "action_cycle_rate:=10"
    + SP
    + "rviz_gui:=true"
    + SP
    + "gazebo_gui:=true"
    + SP
    + "objects_controller:=true"
    + SP
    + "rs_mode:=1object"
    + SP
    + "n_objects:=1.0"
    + SP
    + "object_0_model_name:=sphere50_no_collision"
    + SP
    + "object_0_frame:=target ur_model:=ur10"
)


def scan_for_manager(ip: str, lower: int, upper: int) -> sm_grpc.ServerManagerStub:
    """robo-gym's discovery: the first port in range(lower, upper) answering VerifyConnection."""
    for port in range(lower, upper):
        channel = grpc.insecure_channel(f"{ip}:{port}")
        stub = sm_grpc.ServerManagerStub(channel)
        try:
            stub.VerifyConnection(sm.Empty(), timeout=20)
            return stub
        except grpc.RpcError:
            channel.close()
    raise RuntimeError("Failed to connect to Server Manager")


@pytest.fixture(scope="module")
def manager(ray_cluster: None) -> Any:
    from robogym_ray.distributed.robot_actors import start_supervisor
    from robogym_ray.supervision.supervisor import SupervisorConfig

    lower = free_port()
    actor = start_supervisor(
        SupervisorConfig(probe_interval_s=0.5),
        name="test-manager",
        manager_host="127.0.0.1",
        manager_port=lower + 2,  # lower, lower+1: refused, scanned past
    )
    assert ray.get(actor.serving_port.remote()) == lower + 2
    yield lower
    ray.get(actor.shutdown.remote())
    ray.kill(actor, no_restart=True)


def test_robo_gym_client_starts_drives_and_kills_mir100_and_ur10(manager: int) -> None:
    assert len(UR10_CMD) == 435  # the exact string robo-gym 2.0.1 sends
    stub = scan_for_manager("127.0.0.1", manager, manager + 5)
    mir = stub.StartNewServer(sm.RobotServer(cmd=MIR100_CMD, gui=False), timeout=240)
    ur = stub.StartNewServer(sm.RobotServer(cmd=UR10_CMD, gui=False), timeout=240)
    assert mir.success and ur.success, (mir.info, ur.info)

    mir_rs = rs_grpc.RobotServerStub(grpc.insecure_channel(f"127.0.0.1:{mir.port}"))
    state = mir_rs.GetState(rs.Empty(), timeout=20)
    assert state.success and len(state.state) == 1030
    assert mir_rs.SendAction(rs.Action(action=[0.2, 0.1]), timeout=20).success
    ur_rs = rs_grpc.RobotServerStub(grpc.insecure_channel(f"127.0.0.1:{ur.port}"))
    state = ur_rs.GetState(rs.Empty(), timeout=20)
    assert state.success and len(state.state) > 1 and len(state.state_dict) > 1
    after = ur_rs.SendActionGetState(rs.Action(action=[0.0] * 6), timeout=20)
    assert after.success

    for port in (mir.port, ur.port):
        assert stub.KillServer(sm.RobotServer(port=port), timeout=60).success
    with pytest.raises(grpc.RpcError):
        mir_rs.GetState(rs.Empty(), timeout=2)
    # A double kill is harmless (robo-gym kills from __del__ too and raises on success=false);
    # a port this manager never started is not.
    assert stub.KillServer(sm.RobotServer(port=mir.port), timeout=60).success
    assert not stub.KillServer(sm.RobotServer(port=1), timeout=60).success
    assert stub.VerifyConnection(sm.Empty(), timeout=20).alive


def test_unknown_robot_is_refused_with_an_explanation(manager: int) -> None:
    stub = scan_for_manager("127.0.0.1", manager, manager + 5)
    reply = stub.StartNewServer(
        sm.RobotServer(cmd="roslaunch panda_robot_server panda.launch"), timeout=240
    )
    assert not reply.success
    assert "panda.launch" in reply.info and "sim_robot_server.launch" in reply.info
    reply = stub.StartNewServer(
        sm.RobotServer(cmd="roslaunch ur_robot_server ur_robot_server.launch ur_model:=ur42")
    )
    assert not reply.success and "ur42" in reply.info
    # Bad options are refused before a robot-server actor starts: one short line, not the
    # actor's coloured traceback with its paths, PID and node IP.
    for option in ("robot_x:=nan", "action_cycle_rate:=0"):
        robot = "ur_robot_server ur_robot_server.launch ur_model:=ur5"
        if option.startswith("robot_x"):
            robot = "mir100_robot_server sim_robot_server.launch"
        reply = stub.StartNewServer(sm.RobotServer(cmd=f"roslaunch {robot} {option}"), timeout=60)
        assert not reply.success and option.split(":=")[0] in reply.info
        assert "\n" not in reply.info and "\x1b" not in reply.info and len(reply.info) <= 500
    assert stub.KillAllServers(sm.RobotServer()).success


def test_manager_command_serves_and_stops_on_sigterm() -> None:
    port = free_port()
    with tempfile.TemporaryDirectory(prefix="rgm", dir="/tmp") as tmp:
        env = {**os.environ, "RAY_TMPDIR": tmp, "RAY_ADDRESS": ""}
        proc = children.popen(
            [
                sys.executable,
                "-m",
                "robogym_ray.cli",
                "manager",
                "--port",
                str(port),
                "--num-cpus",
                "1",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env=env,
        )
        try:
            line = proc.stdout.readline()  # type: ignore[union-attr]
            assert line.strip() == f"listening on 127.0.0.1:{port}"
            stub = scan_for_manager("127.0.0.1", port, port + 1)
            reply = stub.StartNewServer(sm.RobotServer(cmd=MIR100_CMD.split(" world")[0]))
            assert reply.success, reply.info
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(timeout=60) == 0
            # The robot server it started is gone too: its actor ends with the manager's Ray,
            # a moment after the manager itself, how long a moment being the machine's.
            robot = rs_grpc.RobotServerStub(grpc.insecure_channel(f"127.0.0.1:{reply.port}"))
            hung = time.monotonic() + 60  # a guard against a hang, not a measure of speed
            with pytest.raises(grpc.RpcError):
                while time.monotonic() < hung:
                    robot.GetState(rs.Empty(), timeout=2)
                    time.sleep(0.1)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
