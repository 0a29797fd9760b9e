"""Where a reach policy rests.

IsaacReach (default): episodes of ``IsaacReachUR10Sim-v0`` with no success end (both
tolerances 1e-6), so each runs its 600 steps and the arm shows where it settles. Per episode
(reset with seed + i): the position error at the step a 2.1.0 success would have ended it (first
inside 0.02 m and 0.05 rad), and 30 steps, 90 steps and the episode's last step after; over the
last 20 steps, how far each commanded joint target sits from the joint
(``|joint_position + 0.5 * action - q|``: a policy that holds still commands where the joints
are), how far the end effector moves a step (its position, not its distance to the command),
and how far the mean of its positions is from the command (where it hovers, if it moves).

The deploy reach (``--deploy``): per 4-s command window of ``IsaacDeployReachUR10eSim-v0``, the
window-end errors, the closest ``wrist_3_link`` came inside the window, and over the window's
last 30 steps (0.5 s) its motion a step, where it hovers and the mean |action| on the [-1, 1]
scale. Each action there is relative to the measured joints, so 0 holds the arm: a policy that
has arrived and stopped shows ~0 motion and ~0 action. Episode i resets with seed + i, 1000 + i
by default (``deploy_reach_errors.py``'s episodes).

    python experiments/reach_at_rest.py runs/isaac/RUN/checkpoints/learner.pt --episodes 100 \\
        --out results/RUN-at-rest.json
    python experiments/reach_at_rest.py runs/isaac/RUN/checkpoints/learner.pt --deploy \\
        --episodes 100 --out results/RUN-at-rest.json

Prints the medians as JSON; ``--out`` also keeps every episode's (or window's) row.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

ENV_ID = "RoboGymRay/IsaacReachUR10Sim-v0"
DEPLOY_ENV_ID = "RoboGymRay/IsaacDeployReachUR10eSim-v0"
TOLERANCES = (0.02, 0.05)  # 2.1.0's success: m and rad
TAIL = 20  # the last steps, read as "at rest"
DEPLOY_TAIL = 30  # a deploy window's last steps (0.5 s at 60 Hz)
DEPLOY_KEYS = ("end", "end_rotation", "closest", "step_motion", "hover_centre", "mean_abs_action")


def mean_step(points: Any) -> float:
    """The mean distance between consecutive points (m a step)."""
    return float(np.mean(np.linalg.norm(np.diff(np.asarray(points), axis=0), axis=1)))


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
        step_motion=mean_step(where[-TAIL:]),
        hover_centre=float(np.linalg.norm(np.mean(where[-TAIL:], axis=0) - info["target_coord"])),
    )
    return row


def deploy_windows(env: Any, policy: Any, seed: int) -> list[dict[str, Any]]:
    """One deploy-reach episode's rows, one per command window that ends in it."""
    from robogym_ray.learner.behaviour import to_env_action

    task = env.unwrapped
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    obs, _ = env.reset(seed=seed)
    rows: list[dict[str, Any]] = []
    where, gaps, dist, acts = [], [], [], []
    done = False
    while not done:
        # As deploy_reach_errors.py's loop acts (float32, clipped), so the episodes are its own.
        unit = np.clip(policy(np.asarray(obs, np.float32)), -1.0, 1.0)
        goal = np.array(task.scored_pose[:3], np.float64)  # the command in force this step
        obs, _, terminated, truncated, info = env.step(to_env_action(unit, low, high))
        where.append(np.asarray(info["achieved_goal"][:3], np.float64))
        gaps.append(where[-1] - goal)
        dist.append(info["dist_coord"])
        acts.append(float(np.mean(np.abs(unit))))
        if "window_position_error" in info:
            rows.append({
                "seed": seed,
                "end": float(info["window_position_error"]),
                "end_rotation": float(info["window_rotation_error"]),
                "closest": float(min(dist)),
                "step_motion": mean_step(where[-DEPLOY_TAIL:]),
                "hover_centre": float(np.linalg.norm(np.mean(gaps[-DEPLOY_TAIL:], axis=0))),
                "mean_abs_action": float(np.mean(acts[-DEPLOY_TAIL:])),
            })  # fmt: skip
            where, gaps, dist, acts = [], [], [], []
        done = terminated or truncated
    return rows


def deploy_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The medians over windows."""
    medians = {key: round(float(np.median([row[key] for row in rows])), 5) for key in DEPLOY_KEYS}
    return {"windows": len(rows), **medians}


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


class Measure(NamedTuple):
    """What ``--deploy`` switches: the env, one episode's rows, their summary, the rows' name in
    the JSON, and the first episode's seed."""

    env_id: str
    env_kwargs: dict[str, float]
    rows: Callable[[Any, Any, int], list[dict[str, Any]]]
    summary: Callable[[list[dict[str, Any]]], dict[str, Any]]
    key: str
    seed: int


MEASURES = {
    # No success ends an IsaacReach episode: both tolerances 1e-6.
    False: Measure(
        ENV_ID, {"ee_distance_threshold": 1e-6, "ee_rotation_threshold": 1e-6},
        lambda env, policy, seed: [episode(env, policy, seed)], summary, "episodes", 0,
    ),
    True: Measure(DEPLOY_ENV_ID, {}, deploy_windows, deploy_summary, "windows", 1000),
}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", help="learner.pt, or an exported policy with its .json")
    parser.add_argument("--deploy", action="store_true", help="The deploy reach, per window.")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument(
        "--seed", type=int, default=None, help="Episode i resets with seed + i (0; --deploy 1000)"
    )
    parser.add_argument("--out", type=Path, help="JSON file for the summary and every row")
    args = parser.parse_args(argv)
    measure = MEASURES[args.deploy]
    seed = measure.seed if args.seed is None else args.seed

    import gymnasium as gym

    import robogym_ray.envs  # noqa: F401 - registers the ids
    from robogym_ray.export import load_policy

    policy = load_policy(args.policy)
    env = gym.make(measure.env_id, **measure.env_kwargs)
    try:
        rows = [r for i in range(args.episodes) for r in measure.rows(env, policy, seed + i)]
    finally:
        env.close()
    result = measure.summary(rows)
    print(json.dumps(result, indent=1))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"summary": result, measure.key: rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
