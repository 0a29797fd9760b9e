"""Distributed D4PG on Pendulum-v1: wall time until the greedy policy reaches -200.

Runs the real training program (local Ray, 2 CPUs: rollout-worker actors, learner actor,
evaluator actor) and reads the evaluator's history: the time is the first point where the mean
of the last 5 evaluation episodes is >= -200. Target: <= 60 s on 2 cores.

Usage: python benchmarks/distributed_pendulum.py [--seeds 0 1 2] [--steps 12000] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

import numpy as np

from robogym_ray.training.config import TrainConfig
from robogym_ray.training.run import run_training

THRESHOLD = -200.0


def time_to_threshold(history: list[dict], window: int = 5) -> dict | None:
    returns = [h["return"] for h in history]
    for i in range(window - 1, len(history)):
        if np.mean(returns[i - window + 1 : i + 1]) >= THRESHOLD:
            return history[i]
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=12_000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    print(f"# {time.strftime('%Y-%m-%d')} {os.cpu_count()} cores", flush=True)
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as logdir:
            cfg = TrainConfig(
                task="pendulum",
                workers=args.workers,
                total_steps=args.steps,
                seed=seed,
                logdir=logdir,
                run_name=f"pendulum-{seed}",
                progress=False,
                num_cpus=2,
                random_steps=500,
            )
            summary = run_training(cfg)
        hit = time_to_threshold(summary["eval_history"])
        last = [h["return"] for h in summary["eval_history"][-5:]]
        print(
            json.dumps(
                {
                    "seed": seed,
                    "env_steps": summary["env_steps"],
                    "learner_steps": summary["learner_steps"],
                    "run_wall_s": summary["wall_s"],
                    "reached_minus_200_at_s": hit["wall_s"] if hit else None,
                    "reached_at_env_steps": hit["env_steps"] if hit else None,
                    "final_eval_mean_last5": round(float(np.mean(last)), 1) if last else None,
                    "env_steps_per_s": summary["throughput/env_steps_per_s"],
                    "learner_steps_per_s": summary["throughput/learner_steps_per_s"],
                }
            ),
            flush=True,
        )


if __name__ == "__main__":
    main()
