"""The learner's capacity: updates/s and samples/s by batch, threads and device.

Navigation's shapes and recipe networks: 20 observations, 2 actions, (400, 300) with LayerNorm,
51 atoms, prioritized replay pre-filled with 100,000 random transitions. Three modes:

    python benchmarks/learner_capacity.py alone --batches 256 1024 4096 --threads 1 2
        the learner in this process; also --device cuda, --compile reduce-overhead, --bf16,
        --sgd-steps 8, --replay-device learner (the GPU path's switches);
    RAY_AUTH_MODE=disabled python benchmarks/learner_capacity.py ray --batch 1024 --cpus 1 2
        the learner actor on a local Ray given each number of CPUs (its threads follow them),
        rounds alternating;
    python benchmarks/learner_capacity.py alone --batches 1024 --threads 1 2 --load 0.5
        the same beside one process that keeps a core busy half the time (a rollout worker's
        share of the cores), to measure what a thread the cores cannot hold costs;
    python benchmarks/learner_capacity.py paths --paths compiled whole --batches 256 1792 \
            --device cuda --rounds 3 --call-steps 4
        the learner's step paths side by side in one process: the host-stepped step eager
        ("eager") or with compiled losses ("compiled", torch.compile reduce-overhead), and the
        whole step in one CUDA graph ("whole", whole_step on); each built and warmed once,
        then timed in turn, ``--rounds`` windows each (ratios from one machine, one minute);
    python benchmarks/learner_capacity.py versus /tmp/before --batch 256 --threads 1
        this tree against another checkout (``git worktree add /tmp/before COMMIT``): the
        ``alone`` mode in fresh processes, alternating, the ratio per pair.

Each figure is timed over whole learner steps (sampling, both updates, priorities, targets)
after a warm-up (compilation included there); one JSON line per measurement.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from learner_throughput import random_batch  # benchmarks/ is this script's folder

OBS, ACT, FILL = 20, 2, 100_000
LOAD_PERIOD_S = 0.004
"""A load's busy-then-idle cycle: a few navigation env steps and a call, as a worker runs."""


def nav_config(batch: int, **kw: Any) -> Any:
    from robogym_ray.learner.config import D4PGConfig

    return D4PGConfig(
        policy_hidden=(400, 300), critic_hidden=(400, 300), layer_norm=True, num_atoms=51,
        v_min=-300.0, v_max=450.0, batch_size=batch, replay_capacity=FILL,
        min_replay_size=1000, **kw,
    )  # fmt: skip


def run_steps(learner: Any, steps: int) -> None:
    """``run`` where the learner has it; a checkout from before it has only ``step``."""
    if hasattr(learner, "run"):
        learner.run(steps)
    else:
        for _ in range(steps):
            learner.step()


@contextmanager
def cpu_load(duty: float) -> Iterator[None]:
    """One process beside the learner, busy ``duty`` of every period and asleep the rest: what
    a rollout worker does to the cores the learner's threads run on. The OS places both."""
    if duty <= 0:
        yield
        return
    busy, idle = duty * LOAD_PERIOD_S, (1.0 - duty) * LOAD_PERIOD_S
    code = (
        "import time\n"
        "while True:\n"
        "    t = time.perf_counter()\n"
        f"    while time.perf_counter() - t < {busy}: pass\n"
        f"    time.sleep({idle})\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code])
    try:
        yield
    finally:
        proc.kill()  # by its PID, the only process this started
        proc.wait()


def alone(batch: int, threads: int, seconds: float, args: argparse.Namespace) -> dict:
    import torch

    from robogym_ray.learner.learner import D4PGLearner

    extra = {}
    for field, value in (("compile", args.compile), ("bf16", args.bf16),
                         ("sgd_steps_per_sample", args.sgd_steps),
                         ("replay_device", args.replay_device),
                         ("whole_step", args.whole_step)):  # fmt: skip
        if value not in (None, "", False):
            extra[field] = value
    torch.set_num_threads(threads)
    learner = D4PGLearner(nav_config(batch, device=args.device, **extra), OBS, ACT, seed=0)
    learner.add(random_batch(FILL, OBS, ACT))
    with cpu_load(args.load):
        start = time.perf_counter()
        run_steps(learner, args.warmup)
        warmup_s = time.perf_counter() - start
        steps, start = 0, time.perf_counter()
        chunk = max(1, args.sgd_steps or 1)
        while time.perf_counter() - start < seconds:
            run_steps(learner, chunk)
            steps += chunk
        if learner.device.type == "cuda":
            torch.cuda.synchronize()
        elapsed = time.perf_counter() - start
    profile = {}
    if args.profile:
        try:
            profile = profiled(learner, args.profile, chunk)
        except Exception as exc:  # noqa: BLE001 - a figure is kept when its profile fails
            profile = {"profile_error": repr(exc)}
    return {
        "mode": "alone", "device": str(learner.device), "threads": threads, "batch": batch,
        **extra, **({"load": args.load} if args.load else {}),
        "updates_per_s": round(steps / elapsed, 2),
        "samples_per_s": round(steps * batch / elapsed), "warmup_s": round(warmup_s, 1),
        "code": str(Path(sys.modules[D4PGLearner.__module__].__file__).parents[2]),
        **profile,
    }  # fmt: skip


PATHS = {"eager": {}, "compiled": {"compile": "reduce-overhead"}, "whole": {"whole_step": "on"}}
"""The learner's step paths ``paths`` mode compares, as the D4PG settings that pick them."""


def paths(args: argparse.Namespace) -> None:
    """Each path's learner built and warmed once per batch, then timed window by window in
    turn (``--rounds``), each window ``--seconds`` long in calls of ``--call-steps`` steps."""
    import torch

    from robogym_ray.learner.learner import D4PGLearner

    data = random_batch(FILL, OBS, ACT)
    for batch in args.batches:
        learners = {}
        for name in args.paths:
            try:
                config = nav_config(batch, device=args.device, **PATHS[name])
                learner = D4PGLearner(config, OBS, ACT, seed=0)
                learner.add(data)
                start = time.perf_counter()
                run_steps(learner, args.warmup)
                learners[name] = (learner, round(time.perf_counter() - start, 1))
            except Exception as exc:  # noqa: BLE001 - the other paths are still measured
                print(json.dumps({"mode": "paths", "path": name, "batch": batch,
                                  "error": repr(exc)[:400]}), flush=True)  # fmt: skip
        for r in range(args.rounds):
            for name, (learner, warmup_s) in learners.items():
                steps, start = 0, time.perf_counter()
                while time.perf_counter() - start < args.seconds:
                    learner.run(args.call_steps)
                    steps += args.call_steps
                if learner.device.type == "cuda":
                    torch.cuda.synchronize()
                elapsed = time.perf_counter() - start
                print(json.dumps({
                    "mode": "paths", "path": name, "round": r, "batch": batch,
                    "device": str(learner.device), "call_steps": args.call_steps,
                    "updates_per_s": round(steps / elapsed, 1),
                    "samples_per_s": round(steps * batch / elapsed), "warmup_s": warmup_s,
                }), flush=True)  # fmt: skip


def profiled(learner: Any, steps: int, chunk: int) -> dict:
    """Where a step's time goes: wall time, the device's kernel time (its busy share on a GPU),
    the host's operator calls per step (nested ones included) and those that take its time."""
    import torch
    from torch.autograd import DeviceType
    from torch.profiler import ProfilerActivity, profile

    cuda = learner.device.type == "cuda"
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if cuda else [])
    steps = max(chunk, steps - steps % chunk)
    with profile(activities=activities) as prof:
        start = time.perf_counter()
        run_steps(learner, steps)
        if cuda:
            torch.cuda.synchronize()
        wall = time.perf_counter() - start
    # The device's own events are its kernels, copies and fills, each with its interval (one
    # stream); annotated ranges are device events too, spanning kernels already counted.
    kernel_us = sum(
        e.time_range.elapsed_us()
        for e in prof.events()
        if e.device_type == DeviceType.CUDA and not getattr(e, "is_user_annotation", False)
    )
    ops = [e for e in prof.key_averages() if e.key.startswith("aten::")]
    top = sorted(ops, key=lambda e: e.self_cpu_time_total, reverse=True)[:8]
    return {
        "profile_steps": steps,
        "wall_ms_per_step": round(wall * 1e3 / steps, 3),
        **({"kernel_ms_per_step": round(kernel_us / 1e3 / steps, 3)} if cuda else {}),
        "aten_calls_per_step": round(sum(e.count for e in ops) / steps, 1),
        "top_host_ops": [
            [e.key, round(e.self_cpu_time_total / 1e3 / steps, 3), round(e.count / steps, 1)]
            for e in top
        ],
    }


def on_ray(batch: int, cpus: list[float], rounds: int, steps: int) -> list[dict]:
    import ray

    from robogym_ray.distributed import remote
    from robogym_ray.distributed.local_ray import start_local_ray

    temp = tempfile.mkdtemp(prefix="rgr-cap", dir="/tmp")
    start_local_ray(max(cpus), _temp_dir=temp, logging_level="ERROR", log_to_driver=False)
    # A tiny samples_per_insert: the fill earns no steps; train(steps) is timed on its own.
    d4pg = nav_config(batch, device="cpu", samples_per_insert=1e-3)
    data = ray.put(random_batch(FILL, OBS, ACT))
    out = []
    try:
        for r in range(rounds):
            for c in cpus:
                learner = remote.LearnerActor.options(num_cpus=c).remote(d4pg, OBS, ACT)
                ray.get(learner.add.remote(data))
                ray.get(learner.train.remote(5))  # warm-up
                before = ray.get(learner.train.remote(0))["learner_time_s"]
                after = ray.get(learner.train.remote(steps))["learner_time_s"]
                threads = ray.get(learner.status.remote())["threads"]
                ray.kill(learner)
                elapsed = after - before
                out.append({
                    "mode": "ray", "round": r, "num_cpus": c, "threads": threads,
                    "batch": batch, "updates_per_s": round(steps / elapsed, 2),
                    "samples_per_s": round(steps * batch / elapsed),
                })  # fmt: skip
                print(json.dumps(out[-1]), flush=True)
    finally:
        ray.shutdown()
    return out


def versus(other: Path, args: argparse.Namespace) -> dict:
    """The ``alone`` mode in fresh processes, this tree and ``other`` in turn."""
    here = Path(__file__).resolve().parents[1]
    figures: dict[str, list[float]] = {"this": [], "other": []}
    for _ in range(args.rounds):
        for label, root in (("this", here), ("other", other)):
            env = {**os.environ, "PYTHONPATH": str(root)}
            cmd = [sys.executable, __file__, "alone", "--batches", str(args.batch),
                   "--threads", str(args.threads[0]), "--seconds", str(args.seconds)]  # fmt: skip
            line = (
                subprocess.run(cmd, env=env, cwd=root, capture_output=True, text=True, check=True)
                .stdout.strip()
                .splitlines()[-1]
            )
            figures[label].append(json.loads(line)["updates_per_s"])
    ratios = [a / b for a, b in zip(figures["this"], figures["other"], strict=True)]
    return {
        "mode": "versus", "other": str(other), "batch": args.batch, "threads": args.threads[0],
        "this_updates_per_s": figures["this"], "other_updates_per_s": figures["other"],
        "ratio_median": round(statistics.median(ratios), 3),
        "ratio_min": round(min(ratios), 3), "ratio_max": round(max(ratios), 3),
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("alone", "ray", "versus", "paths"))
    parser.add_argument("other", nargs="?", type=Path, help="versus: the other checkout")
    parser.add_argument("--batches", type=int, nargs="+", default=[256, 1024, 4096])
    parser.add_argument("--batch", type=int, default=1024, help="ray and versus modes")
    parser.add_argument("--threads", type=int, nargs="+", default=[1])
    parser.add_argument("--cpus", type=float, nargs="+", default=[1.0, 2.0], help="ray mode")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=10.0, help="timed per figure")
    parser.add_argument("--ray-steps", type=int, default=100, help="ray mode: steps timed")
    parser.add_argument("--warmup", type=int, default=10, help="steps before timing")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--compile", default="")
    parser.add_argument("--bf16", action="store_true")
    parser.add_argument("--sgd-steps", type=int, default=0, help="sgd_steps_per_sample")
    parser.add_argument("--replay-device", default="")
    parser.add_argument("--whole-step", default="", help="alone: whole_step (on, off, auto)")
    parser.add_argument("--paths", nargs="+", choices=list(PATHS), default=["compiled", "whole"])
    parser.add_argument("--call-steps", type=int, default=1, help="paths: steps per run call")
    parser.add_argument(
        "--load",
        type=float,
        default=0.0,
        help="alone: a process beside, busy this share of one core",
    )
    parser.add_argument("--profile", type=int, default=0, help="alone: steps profiled after")
    args = parser.parse_args(argv)
    if args.mode == "alone":
        for batch in args.batches:
            for threads in args.threads:
                print(json.dumps(alone(batch, threads, args.seconds, args)), flush=True)
    elif args.mode == "paths":
        paths(args)
    elif args.mode == "ray":
        on_ray(args.batch, args.cpus, args.rounds, args.ray_steps)
    else:
        if args.other is None:
            parser.error("versus needs the other checkout's path")
        print(json.dumps(versus(args.other, args)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
