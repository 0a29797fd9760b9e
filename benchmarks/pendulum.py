"""D4PG learning check on Pendulum-v1: 20k env steps, 3 seeds, 10 deterministic eval episodes.

    nice python benchmarks/pendulum.py [--steps 20000] [--seeds 0 1 2] [--num-threads 1]

Uses the Pendulum-v1 preset of ``robogym_ray.training.local`` (support [-1500, 0], one
learner step per env step, Polyak targets; see PRESETS there). Seeds run one after another.
Target: every seed >= -250 and median >= -200 (SB3 TD3, zoo settings: about -150 at 20k).
Prints one JSON line per seed, then a summary line.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from robogym_ray.learner.config import D4PGConfig
from robogym_ray.training.local import PRESETS, RunConfig, train

FLOOR, MEDIAN_TARGET = -250.0, -200.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument(
        "--num-threads",
        type=int,
        default=1,
        help="torch threads; 1 is fastest on a shared 2-core machine",
    )
    args = parser.parse_args()
    cfg = D4PGConfig(**{**PRESETS["Pendulum-v1"], "num_threads": args.num_threads})
    start = time.perf_counter()
    results = []
    for seed in args.seeds:
        run = RunConfig(
            env="Pendulum-v1", steps=args.steps, seed=seed, eval_episodes=args.eval_episodes
        )
        result = {k: v for k, v in train(run, cfg).items() if k != "config"}
        results.append(result)
        print(json.dumps(result), flush=True)
    means = np.array([r["eval_mean"] for r in results])
    summary = {
        "benchmark": "pendulum",
        "steps": args.steps,
        "seeds": args.seeds,
        "eval_means": means.round(1).tolist(),
        "median": float(np.median(means)),
        "min": float(means.min()),
        "wall_s_per_seed": [r["wall_s"] for r in results],
        "total_wall_s": round(time.perf_counter() - start, 1),
        "pass": bool(means.min() >= FLOOR and np.median(means) >= MEDIAN_TARGET),
        "config": dataclasses.asdict(cfg),
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
