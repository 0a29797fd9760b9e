"""Rollout env steps/s with and without revisiting failed starts, side by side in one run.

Two in-process rollout workers on the navigation task, each with its own embedded robot server
(no Ray, so only the worker's own cost is compared): one resets with revisits
(``--revisit-failed``), one without. Rounds alternate between them. Episodes are cut at
``--max-steps`` (50), so resets are far more frequent than in training (episodes there last
~130 steps), and the untrained policy fails every episode: the pool is always full and about
``--revisit-failed`` of the resets re-run a failed start. That is the worst case for any
per-reset cost of revisits.

Usage: python benchmarks/revisits.py [--steps 3000] [--rounds 5] [--revisit-failed 0.2]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

from robogym_ray.experience.revisits import FailedStartRevisits
from robogym_ray.experience.rollout import RolloutWorker, box_dims, make_gym_env
from robogym_ray.learner.service import LearnerService
from robogym_ray.training.presets import d4pg_for, resolve_task


def rate(worker: RolloutWorker, steps: int) -> tuple[float, int, int]:
    """(env steps/s, revisited episodes, episodes) of one round."""
    start = time.perf_counter()
    result = worker.collect(steps)
    revisits = sum(e.revisit for e in result.episodes)
    return result.steps / (time.perf_counter() - start), revisits, len(result.episodes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="env steps per worker and round")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--max-steps", type=int, default=50, help="episode step limit")
    parser.add_argument("--revisit-failed", type=float, default=0.2)
    args = parser.parse_args()
    preset = resolve_task("navigation")
    d4pg = d4pg_for(preset)
    factory = make_gym_env(preset.env_id, {"max_steps": args.max_steps})
    probe = factory()
    obs_dim, act_dim = box_dims(probe)
    probe.close()
    weights, version = LearnerService(d4pg, obs_dim, act_dim).get_weights()
    plain = RolloutWorker(factory, d4pg, seed=0)
    revisiting = RolloutWorker(
        factory, d4pg, seed=0, revisits=FailedStartRevisits(args.revisit_failed, seed=0)
    )
    for worker in (plain, revisiting):
        worker.set_weights(weights, version)
        worker.collect(300)  # warm-up: first resets, code paths
    without, with_, revisits, episodes = [], [], 0, 0
    for _ in range(args.rounds):
        without.append(rate(plain, args.steps)[0])
        r, n, e = rate(revisiting, args.steps)
        with_.append(r)
        revisits, episodes = revisits + n, episodes + e
    r0, r1 = float(np.median(without)), float(np.median(with_))
    print(f"# {time.strftime('%Y-%m-%d')} {platform.machine()} {os.cpu_count()} cores")
    print(
        json.dumps(
            {
                "task": preset.env_id,
                "steps_per_round": args.steps,
                "rounds": args.rounds,
                "revisit_failed": args.revisit_failed,
                "max_steps": args.max_steps,
                "without_steps_per_s": round(r0),
                "with_steps_per_s": round(r1),
                "ratio_with_over_without": round(r1 / r0, 3),
                "revisited_episodes": revisits,
                "episodes_with_revisits": episodes,
                "rounds_without": [round(x) for x in without],
                "rounds_with": [round(x) for x in with_],
            }
        )
    )
    plain.close()
    revisiting.close()


if __name__ == "__main__":
    main()
