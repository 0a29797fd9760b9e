"""How much a policy's joint targets change a step, against what the workers' noise adds:
``sum_j (a_t - a_t-1)^2`` in the env's raw action units (the quantity the action-rate term
weighs), over 4 whole episodes of ``IsaacReachFineTanhUR10Sim-v0`` (seeds 100-103) and over
their last 100 steps, with no noise and with the workers' sigmas (N(0, sigma) times the action
box's half-width, clipped to the box: the workers' ``BehaviourPolicy``).

    python docs/results/isaac-reach-ur10-narrow-support-2026-11-30/action_rate.py \\
        runs/isaac/reach-narrow-s0/checkpoints/learner.pt
"""

import sys

import gymnasium as gym
import numpy as np

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.export import load_policy
from robogym_ray.learner.behaviour import BehaviourPolicy, to_env_action

ENV_ID = "RoboGymRay/IsaacReachFineTanhUR10Sim-v0"


def main(path: str) -> None:
    policy = load_policy(path)
    info, weights = policy.info, {k: v.numpy() for k, v in policy.module.state_dict().items()}
    env = gym.make(ENV_ID)
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    try:
        for sigma in (0.0, 0.1, 0.3):
            # The workers' own behaviour policy: noise on the box's scale, clipped to the box.
            actor = BehaviourPolicy(
                info.obs_dim, info.act_dim, info.policy_hidden, sigma, info.layer_norm, seed=0
            )
            actor.set_weights(weights)
            whole: list[float] = []
            tail: list[float] = []
            for seed in range(100, 104):
                obs, _ = env.reset(seed=seed)
                prev, rates, done = None, [], False
                while not done:
                    raw = to_env_action(actor.act(obs, explore=True).astype(np.float64), low, high)
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
