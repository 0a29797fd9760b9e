"""``robogym-ray manager``: robo-gym's server manager, served by the supervisor actor.

Starts (or joins) Ray, creates the named supervisor actor with the ServerManager gRPC service on
``host:port`` (robo-gym's clients scan 50100..50199), prints ``listening on HOST:PORT`` once it
accepts calls, and on SIGINT/SIGTERM stops every robot server it started.
"""

from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass

from robogym_ray.config import add_config_args, check_port, check_ray_address, config_from_args
from robogym_ray.errors import ConfigError
from robogym_ray.foreground import StopSignals
from robogym_ray.protocol.tls import server_tls
from robogym_ray.robots.ports import check_port_free
from robogym_ray.supervision.manager_service import ManagerLimits
from robogym_ray.supervision.restart_policy import RestartPolicy
from robogym_ray.supervision.supervisor import SupervisorConfig

log = logging.getLogger(__name__)

MANAGER_STOP_DEADLINE_S = 60.0
"""The manager's stop ends every robot server it started and its Ray session: more to do than
one server's, so a longer deadline than ``foreground.STOP_DEADLINE_S``."""


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
    max_servers: int = ManagerLimits.max_servers
    """Robot servers run at most; a StartNewServer beyond is refused at once (success=false).
    Servers reserve no Ray CPU (they mostly wait on their socket), so this is the bound: about
    200 MB of memory each (a MiR100 server, measured)."""
    idle_timeout_s: float = 600.0
    """Stop a robot server that had no SetState/SendAction for this long (0 = never): robo-gym
    clients that vanish without KillServer would otherwise hold their server forever."""
    max_concurrent_starts: int = ManagerLimits.max_concurrent_starts
    """Robot servers started at the same time (each start loads PyBullet: CPU-bound)."""
    start_wait_s: float = ManagerLimits.start_wait_s
    """Seconds a StartNewServer waits for a start slot before it is refused as busy."""
    tls_cert: str | None = None
    """PEM certificate chain: serve the ServerManager service over TLS (with --tls-key);
    robo-gym's client has no TLS, and the simulated robot servers it starts stay plain."""
    tls_key: str | None = None
    """PEM private key of --tls-cert (unencrypted; keep it readable by this user only)."""

    def __post_init__(self) -> None:
        check_port(self.port, "ManagerConfig.port (--port)")
        if self.ray_address is not None:  # else Ray fails on it later, in a traceback
            check_ray_address(self.ray_address, "--ray-address")
        for name, ok in (
            ("num_cpus", self.num_cpus > 0),
            ("probe_interval_s", self.probe_interval_s > 0),
            ("max_restarts", self.max_restarts >= 0),
            ("max_servers", self.max_servers >= 1),
            ("idle_timeout_s", self.idle_timeout_s >= 0),
            ("max_concurrent_starts", self.max_concurrent_starts >= 1),
            ("start_wait_s", self.start_wait_s >= 0),
        ):
            if not ok:  # NaN fails these comparisons too
                raise ConfigError(f"ManagerConfig.{name} = {getattr(self, name)!r}; out of range")

    def supervisor_config(self) -> SupervisorConfig:
        """The supervisor this manager runs on."""
        return SupervisorConfig(
            probe_interval_s=self.probe_interval_s,
            restart=RestartPolicy(max_restarts=self.max_restarts),
            # A robot server waits on its socket between calls; reserving Ray CPU for it capped
            # a 2-CPU manager at 7 servers. max_servers bounds them instead.
            server_num_cpus=0.0,
            idle_timeout_s=self.idle_timeout_s,
        )

    def limits(self) -> ManagerLimits:
        return ManagerLimits(
            max_servers=self.max_servers,
            max_concurrent_starts=self.max_concurrent_starts,
            start_wait_s=self.start_wait_s,
        )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_args(parser, ManagerConfig)


def run(args: argparse.Namespace) -> int:
    cfg = config_from_args(ManagerConfig, args)
    tls = server_tls(cfg.tls_cert, cfg.tls_key)  # read and checked before anything starts
    # A held port is refused here, in one line, before Ray is imported or started (seconds, and
    # log lines on stderr); the actor's own exclusive bind still catches a port taken later.
    check_port_free(cfg.host, cfg.port, "server manager port")

    import ray  # lazy: `robogym-ray --help` must not import Ray

    from robogym_ray.distributed.local_ray import join_ray, start_local_ray
    from robogym_ray.distributed.names import NAMESPACE
    from robogym_ray.distributed.robot_actors import creation_error, start_supervisor

    if cfg.ray_address:
        join_ray(cfg.ray_address, namespace=NAMESPACE)
    else:
        start_local_ray(cfg.num_cpus, namespace=NAMESPACE)
    try:
        supervisor = start_supervisor(
            cfg.supervisor_config(),
            manager_host=cfg.host,
            manager_port=cfg.port,
            manager_limits=cfg.limits(),
            manager_tls=tls,
        )
    except Exception as exc:  # noqa: BLE001 - the actor's constructor failed (port taken ...)
        ray.shutdown()
        raise ConfigError(
            f"could not start the server manager on {cfg.host}:{cfg.port}: {creation_error(exc)}"
        ) from None
    stop = StopSignals()
    port = ray.get(supervisor.serving_port.remote())
    host = f"[{cfg.host}]" if ":" in cfg.host else cfg.host
    print(f"listening on {host}:{port}", flush=True)
    stop.wait(MANAGER_STOP_DEADLINE_S)
    stopped = ray.get(supervisor.shutdown.remote())
    log.info("stopped %s", stopped)
    ray.kill(supervisor, no_restart=True)
    ray.shutdown()
    print("stopped", flush=True)
    return 0
