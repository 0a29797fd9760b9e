"""Real Ray clusters started with the `ray` CLI: `ray job submit`, and two nodes on one machine.

Each cluster runs `ray start --block` in its own process group and is stopped by signalling that
group (by PID) - never with `ray stop`, which would kill every Ray on the machine.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.distributed.conftest import free_port

pytestmark = [pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
RAY = [sys.executable, "-m", "ray.scripts.scripts"]


def cluster_env() -> dict[str, str]:
    env = {**os.environ, "RAY_AUTH_MODE": "disabled", "RAY_USAGE_STATS_ENABLED": "0"}
    env.pop("RAY_ADDRESS", None)
    return env


def wait_for(check, timeout: float, what: str) -> None:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if check():
            return
        time.sleep(1.0)
    raise TimeoutError(f"timed out after {timeout} s waiting for {what}")


def cluster_cpus(address: str, env: dict[str, str]) -> float:
    code = (
        f"import ray; ray.init(address={address!r}, logging_level='ERROR'); "
        "print(ray.cluster_resources().get('CPU', 0))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60
    )
    try:
        return float(out.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return 0.0


@contextmanager
def ray_node(args: list[str], temp_dir: str) -> Iterator[subprocess.Popen]:
    log = open(Path(temp_dir) / f"node-{len(os.listdir(temp_dir))}.log", "w")  # noqa: SIM115
    proc = subprocess.Popen(
        [*RAY, "start", "--block", "--disable-usage-stats", *args],
        env=cluster_env(),
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    try:
        yield proc
    finally:
        # `ray start --block` tears down the processes it started when signalled.
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
        log.close()


@pytest.fixture
def temp_dir() -> Iterator[str]:
    path = tempfile.mkdtemp(prefix="rgc", dir="/tmp")  # short: Unix socket paths are limited
    yield path
    shutil.rmtree(path, ignore_errors=True)


def agent_ports() -> list[str]:
    """Free ports for the node's dashboard agent. Its default HTTP port (52365) is one per
    machine: any other Ray running here (a training, another test session) holds it, and
    the agent of a node started beside it fails to bind, so `ray job submit` finds none."""
    return [
        f"--dashboard-agent-listen-port={free_port()}",
        f"--dashboard-agent-grpc-port={free_port()}",
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


def test_ray_job_submit_runs_a_short_training(temp_dir: str, tmp_path: Path) -> None:
    port, dash = free_port(), free_port()
    with ray_node(head_args(port, temp_dir, 2, dash), temp_dir):
        env = cluster_env()
        wait_for(lambda: cluster_cpus(f"127.0.0.1:{port}", env) >= 2, 90, "the head node")
        cmd = [
            *RAY,
            "job",
            "submit",
            f"--address=http://127.0.0.1:{dash}",
            f"--working-dir={REPO}",
            "--",
            "robogym-ray",
            "train",
            "--task",
            "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
            "--workers",
            "1",
            "--total-steps",
            "600",
            "--logdir",
            str(tmp_path),
            "--run-name",
            "job",
            "--address",
            "auto",
            "--no-progress",
            "--no-evaluator",
        ]
        deadline = time.monotonic() + 90
        while True:  # the head's job agent starts after its CPUs show: Ray says "try again later"
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=400)
            if "No available agent" not in out.stderr or time.monotonic() > deadline:
                break
            time.sleep(3)
        assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
        assert "succeeded" in out.stdout + out.stderr
    summary = json.loads((tmp_path / "job" / "summary.json").read_text())
    assert summary["env_steps"] >= 600


def test_two_nodes_robot_servers_on_the_second(temp_dir: str, tmp_path: Path) -> None:
    port = free_port()
    with ray_node(head_args(port, temp_dir, 1), temp_dir):
        env = cluster_env()
        wait_for(lambda: cluster_cpus(f"127.0.0.1:{port}", env) >= 1, 90, "the head node")
        second = [
            f"--address=127.0.0.1:{port}",
            "--num-cpus=1",
            '--resources={"robot_node": 4}',
            "--min-worker-port=0",
            "--max-worker-port=0",
            *agent_ports(),  # the second node's agent would want the head's port too
        ]
        with ray_node(second, temp_dir):
            wait_for(lambda: cluster_cpus(f"127.0.0.1:{port}", env) >= 2, 90, "the second node")
            # Robot servers need `robot_node`, which only the second node has: the run can only
            # complete if the supervisor placed them there.
            cmd = [
                sys.executable,
                "-m",
                "robogym_ray.cli",
                "train",
                "--task",
                "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
                "--workers",
                "1",
                "--total-steps",
                "400",
                "--logdir",
                str(tmp_path),
                "--run-name",
                "two",
                "--address",
                f"127.0.0.1:{port}",
                "--sim-path",
                "grpc",
                "--envs-per-worker",
                "1",
                "--server-resource",
                "robot_node",
                "--no-progress",
                "--no-evaluator",
            ]
            out = subprocess.run(
                cmd, env=env, capture_output=True, text=True, timeout=400, cwd=REPO
            )
            assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    summary = json.loads((tmp_path / "two" / "summary.json").read_text())
    assert summary["env_steps"] >= 400
    assert summary["server_nodes"]
    assert all(n.get("robot_node", 0) > 0 for n in summary["server_nodes"]), summary["server_nodes"]
