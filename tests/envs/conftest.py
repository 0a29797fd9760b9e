"""Fixtures for env tests: a scriptable fake robot server (no PyBullet) and subprocess servers."""

from __future__ import annotations

import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from concurrent import futures
from typing import Any

import grpc
import pytest

from robogym_ray import children
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.protocol import robot_server_pb2_grpc as pb_grpc


class FakeRobotServer(pb_grpc.RobotServerServicer):
    """Answers every RPC with ``reply(rpc, request, context)``; records the requests."""

    def __init__(self, reply: Callable[[str, Any, grpc.ServicerContext], Any]) -> None:
        self.reply = reply
        self.requests: list[tuple[str, Any]] = []

    def _answer(self, rpc: str, request: Any, context: grpc.ServicerContext) -> Any:
        self.requests.append((rpc, request))
        return self.reply(rpc, request, context)

    def GetState(self, request, context):  # noqa: N802
        return self._answer("GetState", request, context)

    def SetState(self, request, context):  # noqa: N802
        return self._answer("SetState", request, context)

    def SendAction(self, request, context):  # noqa: N802
        return self._answer("SendAction", request, context)

    def SendActionGetState(self, request, context):  # noqa: N802
        return self._answer("SendActionGetState", request, context)


@pytest.fixture
def fake_server() -> Iterator[Callable[..., tuple[str, FakeRobotServer]]]:
    """``start(reply) -> (address, servicer)``; every server started is stopped afterwards."""
    servers: list[grpc.Server] = []

    def start(
        reply: Callable[[str, Any, grpc.ServicerContext], Any],
    ) -> tuple[str, FakeRobotServer]:
        servicer = FakeRobotServer(reply)
        server = grpc.server(futures.ThreadPoolExecutor(max_workers=4))
        pb_grpc.add_RobotServerServicer_to_server(servicer, server)
        port = server.add_insecure_port("127.0.0.1:0")
        server.start()
        servers.append(server)
        return f"127.0.0.1:{port}", servicer

    yield start
    for server in servers:
        server.stop(0)


def success_for(rpc: str, state: pb.State) -> Any:
    return pb.Success(success=True) if rpc in ("SetState", "SendAction") else state


@pytest.fixture
def serve_subprocess() -> Iterator[Callable[..., str]]:
    """``start(robot, *args) -> address`` of a ``robogym-ray serve`` child process."""
    procs: list[subprocess.Popen[str]] = []

    def start(robot: str, *args: str) -> str:
        cmd = [sys.executable, "-m", "robogym_ray.cli", "serve", "--robot", robot, "--port", "0"]
        proc = children.popen([*cmd, *args], stdout=subprocess.PIPE, text=True)
        procs.append(proc)
        deadline = time.monotonic() + 60
        assert proc.stdout is not None
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if line.startswith("listening on "):
                return line.split()[-1]
            if not line and proc.poll() is not None:
                break
        raise RuntimeError(f"robogym-ray serve did not start (rc={proc.poll()})")

    yield start
    for proc in procs:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def check_env_warnings(env: Any, known: Iterable[str]) -> list[str]:
    """Gymnasium's ``check_env`` on ``env``: the warnings it gives beyond the ``known`` ones
    (each named by a piece of its text); raises what check_env raises."""
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    return [str(w.message) for w in caught if not any(k in str(w.message) for k in known)]
