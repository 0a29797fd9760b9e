"""Where the CPU of a running training goes, per role and per env step.

Attaches to a training that is already running on this machine (started with
``robogym-ray train``, local Ray) and reads nothing but ``/proc``: each process's user +
system CPU time at the start and the end of a window, grouped by what it is (Ray names its
actor processes ``ray::<ClassName>...``). With ``--run-dir`` it also reads the run's
TensorBoard file at both ends of the window to turn CPU seconds into milliseconds per env
step and per learner step, which is what decides how much experience 2 hours buy.

It changes nothing in the run and costs it next to nothing (two reads of ``/proc`` and of the
event file). The window's split is one moment of the run: episodes are longer early on, and
the evaluator's share depends on ``--eval-interval-s``; repeat it at a few points of the run.

Usage: python benchmarks/cpu_split.py --run-dir /tmp/paper/RUN [--seconds 60]
"""

from __future__ import annotations

import argparse
import os
import time
from collections import defaultdict
from pathlib import Path

# Ray titles actor processes "ray::<ClassName>" or "ray::<ClassName>.<method>" while busy.
ROLES = {
    "LearnerService": "learner",
    "_RayRobotServerHost": "robot servers",
    "_Rollout": "rollout workers",
    "_Evaluator": "evaluator",
    "_RaySupervisor": "supervisor",
}
RAY_ITSELF = ("raylet", "gcs_server", "dashboard", "log_monitor", "DashboardAgent", "monitor")
TICK = os.sysconf("SC_CLK_TCK")


def role_of(cmdline: str) -> str | None:
    """The role of a process from its command line, or None if it is no part of a training."""
    if cmdline.startswith("ray::"):
        name = cmdline[len("ray::") :].split()[0].split(".")[0]
        return ROLES.get(name, "Ray itself" if name in RAY_ITSELF else "other Ray workers")
    if "robogym-ray train" in cmdline:
        return "driver"
    if any(part in cmdline for part in RAY_ITSELF) and "/ray/" in cmdline:
        return "Ray itself"
    return None


def cpu_seconds() -> dict[int, tuple[str, float]]:
    """pid -> (role, user + system CPU seconds) for every process that belongs to a training."""
    out: dict[int, tuple[str, float]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
            # Fields 14 and 15 (utime, stime) come after the parenthesised command name,
            # which may itself contain spaces: split after its closing parenthesis.
            stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            continue  # the process ended between listing and reading
        role = role_of(cmdline)
        if role is not None:
            out[int(entry.name)] = (role, (int(stat[11]) + int(stat[12])) / TICK)
    return out


def machine_busy_seconds() -> float:
    """CPU seconds the whole machine spent busy (all processes, all CPUs) since boot.

    Steal time (field 8: the hypervisor ran someone else) counts as busy here, so on a shared
    host this line can sit above the sum of the processes even when nothing else runs."""
    fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = fields[3] + fields[4]  # idle + iowait
    return (sum(fields[:8]) - idle) / TICK


def run_counters(run_dir: Path) -> tuple[float, int, int] | None:
    """(wall time, env steps, learner steps) of the run's latest ``learner/steps`` point."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(str(run_dir), size_guidance={"scalars": 0})
    acc.Reload()
    if "learner/steps" not in acc.Tags()["scalars"]:
        return None
    last = acc.Scalars("learner/steps")[-1]
    return last.wall_time, last.step, int(last.value)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="window length")
    parser.add_argument("--run-dir", type=Path, help="the run's directory (TensorBoard events)")
    args = parser.parse_args()
    # Reading the event file costs seconds of CPU on a long run: keep it out of the window.
    counters_before = run_counters(args.run_dir) if args.run_dir else None
    before, busy_before = cpu_seconds(), machine_busy_seconds()
    start = time.monotonic()
    time.sleep(args.seconds)
    after, busy = cpu_seconds(), machine_busy_seconds() - busy_before
    wall = time.monotonic() - start
    counters_after = run_counters(args.run_dir) if args.run_dir else None
    by_role: dict[str, float] = defaultdict(float)
    count: dict[str, int] = defaultdict(int)
    for pid, (role, cpu) in after.items():
        if pid in before:  # processes started inside the window are left out
            by_role[role] += cpu - before[pid][1]
            count[role] += 1
    total = sum(by_role.values())
    # Rates from the run's own clock (its TensorBoard points), CPU shares from this window's:
    # the two are a few seconds apart at each end, so the per-step figures carry that error.
    env_rate = learner_rate = 0.0
    if counters_before and counters_after and counters_after[0] > counters_before[0]:
        span = counters_after[0] - counters_before[0]
        env_rate = (counters_after[1] - counters_before[1]) / span
        learner_rate = (counters_after[2] - counters_before[2]) / span
    print(f"window {wall:.0f} s, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
    if env_rate > 0:
        print(f"run: {env_rate:.0f} env steps/s, {learner_rate:.1f} learner steps/s")
    print("| role | processes | share of one core | ms CPU per env step |")
    print("|---|---|---|---|")
    rows = sorted(by_role.items(), key=lambda item: -item[1])
    rows += [("all of the training", total), ("whole machine (every process)", busy)]
    count["all of the training"] = sum(count.values())
    for role, cpu in rows:
        per_step = f"{1000 * cpu / wall / env_rate:.2f}" if env_rate > 0 else "-"
        procs = count.get(role, "-")
        print(f"| {role} | {procs} | {100 * cpu / wall:.0f} % | {per_step} |")


if __name__ == "__main__":
    main()
