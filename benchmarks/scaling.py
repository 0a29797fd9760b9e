"""The data path's capacity and the training configurations the cost model is checked against.

    RAY_AUTH_MODE=disabled python benchmarks/scaling.py train --task free --workers 1 2 \
        --envs 1 4 8 --samples-per-insert 0.001 --wall-s 60 --repeats 3
        ``robogym-ray train`` runs (embedded Ray, 2 CPUs, no evaluator) for each combination,
        one after another and the combinations in turn ``--repeats`` times (the machine is noisy:
        medians and spreads, not one run); prints env steps/s, learner steps/s, collect calls/s
        and object-store bytes/s per run. ``--task free`` is ``RoboGymRayBench/Free-v0`` (no
        simulation, navigation's shapes); with a tiny samples-per-insert the learner takes no
        steps, so env steps/s is what the data path carries. ``--task navigation`` and
        ``--batch``/``--learner-cpus`` give the learner-bound configurations.
    RAY_AUTH_MODE=disabled python benchmarks/scaling.py broadcast --workers 1 2 4 8
        the navigation policy's weights (one object-store put) to N rollout actors: seconds from
        the put to the last worker's answer, median of --rounds.
    python benchmarks/scaling.py worker --task free navigation --envs 1 4 8
        a rollout worker's CPU per env step in this process (the cost model's env side);
    python benchmarks/scaling.py replay --capacities 1000000 10000000
        the prioritized replay's insert (a 200-transition batch, one collect call's) and sample
        (batch 256 and 1,024) costs when full.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from robogym_ray.envs.free import FREE_ENV_ID

HERE = Path(__file__).resolve().parent
TASKS = {"free": FREE_ENV_ID, "navigation": "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"}
CONFIG = HERE.parent / "experiments/configs/navigation-average.json"
BYTES_PER_TRANSITION = 4 * (20 + 2 + 1 + 1 + 20)
"""obs, action, reward, discount, next_obs as float32: what one navigation transition moves."""


def train_run(task: str, workers: int, envs: int, args: argparse.Namespace, run: str) -> dict:
    d4pg = {"samples_per_insert": args.samples_per_insert, "batch_size": args.batch,
            **json.loads(args.d4pg)}  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="scaling-") as logdir:
        config = Path(logdir) / "config.json"
        # Scalars every 2 s: enough points for the late rate of a 30-s run (late_rates).
        config.write_text(json.dumps({"extends": str(CONFIG), "d4pg": d4pg,
                                      "train": {"log_every_s": 2.0}}))  # fmt: skip
        # The CLI by its module: a node with the repository on PYTHONPATH has no robogym-ray.
        cmd = [sys.executable, "-m", "robogym_ray.cli", "train", "--config", str(config),
               "--task", TASKS[task],
               "--workers", str(workers), "--envs-per-worker", str(envs),
               "--total-steps", "1000000000", "--max-wall-s", str(args.wall_s),
               "--logdir", logdir, "--run-name", run, "--no-progress",
               "--num-cpus", str(args.num_cpus), "--learner-gpus", str(args.learner_gpus),
               "--no-evaluator", "--learner-cpus", str(args.learner_cpus),
               "--worker-cpus", str(args.worker_cpus),
               "--policy-snapshot-every-s", "0", "--checkpoint-every", "0"]  # fmt: skip
        load = os.getloadavg()[0]
        env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise SystemExit(f"{run} failed:\n{done.stderr[-3000:]}")
        s = json.loads((Path(logdir) / run / "summary.json").read_text())
        late = late_rates(Path(logdir) / run)
    env_rate = s["throughput/env_steps_per_s"]
    return {
        "task": task, "workers": workers, "envs": envs, "batch": args.batch,
        "samples_per_insert": args.samples_per_insert, "learner_cpus": args.learner_cpus,
        "worker_cpus": args.worker_cpus,
        "learner_threads": s.get("learner_threads"), "learner_device": s.get("learner_device"),
        "d4pg": args.d4pg,
        "env_steps_per_s": round(env_rate, 1),
        "learner_steps_per_s": round(s["throughput/learner_steps_per_s"], 2),
        "collect_calls_per_s": round(env_rate / 50, 2),  # steps_per_call 50 (the recipe's)
        "object_store_mb_per_s": round(env_rate * BYTES_PER_TRANSITION / 1e6, 3),
        "load_before": round(load, 2), "wall_s": s["wall_s"], **late,
    }  # fmt: skip


def late_rates(run_dir: Path) -> dict:
    """Env and learner steps/s over the run's second half, from its TensorBoard events (a
    scalar's step is the env step; ``learner/steps`` is its value): the rate once the workers'
    start and the replay's warm-up are behind, which a short run's whole-wall rate hides."""
    try:
        from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    except ImportError:
        return {}
    events = EventAccumulator(str(run_dir), size_guidance={"scalars": 0})
    events.Reload()
    try:
        series = events.Scalars("learner/steps")
    except KeyError:
        return {}
    if len(series) < 3:
        return {}
    mid, last = series[len(series) // 2], series[-1]
    span = last.wall_time - mid.wall_time
    return {
        "late_env_steps_per_s": round((last.step - mid.step) / span, 1),
        "late_learner_steps_per_s": round((last.value - mid.value) / span, 2),
        "late_span_s": round(span, 1),
    }


def train(args: argparse.Namespace) -> None:
    rows = []
    combos = list(itertools.product(args.task, args.workers, args.envs))
    for r in range(args.repeats):
        for i, (task, workers, envs) in enumerate(combos):
            rows.append(train_run(task, workers, envs, args, f"{task}-{workers}x{envs}-{r}-{i}"))
            print(json.dumps(rows[-1]), flush=True)
    for combo in combos:
        runs = [x for x in rows if (x["task"], x["workers"], x["envs"]) == combo]
        rates = [x["env_steps_per_s"] for x in runs]
        print(json.dumps({
            "summary": f"{combo[0]} {combo[1]}x{combo[2]} batch {args.batch} spi "
                       f"{args.samples_per_insert} learner_cpus {args.learner_cpus}",
            "env_steps_per_s_median": statistics.median(rates),
            "env_min": min(rates), "env_max": max(rates),
            "learner_steps_per_s_median": statistics.median(
                x["learner_steps_per_s"] for x in runs
            ),
        }))  # fmt: skip


def broadcast(args: argparse.Namespace) -> None:
    import ray

    from robogym_ray.distributed import remote
    from robogym_ray.distributed.local_ray import start_local_ray
    from robogym_ray.experience.rollout import make_gym_env
    from robogym_ray.learner.config import D4PGConfig
    from robogym_ray.learner.networks import Policy

    temp = tempfile.mkdtemp(prefix="rgr-bcast", dir="/tmp")
    start_local_ray(2, _temp_dir=temp, logging_level="ERROR", log_to_driver=False)
    d4pg = D4PGConfig(policy_hidden=(400, 300), critic_hidden=(400, 300), layer_norm=True)
    policy = Policy(20, 2, d4pg.policy_hidden, d4pg.layer_norm)
    weights = {k: v.numpy().copy() for k, v in policy.state_dict().items()}
    size = sum(w.nbytes for w in weights.values())
    try:
        for n in args.workers:
            actors = [
                remote.RolloutActor.options(num_cpus=0.01).remote(
                    make_gym_env(FREE_ENV_ID), d4pg, index=i, seed=i
                )
                for i in range(n)
            ]
            times = []
            for _ in range(args.rounds):
                start = time.perf_counter()
                ref = ray.put((weights, 1))  # what the driver sends: (weights, version)
                ray.get([a.set_weights.remote(ref) for a in actors])
                times.append(time.perf_counter() - start)
            for a in actors:
                ray.kill(a)
            print(json.dumps({
                "broadcast_workers": n, "weights_mb": round(size / 1e6, 3),
                "seconds_median": round(statistics.median(times[1:] or times), 5),
                "seconds_max": round(max(times), 5),
            }), flush=True)  # fmt: skip
    finally:
        ray.shutdown()


def worker(args: argparse.Namespace) -> None:
    """A rollout worker's CPU per env step (``collect`` in this process, one torch thread,
    the recipe's policy; no Ray): the model's ``env_cpu_s``."""
    import torch

    from robogym_ray.experience.rollout import RolloutWorker, make_gym_env
    from robogym_ray.learner.config import D4PGConfig

    torch.set_num_threads(1)
    d4pg = D4PGConfig(policy_hidden=(400, 300), critic_hidden=(400, 300), layer_norm=True)
    for task in args.task:
        for envs in args.envs:
            w = RolloutWorker(make_gym_env(TASKS[task]), d4pg, seed=0, num_envs=envs)
            w.collect(200)  # warm-up: resets, first forward passes
            best = float("inf")
            for _ in range(args.rounds):
                start = time.process_time()
                w.collect(args.steps)
                best = min(best, (time.process_time() - start) / args.steps)
            w.close()
            row = {"worker_task": task, "envs": envs, "cpu_ms_per_env_step": round(best * 1e3, 4)}
            print(json.dumps(row), flush=True)


def replay(args: argparse.Namespace) -> None:
    from robogym_ray.learner.replay import PrioritizedReplay

    rng = np.random.default_rng(0)
    for capacity in args.capacities:
        r = PrioritizedReplay(capacity, 20, 2, alpha=0.6, seed=0)
        chunk = 100_000
        for start in range(0, capacity, chunk):
            n = min(chunk, capacity - start)
            r.add({
                "obs": rng.standard_normal((n, 20), dtype=np.float32),
                "action": np.zeros((n, 2), np.float32), "reward": np.zeros(n, np.float32),
                "discount": np.ones(n, np.float32),
                "next_obs": rng.standard_normal((n, 20), dtype=np.float32),
            }, rng.random(n) + 0.1)  # fmt: skip
        insert = {
            "obs": rng.standard_normal((200, 20), dtype=np.float32),
            "action": np.zeros((200, 2), np.float32), "reward": np.zeros(200, np.float32),
            "discount": np.ones(200, np.float32),
            "next_obs": rng.standard_normal((200, 20), dtype=np.float32),
        }  # fmt: skip
        row = {"capacity": capacity}
        start = time.perf_counter()
        for _ in range(200):
            r.add(insert)
        row["insert_200_ms"] = round((time.perf_counter() - start) / 200 * 1e3, 4)
        for batch in (256, 1024):
            start = time.perf_counter()
            for _ in range(100):
                _, idx, _ = r.sample(batch, 0.6)
                r.update_priorities(idx, rng.random(batch))
            row[f"sample_and_update_{batch}_ms"] = round((time.perf_counter() - start) * 10, 4)
        print(json.dumps(row), flush=True)
        del r


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    t = sub.add_parser("train")
    t.add_argument("--task", nargs="+", choices=list(TASKS), default=["free"])
    t.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    t.add_argument("--envs", type=int, nargs="+", default=[4])
    t.add_argument("--batch", type=int, default=256)
    t.add_argument("--samples-per-insert", type=float, default=32.0)
    t.add_argument("--learner-cpus", type=float, default=0.5)
    t.add_argument("--worker-cpus", type=float, default=0.25)
    t.add_argument("--wall-s", type=float, default=60.0)
    t.add_argument("--repeats", type=int, default=3)
    t.add_argument("--num-cpus", type=float, default=2.0, help="the embedded Ray's CPUs")
    t.add_argument("--learner-gpus", type=float, default=-1.0, help="0: a CPU learner")
    t.add_argument("--d4pg", default="{}", help="JSON: more d4pg settings, e.g. compile")
    b = sub.add_parser("broadcast")
    b.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4, 8])
    b.add_argument("--rounds", type=int, default=20)
    w = sub.add_parser("worker")
    w.add_argument("--task", nargs="+", choices=list(TASKS), default=["free", "navigation"])
    w.add_argument("--envs", type=int, nargs="+", default=[1, 4, 8])
    w.add_argument("--steps", type=int, default=2000)
    w.add_argument("--rounds", type=int, default=3)
    r = sub.add_parser("replay")
    r.add_argument("--capacities", type=int, nargs="+", default=[1_000_000, 10_000_000])
    args = parser.parse_args()
    modes = {"train": train, "broadcast": broadcast, "worker": worker, "replay": replay}
    modes[args.mode](args)


if __name__ == "__main__":
    main()
