"""What the critic's pose features (``d4pg.critic_features``) cost a learner step.

    python benchmarks/critic_features.py [--rounds 5] [--seconds 8] [--threads 1 2]

For each feature module of ``learner/features.py``: two learners of its task's sizes and the
arm presets' networks ((400, 300), LayerNorm, 51 atoms, batch 256, prioritized replay of 20,000
random transitions whose commands are unit quaternions), one without the features and one with
them, built in this process and timed in turn, ``--rounds`` windows of ``--seconds`` each, after
a warm-up. Each window counts whole learner steps (sampling, both updates, priorities, target
updates). One JSON line per pair; the ratio is taken per pair, so that the machine's drift hits
both alike. Then the features alone: one forward of a batch, and a forward and backward.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
import torch
from learner_throughput import random_batch  # benchmarks/ is this script's folder

from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.features import CRITIC_FEATURES, critic_features, feature_class
from robogym_ray.learner.learner import D4PGLearner

FILL, BATCH = 20_000, 256
QUAT = slice(15, 19)
"""The command's quaternion in both tasks' observations (x-y-z-w in one, w-x-y-z in the other)."""


def sizes(name: str) -> tuple[int, int]:
    kind = feature_class(name)
    return kind.OBS_DIM, kind.ACT_DIM


def transitions(n: int, obs_dim: int, act_dim: int, seed: int) -> dict[str, np.ndarray]:
    """``random_batch``'s transitions with unit quaternions where the commands' are."""
    batch = random_batch(n, obs_dim, act_dim, seed)
    for key in ("obs", "next_obs"):
        batch[key][:, QUAT] /= np.linalg.norm(batch[key][:, QUAT], axis=1, keepdims=True)
    return batch


def learner(name: str, features: str) -> D4PGLearner:
    obs_dim, act_dim = sizes(name)
    config = D4PGConfig(
        policy_hidden=(400, 300), critic_hidden=(400, 300), layer_norm=True, num_atoms=51,
        v_min=-4.0, v_max=2.0, batch_size=BATCH, replay_capacity=FILL, min_replay_size=1000,
        critic_features=features, device="cpu",
    )  # fmt: skip
    out = D4PGLearner(config, obs_dim, act_dim, seed=0)
    out.add(transitions(FILL, obs_dim, act_dim, seed=0))
    out.run(20)  # warm-up
    return out


def rate(learn: D4PGLearner, seconds: float) -> float:
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        learn.run(5)
        steps += 5
    return steps / (time.perf_counter() - start)


def features_alone(name: str, repeats: int = 50) -> dict:
    obs_dim, act_dim = sizes(name)
    batch = transitions(BATCH, obs_dim, act_dim, seed=1)
    obs = torch.from_numpy(batch["obs"])
    module = critic_features(name, obs_dim, act_dim)
    out = {}
    for kind in ("forward", "forward_backward"):
        start = time.perf_counter()
        for _ in range(repeats):
            action = torch.from_numpy(batch["action"]).requires_grad_(kind != "forward")
            value = module(obs, action)
            if kind != "forward":
                value.sum().backward()
        out[f"{kind}_ms"] = round(1000 * (time.perf_counter() - start) / repeats, 2)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    for threads in args.threads:
        torch.set_num_threads(threads)
        for name in CRITIC_FEATURES:
            plain, featured = learner(name, ""), learner(name, name)
            pairs = [(rate(plain, args.seconds), rate(featured, args.seconds))
                     for _ in range(args.rounds)]  # fmt: skip
            print(json.dumps({
                "features": name, "threads": threads,
                "without_steps_per_s": [round(a, 1) for a, _ in pairs],
                "with_steps_per_s": [round(b, 1) for _, b in pairs],
                "ratio_median": round(statistics.median(b / a for a, b in pairs), 3),
                "batch_of_256": features_alone(name),
            }), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
