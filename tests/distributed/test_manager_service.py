"""The ServerManager service over in-process robot servers, called through real gRPC (no Ray).

What robo-gym's client meets at the manager's edge: bad launch
commands and options refused before anything starts, with one short line; kill replies its
client can live with; a full or busy manager answering at once; idle servers reclaimed.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import grpc
import pytest

from robogym_ray.protocol import robot_server_pb2 as rs
from robogym_ray.protocol import robot_server_pb2_grpc as rs_grpc
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from robogym_ray.supervision.manager_service import ManagerLimits, serve_manager
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.spawners import InProcessSpawner, SpawnedServer
from robogym_ray.supervision.supervisor import Supervisor, SupervisorConfig

UR5 = "roslaunch ur_robot_server ur_robot_server.launch ur_model:=ur5"
MIR = "roslaunch mir100_robot_server sim_robot_server.launch world_name:=empty_world_target.world"


class CountingSpawner(InProcessSpawner):
    """In-process servers, counting how many were started; ``delay_s`` makes starts slow (a
    loaded machine)."""

    def __init__(self, delay_s: float = 0.0) -> None:
        self.spawned = 0
        self.delay_s = delay_s

    def spawn(self, spec: ServerSpec) -> SpawnedServer:
        self.spawned += 1
        time.sleep(self.delay_s)
        return super().spawn(spec)


@pytest.fixture
def make_manager() -> Iterator[Callable[..., tuple[Any, CountingSpawner, Supervisor]]]:
    """``make_manager(limits, config, delay_s)`` -> (stub, spawner, supervisor) on a free port."""
    cleanup: list[Callable[[], None]] = []

    def make(
        limits: ManagerLimits | None = None,
        config: SupervisorConfig | None = None,
        delay_s: float = 0.0,
    ) -> tuple[Any, CountingSpawner, Supervisor]:
        spawner = CountingSpawner(delay_s)
        sup = Supervisor(config or SupervisorConfig(probe_interval_s=0), spawner)
        server, port = serve_manager(sup, "127.0.0.1", 0, limits=limits)
        channel = grpc.insecure_channel(f"127.0.0.1:{port}")
        cleanup.extend([sup.shutdown, lambda: server.stop(grace=None), channel.close])
        return sm_grpc.ServerManagerStub(channel), spawner, sup

    yield make
    for step in reversed(cleanup):
        step()


@pytest.fixture
def manager(make_manager: Callable[..., Any]) -> tuple[Any, CountingSpawner]:
    stub, spawner, _ = make_manager()
    return stub, spawner


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


def timed(call: Callable[[], Any]) -> tuple[Any, float]:
    began = time.monotonic()
    return call(), time.monotonic() - began


def test_a_full_manager_refuses_at_once_and_serves_again_after_a_kill(
    make_manager: Callable[..., Any],
) -> None:
    stub, spawner, _ = make_manager(ManagerLimits(max_servers=2))
    ports = [stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60).port for _ in range(2)]
    assert all(ports)
    reply, took = timed(lambda: stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60))
    assert not reply.success and "full" in reply.info and "max_servers 2" in reply.info
    assert took < 1.0 and spawner.spawned == 2
    assert stub.KillServer(sm.RobotServer(port=ports[0]), timeout=30).success
    assert stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60).success


def test_verify_connection_answers_while_starts_crowd_the_manager(
    make_manager: Callable[..., Any],
) -> None:
    # 24 concurrent starts of 1 s each, more than gRPC threads: each is answered within its
    # wait plus one start (served or "busy"), and VerifyConnection stays fast throughout.
    limits = ManagerLimits(max_concurrent_starts=2, max_waiting_starts=4, start_wait_s=1.0)
    stub, _, _ = make_manager(limits, delay_s=1.0)
    done = threading.Event()
    verify_times: list[float] = []

    def verify_loop() -> None:
        while not done.is_set():
            alive, took = timed(lambda: stub.VerifyConnection(sm.Empty(), timeout=20).alive)
            assert alive
            verify_times.append(took)
            time.sleep(0.05)

    verifier = threading.Thread(target=verify_loop)
    verifier.start()
    try:
        with ThreadPoolExecutor(max_workers=24) as pool:
            calls = [lambda: stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60)] * 24
            replies = list(pool.map(timed, calls))
    finally:
        done.set()
        verifier.join()
    served = [r for r, _ in replies if r.success]
    busy = [r for r, _ in replies if not r.success]
    assert served and busy and all("busy" in r.info for r in busy)
    assert max(took for _, took in replies) < 1.0 + 1.0 + 1.5  # wait + one start + slack
    assert verify_times and max(verify_times) < 0.5


def test_idle_servers_are_stopped_and_counted_busy_ones_kept(
    make_manager: Callable[..., Any],
) -> None:
    config = SupervisorConfig(probe_interval_s=0.1, idle_timeout_s=1.0)
    stub, _, sup = make_manager(config=config)
    idle, used = (stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60) for _ in range(2))
    robot = rs_grpc.RobotServerStub(grpc.insecure_channel(f"127.0.0.1:{used.port}"))
    end = time.monotonic() + 10
    while sup.reaped == 0 and time.monotonic() < end:
        assert robot.SendAction(rs.Action(action=[0.0, 0.0]), timeout=5).success
        time.sleep(0.2)
    assert sup.reaped == 1
    assert [s["port"] for s in sup.status()] == [used.port]
    with pytest.raises(grpc.RpcError):
        rs_grpc.RobotServerStub(grpc.insecure_channel(f"127.0.0.1:{idle.port}")).GetState(
            rs.Empty(), timeout=2
        )
    # its client's late KillServer (robo-gym's close() or __del__) is still answered success
    late = stub.KillServer(sm.RobotServer(port=idle.port), timeout=30)
    assert late.success and "already stopped" in late.info
