"""A run on a cluster of separate disks: three `ray start` nodes on one machine, each with its own
temp dir, one of them with a folder of its own (a private mount namespace: the folder other
nodes see is not there), losing nodes mid-run.

One cluster, one sequence (starting nodes dominates the cost on 2 cores):

1. storage that one node cannot see is refused in one line before anything starts;
2. a training on shared storage (it stands for an NFS mount), the learner placed by
   ``--learner-resource``; the workers-only node is killed: its workers are replaced on the
   surviving node; a new node joins (as an autoscaler's would);
3. the learner's node is killed: Ray restarts the learner on the new node, which restores its
   checkpoint and replay snapshot from the storage and trains on; the run, then stopped as
   `ray job stop` would stop it, ends with its summary, counts right, and stderr carries no
   unhandled-error traceback.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from robogym_ray import children
from tests.distributed.cluster import (
    agent_ports,
    alive_nodes,
    cluster_cpus,
    cluster_env,
    head_args,
    ray_node,
    wait_for,
)
from tests.distributed.conftest import free_port

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]

RUN = "mn"


def can_unshare() -> bool:
    probe = ["unshare", "-m", "--propagation", "private", "true"]
    try:
        return children.run(probe, capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def worker_node(port: int, temp: str, resources: dict[str, float] | None = None) -> list[str]:
    return [
        f"--address=127.0.0.1:{port}",
        "--num-cpus=2",
        f"--temp-dir={temp}",
        "--min-worker-port=0",
        "--max-worker-port=0",
        *(["--resources=" + json.dumps(resources)] if resources else []),
        *agent_ports(),
    ]


def ancestors(pid: int) -> set[int]:
    """``pid`` and every parent of it up to init."""
    seen = set()
    while pid > 1 and pid not in seen:
        seen.add(pid)
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            break
        pid = int(stat.rsplit(")", 1)[1].split()[1])
    return seen


def ask_run(port: int, env: dict[str, str], body: str, required: bool = True) -> Any:
    """What ``body`` (Python run by a driver joined to the cluster, with ``ray`` and ``json``
    imported) prints after ``ANSWER``, as JSON. When it printed none: a failed assertion with
    the driver's output, or None where an answer is not ``required``."""
    code = f"""
import json, ray
ray.init(address="127.0.0.1:{port}", logging_level="ERROR", namespace="robogym-ray")
{body}
"""
    out = children.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=180
    )
    line = [x for x in out.stdout.splitlines() if x.startswith("ANSWER")]
    assert line or not required, out.stdout[-2000:] + out.stderr[-2000:]
    return json.loads(line[-1][len("ANSWER") :]) if line else None


def actor_pids(port: int, env: dict[str, str]) -> dict[str, int]:
    """{actor name: pid} of the run's learner and rollout workers, asked over Ray."""
    return ask_run(port, env, f"""
out = {{}}
for a in ray.util.list_named_actors(all_namespaces=True):
    name = a["name"]
    if name == "learner-{RUN}":
        out[name] = ray.get(ray.get_actor(name, namespace=a["namespace"]).ping.remote(), timeout=60)
    elif name.startswith("rollout-{RUN}-"):
        try:
            h = ray.get_actor(name, namespace=a["namespace"])
            out[name] = ray.get(h.pid.remote(), timeout=60)
        except Exception:
            pass
print("ANSWER" + json.dumps(out))
""")  # fmt: skip


def learner_status(port: int, env: dict[str, str]) -> dict[str, int]:
    """The run's learner's ``status()``, asked over Ray (empty while it does not answer)."""
    status = ask_run(port, env, f"""
learner = ray.get_actor("learner-{RUN}")
print("ANSWER" + json.dumps(ray.get(learner.status.remote(), timeout=30)))
""", required=False)  # fmt: skip
    return status or {}


def on_node(pids: dict[str, int], node: subprocess.Popen) -> list[str]:
    return [name for name, pid in pids.items() if node.pid in ancestors(pid)]


def snapshot_state(checkpoints: Path) -> tuple[int, int]:
    """(learner step of learner.pt, transitions in its replay snapshot) right now."""
    step = int(torch.load(checkpoints / "learner.pt", weights_only=True)["num_steps"])
    with np.load(checkpoints / "learner.pt.replay.npz", allow_pickle=False) as data:
        size = int(data["counters"][1])
    return step, size


def train(port: int, storage: Path, *more: str) -> list[str]:
    return [
        sys.executable, "-m", "robogym_ray.cli", "train",
        "--task", "navigation", "--address", f"127.0.0.1:{port}",
        "--storage", str(storage), "--run-name", RUN, "--no-progress", "--no-evaluator",
        *more,
    ]  # fmt: skip


@pytest.mark.skipif(not can_unshare(), reason="needs mount namespaces (unshare -m) for a node")
def test_node_losses_on_a_cluster_of_separate_disks(temp_dir: str, tmp_path: Path) -> None:
    env = cluster_env()
    # Node deaths noticed in ~3 s rather than ~15: the test waits for two.
    env["RAY_health_check_period_ms"] = "1000"
    env["RAY_health_check_failure_threshold"] = "3"
    shared, private = tmp_path / "shared", tmp_path / "local-only"
    private.mkdir()
    temps = [os.path.join(temp_dir, name) for name in ("h", "a", "b", "c")]
    port = free_port()
    address = f"127.0.0.1:{port}"
    # B: the same path shows an empty folder of its own (its own disk), the rest as everyone's.
    own_disk = ["unshare", "-m", "--propagation", "private", "sh", "-c",
                f'mount -t tmpfs tmpfs {private} && exec "$0" "$@"']  # fmt: skip
    log = (tmp_path / "driver.err").open("w")
    with ray_node(head_args(port, temps[0], 0), temp_dir, env=env):
        wait_for(lambda: alive_nodes(address) >= 1, 180, "the head node")
        node_a = ray_node(worker_node(port, temps[1], {"learner_node": 1}), temp_dir, env=env)
        with node_a as a:
            wait_for(lambda: cluster_cpus(address) >= 2, 180, "node A")
            with ray_node(worker_node(port, temps[2]), temp_dir, own_disk, env) as b:
                wait_for(lambda: cluster_cpus(address) >= 4, 180, "node B")
                # 1. Storage that node B cannot see: refused before anything starts.
                out = children.run(train(port, private, "--total-steps", "100"), env=env,
                                   capture_output=True, text=True, timeout=300)  # fmt: skip
                assert out.returncode == 2, out.stderr[-3000:]
                line = out.stderr.strip().splitlines()[-1]
                assert line.startswith(f"error: storage {private} is not shared by the "
                                       "cluster's 3 nodes"), line  # fmt: skip
                assert line.count("cannot read it") == 1 and "s3://" in line, line
                assert list(private.iterdir()) == []  # no run folder, no marker left

                # 2. A training on shared storage; the learner only where learner_node is.
                # --max-wall-s guards against a hang only: the run ends by SIGTERM below, and
                # the cap is past the waits' own guards put together (900 s).
                driver = children.popen(
                    train(port, shared, "--workers", "2", "--envs-per-worker", "2",
                          "--total-steps", "10000000", "--max-wall-s", "1200",
                          "--learner-resource", "learner_node", "--checkpoint-every", "100",
                          "--replay-snapshot-every-s", "4", "--policy-snapshot-every-s", "0"),
                    env=env, stdout=subprocess.PIPE, stderr=log, text=True,
                )  # fmt: skip
                checkpoints = shared / RUN / "checkpoints"
                replay = checkpoints / "learner.pt.replay.npz"
                wait_for(replay.exists, 240, "the learner's first replay snapshot")
                pids = actor_pids(port, env)
                assert f"learner-{RUN}" in on_node(pids, a), pids
                lost_workers = on_node(pids, b)
                assert lost_workers, f"SPREAD put no worker on node B: {pids}"
                os.killpg(b.pid, signal.SIGKILL)  # a workers-only machine lost
                b.wait(timeout=30)
                # Seen lost (its health checks fail) before node C joins, so that C is what
                # makes three alive nodes below, not B counted still.
                wait_for(lambda: alive_nodes(address) == 2, 60, "node B's loss")
            # A new machine joins, with the learner's resource: the learner's next home.
            node_c = ray_node(worker_node(port, temps[3], {"learner_node": 1}), temp_dir, env=env)
            with node_c:
                wait_for(lambda: alive_nodes(address) >= 3, 180, "node C")
                before = snapshot_state(checkpoints)
                wait_for(lambda: snapshot_state(checkpoints) > before, 120, "a later snapshot")
                # 3. The learner's machine lost: the new learner must restore at least this.
                pids = actor_pids(port, env)
                moved_workers = [n for n in on_node(pids, a) if n.startswith("rollout-")]
                step, transitions = snapshot_state(checkpoints)
                os.killpg(a.pid, signal.SIGKILL)
                killed = time.monotonic()
                a.wait(timeout=30)

                def trained_after_restoring() -> bool:
                    status = learner_status(port, env)
                    restored = status.get("restored_from_step", 0)
                    return restored >= step > 0 and status["version"] > restored

                wait_for(trained_after_restoring, 300, "the restarted learner to train on")
                # All this run can show is shown: it ends as `ray job stop` would end it (the
                # rest of --max-wall-s would only add time), with its summary.
                driver.send_signal(signal.SIGTERM)
                stdout, _ = driver.communicate(timeout=400)
                ended = time.monotonic()
    log.close()
    err = (tmp_path / "driver.err").read_text()
    assert driver.returncode == 0, stdout[-2000:] + err[-4000:]
    summary = json.loads((shared / RUN / "summary.json").read_text())
    assert summary["ended"] == "stopped" and summary["stopped_by"] == "SIGTERM"
    assert summary["faults/learner_failures"] == 1
    assert summary["learner_restored_from_step"] >= step
    assert summary["learner_restored_replay"] >= transitions
    assert summary["learner_steps"] > summary["learner_restored_from_step"]
    assert summary["faults/worker_replacements"] >= len(lost_workers) + len(moved_workers)
    assert "Unhandled error" not in err and "Traceback" not in err, err[-4000:]
    assert f"files:       {shared / RUN}/" in stdout
    # What the loss cost (docs/architecture.md "Clusters"; run with -s to see it): the kill's
    # time on the run's clock is estimated from the end (the summary's wall_s, ~1 s late).
    (restart,) = summary["learner_restarts"]
    cost = {"killed_at_wall_s": round(summary["wall_s"] - (ended - killed), 1), **restart,
            "step_at_kill": step, "snapshot_transitions": transitions,
            "lost_transitions": summary["lost_transitions"]}  # fmt: skip
    print("NODE-LOSS " + json.dumps(cost))
