"""Real Ray clusters on one machine, started with the `ray` CLI: each node runs `ray start
--block` in its own process group (a session) and is stopped - or killed, as a lost machine - by
signalling that group by PID, never with `ray stop`, which would stop every Ray on the machine.
Each node may get a temp dir of its own, as separate machines have separate disks."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from robogym_ray import children
from tests.distributed.conftest import free_port

REPO = Path(__file__).resolve().parents[2]
RAY = [sys.executable, "-m", "ray.scripts.scripts"]


def cluster_env() -> dict[str, str]:
    env = {**os.environ, "RAY_AUTH_MODE": "disabled", "RAY_USAGE_STATS_ENABLED": "0"}
    # A node's raylet waits for its dashboard agent (a Python process) to start: on 2 busy
    # cores with several nodes starting that takes longer than Ray's default allows.
    env.setdefault("RAY_agent_register_timeout_ms", "180000")
    env.setdefault("RAY_raylet_start_wait_time_s", "180")
    # Ray 2.60 drains a node on SIGTERM (for Serve's replicas) for up to 30 s before it stops
    # its processes; an idle test node sat out the whole 30 s at every stop. None is drained.
    env.setdefault("RAY_GRACEFUL_SHUTDOWN_DRAIN_TIMEOUT_S", "0")
    env.pop("RAY_ADDRESS", None)
    # A job's entrypoint (`robogym-ray ...`) runs in a shell of the head's: find this Python's
    # scripts even when the tests run without the venv activated.
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    return env


def wait_for(check, timeout: float, what: str) -> None:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if check():
            return
        time.sleep(0.25)
    raise TimeoutError(f"timed out after {timeout} s waiting for {what}")


def _alive_nodes(address: str) -> list:
    """The alive nodes' records, read from the cluster's GCS directly (no driver joins: on 2
    cores a polling driver per second, each importing Ray, slowed the nodes it waited for);
    none while the GCS does not answer."""
    from ray._raylet import GcsClient
    from ray.core.generated.gcs_pb2 import GcsNodeInfo

    try:
        nodes = GcsClient(address=address).get_all_node_info(timeout=5).values()
    except Exception:  # noqa: BLE001 - not up yet, or gone: no alive node to count
        return []
    return [n for n in nodes if n.state == GcsNodeInfo.GcsNodeState.ALIVE]


def cluster_cpus(address: str) -> float:
    """The CPUs of the cluster's alive nodes (0 when it does not answer)."""
    return sum(n.resources_total.get("CPU", 0.0) for n in _alive_nodes(address))


def alive_nodes(address: str) -> int:
    """How many nodes of the cluster at ``address`` are alive (0: it does not answer)."""
    return len(_alive_nodes(address))


@contextmanager
def ray_node(
    args: list[str],
    temp_dir: str,
    wrap: list[str] | None = None,
    env: dict[str, str] | None = None,
) -> Iterator[subprocess.Popen]:
    """A node; ``wrap``: a command line the node's `ray start` runs under (e.g. a private mount
    namespace, to give it a disk of its own). A node killed already (a machine lost) is fine."""
    log = open(Path(temp_dir) / f"node-{len(os.listdir(temp_dir))}.log", "w")  # noqa: SIM115
    proc = children.popen(
        [*(wrap or []), *RAY, "start", "--block", "--disable-usage-stats", *args],
        env=env or cluster_env(),
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    try:
        yield proc
    finally:
        # `ray start --block` tears down the processes it started when signalled.
        with suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
        log.close()


def agent_ports() -> list[str]:
    """Free ports for the node's agents, each given rather than left to the agent to choose.
    The dashboard agent's default HTTP port (52365) is one per machine: any other Ray running
    here (a training, another test session) holds it, and the agent of a node started beside
    it fails to bind, so `ray job submit` finds none. A port left at 0 is written to a file by
    its agent, and the raylet gives up on that file after 15 s and dies (a node that never
    joins): on 2 cores busy with a training an agent can take longer than that to start."""
    return [
        f"--dashboard-agent-listen-port={free_port()}",
        f"--dashboard-agent-grpc-port={free_port()}",
        f"--metrics-export-port={free_port()}",
        f"--runtime-env-agent-port={free_port()}",
    ]


def head_args(port: int, temp_dir: str, cpus: int, dashboard_port: int | None = None) -> list:
    args = [
        "--head",
        f"--port={port}",
        f"--num-cpus={cpus}",
        f"--temp-dir={temp_dir}",
        "--min-worker-port=0",
        "--max-worker-port=0",
        *agent_ports(),
    ]
    if dashboard_port is None:
        return [*args, "--include-dashboard=false"]
    return [
        *args,
        "--include-dashboard=true",
        "--dashboard-host=127.0.0.1",
        f"--dashboard-port={dashboard_port}",
    ]
