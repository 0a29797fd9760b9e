"""The ServerManager service over in-process robot servers, called through real gRPC (no Ray).

What robo-gym's client meets at the manager's edge (issue 20, items 3 and 5): bad launch
commands and options refused before anything starts, with one short line; kill replies its
client can live with; a full or busy manager answering at once; idle servers reclaimed.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import grpc
import pytest

from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from robogym_ray.supervision.manager_service import serve_manager
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.supervisor import (
    InProcessSpawner,
    SpawnedServer,
    Supervisor,
    SupervisorConfig,
)

UR5 = "roslaunch ur_robot_server ur_robot_server.launch ur_model:=ur5"
MIR = "roslaunch mir100_robot_server sim_robot_server.launch world_name:=empty_world_target.world"


class CountingSpawner(InProcessSpawner):
    """In-process servers, counting how many were started."""

    def __init__(self) -> None:
        self.spawned = 0

    def spawn(self, spec: ServerSpec) -> SpawnedServer:
        self.spawned += 1
        return super().spawn(spec)


@pytest.fixture
def manager() -> Iterator[tuple[Any, CountingSpawner]]:
    spawner = CountingSpawner()
    sup = Supervisor(SupervisorConfig(probe_interval_s=0), spawner)
    server, port = serve_manager(sup, "127.0.0.1", 0)
    channel = grpc.insecure_channel(f"127.0.0.1:{port}")
    try:
        yield sm_grpc.ServerManagerStub(channel), spawner
    finally:
        channel.close()
        server.stop(grace=None)
        sup.shutdown()


@pytest.mark.parametrize(
    ("cmd", "named"),
    [
        (f"{MIR} robot_x:=nan", "robot_x"),
        (f"{MIR} robot_y:=1e9", "robot_y"),
        (f"{UR5} action_cycle_rate:=0", "action_cycle_rate"),
        (f"{UR5} action_cycle_rate:=inf", "action_cycle_rate"),
        (f"{UR5} gripper:=true", "gripper"),
        (f"{MIR} speed:=2", "speed"),
        (f"{UR5} world_name:=moon.world", "moon.world"),
        (f"{MIR} {'x' * 100_000}:=1", "xxxx"),
        ("roslaunch ur_robot_server ur_robot_server.launch ur_model:=ur42", "ur42"),
        ("rosrun something", "roslaunch"),
    ],
)
def test_bad_commands_and_options_are_refused_before_anything_starts(
    manager: tuple[Any, CountingSpawner], cmd: str, named: str
) -> None:
    stub, spawner = manager
    reply = stub.StartNewServer(sm.RobotServer(cmd=cmd, gui=False), timeout=30)
    assert not reply.success
    assert named in reply.info
    assert "\n" not in reply.info and "\x1b" not in reply.info and "Traceback" not in reply.info
    assert len(reply.info) <= 500
    assert spawner.spawned == 0  # refused by the option parser, not by a failed server


def test_kill_replies_fit_robo_gym_s_client(manager: tuple[Any, CountingSpawner]) -> None:
    stub, _ = manager
    started = stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60)
    assert started.success, started.info
    first = stub.KillServer(sm.RobotServer(port=started.port), timeout=30)
    assert first.success and "stopped" in first.info
    # robo-gym's client kills again from __del__ and raises on success=false: still true.
    again = stub.KillServer(sm.RobotServer(port=started.port), timeout=30)
    assert again.success and "already stopped" in again.info
    never = stub.KillServer(sm.RobotServer(port=1), timeout=30)
    assert not never.success and "never started" in never.info
    assert "\n" not in never.info
