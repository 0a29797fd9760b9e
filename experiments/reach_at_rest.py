"""Where an IsaacReach policy rests: episodes of ``IsaacReachUR10Sim-v0`` with no success end
(both tolerances 1e-6), so each runs its 600 steps and the arm shows where it settles.

Per episode (reset with seed + i): the position error at the step a 2.1.0 success would have
ended it (first inside 0.02 m and 0.05 rad), and 30 steps, 90 steps and the episode's last step
after; over the last 20 steps, how far each commanded joint target sits from the joint
(``|joint_position + 0.5 * action - q|``: a policy that holds still commands where the joints
are), how far the end effector moves a step (its position, not its distance to the command),
and how far the mean of its positions is from the command (where it hovers, if it moves).

    python experiments/reach_at_rest.py runs/isaac/RUN/checkpoints/learner.pt --episodes 100 \\
        --out results/RUN-at-rest.json

Prints the medians as JSON; ``--out`` also keeps every episode's row.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

ENV_ID = "RoboGymRay/IsaacReachUR10Sim-v0"
TOLERANCES = (0.02, 0.05)  # 2.1.0's success: m and rad
TAIL = 20  # the last steps, read as "at rest"


def episode(env: Any, policy: Any, seed: int) -> dict[str, Any]:
    """One 600-step episode's row (see the module docstring)."""
    from robogym_ray.learner.behaviour import to_env_action

    task = env.unwrapped
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    obs, _ = env.reset(seed=seed)
    dist, rot, gaps, where = [], [], [], []
    done = False
    while not done:
        joints = task.joint_position + obs[: task.joint_position.size].astype(np.float64)
        action = to_env_action(np.clip(policy(np.asarray(obs, np.float32)), -1, 1), low, high)
        gaps.append(np.abs(task.joint_targets(action) - joints))
        obs, _, terminated, truncated, info = env.step(action)
        dist.append(info["dist_coord"])
        where.append(task.position())  # the frame of the command's info["target_coord"]
        rot.append(info["dist_rot"])
        done = terminated or truncated
    d, r = np.asarray(dist), np.asarray(rot)
    inside = np.flatnonzero((d < TOLERANCES[0]) & (r < TOLERANCES[1]))
    row: dict[str, Any] = {"seed": seed, "status": info["final_status"], "steps": len(d)}
    at = int(inside[0]) if inside.size else None
    for name, lag in (("at_success", 0), ("after_30", 30), ("after_90", 90)):
        row[name] = None if at is None else float(d[min(at + lag, len(d) - 1)])
    row.update(
        end=float(d[-1]),
        end_rotation=float(r[-1]),
        closest=float(d.min()),
        target_gap=np.mean(gaps[-TAIL:], axis=0).round(5).tolist(),
        step_motion=float(np.mean(np.linalg.norm(np.diff(where[-TAIL:], axis=0), axis=1))),
        hover_centre=float(np.linalg.norm(np.mean(where[-TAIL:], axis=0) - info["target_coord"])),
    )
    return row


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    def median(key: str) -> float | None:
        values = [row[key] for row in rows if row[key] is not None]
        return round(float(np.median(values)), 5) if values else None

    gaps = np.asarray([row["target_gap"] for row in rows])
    return {
        "episodes": len(rows),
        "would_succeed": sum(row["at_success"] is not None for row in rows),
        **{key: median(key) for key in ("at_success", "after_30", "after_90", "end")},
        "end_rotation": median("end_rotation"),
        "closest": median("closest"),
        "step_motion": median("step_motion"),
        "hover_centre": median("hover_centre"),
        "target_gap": np.median(gaps, axis=0).round(4).tolist(),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", help="learner.pt, or an exported policy with its .json")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, help="JSON file for the summary and every row")
    args = parser.parse_args(argv)

    import gymnasium as gym

    import robogym_ray.envs  # noqa: F401 - registers the ids
    from robogym_ray.export import load_policy

    policy = load_policy(args.policy)
    env = gym.make(ENV_ID, ee_distance_threshold=1e-6, ee_rotation_threshold=1e-6)
    try:
        rows = [episode(env, policy, args.seed + i) for i in range(args.episodes)]
    finally:
        env.close()
    result = summary(rows)
    print(json.dumps(result, indent=1))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"summary": result, "episodes": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
