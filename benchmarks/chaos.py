"""Chaos: a navigation training under robot-server, rollout-worker and learner kills
(docs/benchmarks.md section 11).

    python benchmarks/chaos.py [--seconds 420] [--server-every 20] [--worker-at 50]
                               [--learner-at 110] [--after-snapshot 30] [--snapshot-every S]
                               [--checkpoint-every N] [--keep]

Runs ``run_training`` (navigation, 2 workers with one supervised robot server each, gRPC path,
on its own local Ray with 2 CPUs and a fresh logdir) for ``--seconds`` of training while
background threads SIGKILL, by the PIDs the run's actors report: a robot server every
``--server-every`` s, rollout worker 1 once at ``--worker-at`` s, and the learner once, at
``--learner-at`` s or later: ``--after-snapshot`` s after a replay snapshot, with at least one
regular checkpoint between (as a crash lands in a real run). The cadences default to
``TrainConfig``'s (a snapshot every 300 s, a checkpoint every 500 learner steps), hence the
420 s. It prints a markdown report for docs/benchmarks.md: what summary.json counted, the
snapshot's transitions against what the restarted learner restored, and how long each fault
took to recover. Exits 1 if the run did not finish (no summary.json) or the restarted learner
restored fewer transitions than the snapshot before its kill held.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import shutil
import signal
import statistics
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import ray

from robogym_ray.distributed.local_ray import start_local_ray
from robogym_ray.distributed.names import NAMESPACE, SUPERVISOR_NAME
from robogym_ray.learner.checkpoint import CHECKPOINT_NAME, read_replay, replay_path
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.run import run_training

RUN = "chaos"
POLL_S = 0.1  # recovery times are read to about this


def actor(name: str) -> Any:
    return ray.get_actor(name, namespace=NAMESPACE)


def worker_pid(name: str) -> int:
    return int(ray.get(actor(name).pid.remote(), timeout=10))


class Chaos:
    """The fault injectors (one thread each) and what they saw, in seconds of training: from
    ``t0``, when run_training wrote config.json (its actors are up, its loop starts)."""

    def __init__(self, args: argparse.Namespace, run_dir: Path) -> None:
        self.args, self.run_dir = args, run_dir
        self.t0 = math.inf
        self.done = threading.Event()
        self.events: list[dict[str, Any]] = []  # one per kill, filled in by its measurement
        self.replay_before: int | None = None
        self.snapshot: dict[str, float] | None = None
        """The replay snapshot the learner was killed after: its transitions, and seconds from
        it to the kill (checkpoints between: the learner.pt mtime went past it)."""
        self.threads = [
            threading.Thread(target=self._guard, args=(f,), daemon=True)
            for f in (self._servers, self._worker, self._learner)
        ]

    def elapsed(self) -> float:
        return time.monotonic() - self.t0

    def start(self) -> None:
        for t in self.threads:
            t.start()

    def stop(self) -> None:
        self.done.set()
        for t in self.threads:
            t.join(timeout=30)

    def _guard(self, body: Callable[[], None]) -> None:
        config = self.run_dir / "config.json"
        if not self._wait_for(config.exists, 600):
            return
        # Its mtime, not when this thread saw it, so that all three threads share one clock.
        self.t0 = time.monotonic() - (time.time() - config.stat().st_mtime)
        # An injector that fails must say so, not silently leave a fault out of the report.
        try:
            body()
        except Exception:  # noqa: BLE001 - reported, and the run goes on
            traceback.print_exc()

    def _wait_for(self, probe: Callable[[], Any], timeout: float = 120.0) -> Any:
        """Poll ``probe`` until it returns something truthy; None on timeout or run end.
        Exceptions count as "not yet": actors are missing or restarting while we look."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and not self.done.is_set():
            try:
                if value := probe():
                    return value
            except Exception:  # noqa: BLE001 - see the docstring
                pass
            time.sleep(POLL_S)
        return None

    def _kill(self, fault: str, target: str, pid: int) -> dict[str, Any] | None:
        if self.elapsed() > self.args.seconds - 2 or self.done.is_set():
            return None  # the run is ending: a kill now would hit its shutdown, not training
        os.kill(pid, signal.SIGKILL)
        event = {"fault": fault, "target": target, "pid": pid, "at": self.elapsed()}
        event["killed"] = time.monotonic()
        self.events.append(event)
        return event

    def _recovered(self, event: dict[str, Any], value: Any) -> None:
        event["recovery_s"] = time.monotonic() - event["killed"] if value else None

    # -- robot servers: one every --server-every s while the run has time to see it recover ---
    def _status(self) -> list[dict[str, Any]]:
        sup = actor(f"{SUPERVISOR_NAME}-{RUN}")
        return ray.get(sup.status.remote(), timeout=10)

    def _servers(self) -> None:
        if not self._wait_for(lambda: sum(bool(s["pid"]) for s in self._status()) >= 2, 180):
            return
        kills: dict[str, int] = {}
        period = self.args.server_every
        next_at = self.t0 + period * (1 + int(self.elapsed() // period))  # at 20, 40, ... s
        # No kill in the last period (at most 15 s): its recovery would race the shutdown.
        last_at = self.args.seconds - min(15.0, self.args.server_every)
        while not self.done.wait(max(0.0, next_at - time.monotonic())):
            next_at += self.args.server_every
            if self.elapsed() > last_at:
                return
            servers = self._wait_for(self._status, 10) or []
            running = [s for s in servers if s["pid"] and s["state"] == "running"]
            if not running:
                continue
            # The least-killed server: the supervisor gives up a server after 5 restarts in
            # 300 s (RestartPolicy), so spreading the kills keeps every one of them in play.
            victim = min(running, key=lambda s: (kills.get(s["id"], 0), s["id"]))
            kills[victim["id"]] = kills.get(victim["id"], 0) + 1
            event = self._kill("robot server", victim["id"], int(victim["pid"]))
            if event is None:
                return
            event["holder"] = victim["holder"]  # worker-I; worker-10000 is the evaluator's
            threading.Thread(target=self._server_back, args=(event,), daemon=True).start()

    def _server_back(self, event: dict[str, Any]) -> None:
        def back() -> dict[str, Any] | None:
            for s in self._status():
                if s["id"] == event["target"] and s["state"] == "running" and s["pid"]:
                    return s if s["pid"] != event["pid"] else None
            return None

        server = self._wait_for(back, 60)
        self._recovered(event, server)
        if server and server["recoveries"]:  # the supervisor's own time, fault seen -> running
            event["supervisor_s"] = server["recoveries"][-1][1]

    # -- one rollout worker ---------------------------------------------------------------------
    def _worker(self) -> None:
        i = 1
        self.done.wait(max(0.0, self.args.worker_at - self.elapsed()))
        pid = self._wait_for(lambda: worker_pid(f"rollout-{RUN}-{i}"))
        if not pid:
            return
        event = self._kill("rollout worker", f"rollout-{RUN}-{i}", int(pid))
        if event is None:
            return
        # The driver replaces a dead worker under the name ...-GENERATION.
        again = self._wait_for(lambda: worker_pid(f"rollout-{RUN}-{i}-1"))
        self._recovered(event, again)

    # -- the learner, a while after a replay snapshot ---------------------------------------------
    def _snapshot_then_checkpoint(self) -> dict[str, float] | None:
        """The newest replay snapshot (its transitions and mtime), once ``--after-snapshot``
        s have passed since it and a regular checkpoint was written after it: a kill right at
        a snapshot is the best case, and once hid that regular checkpoints deleted it."""
        checkpoint = self.run_dir / "checkpoints" / CHECKPOINT_NAME
        replay, seen = replay_path(checkpoint), self.snapshot or {"mtime": 0.0}
        if replay.exists() and replay.stat().st_mtime != seen["mtime"]:
            mtime = replay.stat().st_mtime
            seen = {"mtime": mtime, "transitions": int(read_replay(replay)["counters"][1])}
        self.snapshot = seen
        since = time.time() - seen["mtime"]
        checkpointed = checkpoint.stat().st_mtime - seen["mtime"] >= 1.0  # not the snapshot's own
        return (
            seen if seen["mtime"] and checkpointed and since >= self.args.after_snapshot else None
        )

    def _learner(self) -> None:
        self.done.wait(max(0.0, self.args.learner_at - self.elapsed()))
        snapshot = self._wait_for(self._snapshot_then_checkpoint, self.args.seconds)
        if not snapshot:
            return
        snapshot["before_kill_s"] = time.time() - snapshot["mtime"]
        status = self._wait_for(
            lambda: ray.get(actor(f"learner-{RUN}").status.remote(), timeout=10)
        )
        if not status:
            return
        # total_added == replay size here: the 1 M capacity is never reached in this run.
        self.replay_before = int(status["total_added"])
        event = self._kill("learner", f"learner-{RUN}", int(status["pid"]))
        if event is None:
            return

        def new_pid() -> bool:
            # A fresh handle each time; a call to a restarting actor waits, hence the timeout.
            now = ray.get(actor(f"learner-{RUN}").status.remote(), timeout=5)
            return now["pid"] != event["pid"]

        self._recovered(event, self._wait_for(new_pid, 180))


def seconds(value: float | None) -> str:
    return "not seen" if value is None else f"{value:.2f}"


def restored_enough(chaos: Chaos, summary: dict[str, Any] | None) -> bool:
    """Whether the restarted learner restored at least the snapshot it was killed after."""
    killed = any(e["fault"] == "learner" for e in chaos.events)
    if not (summary and killed and chaos.snapshot):
        return True  # nothing to compare: the report says the learner was not killed
    return summary["learner_restored_replay"] >= chaos.snapshot["transitions"]


def report(chaos: Chaos, summary: dict[str, Any] | None) -> None:
    command = "python " + " ".join(sys.argv)
    print(
        f"`{command}`, {datetime.date.today()}, machine `{platform.node()}`, "
        f"{os.cpu_count()} CPUs (Ray num_cpus=2); summary.json written: "
        f"{'yes' if summary else 'NO'}.\n"
    )
    if summary:
        restored = summary["learner_restored_replay"]
        snap = chaos.snapshot or {}
        restarts = ", ".join(f"{k} {v}" for k, v in summary["restarts"].items() if v) or "none"
        rows = [
            ("wall s (training)", str(summary["wall_s"])),
            ("env steps", f"{summary['env_steps']:,}"),
            ("learner steps", f"{summary['learner_steps']:,}"),
            ("server restarts by cause (`restarts`)", restarts),
            (
                "servers given up by the restart policy (`servers_given_up`)",
                summary["servers_given_up"],
            ),
            ("`faults/worker_failures`", summary["faults/worker_failures"]),
            ("`faults/worker_replacements`", summary["faults/worker_replacements"]),
            ("`faults/learner_failures`", summary.get("faults/learner_failures")),
            ("`dropped_steps`", summary["dropped_steps"]),
            ("`lost_transitions`", summary["lost_transitions"]),
            ("`learner_restored_from_step`", summary["learner_restored_from_step"]),
            ("replay just before the learner kill (its `total_added`)", chaos.replay_before),
            ("transitions in the replay snapshot before the kill", snap.get("transitions")),
            ("seconds from that snapshot to the kill", round(snap.get("before_kill_s", -1), 1)),
            ("replay after its restart (`learner_restored_replay`)", restored),
            ("restored at least the snapshot", "yes" if restored_enough(chaos, summary) else "NO"),
        ]
        print("| quantity | value |\n|---|---|")
        for name, value in rows:  # counters come back as floats from the scalars
            print(f"| {name} | {int(value) if isinstance(value, float) else value} |")
        print()
    print("| fault | target | killed at (s) | pid | back in (s) | supervisor's figure (s) |")
    print("|---|---|---|---|---|---|")
    for e in chaos.events:
        sup = seconds(e["supervisor_s"]) if "supervisor_s" in e else "-"
        target = f"{e['target']} ({e['holder']})" if e.get("holder") else e["target"]
        print(
            f"| {e['fault']} | {target} | {e['at']:.1f} | {e['pid']} | "
            f"{seconds(e.get('recovery_s'))} | {sup} |"
        )
    for fault in ("robot server", "rollout worker", "learner"):
        if not any(e["fault"] == fault for e in chaos.events):
            print(f"| {fault} | not killed before the run's end | | | | |")
    server = [
        e["recovery_s"]
        for e in chaos.events
        if e["fault"] == "robot server" and e.get("recovery_s") is not None
    ]
    if server:
        print(
            f"\nRobot servers: {len(server)} of "
            f"{sum(e['fault'] == 'robot server' for e in chaos.events)} back, median "
            f"{statistics.median(server):.2f} s, max {max(server):.2f} s."
        )
    print(
        "\nBack in: from the SIGKILL to a server running again with a new pid "
        "(supervisor status), the replacement worker `rollout-chaos-1-1` answering "
        "`pid()`, the learner answering `status()` with a new pid; polled every "
        f"{POLL_S} s. Killed at: seconds of training (from config.json, written as it starts)."
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    defaults = TrainConfig()  # the cadences a user's run has, unless told otherwise
    parser.add_argument("--seconds", type=float, default=420.0, help="max_wall_s of training")
    parser.add_argument("--server-every", type=float, default=20.0)
    parser.add_argument("--worker-at", type=float, default=50.0)
    parser.add_argument("--learner-at", type=float, default=110.0, help="not before (s)")
    parser.add_argument(
        "--after-snapshot", type=float, default=30.0,
        help="kill the learner this many s after a replay snapshot (checkpoints between)",
    )  # fmt: skip
    parser.add_argument("--snapshot-every", type=float, default=defaults.replay_snapshot_every_s)
    parser.add_argument("--checkpoint-every", type=int, default=defaults.checkpoint_every)
    parser.add_argument("--keep", action="store_true", help="keep the run directory")
    args = parser.parse_args()
    logdir = tempfile.mkdtemp(prefix="chaos-")
    temp_dir = tempfile.mkdtemp(prefix="rgc", dir="/tmp")  # short: Ray's socket paths
    start_local_ray(
        2,
        _temp_dir=temp_dir,
        logging_level="ERROR",
        log_to_driver=False,
    )
    cfg = TrainConfig(
        task="navigation",
        workers=2,
        sim_path="grpc",  # supervised robot servers, for the server kills
        envs_per_worker=1,  # one server per worker, as the server injector rotates over them
        total_steps=10_000_000,  # never reached: --seconds ends the run
        max_wall_s=args.seconds,
        logdir=logdir,
        run_name=RUN,
        progress=False,
        checkpoint_every=args.checkpoint_every,
        replay_snapshot_every_s=args.snapshot_every,
    )
    chaos = Chaos(args, Path(logdir) / RUN)
    summary, finished = None, False
    try:
        chaos.start()
        try:
            summary = run_training(cfg)
        except Exception:  # noqa: BLE001 - the report says the run did not finish
            traceback.print_exc()
        chaos.stop()
        finished = (Path(logdir) / RUN / "summary.json").exists()
        report(chaos, summary if finished else None)
        finished = finished and restored_enough(chaos, summary)
    finally:
        ray.shutdown()
        shutil.rmtree(temp_dir, ignore_errors=True)
        if not args.keep:
            shutil.rmtree(logdir, ignore_errors=True)
        else:
            print(f"\nrun directory: {logdir}/{RUN}")
    return 0 if finished else 1


if __name__ == "__main__":
    sys.exit(main())
