"""Learner gradient steps/s: D4PGLearner vs SB3 TD3, same nets, batch and thread count.

    nice python benchmarks/learner_throughput.py [--steps 300] [--rounds 3] [--threads 0]

Both learners train on a replay pre-filled with 100k random Pendulum-sized transitions and
are timed over whole gradient steps, sampling included (D4PG: prioritized sampling and
priority write-back; TD3: its uniform buffer, policy delay 2, Polyak targets). Rounds
alternate between the two so that load from other processes hits both alike; the best round
of each is reported. SB3 is a benchmark-only dependency.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import torch

from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner

FILL = 100_000
BATCH = 256


def random_batch(n: int, obs_dim: int, act_dim: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "obs": rng.standard_normal((n, obs_dim), dtype=np.float32),
        "action": rng.uniform(-1, 1, (n, act_dim)).astype(np.float32),
        "reward": rng.uniform(-16.3, 0.0, n).astype(np.float32),
        "discount": np.full(n, 0.99**5, np.float32),
        "next_obs": rng.standard_normal((n, obs_dim), dtype=np.float32),
    }


def make_d4pg(hidden: tuple[int, ...]) -> Callable[[int], None]:
    cfg = D4PGConfig(
        policy_hidden=hidden,
        critic_hidden=hidden,
        batch_size=BATCH,
        v_min=-1500.0,
        v_max=0.0,
        replay_capacity=FILL,
        device="cpu",
    )
    learner = D4PGLearner(cfg, obs_dim=3, act_dim=1, seed=0)
    learner.add(random_batch(FILL, 3, 1))

    def run(steps: int) -> None:
        for _ in range(steps):
            learner.step()

    return run


def make_td3(hidden: tuple[int, ...]) -> Callable[[int], None]:
    from stable_baselines3 import TD3  # benchmark-only dependency

    model = TD3(
        "MlpPolicy",
        gym.make("Pendulum-v1"),
        batch_size=BATCH,
        buffer_size=FILL,
        policy_kwargs={"net_arch": list(hidden)},
        device="cpu",
        seed=0,
    )
    data = random_batch(FILL, 3, 1)
    buf = model.replay_buffer
    buf.observations[:FILL, 0] = data["obs"]
    buf.next_observations[:FILL, 0] = data["next_obs"]
    buf.actions[:FILL, 0] = data["action"]
    buf.rewards[:FILL, 0] = data["reward"]
    buf.full, buf.pos = True, 0
    model._setup_learn(total_timesteps=1)  # sets the logger that train() writes to

    def run(steps: int) -> None:
        model.train(gradient_steps=steps, batch_size=BATCH)

    return run


def steps_per_second(run: Callable[[int], None], steps: int) -> float:
    start = time.perf_counter()
    run(steps)
    return steps / (time.perf_counter() - start)


def compare(hidden: tuple[int, ...], steps: int, rounds: int) -> dict[str, object]:
    runners = {"d4pg": make_d4pg(hidden), "sb3_td3": make_td3(hidden)}
    for run in runners.values():
        run(20)  # warm-up: allocator, oneDNN kernel selection
    best = {name: 0.0 for name in runners}
    for _ in range(rounds):
        for name, run in runners.items():
            best[name] = max(best[name], steps_per_second(run, steps))
    return {
        "hidden": list(hidden),
        "batch": BATCH,
        "d4pg_steps_per_s": round(best["d4pg"], 1),
        "td3_steps_per_s": round(best["sb3_td3"], 1),
        "ratio": round(best["d4pg"] / best["sb3_td3"], 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="gradient steps per round")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds per learner")
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: default)")
    args = parser.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    results = [compare(h, args.steps, args.rounds) for h in ((400, 300), (256, 256))]
    for r in results:
        print(
            f"nets {r['hidden']}: D4PG {r['d4pg_steps_per_s']} steps/s, "
            f"SB3 TD3 {r['td3_steps_per_s']} steps/s, ratio {r['ratio']}x"
        )
    print(json.dumps({"torch_threads": torch.get_num_threads(), "results": results}))


if __name__ == "__main__":
    main()
