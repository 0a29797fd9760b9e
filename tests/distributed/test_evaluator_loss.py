"""A lost evaluator is replaced: its process killed mid-run, a new one leases the server the
dead one held (--sim-path grpc) and goes on from its episodes; the run counts the loss."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable
from pathlib import Path

import pytest
import ray

from robogym_ray.distributed import names
from robogym_ray.supervision.restart_policy import FaultCause
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.run import run_training

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.usefixtures("ray_cluster")]

KILL_AFTER = 2
"""Episodes the first evaluator plays before it is killed: more than a replacement that
started its count again would report after its first call (one episode)."""


def test_a_killed_evaluator_is_replaced_and_goes_on(
    tmp_path: Path, stop_run: Callable[[], None]
) -> None:
    run = "evalloss"
    cfg = TrainConfig(
        task="navigation",
        workers=1,
        sim_path="grpc",  # the evaluator leases a supervised server, as holder "evaluator"
        envs_per_worker=1,
        total_steps=10**6,
        # A guard against a hang, not a measure of speed: the run is stopped once the
        # replacement has gone on (21-28 s on 2 cores, twice that on a slower CPU).
        max_wall_s=600.0,
        logdir=str(tmp_path),
        run_name=run,
        progress=False,
    )
    done = threading.Event()
    seen: dict[str, int] = {}
    held: dict[str, str] = {}  # the id of the server the evaluator leased: dead, replacement

    def status(name: str) -> dict[str, int] | None:
        try:
            actor = ray.get_actor(name, namespace=names.NAMESPACE)
            return ray.get(actor.status.remote(), timeout=30)  # waits for a running episode
        except Exception:  # noqa: BLE001 - not started yet, or already gone
            return None

    def evaluators_server() -> str:
        """The id of the server leased by holder "evaluator" ("" if none is)."""
        supervisor = ray.get_actor(names.run_supervisor_name(run), namespace=names.NAMESPACE)
        servers = ray.get(supervisor.status.remote(), timeout=30)
        return next((s["id"] for s in servers if s["holder"] == "evaluator"), "")

    def kill_then_watch() -> None:
        while not done.wait(0.3):
            first = status(f"evaluator-{run}")
            if first and first["episodes"] >= KILL_AFTER:
                held["dead"] = evaluators_server()
                os.kill(first["pid"], signal.SIGKILL)
                seen["killed_at"] = first["episodes"]
                seen["killed_pid"] = first["pid"]
                break
        while not done.wait(0.3):
            second = status(f"evaluator-{run}-1")
            if second is None:
                continue
            # Its status can answer before its first episode (the run's ping comes first):
            # the first count seen says where it started, a later one that it went on.
            seen.setdefault("replacement_first", second["episodes"])
            seen["replacement"] = second["episodes"]
            seen["replacement_pid"] = second["pid"]
            if second["episodes"] > seen["killed_at"]:
                held["replacement"] = evaluators_server()
                stop_run()  # seen all it shows: the rest of max_wall_s would add nothing
                return

    failed: list[BaseException] = []

    def watch() -> None:  # a watcher that fails stops the run: its error, not a timeout
        try:
            kill_then_watch()
        except BaseException as exc:  # noqa: BLE001 - re-raised in the test's thread
            failed.append(exc)
            stop_run()

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        summary = run_training(cfg)
    finally:
        done.set()
        watcher.join()
    if failed:
        raise failed[0]
    assert seen.get("killed_at", 0) >= KILL_AFTER, seen
    assert summary["faults/evaluator_failures"] == 1
    # The replacement started from the dead one's count (a fresh count would first show 0 or
    # 1), went on past it, and in a process of its own.
    assert seen.get("replacement_first", 0) >= seen["killed_at"], seen
    assert seen.get("replacement", 0) > seen["killed_at"], seen
    assert seen["replacement_pid"] != seen["killed_pid"], seen
    assert summary["eval/episodes"] > seen["killed_at"]
    # It leased the very server the dead one held: the dead lease was ended, not leaked.
    assert held["dead"] and held.get("replacement") == held["dead"], held
    # Losing the evaluator cost nothing else: no worker or learner, and no server restart for
    # a fault the loss could leave (a server gone, refused, or left in a bad state). A call
    # over its 5-s deadline or a missed probe is the machine's speed, not the loss: a CI run
    # at four times this test's usual time saw two such restarts, which the supervisor is
    # there to make (tests/distributed/test_fault_counts.py counts them).
    assert summary["faults/learner_failures"] == 0 == summary["faults/worker_failures"]
    timing = {FaultCause.DEADLINE.value, FaultCause.HUNG.value}
    lost = {cause: n for cause, n in summary["restarts"].items() if cause not in timing}
    assert sum(lost.values()) == 0, summary["restarts"]
