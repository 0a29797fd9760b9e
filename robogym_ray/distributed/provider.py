"""``SupervisorServerProvider``: Sim envs get their robot servers from the supervisor actor.

Implements ``robogym_ray.envs.servers.ServerProvider``. A lease remembers the server's
*generation*; ``report_fault`` asks the supervisor to restart that generation and waits until the
new one serves (a fault the supervisor's own probe already handled is not restarted twice), so the
env's next ``acquire`` gets the new address. If the supervisor gave the server up,
``report_fault`` raises ``RobotServerError`` with the supervisor's message.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import ray

from robogym_ray.distributed.names import SUPERVISOR_NAME
from robogym_ray.distributed.robot_actors import get_supervisor
from robogym_ray.errors import RobotServerError
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.supervision.server_host import ServerSpec

log = logging.getLogger(__name__)


@dataclass
class SupervisorLease:
    """One leased supervised server (``ServerLease`` protocol)."""

    supervisor: Any
    server_id: str
    address: str
    generation: int
    token: str | None = None
    faults: list[str] = field(default_factory=list)
    released: bool = False

    def report_fault(self, cause: str) -> None:
        self.faults.append(cause)
        info = ray.get(self.supervisor.report_fault.remote(self.server_id, cause, self.generation))
        if info["state"] == "given_up":
            raise RobotServerError(info["message"], address=self.address, cause="given_up")
        log.warning("robot server %s (%s) restarted at %s", self.server_id, cause, info["address"])

    def release(self) -> None:
        if not self.released:
            self.released = True
            ray.get(self.supervisor.release.remote(self.server_id))


@dataclass(frozen=True)
class SupervisorServerProvider:
    """Leases servers from the named supervisor actor (it must be running).

    Args:
        name: the supervisor actor's name (namespace ``robogym-ray``).
        host: interface the servers bind (``auto``: loopback on one node, node IP on a cluster).
        real_time: pace servers against the wall clock.
        resources: custom Ray resources a server needs (places it on the nodes that have them).
        emulation: lease emulated robots (noise, latency, dynamics differences) instead of the
            plain simulation (domain randomisation).
    """

    name: str = SUPERVISOR_NAME
    host: str = "auto"
    real_time: bool = False
    resources: tuple[tuple[str, float], ...] = ()
    emulation: EmulationConfig | None = None
    holder: str = ""
    """Names the lease holder (a training run's worker), so a replacement can release it."""

    def acquire(
        self, robot: str, scene: str | None, options: Mapping[str, str], seed: int | None
    ) -> SupervisorLease:
        supervisor = get_supervisor(self.name)
        if supervisor is None:
            raise RobotServerError(f"no supervisor actor {self.name!r} is running", cause="start")
        spec = ServerSpec(
            robot=robot,
            scene=scene,
            options=dict(options),
            seed=seed,
            host=self.host,
            real_time=self.real_time,
            resources=dict(self.resources),
            emulation=self.emulation,
        )
        info = ray.get(supervisor.acquire.remote(spec, self.holder))
        return SupervisorLease(supervisor, info["id"], info["address"], info["generation"])
