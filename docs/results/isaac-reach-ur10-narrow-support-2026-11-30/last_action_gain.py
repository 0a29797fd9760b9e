"""How a policy's joint targets depend on its own previous action, the observation's last
slot (indices 19-24), near the command: the 6 x 6 Jacobian d a_t / d a_t-1 of the averaged
policy in the env's raw action units, at steps 80-114 of the first command window of 12
episodes of ``IsaacReachFineTanhUR10Sim-v0`` (seeds 200-211; the arm is at rest near the
command from ~60 steps on). An eigenvalue below -1 makes that path alone alternate the targets
from step to step; the arm's own response is a second path, not measured here.

    python docs/results/isaac-reach-ur10-narrow-support-2026-11-30/last_action_gain.py \\
        runs/isaac/reach-narrow-s0/checkpoints/learner.pt
"""

import sys

import gymnasium as gym
import numpy as np
import torch

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.export import load_policy
from robogym_ray.learner.behaviour import to_env_action

ENV_ID = "RoboGymRay/IsaacReachFineTanhUR10Sim-v0"
LAST_ACTION = slice(19, 25)


def main(path: str) -> None:
    module = load_policy(path).module.eval()
    env = gym.make(ENV_ID)
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    half = (high - low) / 2  # raw units per unit of the policy's [-1, 1] output
    diagonals, eigenvalues = [], []
    try:
        for seed in range(200, 212):
            obs, _ = env.reset(seed=seed)
            for t in range(115):
                x = torch.as_tensor(obs[None], dtype=torch.float32)
                with torch.no_grad():
                    out = module(x).numpy()[0].astype(np.float64)
                if t >= 80:
                    jac = torch.autograd.functional.jacobian(lambda o: module(o)[0], x)
                    block = half[:, None] * jac[:, 0, LAST_ACTION].numpy()
                    diagonals.append(np.diag(block))
                    eigenvalues.append(np.linalg.eigvals(block))
                obs = env.step(to_env_action(out, low, high).astype(np.float32))[0]
    finally:
        env.close()
    ev = np.array(eigenvalues)
    most_negative = float(np.median(ev.real.min(axis=1)))
    largest = float(np.median(np.abs(ev).max(axis=1)))
    print(f"{len(diagonals)} states; median diagonal of d a_t / d a_t-1:",
          np.round(np.median(diagonals, axis=0), 3))  # fmt: skip
    print(
        f"medians over states: the most negative eigenvalue's real part {most_negative:.3f},"
        f" the largest modulus {largest:.3f}"
    )


if __name__ == "__main__":
    main(sys.argv[1])
