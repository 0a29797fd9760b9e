"""Whether a deploy-reach policy settles: for each 4-s command window of
``IsaacDeployReachUR10eSim-v0``, how far ``wrist_3_link`` is from the command at the window's end,
the closest it came inside the window, and over the window's last 30 steps (0.5 s) how far it
moves a step, how far the mean of those positions is from the command (where it hovers, if it
moves) and the mean |action| on the [-1, 1] scale. Each action is relative to the measured
joints, so 0 holds the arm: a policy that has arrived and stopped shows ~0 motion and ~0 action.

    python experiments/deploy_reach_at_rest.py runs/isaac/RUN/checkpoints/learner.pt \\
        --episodes 100 --out results/RUN-at-rest.json

Episode i resets with seed + i (1000 + i by default, ``deploy_reach_errors.py``'s episodes).
Prints the medians over windows as JSON; ``--out`` also keeps every window's row.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ENV_ID = "RoboGymRay/IsaacDeployReachUR10eSim-v0"
TAIL = 30  # the window's last steps, read as "at rest"
KEYS = ("end", "end_rotation", "closest", "step_motion", "hover_centre", "mean_abs_action")


def episode(env: Any, policy: Callable[[np.ndarray], np.ndarray], seed: int) -> list[dict]:
    """One episode's rows, one per command window that ends in it (see the module docstring)."""
    from robogym_ray.learner.behaviour import to_env_action

    task = env.unwrapped
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    obs, _ = env.reset(seed=seed)
    rows: list[dict] = []
    where, gaps, dist, acts = [], [], [], []
    done = False
    while not done:
        unit = np.clip(np.asarray(policy(np.asarray(obs, np.float32)), np.float64), -1, 1)
        goal = np.asarray(task.scored_pose[:3], np.float64).copy()  # the command of this step
        obs, _, terminated, truncated, info = env.step(to_env_action(unit, low, high))
        here = np.asarray(info["achieved_goal"][:3], np.float64)
        where.append(here)
        gaps.append(here - goal)
        dist.append(info["dist_coord"])
        acts.append(float(np.mean(np.abs(unit))))
        if "window_position_error" in info:
            tail = np.asarray(where[-TAIL:])
            rows.append({
                "seed": seed,
                "end": float(info["window_position_error"]),
                "end_rotation": float(info["window_rotation_error"]),
                "closest": float(min(dist)),
                "step_motion": float(np.mean(np.linalg.norm(np.diff(tail, axis=0), axis=1))),
                "hover_centre": float(np.linalg.norm(np.mean(gaps[-TAIL:], axis=0))),
                "mean_abs_action": float(np.mean(acts[-TAIL:])),
            })  # fmt: skip
            where, gaps, dist, acts = [], [], [], []
        done = terminated or truncated
    return rows


def summary(rows: list[dict]) -> dict[str, Any]:
    """The medians over windows."""
    return {
        "windows": len(rows),
        **{key: round(float(np.median([row[key] for row in rows])), 5) for key in KEYS},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", help="learner.pt, or an exported policy with its .json")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1000, help="Episode i resets with seed + i.")
    parser.add_argument("--out", type=Path, help="JSON file for the summary and every row")
    args = parser.parse_args(argv)

    import gymnasium as gym

    import robogym_ray.envs  # noqa: F401 - registers the ids
    from robogym_ray.export import load_policy

    policy = load_policy(args.policy)
    env = gym.make(ENV_ID)
    try:
        rows = [row for i in range(args.episodes) for row in episode(env, policy, args.seed + i)]
    finally:
        env.close()
    result = summary(rows)
    print(json.dumps(result, indent=1))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"summary": result, "windows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
