"""How much a policy's output changes a step at rest, beside how far the end effector moves.

12 episodes of ``IsaacReachUR10Sim-v0`` (seeds 0-11) with no success end (both tolerances
1e-6, as ``experiments/reach_at_rest.py`` runs them), each its 600 steps; over the last 20
steps, the policy's ``|a_t - a_t-1|^2`` on the env's [-1, 1] action scale and the end
effector's motion a step (m). Medians over episodes.

    python docs/results/isaac-reach-ur10-smooth-2026-12-01/output_at_rest.py \\
        runs/isaac/reach-smooth-s0/checkpoints/learner.pt
"""

import sys

import gymnasium as gym
import numpy as np

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.export import load_policy
from robogym_ray.learner.behaviour import to_env_action

TAIL = 20


def main(path: str) -> None:
    policy = load_policy(path)
    env = gym.make(
        "RoboGymRay/IsaacReachUR10Sim-v0", ee_distance_threshold=1e-6, ee_rotation_threshold=1e-6
    )
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    changes, motions = [], []
    try:
        for seed in range(12):
            obs, _ = env.reset(seed=seed)
            outputs, where, done = [], [], False
            while not done:
                action = np.clip(policy(np.asarray(obs, np.float32)), -1, 1)
                outputs.append(action)
                obs, _, terminated, truncated, _ = env.step(to_env_action(action, low, high))
                where.append(env.unwrapped.position())
                done = terminated or truncated
            tail, moved = np.asarray(outputs[-TAIL - 1 :]), np.asarray(where[-TAIL - 1 :])
            changes.append(np.mean(np.sum(np.diff(tail, axis=0) ** 2, axis=1)))
            motions.append(np.mean(np.linalg.norm(np.diff(moved, axis=0), axis=1)))
    finally:
        env.close()
    print(
        f"|a_t - a_t-1|^2 {np.median(changes):.4f}, end effector {np.median(motions):.4f} m a step"
    )


if __name__ == "__main__":
    main(sys.argv[1])
