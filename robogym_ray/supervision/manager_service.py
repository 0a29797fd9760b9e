"""robo-gym's ``ServerManager`` gRPC service over a ``Supervisor`` (spec b and f).

robo-gym's client finds the manager by scanning ports 50100..50199 with VerifyConnection, asks
StartNewServer with a roslaunch-style ``cmd`` and then talks to ``<manager ip>:<port>``; so the
robot servers started here bind the manager's own interface. Replies follow the reference
manager: failures are ``success=false`` with a one-line reason in ``info`` (robo-gym never
reads it, but a person debugging does), never a gRPC error.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from typing import Any

import grpc

from robogym_ray.errors import RoboGymRayError
from robogym_ray.protocol import server_manager_pb2 as sm
from robogym_ray.protocol import server_manager_pb2_grpc as sm_grpc
from robogym_ray.protocol.tls import ServerTls
from robogym_ray.robots.ports import grpc_server, listen
from robogym_ray.robots.registry import check_options
from robogym_ray.supervision.launch import LaunchSpec, parse_launch_cmd
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.supervisor import Supervisor
from robogym_ray.text import clip_text, reason

log = logging.getLogger(__name__)

OWNER = "manager"
"""``Supervisor`` owner tag of the servers started through this service."""
SPARE_THREADS = 8
"""gRPC threads no StartNewServer may take: VerifyConnection and kills are answered meanwhile."""


@dataclass(frozen=True)
class ManagerLimits:
    """How many robot servers the manager runs and starts at once (``ManagerConfig`` fields)."""

    max_servers: int = 32
    """Robot servers this manager runs at most; a StartNewServer beyond is refused at once."""
    max_concurrent_starts: int = 2
    """Servers started at the same time (each start is a process loading PyBullet: CPU-bound)."""
    max_waiting_starts: int = 8
    """StartNewServer calls that may wait for a start slot; more are refused at once."""
    start_wait_s: float = 3.0
    """Seconds a StartNewServer waits for a start slot before it is refused ('busy')."""


def _running(entries: list[dict[str, Any]]) -> int:
    return sum(
        1 for e in entries if e["owner"] == OWNER and e["state"] in ("running", "restarting")
    )


class ServerManagerService(sm_grpc.ServerManagerServicer):
    """StartNewServer / KillServer / KillAllServers / VerifyConnection over a supervisor.

    Args:
        supervisor: starts, watches and kills the robot servers.
        host: the interface the manager listens on; robot servers bind it too.
        node: node IP to place robot servers on (the manager's node), or None.
        limits: how many servers it runs and starts at once.
    """

    def __init__(
        self,
        supervisor: Supervisor,
        host: str,
        node: str | None = None,
        limits: ManagerLimits | None = None,
    ) -> None:
        self.supervisor = supervisor
        self.host = host
        self.node = node
        self.limits = limits or ManagerLimits()
        self._started_ports: set[int] = set()  # every port handed out; see KillServer
        self._slots = threading.BoundedSemaphore(self.limits.max_concurrent_starts)
        self._admit_lock = threading.Lock()
        self._admitted = 0  # StartNewServer calls past validation: waiting for a slot or starting

    def StartNewServer(self, request: sm.RobotServer, context: Any) -> sm.RobotServer:  # noqa: N802
        try:
            # Refuse bad commands and options here, with the robot's own option parser: a robot
            # server process started only to fail costs seconds and its error is a traceback.
            launch = parse_launch_cmd(request.cmd)
            check_options(launch.robot, None, launch.options)
        except RoboGymRayError as exc:
            return self._refuse(request.cmd, exc)
        # Answer at once when full or crowded: robo-gym's client retries a refused start (10
        # times), while a call that blocks holds one of a fixed number of gRPC threads.
        limits = self.limits
        with self._admit_lock:
            running = _running(self.supervisor.status())
            if running + self._admitted >= limits.max_servers:
                return self._refuse(request.cmd, f"manager full: {running} robot servers running "
                    f"and {self._admitted} starting, max_servers {limits.max_servers}; stop one "
                    "(KillServer) or wait for idle ones to be stopped")  # fmt: skip
            if self._admitted >= limits.max_concurrent_starts + limits.max_waiting_starts:
                return self._busy(request.cmd)
            self._admitted += 1
        try:
            if not self._slots.acquire(timeout=limits.start_wait_s):
                return self._busy(request.cmd)
            try:
                return self._start(request.cmd, launch)
            finally:
                self._slots.release()
        finally:
            with self._admit_lock:
                self._admitted -= 1

    def _start(self, cmd: str, launch: LaunchSpec) -> sm.RobotServer:
        spec = ServerSpec(
            robot=launch.robot, options=launch.options, host=self.host, node=self.node
        )
        try:
            info = self.supervisor.start_server(spec, owner=OWNER, keep_port=True, reap_idle=True)
        except Exception as exc:  # noqa: BLE001 - robo-gym expects success=false, not an error
            log.exception("StartNewServer(%r) failed", cmd)
            return self._refuse(cmd, exc)
        self._started_ports.add(info["port"])
        log.info("StartNewServer: %s on port %d (gui ignored)", launch.robot, info["port"])
        return sm.RobotServer(
            cmd=cmd,
            port=info["port"],
            success=True,
            info=f"{launch.robot} at {info['address']}, id {info['id']}",
        )

    def _busy(self, cmd: str) -> sm.RobotServer:
        return self._refuse(cmd, f"manager busy: {self._admitted} starts in progress or waiting "
            f"for one of {self.limits.max_concurrent_starts} start slots; try again")  # fmt: skip

    def _refuse(self, cmd: str, why: BaseException | str) -> sm.RobotServer:
        # One line, no traceback: the reply goes to any client (robo-gym prints it whole).
        info = reason(why if isinstance(why, str) else f"{type(why).__name__}: {why}")
        log.warning("StartNewServer(%s) refused: %s", clip_text(repr(cmd), 300), info)
        return sm.RobotServer(cmd=cmd, success=False, info=info)

    def KillServer(self, request: sm.RobotServer, context: Any) -> sm.RobotServer:  # noqa: N802
        port = request.port
        if self.supervisor.kill_port(port):
            return sm.RobotServer(
                port=port, success=True, info=f"stopped the server on port {port}"
            )
        # robo-gym's client kills from __del__ as well as from close(), retries a kill answered
        # success=false and then raises; so a port this manager started and already stopped
        # (a double kill, or an idle server reaped) is success=true, and only a port it never
        # started is success=false.
        if port in self._started_ports:
            return sm.RobotServer(
                port=port, success=True, info=f"the server on port {port} was already stopped"
            )
        return sm.RobotServer(
            port=port, success=False, info=f"this manager never started a server on port {port}"
        )

    def KillAllServers(self, request: sm.RobotServer, context: Any) -> sm.RobotServer:  # noqa: N802
        count = self.supervisor.kill_all(owner=OWNER)
        return sm.RobotServer(success=True, info=f"stopped {count} server(s)")

    def VerifyConnection(self, request: sm.Empty, context: Any) -> sm.Status:  # noqa: N802
        return sm.Status(alive=True)


def serve_manager(
    supervisor: Supervisor,
    host: str = "127.0.0.1",
    port: int = 50100,
    node: str | None = None,
    limits: ManagerLimits | None = None,
    tls: ServerTls | None = None,
) -> tuple[grpc.Server, int]:
    """Start the ServerManager service on ``host:port``; returns the server and the bound port.

    ``tls`` serves it over TLS (robo-gym's own client, which has no TLS, then cannot use it).

    Raises:
        PortInUseError: the port is held (by another manager, robot server or any program);
            robo-gym's client would otherwise reach either manager.
        BindError: the port cannot be bound for another reason.
    """
    service = ServerManagerService(supervisor, host, node, limits)
    # Starts hold at most max_concurrent_starts + max_waiting_starts threads; the spare ones
    # keep VerifyConnection (robo-gym's discovery, 20 s deadline) and kills answered meanwhile.
    starts = service.limits.max_concurrent_starts + service.limits.max_waiting_starts
    server = grpc_server(starts + SPARE_THREADS)
    sm_grpc.add_ServerManagerServicer_to_server(service, server)
    credentials = tls.credentials() if tls else None
    bound = listen(server, host, port, "server manager port", credentials)
    server.start()
    return server, bound
