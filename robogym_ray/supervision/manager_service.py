"""robo-gym's ``ServerManager`` gRPC service over a ``Supervisor`` (spec b and f).

robo-gym's client finds the manager by scanning ports 50100..50199 with VerifyConnection, asks
StartNewServer with a roslaunch-style ``cmd`` and then talks to ``<manager ip>:<port>``; so the
robot servers started here bind the manager's own interface. Replies follow the reference
manager: failures are ``success=false`` with the reason in ``info`` (robo-gym never reads it,
but a person debugging does), never a gRPC error.
"""

from __future__ import annotations

import logging
from concurrent import futures
from typing import Any

import grpc

from robogym_ray.errors import RoboGymRayError
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from robogym_ray.supervision.launch import parse_launch_cmd
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.supervisor import Supervisor

log = logging.getLogger(__name__)

OWNER = "manager"
"""``Supervisor`` owner tag of the servers started through this service."""


class ServerManagerService(sm_grpc.ServerManagerServicer):
    """StartNewServer / KillServer / KillAllServers / VerifyConnection over a supervisor.

    Args:
        supervisor: starts, watches and kills the robot servers.
        host: the interface the manager listens on; robot servers bind it too.
        node: node IP to place robot servers on (the manager's node), or None.
    """

    def __init__(self, supervisor: Supervisor, host: str, node: str | None = None) -> None:
        self.supervisor = supervisor
        self.host = host
        self.node = node

    def StartNewServer(self, request: sm.RobotServer, context: Any) -> sm.RobotServer:  # noqa: N802
        try:
            launch = parse_launch_cmd(request.cmd)
            spec = ServerSpec(
                robot=launch.robot, options=launch.options, host=self.host, node=self.node
            )
            info = self.supervisor.start_server(spec, owner=OWNER, keep_port=True)
        except RoboGymRayError as exc:
            log.warning("StartNewServer(%r) failed: %s", request.cmd, exc)
            return sm.RobotServer(success=False, info=f"{type(exc).__name__}: {exc}")
        except Exception as exc:  # noqa: BLE001 - robo-gym expects success=false, not an error
            log.exception("StartNewServer(%r) failed", request.cmd)
            return sm.RobotServer(success=False, info=f"{type(exc).__name__}: {exc}")
        log.info("StartNewServer: %s on port %d (gui ignored)", launch.robot, info["port"])
        return sm.RobotServer(
            cmd=request.cmd,
            port=info["port"],
            success=True,
            info=f"{launch.robot} at {info['address']}, id {info['id']}",
        )

    def KillServer(self, request: sm.RobotServer, context: Any) -> sm.RobotServer:  # noqa: N802
        # Idempotent: robo-gym kills from __del__ too, so double and unknown kills are normal.
        killed = self.supervisor.kill_port(request.port)
        info = (
            f"stopped the server on port {request.port}"
            if killed
            else (f"no server on port {request.port} (already stopped?)")
        )
        return sm.RobotServer(port=request.port, success=True, info=info)

    def KillAllServers(self, request: sm.RobotServer, context: Any) -> sm.RobotServer:  # noqa: N802
        count = self.supervisor.kill_all(owner=OWNER)
        return sm.RobotServer(success=True, info=f"stopped {count} server(s)")

    def VerifyConnection(self, request: sm.Empty, context: Any) -> sm.Status:  # noqa: N802
        return sm.Status(alive=True)


def serve_manager(
    supervisor: Supervisor, host: str = "127.0.0.1", port: int = 50100, node: str | None = None
) -> tuple[grpc.Server, int]:
    """Start the ServerManager service on ``host:port``; returns the server and the bound port.

    Raises:
        OSError: the port could not be bound.
    """
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=16))
    sm_grpc.add_ServerManagerServicer_to_server(
        ServerManagerService(supervisor, host, node), server
    )
    bound = server.add_insecure_port(f"[{host}]:{port}" if ":" in host else f"{host}:{port}")
    if bound == 0:
        raise OSError(f"could not bind the server manager to {host}:{port}")
    server.start()
    return server, bound
