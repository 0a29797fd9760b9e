"""The Ray edge, robot side: the supervisor, the robot-server and the real-robot actors
(``remote.py`` is the learning side). Apart from it because a Ray actor's process imports the
module its class is defined in, and this side must not import torch: each robot server is a
process of its own, a manager starts dozens, and torch would add its import time and memory to
every one of them (``tests/test_layers.py`` checks that it stays out).

Ray mechanisms used, and why:

* **Ownership / fate sharing**: the supervisor actor creates the robot-server actors, so it owns
  them; if the supervisor dies its servers die with it - no leaked simulations. The supervisor
  itself has ``max_restarts`` (Ray restarts it, and it re-serves the ServerManager port).
* **Robot-server actors have ``max_restarts=0``**: their restarts need a per-cause count, backoff,
  a give-up limit and a readiness check before the new address is handed out, which Ray's
  automatic restart does not give; the supervisor ``ray.kill``s and re-creates them instead.
* **Named actors** (namespace ``robogym-ray``): the supervisor and each real robot can be found
  from any driver (``SupervisorServerProvider``, ``robogym-ray resume-robot NAME``).
* **Real-robot actors have ``max_restarts=0``** and are never restarted by anything.
* Fractional ``num_cpus``: these actors mostly wait on sockets.
"""

from __future__ import annotations

import logging
import os
import re
import time
from typing import Any

import ray
from ray.exceptions import GetTimeoutError, RayActorError

from robogym_ray.distributed.names import NAMESPACE, SUPERVISOR_NAME
from robogym_ray.errors import RobotServerError
from robogym_ray.protocol.tls import ServerTls
from robogym_ray.realrobot.robot import RealRobot
from robogym_ray.realrobot.safety import SafetyConfig
from robogym_ray.supervision.manager_service import ManagerLimits, serve_manager
from robogym_ray.supervision.server_host import RobotServerHost, ServerSpec
from robogym_ray.supervision.spawners import SpawnedServer
from robogym_ray.supervision.supervisor import Supervisor, SupervisorConfig

log = logging.getLogger(__name__)


def _alive_nodes() -> int:
    return sum(1 for node in ray.nodes() if node.get("Alive"))


def _wait_for_exit(pid: int, deadline: float) -> None:
    """Wait (until ``deadline``) for process ``pid`` on this node to exit."""
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return
        except PermissionError:  # alive, but not ours to signal
            pass
        time.sleep(0.05)


class _RayRobotServerHost(RobotServerHost):
    def info(self) -> dict[str, Any]:
        return {**super().info(), "node_id": ray.get_runtime_context().get_node_id()}

    def bind_host(self, host: str) -> str:
        # Other nodes must reach us on a cluster; on one machine loopback exposes nothing.
        if host != "auto":
            return host
        return "127.0.0.1" if _alive_nodes() <= 1 else ray.util.get_node_ip_address()


RobotServerActor = ray.remote(num_cpus=0.25, max_restarts=0)(_RayRobotServerHost)


class RaySpawner:
    """Starts each robot server as a robot-server actor (placed by ``spec.node``/``resources``)."""

    def __init__(self, config: SupervisorConfig) -> None:
        self.config = config

    def spawn(self, spec: ServerSpec) -> SpawnedServer:
        resources = dict(spec.resources)
        if spec.node:
            resources[f"node:{spec.node}"] = 0.001  # Ray's built-in per-node resource
        options: dict[str, Any] = {"num_cpus": self.config.server_num_cpus}
        if resources:
            options["resources"] = resources
        actor = RobotServerActor.options(**options).remote(spec)
        try:
            info = ray.get(actor.info.remote(), timeout=self.config.start_timeout_s)
        except Exception:
            ray.kill(actor, no_restart=True)
            raise
        return SpawnedServer(
            info["address"], info["port"], info["pid"], actor, node_id=info.get("node_id", "")
        )

    def kill(self, server: SpawnedServer) -> None:
        # Close the gRPC port first, in the actor: Ray may report an actor dead while its
        # process (and the gRPC threads in it) still lives for a moment, so "ping fails" alone
        # does not mean "port closed". A hung or dead actor cannot stop itself; the kill below
        # still ends it.
        try:
            ray.get(server.ref.stop.remote(), timeout=5.0)
        except Exception:  # noqa: BLE001 - hung or gone already; ray.kill follows either way
            log.debug("graceful stop of %s failed", server.address, exc_info=True)
        ray.kill(server.ref, no_restart=True)
        # Wait until the process is gone: a restart may rebind its port, and servers bind it
        # exclusively, so while the old one lives the new bind fails (and RobotServerHost
        # falls back to a free port, which robo-gym's client cannot follow).
        end = time.monotonic() + 10.0
        while time.monotonic() < end:
            try:
                ray.get(server.ref.ping.remote(), timeout=1.0)
            except RayActorError:
                break
            except GetTimeoutError:
                continue
            time.sleep(0.05)
        if server.node_id == ray.get_runtime_context().get_node_id():
            _wait_for_exit(server.pid, end)

    def inject_fault(self, server: SpawnedServer, fault: str, stall_s: float | None) -> None:
        ray.get(server.ref.inject_fault.remote(fault, stall_s))

    def activity(self, server: SpawnedServer) -> int:
        return ray.get(server.ref.activity.remote(), timeout=self.config.probe_deadline_s)


RealRobotActor = ray.remote(num_cpus=0.05, max_restarts=0, max_concurrency=4)(RealRobot)


def start_real_robot(
    name: str,
    address: str,
    safety: SafetyConfig,
    token: str | None = None,
    probe_interval_s: float = 2.0,
    tls_ca: bytes | None = None,
) -> Any:
    """Join the real robot at ``address`` as the named actor ``name`` (health-checked now,
    then whenever it has had no command for ``probe_interval_s``). ``tls_ca``: the PEM (bytes,
    read where the command runs, so no node needs the file) of its server's TLS CA."""
    actor = RealRobotActor.options(name=name, namespace=NAMESPACE).remote(
        name, address, safety, token=token, probe_interval_s=probe_interval_s, tls_ca=tls_ca
    )
    try:
        ray.get(actor.status.remote())  # surfaces a failed health check here, not later
    except RayActorError as exc:
        if not exc.actor_init_failed:
            raise
        # One line (a TLS refusal, a wrong token, no server), not the constructor's traceback.
        raise RobotServerError(
            f"real robot {name!r} could not join: {creation_error(exc)}", cause="start"
        ) from None
    return actor


def creation_error(exc: BaseException) -> str:
    """What an actor's constructor raised, in one line: Ray's error holds the whole traceback,
    whose last line is the error itself (``TlsError: ...``, its module path dropped)."""
    last = (str(exc).strip().splitlines() or [type(exc).__name__])[-1]
    return re.sub(r"^(?:\w+\.)+(?=\w+: )", "", last)


def get_real_robot(name: str) -> Any:
    return ray.get_actor(name, namespace=NAMESPACE)


class _RaySupervisor(Supervisor):
    def __init__(
        self,
        config: SupervisorConfig,
        manager_host: str | None = None,
        manager_port: int = 50100,
        manager_limits: ManagerLimits | None = None,
        manager_tls: ServerTls | None = None,
    ) -> None:
        super().__init__(config, RaySpawner(config))
        self.manager_port = 0
        self._real: dict[str, Any] = {}
        if manager_host is not None:  # also on a Ray-driven restart of this actor
            self._grpc, self.manager_port = serve_manager(
                self,
                manager_host,
                manager_port,
                node=ray.util.get_node_ip_address(),
                limits=manager_limits,
                tls=manager_tls,
            )

    def ping(self) -> bool:
        return True

    def serving_port(self) -> int:
        """The ServerManager service's port (0 if this supervisor serves none)."""
        return self.manager_port

    def reaped_count(self) -> int:
        """Servers stopped for being idle (``SupervisorConfig.idle_timeout_s``)."""
        return self.reaped

    def join_real_robot(self, name: str, address: str, safety: SafetyConfig) -> dict[str, Any]:
        """Join a real robot; it probes itself at the supervisor's probe interval when idle (a
        failure pauses it) and the supervisor lists it, but never restarts it."""
        self._real[name] = start_real_robot(
            name, address, safety, probe_interval_s=self.config.probe_interval_s
        )
        return ray.get(self._real[name].status.remote())

    def real_robots(self) -> list[dict[str, Any]]:
        """Status of each joined real robot (a failed check pauses the robot, nothing more)."""
        ray.get([actor.check.remote() for actor in self._real.values()])
        return ray.get([actor.status.remote() for actor in self._real.values()])


SupervisorActor = ray.remote(num_cpus=0.05, max_restarts=3, max_concurrency=32)(_RaySupervisor)


def start_supervisor(
    config: SupervisorConfig | None = None,
    *,
    name: str = SUPERVISOR_NAME,
    manager_host: str | None = None,
    manager_port: int = 50100,
    manager_limits: ManagerLimits | None = None,
    manager_tls: ServerTls | None = None,
) -> Any:
    """Create the named supervisor actor (and its ServerManager service if ``manager_host``,
    over TLS with ``manager_tls``).

    Returns once it is up; ``ray.get(handle.ping.remote())`` has succeeded.
    """
    actor = SupervisorActor.options(name=name, namespace=NAMESPACE).remote(
        config or SupervisorConfig(), manager_host, manager_port, manager_limits, manager_tls
    )
    ray.get(actor.ping.remote())
    return actor


def get_supervisor(name: str = SUPERVISOR_NAME) -> Any | None:
    """The running supervisor actor called ``name``, or None."""
    try:
        return ray.get_actor(name, namespace=NAMESPACE)
    except ValueError:
        return None
