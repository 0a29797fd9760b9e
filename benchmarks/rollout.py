"""Rollout env steps/s with 1 and 2 Ray rollout workers (each with its supervised robot server).

Workers act with the policy network (random initial weights) and exploration noise, exactly as
in training, but no learner runs, so this isolates the rollout side. Rounds alternate between 1
and 2 workers within one run. Scaling target: rate(2) / rate(1) >= 1.6 (0.8x linear per core).

Usage: python benchmarks/rollout.py [--task navigation] [--steps 1500] [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np
import ray

from robogym_ray.distributed import remote, robot_actors
from robogym_ray.distributed.local_ray import start_local_ray
from robogym_ray.distributed.provider import SupervisorServerProvider
from robogym_ray.experience.rollout import box_dims, make_gym_env
from robogym_ray.learner.service import LearnerService
from robogym_ray.supervision.supervisor import SupervisorConfig
from robogym_ray.training.presets import d4pg_for, resolve_task


def measure(workers: list, steps: int) -> float:
    start = time.perf_counter()
    results = ray.get([w.collect.remote(steps) for w in workers])
    return sum(r.steps for r in results) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="navigation")
    parser.add_argument("--steps", type=int, default=1500, help="env steps per worker per round")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    preset = resolve_task(args.task)
    d4pg = d4pg_for(preset)
    start_local_ray(2, log_to_driver=False)
    supervisor = robot_actors.start_supervisor(
        SupervisorConfig(server_num_cpus=0.2), name="bench-supervisor"
    )
    provider = SupervisorServerProvider(name="bench-supervisor")
    factory = make_gym_env(preset.env_id, {"provider": provider})
    obs_dim, act_dim = box_dims(make_gym_env(preset.env_id)())
    weights = LearnerService(d4pg, obs_dim, act_dim).get_weights()
    workers = [
        remote.RolloutActor.options(num_cpus=0.25).remote(factory, d4pg, index=i, seed=i)
        for i in range(2)
    ]
    ray.get([w.set_weights.remote(weights) for w in workers])
    measure(workers, 200)  # warm-up: servers started, episodes reset, code paths compiled
    one, two = [], []
    for _ in range(args.rounds):
        one.append(measure(workers[:1], args.steps))
        two.append(measure(workers, args.steps))
    r1, r2 = float(np.median(one)), float(np.median(two))
    print(f"# {time.strftime('%Y-%m-%d')} {platform.machine()} {os.cpu_count()} cores")
    print(
        json.dumps(
            {
                "task": preset.env_id,
                "steps_per_worker_round": args.steps,
                "rounds": args.rounds,
                "one_worker_steps_per_s": round(r1),
                "two_workers_steps_per_s": round(r2),
                "speedup": round(r2 / r1, 2),
                "per_core_efficiency": round(r2 / r1 / 2, 2),
                "rounds_one": [round(x) for x in one],
                "rounds_two": [round(x) for x in two],
            }
        )
    )
    ray.get(supervisor.shutdown.remote())
    ray.shutdown()


if __name__ == "__main__":
    main()
