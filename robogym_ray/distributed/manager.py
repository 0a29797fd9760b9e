"""``robogym-ray manager``: robo-gym's server manager, served by the supervisor actor.

Starts (or joins) Ray, creates the named supervisor actor with the ServerManager gRPC service on
``host:port`` (robo-gym's clients scan 50100..50199), prints ``listening on HOST:PORT`` once it
accepts calls, and on SIGINT/SIGTERM stops every robot server it started.
"""

from __future__ import annotations

import argparse
import logging
import signal
import threading
from dataclasses import dataclass

from robogym_ray.config import add_config_args, check_port, config_from_args
from robogym_ray.errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ManagerConfig:
    """What ``robogym-ray manager`` serves."""

    host: str = "127.0.0.1"
    """Interface of the ServerManager service; robot servers bind it too (robo-gym's client
    reaches them at the manager's address)."""
    port: int = 50100
    """ServerManager port (the first one robo-gym's client scans)."""
    ray_address: str | None = None
    """Ray cluster to join (e.g. 'auto'); default: start a local Ray in this process."""
    num_cpus: float = 2.0
    """CPUs of the local Ray started when no --ray-address is given."""
    probe_interval_s: float = 1.0
    """Seconds between health probes of each robot server."""
    max_restarts: int = 5
    """Automatic restarts of one server within 5 minutes before it is given up."""

    def __post_init__(self) -> None:
        check_port(self.port, "ManagerConfig.port (--port)")
        for name, ok in (
            ("num_cpus", self.num_cpus > 0),
            ("probe_interval_s", self.probe_interval_s > 0),
            ("max_restarts", self.max_restarts >= 0),
        ):
            if not ok:  # NaN fails these comparisons too
                raise ConfigError(f"ManagerConfig.{name} = {getattr(self, name)!r}; out of range")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_args(parser, ManagerConfig)


def run(args: argparse.Namespace) -> int:
    import ray  # lazy: `robogym-ray --help` must not import Ray

    from robogym_ray.distributed.names import NAMESPACE
    from robogym_ray.distributed.remote import start_supervisor
    from robogym_ray.supervision.restart_policy import RestartPolicy
    from robogym_ray.supervision.supervisor import SupervisorConfig

    cfg = config_from_args(ManagerConfig, args)
    if cfg.ray_address:
        ray.init(address=cfg.ray_address, namespace=NAMESPACE)
    else:
        ray.init(num_cpus=cfg.num_cpus, include_dashboard=False, namespace=NAMESPACE)
    sup_cfg = SupervisorConfig(
        probe_interval_s=cfg.probe_interval_s, restart=RestartPolicy(max_restarts=cfg.max_restarts)
    )
    try:
        supervisor = start_supervisor(sup_cfg, manager_host=cfg.host, manager_port=cfg.port)
    except Exception as exc:  # noqa: BLE001 - the actor's constructor failed (port taken ...)
        ray.shutdown()
        raise ConfigError(
            f"could not start the server manager on {cfg.host}:{cfg.port}: {exc}"
        ) from None
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    port = ray.get(supervisor.serving_port.remote())
    host = f"[{cfg.host}]" if ":" in cfg.host else cfg.host
    print(f"listening on {host}:{port}", flush=True)
    stop.wait()
    stopped = ray.get(supervisor.shutdown.remote())
    log.info("stopped %s", stopped)
    ray.kill(supervisor, no_restart=True)
    ray.shutdown()
    print("stopped", flush=True)
    return 0
