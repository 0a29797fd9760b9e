"""How much a policy's joint targets change a step, against what the workers' noise adds:
``sum_j (a_t - a_t-1)^2`` in the env's raw action units (the quantity the action-rate term
weighs), over 4 whole episodes of ``IsaacReachFineTanhUR10Sim-v0`` (seeds 100-103) and over
their last 100 steps, with no noise and with the workers' sigmas (N(0, sigma) times the action
box's half-width, clipped to the box, as ``learner/behaviour.py`` acts).

    python docs/results/isaac-reach-ur10-narrow-support-2026-11-30/action_rate.py \\
        runs/isaac/reach-narrow-s0/checkpoints/learner.pt
"""

import sys

import gymnasium as gym
import numpy as np

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.export import load_policy
from robogym_ray.learner.behaviour import to_env_action

ENV_ID = "RoboGymRay/IsaacReachFineTanhUR10Sim-v0"


def main(path: str) -> None:
    policy = load_policy(path)
    center = policy.module.box_center.numpy().astype(np.float64)
    half = policy.module.box_half.numpy().astype(np.float64)
    env = gym.make(ENV_ID)
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    try:
        for sigma in (0.0, 0.1, 0.3):
            rng = np.random.default_rng(0)
            whole: list[float] = []
            tail: list[float] = []
            for seed in range(100, 104):
                obs, _ = env.reset(seed=seed)
                prev, rates, done = None, [], False
                while not done:
                    action = np.asarray(policy(np.asarray(obs, np.float32)), np.float64)
                    action = action + sigma * half * rng.standard_normal(action.shape)
                    raw = to_env_action(np.clip(action, center - half, center + half), low, high)
                    if prev is not None:
                        rates.append(float(np.sum(np.square(raw - prev))))
                    prev = raw
                    obs, _, terminated, truncated, _ = env.step(raw.astype(np.float32))
                    done = terminated or truncated
                whole += rates
                tail += rates[-100:]
            print(
                f"sigma {sigma}: {len(whole)} steps; sum (da)^2 a step: "
                f"whole episodes {np.mean(whole):.1f}, last 100 steps {np.mean(tail):.1f}"
            )
    finally:
        env.close()


if __name__ == "__main__":
    main(sys.argv[1])
