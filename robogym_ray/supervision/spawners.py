"""How a supervisor starts and stops robot servers: the ``ServerSpawner`` protocol, and the
spawner that keeps them in this process (tests and benchmarks without Ray; the Ray one is
``distributed/robot_actors.py``'s ``RaySpawner``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from robogym_ray.supervision.server_host import RobotServerHost, ServerSpec


@dataclass
class SpawnedServer:
    """One started robot server: where it listens and the spawner's handle to it."""

    address: str
    port: int
    pid: int
    ref: Any
    node_id: str = ""
    """Ray node the server runs on ("" outside Ray)."""


class ServerSpawner(Protocol):
    def spawn(self, spec: ServerSpec) -> SpawnedServer:
        """Start a server; raise on failure (it need not be answering yet)."""

    def kill(self, server: SpawnedServer) -> None:
        """Stop it for good, returning once its port is free again."""

    def inject_fault(self, server: SpawnedServer, fault: str, stall_s: float | None) -> None:
        """Testing hook, see ``server_host.FaultInjection``."""

    def activity(self, server: SpawnedServer) -> int:
        """How many client calls it has served (``RobotServerHost.activity``); grows when used."""


class InProcessSpawner:
    """Servers in this process (tests and benchmarks without Ray)."""

    def spawn(self, spec: ServerSpec) -> SpawnedServer:
        host = RobotServerHost(spec)
        info = host.info()
        return SpawnedServer(info["address"], info["port"], info["pid"], host)

    def kill(self, server: SpawnedServer) -> None:
        server.ref.stop()

    def inject_fault(self, server: SpawnedServer, fault: str, stall_s: float | None) -> None:
        server.ref.inject_fault(fault, stall_s)

    def activity(self, server: SpawnedServer) -> int:
        return server.ref.activity()
