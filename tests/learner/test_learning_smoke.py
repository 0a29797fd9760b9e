"""CI smoke test: D4PG visibly learns Pendulum-v1 in 3,000 env steps (~10-15 s on 2 cores).

Small nets and batch keep it fast; one torch thread and fixed seeds keep it deterministic.
With these settings seeds 0 and 1 reach about -100 to -130 from a ~-1,200 untrained policy,
so the thresholds below leave a wide margin against flakiness.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.learner.behaviour import BehaviourPolicy
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.training.local import PRESETS, RunConfig, evaluate, train

pytest.importorskip("gymnasium.envs.classic_control")


def test_d4pg_learns_pendulum_quickly() -> None:
    cfg = D4PGConfig(
        **{
            **PRESETS["Pendulum-v1"],
            "policy_hidden": (64, 64),
            "critic_hidden": (64, 64),
            "batch_size": 128,
            "samples_per_insert": 128.0,
            "min_replay_size": 500,
            "num_threads": 1,
        }
    )
    run = RunConfig(env="Pendulum-v1", steps=3_000, seed=0, eval_episodes=5)

    # Baseline: the same architecture, untrained, on the same evaluation seeds.
    env = gym.make(run.env)
    untrained = BehaviourPolicy(
        env.observation_space.shape[0],
        env.action_space.shape[0],
        cfg.policy_hidden,
        cfg.sigma,
        seed=run.seed,
    )
    before = float(np.mean(evaluate(run.env, untrained, run.eval_episodes, run.seed + 10_000)))

    result = train(run, cfg)
    assert result["learner_steps"] > 2_000
    assert result["config"] == dataclasses.asdict(cfg)
    assert before < -700, before
    assert result["eval_mean"] > -500, result
    assert result["eval_mean"] - before > 400, (before, result["eval_mean"])
