"""One port, one server: robot servers and the server manager bind their port exclusively.

gRPC sets SO_REUSEPORT by default, so a second server on a port a first one listens on used to
bind as well, and the kernel spread new connections over both: clients of one address reached
two robots. Real servers on 127.0.0.1 and real ``robogym-ray`` subprocesses throughout.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import grpc
import numpy as np
import pytest

from robogym_ray import children
from robogym_ray.errors import PortInUseError
from robogym_ray.foreground import STOP_DEADLINE_S
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from robogym_ray.robots.serve import serve_process
from robogym_ray.robots.server import RobotServerHandle, start_robot_server
from robogym_ray.supervision.manager_service import serve_manager
from robogym_ray.supervision.server_host import RobotServerHost, ServerSpec
from robogym_ray.supervision.spawners import InProcessSpawner
from robogym_ray.supervision.supervisor import Supervisor, SupervisorConfig


def mir_state(x: float) -> pb.State:
    """A MiR100 state whose pose x tells the servers apart."""
    state = np.zeros(1030, dtype=np.float32)
    state[0:3], state[3:6] = (2.0, 0.0, 0.0), (x, -2.5, 0.0)
    state[1021:1030] = [-2.0, 0.0, 0.0, 0.0, 0.5, 0.0, 2.0, -0.5, 0.0]
    return pb.State(state=state.tolist())


def pose_x_seen_by_a_fresh_client(address: str) -> float:
    """GetState through a new channel (a new TCP connection): the kernel picks its listener."""
    with grpc.insecure_channel(address) as channel:
        msg = pb_grpc.RobotServerStub(channel).GetState(pb.Empty(), timeout=10)
    assert msg.success
    return float(msg.state[3])


@pytest.fixture
def mir() -> Iterator[RobotServerHandle]:
    handle = start_robot_server("mir100", scene="lab_6x8", seed=0)
    yield handle
    handle.stop()


@pytest.fixture
def plain_listener() -> Iterator[int]:
    """A port held by a plain (non-gRPC) listening socket, as any other program would."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen()
        yield int(sock.getsockname()[1])


def test_a_second_robot_server_on_a_held_port_is_refused(mir: RobotServerHandle) -> None:
    with pytest.raises(PortInUseError, match=rf"\b{mir.port}\b") as caught:
        second = start_robot_server("mir100", scene="lab_6x8", seed=1, port=mir.port)
        second.stop()  # before the fix it bound; stop it so it cannot outlive the test
    assert caught.value.port == mir.port
    assert isinstance(caught.value, OSError)  # server_host's keep-port fallback catches OSError
    # Every fresh client of that address reaches the first robot, and only it.
    with grpc.insecure_channel(mir.address) as channel:
        assert pb_grpc.RobotServerStub(channel).SetState(mir_state(1.25), timeout=10).success
    seen = [pose_x_seen_by_a_fresh_client(mir.address) for _ in range(20)]
    assert seen == pytest.approx([1.25] * 20, abs=1e-5)


def test_a_robot_server_on_a_port_a_plain_socket_holds_is_refused(plain_listener: int) -> None:
    with pytest.raises(PortInUseError, match=rf"\b{plain_listener}\b"):
        start_robot_server("mir100", port=plain_listener).stop()


def test_a_second_server_manager_on_a_held_port_is_refused() -> None:
    sup = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
    first, port = serve_manager(sup, "127.0.0.1", 0)
    try:
        with pytest.raises(PortInUseError, match=rf"\b{port}\b"):
            serve_manager(sup, "127.0.0.1", port)[0].stop(grace=None)
        # The one manager there still answers.
        with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
            stub = sm_grpc.ServerManagerStub(channel)
            assert stub.VerifyConnection(sm.Empty(), timeout=10).alive
    finally:
        first.stop(grace=None)
        sup.shutdown()


def test_a_server_manager_on_a_port_a_plain_socket_holds_is_refused(plain_listener: int) -> None:
    sup = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
    try:
        with pytest.raises(PortInUseError, match=rf"\b{plain_listener}\b"):
            serve_manager(sup, "127.0.0.1", plain_listener)[0].stop(grace=None)
    finally:
        sup.shutdown()


def run_cli(
    *args: str, timeout_s: float = 60.0, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess:
    return children.run(
        [sys.executable, "-m", "robogym_ray.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        env={**os.environ, "RAY_ADDRESS": "", **(env or {})},
    )


def assert_one_line_naming(out: subprocess.CompletedProcess, port: int) -> None:
    assert out.returncode == 2, out.stderr
    lines = out.stderr.splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("error: ") and f" {port} " in lines[0], lines[0]
    assert "listening on" not in out.stdout


def test_serve_cli_on_a_port_another_serve_holds_exits_2_with_one_line() -> None:
    with serve_process(["--robot", "mir100", "--port", "0"]) as address:
        port = int(address.rsplit(":", 1)[1])
        out = run_cli("serve", "--robot", "mir100", "--port", str(port))
        assert_one_line_naming(out, port)
        pose_x_seen_by_a_fresh_client(address)  # the first one still serves


def test_serve_cli_on_a_port_a_plain_socket_holds_exits_2_with_one_line(
    plain_listener: int,
) -> None:
    assert_one_line_naming(run_cli("serve", "--robot", "mir100", "--port", str(plain_listener)),
                           plain_listener)  # fmt: skip


def test_manager_cli_on_a_held_port_exits_2_with_one_line_before_starting_ray(
    plain_listener: int, tmp_path: Path
) -> None:
    # Refused up front, not after a Ray start: a Ray started here would have made its session
    # folder under RAY_TMPDIR (Ray's own setting for where its files go).
    ray_files = tmp_path / "ray-tmp"
    out = run_cli("manager", "--port", str(plain_listener), "--num-cpus", "1",
                  env={"RAY_TMPDIR": str(ray_files)})  # fmt: skip
    assert_one_line_naming(out, plain_listener)
    assert not ray_files.exists(), sorted(p.name for p in ray_files.rglob("*"))[:10]


def test_manager_cli_on_a_port_our_grpc_server_holds_exits_2_with_one_line() -> None:
    sup = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
    first, port = serve_manager(sup, "127.0.0.1", 0)
    try:
        out = run_cli("manager", "--port", str(port), "--num-cpus", "1")
        assert_one_line_naming(out, port)
    finally:
        first.stop(grace=None)
        sup.shutdown()


def time_wait_ports() -> set[int]:
    """Local ports of TCP connections in TIME_WAIT (state 06 in /proc/net/tcp*)."""
    ports = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as rows:
            for row in rows.readlines()[1:]:
                local, state = row.split()[1], row.split()[3]
                if state == "06":
                    ports.add(int(local.rsplit(":", 1)[1], 16))
    return ports


@pytest.mark.skipif(not os.path.exists("/proc/net/tcp"), reason="reads Linux's /proc/net/tcp")
def test_a_server_binds_a_port_its_stopped_predecessor_left_in_time_wait() -> None:
    """Exclusive binding keeps SO_REUSEADDR: connections a server closed first stay in TIME_WAIT
    on its port for a minute, and a keep-port restart must still bind it."""
    with socket.socket() as listener:  # like gRPC's listener: SO_REUSEADDR, closes first
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        port = int(listener.getsockname()[1])
        with socket.create_connection(("127.0.0.1", port)) as client:
            accepted, _ = listener.accept()
            accepted.close()  # the server side closes first: TIME_WAIT is on `port`
            client.recv(1)
    assert port in time_wait_ports()
    handle = start_robot_server("mir100", port=port)
    try:
        assert handle.port == port
        pose_x_seen_by_a_fresh_client(handle.address)  # it serves
    finally:
        handle.stop()


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGKILL])
def test_a_server_restarts_on_the_port_its_dead_predecessor_used(
    stop_signal: int, tmp_path: Path
) -> None:
    """The supervisor's keep-port restart: once the old process is gone (stopped, or killed
    with a client still connected), a new server binds the same port. A stopped one exits
    cleanly; one whose stop hangs dumps its stacks to stderr at its deadline (shown here)."""
    cmd = [sys.executable, "-m", "robogym_ray.cli", "serve", "--robot", "mir100", "--port", "0"]
    stderr = tmp_path / "stderr.txt"
    with stderr.open("w") as err:
        old = children.popen(cmd, stdout=subprocess.PIPE, stderr=err, text=True)
    connected = None
    try:
        address = old.stdout.readline().strip().removeprefix("listening on ")  # type: ignore[union-attr]
        port = int(address.rsplit(":", 1)[1])
        connected = grpc.insecure_channel(address)  # a client that stays through the restart
        assert pb_grpc.RobotServerStub(connected).GetState(pb.Empty(), timeout=10).success
        old.send_signal(stop_signal)
        old.wait(timeout=STOP_DEADLINE_S + 30)
        if stop_signal == signal.SIGTERM:
            assert old.returncode == 0, stderr.read_text()[-4000:]
        with serve_process(["--robot", "mir100", "--port", str(port)]) as again:
            assert again == address
            with grpc.insecure_channel(again) as channel:
                stub = pb_grpc.RobotServerStub(channel)
                assert stub.SetState(mir_state(0.5), timeout=10).success
            assert pose_x_seen_by_a_fresh_client(again) == pytest.approx(0.5, abs=1e-5)
    finally:
        if connected is not None:
            connected.close()
        if old.poll() is None:
            old.kill()
            old.wait()


def test_a_keep_port_restart_rebinds_the_same_port() -> None:
    """The supervisor's restart for robo-gym's clients (``keep_port``): the old server is
    stopped, then the new one binds its port, exclusively."""
    sup = Supervisor(SupervisorConfig(probe_interval_s=0), InProcessSpawner())
    try:
        info = sup.start_server(ServerSpec("mir100"), keep_port=True)
        with grpc.insecure_channel(info["address"]) as channel:  # stays open through it
            stub = pb_grpc.RobotServerStub(channel)
            assert stub.SetState(mir_state(1.5), timeout=10).success
            again = sup.restart(info["id"])
            assert again["port"] == info["port"] and again["state"] == "running"
            assert stub.SetState(mir_state(0.75), timeout=10).success
        assert pose_x_seen_by_a_fresh_client(info["address"]) == pytest.approx(0.75, abs=1e-5)
    finally:
        sup.shutdown()


def test_a_server_host_whose_port_is_held_falls_back_to_a_free_port(plain_listener: int) -> None:
    """A keep-port restart whose port something else took serves on a free port rather than
    not at all: the refusal is an OSError, which ``RobotServerHost`` catches (gRPC's own
    RuntimeError slipped past it)."""
    host = RobotServerHost(ServerSpec("mir100", port=plain_listener))
    try:
        assert host.info()["port"] not in (0, plain_listener)
        pose_x_seen_by_a_fresh_client(host.handle.address)  # it serves
    finally:
        host.stop()
