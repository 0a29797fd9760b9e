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
    """In-process servers, counting how many were started; a start waits for ``gate`` to be
    set (a start that takes as long as the test wants; set by default)."""

    def __init__(self) -> None:
        self.spawned = 0
        self.gate = threading.Event()
        self.gate.set()

    def spawn(self, spec: ServerSpec) -> SpawnedServer:
        self.spawned += 1
        assert self.gate.wait(timeout=300), "the test never let this start go"
        return super().spawn(spec)


def wait_for(condition: Callable[[], bool], what: str) -> None:
    """Until ``condition()``; a hang guard of 90 s, not a bound on speed."""
    deadline = time.monotonic() + 90
    while not condition():
        assert time.monotonic() < deadline, f"no {what} in 90 s"
        time.sleep(0.02)


@pytest.fixture
def make_manager() -> Iterator[Callable[..., tuple[Any, CountingSpawner, Supervisor]]]:
    """``make_manager(limits, config)`` -> (stub, spawner, supervisor) on a free port."""
    cleanup: list[Callable[[], None]] = []

    def make(
        limits: ManagerLimits | None = None,
        config: SupervisorConfig | None = None,
    ) -> tuple[Any, CountingSpawner, Supervisor]:
        spawner = CountingSpawner()
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


def test_a_full_manager_refuses_at_once_and_serves_again_after_a_kill(
    make_manager: Callable[..., Any],
) -> None:
    # One server running and a second start held in the only slot: full. "At once" is counted,
    # not timed: the refusal comes while the held start still holds the slot, and a refusal
    # that waited for the slot (start_wait_s 600) would outlive its call's 60-s deadline.
    limits = ManagerLimits(max_servers=2, max_concurrent_starts=1, start_wait_s=600.0)
    stub, spawner, _ = make_manager(limits)
    first = stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60)
    assert first.success, first.info
    spawner.gate.clear()
    with ThreadPoolExecutor(max_workers=1) as pool:
        held = pool.submit(stub.StartNewServer, sm.RobotServer(cmd=MIR), timeout=300)
        wait_for(lambda: spawner.spawned == 2, "second start")
        reply = stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60)
        assert not reply.success and "full" in reply.info and "max_servers 2" in reply.info
        assert "1 robot servers running and 1 starting" in reply.info
        assert not held.done() and spawner.spawned == 2
        spawner.gate.set()
        assert held.result().success
    assert stub.KillServer(sm.RobotServer(port=first.port), timeout=30).success
    assert stub.StartNewServer(sm.RobotServer(cmd=MIR), timeout=60).success


def test_verify_connection_answers_while_starts_crowd_the_manager(
    make_manager: Callable[..., Any],
) -> None:
    # 24 concurrent starts, more than gRPC threads, while the two in the start slots are held:
    # the 4 that may wait are refused "busy" after their 1-s wait, the other 18 at once, and
    # VerifyConnection is answered throughout, all before either held start is let go (counted,
    # not timed: a call that waited for a start would wait for ever).
    limits = ManagerLimits(max_concurrent_starts=2, max_waiting_starts=4, start_wait_s=1.0)
    stub, spawner, _ = make_manager(limits)
    spawner.gate.clear()
    verified: list[bool] = []

    def verify_loop() -> None:
        while not spawner.gate.is_set():
            verified.append(stub.VerifyConnection(sm.Empty(), timeout=20).alive)
            time.sleep(0.05)

    verifier = threading.Thread(target=verify_loop)
    with ThreadPoolExecutor(max_workers=24) as pool:
        calls = [
            pool.submit(stub.StartNewServer, sm.RobotServer(cmd=MIR), timeout=300)
            for _ in range(24)
        ]
        verifier.start()
        try:
            wait_for(lambda: sum(call.done() for call in calls) == 22, "22 replies")
            refused = [call.result() for call in calls if call.done()]
            assert all(not r.success and "busy" in r.info for r in refused), refused
            assert spawner.spawned == 2
            assert stub.VerifyConnection(sm.Empty(), timeout=20).alive  # both starts still held
        finally:
            spawner.gate.set()
            verifier.join()
        served = [call.result() for call in calls if call.result().success]
    assert len(served) == 2 and spawner.spawned == 2
    assert verified and all(verified)


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
