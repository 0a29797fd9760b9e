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

from tests.distributed.conftest import free_port

REPO = Path(__file__).resolve().parents[2]
RAY = [sys.executable, "-m", "ray.scripts.scripts"]


def cluster_env() -> dict[str, str]:
    env = {**os.environ, "RAY_AUTH_MODE": "disabled", "RAY_USAGE_STATS_ENABLED": "0"}
    # A node's raylet waits for its dashboard agent (a Python process) to start: on 2 busy
    # cores with several nodes starting that takes longer than Ray's default allows.
    env.setdefault("RAY_agent_register_timeout_ms", "180000")
    env.setdefault("RAY_raylet_start_wait_time_s", "180")
    env.pop("RAY_ADDRESS", None)
    return env


def wait_for(check, timeout: float, what: str) -> None:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if check():
            return
        time.sleep(1.0)
    raise TimeoutError(f"timed out after {timeout} s waiting for {what}")


def ask_cluster(address: str, env: dict[str, str], expression: str) -> float:
    """``expression`` evaluated by a driver that joins the cluster at ``address`` (0 when the
    cluster does not answer)."""
    code = f"import ray; ray.init(address={address!r}, logging_level='ERROR'); print({expression})"
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60
    )
    try:
        return float(out.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return 0.0


def cluster_cpus(address: str, env: dict[str, str]) -> float:
    return ask_cluster(address, env, "ray.cluster_resources().get('CPU', 0)")


def alive_nodes(address: str, env: dict[str, str]) -> int:
    """How many nodes of the cluster at ``address`` are alive (0: it does not answer)."""
    return int(ask_cluster(address, env, "sum(n['Alive'] for n in ray.nodes())"))


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
    proc = subprocess.Popen(
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
