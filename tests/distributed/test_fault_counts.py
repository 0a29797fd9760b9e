"""One fault, one count: a robot server paused mid-run (--sim-path grpc) is replaced once and
counted once, by the first cause seen, though its worker's client also saw the fault."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from pathlib import Path

import pytest
import ray

from robogym_ray.distributed import remote
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.run import run_training

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.usefixtures("ray_cluster")]


def test_a_paused_robot_server_replaced_once_is_one_restart(tmp_path: Path) -> None:
    run = "paused"
    cfg = TrainConfig(
        task="navigation",
        workers=1,
        sim_path="grpc",
        envs_per_worker=1,
        evaluator=False,
        total_steps=10**6,
        max_wall_s=30.0,  # the pause, its restart, and the worker going on after it
        logdir=str(tmp_path),
        run_name=run,
        progress=False,
    )
    done, paused = threading.Event(), []

    def pause_worker_server() -> None:
        """SIGSTOP worker 0's server once it serves, SIGCONT it 20 s later (if still there)."""
        while not done.wait(0.3):
            try:
                sup = ray.get_actor(f"{remote.SUPERVISOR_NAME}-{run}", namespace=remote.NAMESPACE)
                servers = ray.get(sup.status.remote(), timeout=10)
            except Exception:  # noqa: BLE001 - not started yet
                continue
            pids = [s["pid"] for s in servers if s["pid"] and s["holder"] == "worker-0"]
            if pids:
                os.kill(pids[0], signal.SIGSTOP)
                paused.append(time.monotonic())
                done.wait(20)
                with contextlib.suppress(ProcessLookupError):  # replaced, as it should be
                    os.kill(pids[0], signal.SIGCONT)
                return

    pauser = threading.Thread(target=pause_worker_server)
    pauser.start()
    try:
        summary = run_training(cfg)
    finally:
        done.set()
        pauser.join()
    assert len(paused) == 1
    # The supervisor's probe saw the pause first (hung) and replaced the server; the worker's
    # client then saw its call fail too (a deadline or a reset) - the same fault, not another.
    assert summary["restarts"]["hung"] == 1, summary["restarts"]
    assert sum(summary["restarts"].values()) == 1, summary["restarts"]
    assert summary["servers_given_up"] == 0  # one fault is far from the policy's limit
    # A pause during a step ends that episode as server_restarted; one during a reset is retried
    # inside reset() on the replacement (base.RobotServerEnv.reset), and no episode ends. Either
    # way the worker's view of the fault ends at most one episode.
    assert summary["final_status_counts"].get("server_restarted", 0) <= 1, summary
    assert summary["faults/learner_failures"] == 0
