"""The robot-server supervision a training run uses (``--sim-path grpc``): a running supervisor
(``robogym-ray manager``) or one of its own, and what the run asks of it."""

from __future__ import annotations

import logging
from collections import Counter
from dataclasses import dataclass
from typing import Any

import ray

from robogym_ray.distributed import robot_actors
from robogym_ray.distributed.names import run_supervisor_name
from robogym_ray.distributed.provider import SupervisorServerProvider
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.supervision.restart_policy import FaultCause
from robogym_ray.supervision.supervisor import SupervisorConfig
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.resources import actor_need

log = logging.getLogger(__name__)


@dataclass
@dataclass
class Supervision:
    """The supervisor a run uses: a running one (e.g. ``robogym-ray manager``) or its own."""

    actor: Any
    name: str
    owned: bool
    resources: tuple[tuple[str, float], ...] = ()

    def provider(
        self, emulation: EmulationConfig | None = None, holder: str = ""
    ) -> SupervisorServerProvider:
        return SupervisorServerProvider(
            name=self.name, resources=self.resources, emulation=emulation, holder=holder
        )

    def release_holder(self, holder: str) -> int:
        """End the leases of a worker that died (see ``Supervisor.release_holder``)."""
        return int(ray.get(self.actor.release_holder.remote(holder), timeout=30))

    def restart_counts(self) -> dict[str, int]:
        """Restarts by cause over every server of this supervisor."""
        # Every cause appears (zeros too), so TensorBoard shows the five faults from the start.
        counts: Counter[str] = Counter({cause.value: 0 for cause in FaultCause})
        for server in self._servers():
            counts.update(server.get("restarts", {}))
        return dict(counts)

    def given_up(self) -> int:
        """Servers the restart policy gave up (one fault past its limit: not a restart)."""
        return sum(server.get("state") == "given_up" for server in self._servers())

    def _servers(self) -> list[dict[str, Any]]:
        try:
            return list(ray.get(self.actor.status.remote(), timeout=10))
        except Exception:  # noqa: BLE001 - a dead supervisor must not stop the run's logging
            return []

    def server_nodes(self) -> list[dict[str, Any]]:
        """Where each running server is: its Ray node id and that node's custom resources."""
        nodes = {n["NodeID"]: n.get("Resources", {}) for n in ray.nodes() if n.get("Alive")}
        out = []
        for server in ray.get(self.actor.status.remote()):
            if server.get("pid"):
                res = nodes.get(server.get("node_id", ""), {})
                custom = {
                    k: v
                    for k, v in res.items()
                    if k not in ("CPU", "GPU", "memory", "object_store_memory")
                    and not k.startswith("node:")
                }
                out.append({"id": server["id"], "node_id": server.get("node_id", ""), **custom})
        return out

    def stop(self) -> None:
        if self.owned:
            try:
                ray.get(self.actor.shutdown.remote(), timeout=30)
            finally:
                ray.kill(self.actor, no_restart=True)


def start_supervision(cfg: TrainConfig, env_id: str, run_name: str) -> Supervision | None:
    """Supervision for RoboGymRay Sim tasks on the gRPC path; None for in-process simulation
    (the workers supervise their own) and for other envs (e.g. Pendulum-v1)."""
    if not env_id.startswith("RoboGymRay/") or cfg.sim_path != "grpc":
        return None
    server = actor_need(cfg, "robot server")  # the table's row: the CPU check counted it
    resources = tuple(server.options().get("resources", {}).items())
    running = robot_actors.get_supervisor()
    if running is not None:
        log.warning("using the running supervisor %s", robot_actors.SUPERVISOR_NAME)
        return Supervision(running, robot_actors.SUPERVISOR_NAME, owned=False, resources=resources)
    name = run_supervisor_name(run_name)
    actor = robot_actors.start_supervisor(SupervisorConfig(server_num_cpus=server.cpus), name=name)
    return Supervision(actor, name, owned=True, resources=resources)
