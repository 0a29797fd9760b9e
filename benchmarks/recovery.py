"""Recovery time per fault cause: from injecting a fault to the next call a client gets served.

A local Ray runs one supervisor actor and one MiR100 robot-server actor. For each cause the fault
is injected for real (process killed by PID, hung simulation, NaN state, a call stalled past its
deadline and reported by the client, a manual restart); a client then polls the supervisor for
the server's address and calls GetState (0.5 s deadline) until it gets a valid state.

Run by hand: ``python benchmarks/recovery.py [--repeats 5] [--probe-interval 0.5]``.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import statistics
import tempfile
import time
from typing import Any

import ray

from robogym_ray.distributed.local_ray import start_local_ray
from robogym_ray.distributed.robot_actors import start_supervisor
from robogym_ray.errors import RobotServerError
from robogym_ray.protocol.client import Deadlines, RobotServerClient
from robogym_ray.supervision.restart_policy import RestartPolicy
from robogym_ray.supervision.server_host import ServerSpec
from robogym_ray.supervision.supervisor import SupervisorConfig

CAUSES = ("connection", "hung", "invalid_state", "deadline", "manual")


def served(supervisor: Any, sid: str, timeout: float = 60.0) -> float:
    """Poll until a GetState on the server's current address returns a valid state."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        info = ray.get(supervisor.info.remote(sid))
        if info["state"] == "running":
            try:
                with RobotServerClient(info["address"], deadlines=Deadlines.uniform(0.5)) as c:
                    if all(math.isfinite(v) for v in c.get_state().state):
                        return time.monotonic()
            except RobotServerError:
                pass
        time.sleep(0.01)
    raise TimeoutError(f"server {sid} not served within {timeout} s")


def inject(supervisor: Any, sid: str, cause: str) -> float:
    """Inject ``cause``; returns the time of the injection."""
    info = ray.get(supervisor.info.remote(sid))
    start = time.monotonic()
    if cause == "connection":
        os.kill(info["pid"], signal.SIGKILL)
    elif cause == "hung":
        ray.get(supervisor.inject_fault.remote(sid, "hang"))
    elif cause == "invalid_state":
        ray.get(supervisor.inject_fault.remote(sid, "nan"))
    elif cause == "deadline":
        ray.get(supervisor.inject_fault.remote(sid, "stall", 5.0))
        try:
            with RobotServerClient(info["address"], deadlines=Deadlines.uniform(0.5)) as c:
                c.send_action([0.1, 0.0])
        except RobotServerError as exc:
            ray.get(supervisor.report_fault.remote(sid, exc.cause, info["generation"]))
    else:
        ray.get(supervisor.restart.remote(sid))
    return start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--probe-interval", type=float, default=0.5)
    parser.add_argument("--probe-deadline", type=float, default=0.5)
    args = parser.parse_args()
    temp_dir = tempfile.mkdtemp(prefix="rgb", dir="/tmp")
    start_local_ray(
        2,
        _temp_dir=temp_dir,
        logging_level="ERROR",
        log_to_driver=False,
    )
    config = SupervisorConfig(
        probe_interval_s=args.probe_interval,
        probe_deadline_s=args.probe_deadline,
        restart=RestartPolicy(max_restarts=1000, backoff_s=0.0),  # measure recovery, not backoff
    )
    try:
        supervisor = start_supervisor(config, name="bench-supervisor")
        sid = ray.get(supervisor.start_server.remote(ServerSpec("mir100", scene="empty")))["id"]
        print(
            f"probe interval {args.probe_interval} s, probe deadline {args.probe_deadline} s, "
            f"{args.repeats} repeats"
        )
        print("| cause | median (s) | min (s) | max (s) |\n|---|---|---|---|")
        for cause in CAUSES:
            times = []
            for _ in range(args.repeats):
                start = inject(supervisor, sid, cause)
                times.append(served(supervisor, sid) - start)
                time.sleep(0.3)
            print(
                f"| {cause} | {statistics.median(times):.2f} | {min(times):.2f} | "
                f"{max(times):.2f} |",
                flush=True,
            )
        print("restarts counted:", ray.get(supervisor.info.remote(sid))["restarts"])
        ray.get(supervisor.shutdown.remote())
    finally:
        ray.shutdown()
        shutil.rmtree(temp_dir, ignore_errors=True)


if __name__ == "__main__":
    main()
