"""How much a trained policy's output changes across a 5-step window, and how steep its
critic is in the action, while it approaches a command and while it rests there.

Greedy episodes of ``IsaacReachFineTanhUR10Sim-v0`` (seeds 300-303, the averaged policy
acting). At every state: the online policy's ``|pi(s_t) - pi(s_t+5)|^2`` and
``|pi(s_t) - pi(s_t+1)|^2`` on the critic's [-1, 1] scale, and ``|dQ/da|`` of the critic's mean
at the online policy's action. Medians over steps 0-39 of each 4-s window (approach) and
steps 80-114 (rest). It sized ``policy_smoothness``'s weight before its run.

    python docs/results/isaac-reach-ur10-smooth-2026-12-01/window_change.py \\
        runs/isaac/reach-narrow-s0
"""

import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

import robogym_ray.envs  # noqa: F401 - registers the ids
from robogym_ray.learner.behaviour import to_env_action
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.distributional import expected_value
from robogym_ray.learner.learner import D4PGLearner

ENV_ID = "RoboGymRay/IsaacReachFineTanhUR10Sim-v0"
WINDOW = 120  # steps per command (4 s at 30 Hz)
PHASES = {"approach (steps 0-39)": (0, 40), "rest (steps 80-114)": (80, 115)}


def main(run: str) -> None:
    saved = json.loads(Path(run, "config.json").read_text())["d4pg"]
    config = D4PGConfig(**{k: v for k, v in saved.items() if k in D4PGConfig.__dataclass_fields__})
    env = gym.make(ENV_ID)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    learner = D4PGLearner(config, obs_dim, act_dim)
    learner.restore(f"{run}/checkpoints/learner.pt")
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    found: dict[str, list[np.ndarray]] = {name: [] for name in PHASES}
    try:
        for seed in range(300, 304):
            obs, _ = env.reset(seed=seed)
            states, done = [], False
            while not done:
                with torch.no_grad():
                    action = learner.policy_average(torch.as_tensor(obs[None]))[0].numpy()
                states.append(obs.copy())
                raw = to_env_action(action.astype(np.float64), low, high).astype(np.float32)
                obs, _, terminated, truncated, _ = env.step(raw)
                done = terminated or truncated
            s = torch.as_tensor(np.array(states))
            a = learner.policy(s).detach().requires_grad_(True)
            q = expected_value(learner.critic(s, a).float(), learner.support).sum()
            slope = torch.autograd.grad(q, a)[0].norm(dim=-1).numpy()
            a = a.detach()
            five = (a[:-5] - a[5:]).square().sum(-1).numpy()
            one = (a[:-1] - a[1:]).square().sum(-1).numpy()
            for name, (lo, hi) in PHASES.items():
                at = np.array([t for t in range(len(five)) if lo <= t % WINDOW < hi])
                found[name].append(np.stack([five[at], one[at], slope[at]]))
    finally:
        env.close()
    for name, parts in found.items():
        five, one, slope = np.median(np.concatenate(parts, axis=1), axis=1)
        print(
            f"{name}: |pi(s_t)-pi(s_t+5)|^2 {five:.3f}, |pi(s_t)-pi(s_t+1)|^2 {one:.3f}, "
            f"|dQ/da| {slope:.3f}"
        )


if __name__ == "__main__":
    main(sys.argv[1])
