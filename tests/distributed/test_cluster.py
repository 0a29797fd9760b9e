"""Real Ray clusters started with the `ray` CLI: `ray job submit`, and robot servers placed on a
second node. Both run on one two-node cluster, started once for this module (starting nodes
is most of their cost on 2 cores; neither test kills a node - test_multinode.py, which does,
starts its own).

Each node runs `ray start --block` in its own process group and is stopped by signalling that
group (by PID) - never with `ray stop`, which would kill every Ray on the machine.
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
import time
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from robogym_ray import children
from tests.distributed.cluster import (
    RAY,
    REPO,
    agent_ports,
    cluster_cpus,
    cluster_env,
    head_args,
    ray_node,
    wait_for,
)
from tests.distributed.conftest import free_port

pytestmark = [pytest.mark.slow]


@dataclass(frozen=True)
class TwoNodes:
    port: int  # the head's GCS
    dashboard: int  # the head's dashboard (jobs are submitted there)
    env: dict[str, str]
    results: Path  # ROBOGYM_RAY_RESULTS on the head: where a job's relative --logdir lands
    temp_dir: str  # the head's --temp-dir (Ray's own files, the job's working dir copy)


@pytest.fixture(scope="module")
def two_nodes(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TwoNodes]:
    """A head (2 CPUs, dashboard) and a second node (1 CPU and the custom resource
    ``robot_node``), each in its own process group. The head has room for the robot servers:
    a run that ignored ``--server-resource`` would put them there (with a 1-CPU head the
    learner filled it, and servers landed on the second node whatever the code did)."""
    temp_dir = tempfile.mkdtemp(prefix="rgc", dir="/tmp")  # short: Unix socket paths
    port, dash = free_port(), free_port()
    results = tmp_path_factory.mktemp("results")
    env = {**cluster_env(), "ROBOGYM_RAY_RESULTS": str(results)}
    second = [
        f"--address=127.0.0.1:{port}",
        "--num-cpus=1",
        '--resources={"robot_node": 4}',
        "--min-worker-port=0",
        "--max-worker-port=0",
        *agent_ports(),  # the second node's agent would want the head's port too
    ]
    try:
        with ray_node(head_args(port, temp_dir, 2, dash), temp_dir, env=env):
            wait_for(lambda: cluster_cpus(f"127.0.0.1:{port}") >= 2, 90, "the head node")
            with ray_node(second, temp_dir, env=env):
                wait_for(lambda: cluster_cpus(f"127.0.0.1:{port}") >= 3, 90, "the second node")
                yield TwoNodes(port, dash, env, results, temp_dir)
    finally:
        shutil.rmtree(temp_dir, ignore_errors=True)


def test_ray_job_submit_runs_a_short_training(two_nodes: TwoNodes) -> None:
    """Submitted the README's way, with a relative --logdir: the run's files land together in a
    stable place on the head (here ROBOGYM_RAY_RESULTS; by default ~/robogym_ray_results), not
    in Ray's temporary copy of the working dir, and the summary says where."""
    c = two_nodes
    cmd = [
        *RAY, "job", "submit", f"--address=http://127.0.0.1:{c.dashboard}",
        f"--working-dir={REPO}", "--",
        "robogym-ray", "train", "--task", "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
        "--workers", "1", "--total-steps", "600", "--logdir", "runs", "--run-name", "job",
        "--address", "auto", "--no-progress", "--no-evaluator",
    ]  # fmt: skip
    deadline = time.monotonic() + 90
    while True:  # the head's job agent starts after its CPUs show: Ray says "try again later"
        out = children.run(cmd, env=c.env, capture_output=True, text=True, timeout=400)
        if "No available agent" not in out.stderr or time.monotonic() > deadline:
            break
        time.sleep(1)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    assert "succeeded" in out.stdout + out.stderr
    run = c.results / "runs" / "job"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["env_steps"] >= 600
    assert summary["checkpoint"] == str(run / "checkpoints" / "learner.pt")
    assert {p.name for p in run.iterdir()} >= {"config.json", "summary.json", "checkpoints"}
    assert f"files:       {run}/" in out.stdout + out.stderr
    assert not list(Path(c.temp_dir).rglob("runs/job"))  # nothing in Ray's temporary dirs


def test_a_jobs_upload_leaves_the_committed_results_out(tmp_path: Path) -> None:
    """The README's `ray job submit --working-dir .` packages the clone as Ray's own packaging
    does (the function the submit calls): without `docs/results/` (.rayignore; tens of MB no
    job reads), with the code and the configs a job runs."""
    from ray._private.runtime_env.packaging import create_package

    package = tmp_path / "job.zip"
    create_package(str(REPO), package, include_gitignore=True)
    names = zipfile.ZipFile(package).namelist()
    assert not [n for n in names if n.startswith("docs/results/")]
    assert {"robogym_ray/cli.py", "experiments/configs/navigation.json"} <= set(names)


def test_two_nodes_robot_servers_on_the_second(two_nodes: TwoNodes, tmp_path: Path) -> None:
    # Robot servers need `robot_node`, which only the second node has: the run can only
    # complete if the supervisor placed them there.
    cmd = [
        sys.executable, "-m", "robogym_ray.cli", "train",
        "--task", "RoboGymRay/ObstacleAvoidanceMir100Sim-v0", "--workers", "1",
        "--total-steps", "400", "--logdir", str(tmp_path), "--run-name", "two",
        "--address", f"127.0.0.1:{two_nodes.port}", "--sim-path", "grpc",
        "--envs-per-worker", "1", "--server-resource", "robot_node",
        "--no-progress", "--no-evaluator",
    ]  # fmt: skip
    out = children.run(
        cmd, env=two_nodes.env, capture_output=True, text=True, timeout=400, cwd=REPO
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    summary = json.loads((tmp_path / "two" / "summary.json").read_text())
    assert summary["env_steps"] >= 400
    assert summary["server_nodes"]
    assert all(n.get("robot_node", 0) > 0 for n in summary["server_nodes"]), summary["server_nodes"]
