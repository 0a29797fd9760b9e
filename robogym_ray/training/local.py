"""Single-process D4PG on any Gymnasium id, with the classes the Ray program uses.

    python -m robogym_ray.training.local --env Pendulum-v1 --steps 20000 --seed 0

One actor (BehaviourPolicy + NStepAccumulator) feeds the D4PGLearner's replay; the learner takes
``samples_per_insert / batch_size`` steps per inserted transition and the actor pulls weights
every ``weights_sync_period`` env steps, as a rollout worker would. Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from robogym_ray.config import add_config_args, merge_config
from robogym_ray.experience.episodes import greedy_episode
from robogym_ray.learner.behaviour import BehaviourPolicy, to_env_action
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.nstep import NStepAccumulator, stack_transitions
from robogym_ray.learner.rate_limiter import SamplesPerInsert
from robogym_ray.training.presets import TASKS

PRESETS: dict[str, Mapping[str, Any]] = {"Pendulum-v1": TASKS["pendulum"].d4pg}
"""Tuned settings per env id (training/presets.py), applied under --preset auto."""


@dataclass(frozen=True)
class RunConfig:
    """What to run; learning hyperparameters live in D4PGConfig."""

    env: str = "Pendulum-v1"
    """Gymnasium environment id (Box observation and action spaces)."""
    steps: int = 20_000
    """Environment steps to train for."""
    seed: int = 0
    """Seed of env, networks, replay and exploration."""
    eval_episodes: int = 10
    """Deterministic (no-noise) evaluation episodes at the end."""
    weights_sync_period: int = 1
    """Env steps between the actor's weight pulls from the learner."""
    log_every: int = 0
    """Print progress to stderr every this many env steps (0: never)."""
    preset: str = "auto"
    """'auto': apply PRESETS[env] when known; 'none': D4PGConfig defaults only."""


def build_parser() -> argparse.ArgumentParser:
    """Flags from both dataclasses, with their field docstrings as help."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for cls in (RunConfig, D4PGConfig):
        add_config_args(parser.add_argument_group(cls.__name__), cls, only_given=True)
    return parser


def parse_args(argv: Sequence[str] | None = None) -> tuple[RunConfig, D4PGConfig]:
    given = vars(build_parser().parse_args(argv))
    run_names = {f.name for f in dataclasses.fields(RunConfig)}
    run = merge_config(RunConfig, {k: v for k, v in given.items() if k in run_names}, "flags")
    preset = PRESETS.get(run.env, {}) if run.preset == "auto" else {}
    base = merge_config(D4PGConfig, preset, f"preset {run.env}")
    overrides = {k: v for k, v in given.items() if k not in run_names}
    return run, merge_config(D4PGConfig, overrides, "flags", base=base)


def evaluate(env_id: str, actor: BehaviourPolicy, episodes: int, seed: int) -> list[float]:
    """Undiscounted returns of ``episodes`` noise-free episodes (seeds seed, seed+1, ...)."""
    env = gym.make(env_id)
    returns = [
        greedy_episode(env, lambda obs: actor.act(obs, explore=False), seed + i).ret
        for i in range(episodes)
    ]
    env.close()
    return returns


def train(run: RunConfig, cfg: D4PGConfig) -> dict[str, Any]:
    """Train for ``run.steps`` env steps, evaluate, and return the summary dict."""
    start = time.perf_counter()
    env = gym.make(run.env)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high = env.action_space.low, env.action_space.high
    learner = D4PGLearner(cfg, obs_dim, act_dim, seed=run.seed)
    actor = BehaviourPolicy(
        obs_dim, act_dim, cfg.policy_hidden, cfg.sigma, cfg.layer_norm, seed=run.seed
    )
    actor.set_weights(learner.get_weights())
    nstep = NStepAccumulator(cfg.n_step, cfg.discount)
    limiter = SamplesPerInsert(cfg.samples_per_insert, cfg.batch_size)
    episode_return, returns = 0.0, []
    metrics: dict[str, float] = {}

    obs, _ = env.reset(seed=run.seed)
    for t in range(1, run.steps + 1):
        action = actor.act(obs, explore=True)
        next_obs, reward, terminated, truncated, _ = env.step(to_env_action(action, low, high))
        episode_return += float(reward)
        transitions = nstep.push(obs, action, float(reward), next_obs, terminated, truncated)
        if transitions:
            learner.add(stack_transitions(transitions))
        limiter.inserted(len(transitions), warm=learner.can_step())
        for _ in range(limiter.take()):
            metrics = learner.step()
        if t % run.weights_sync_period == 0:
            actor.set_weights(learner.get_weights())
        obs = next_obs
        if terminated or truncated:
            returns.append(episode_return)
            episode_return = 0.0
            obs, _ = env.reset()
        if run.log_every and t % run.log_every == 0:
            recent = np.mean(returns[-5:]) if returns else float("nan")
            print(f"step {t} return(last5) {recent:.1f} {metrics}", file=sys.stderr)
    env.close()
    train_s = time.perf_counter() - start
    actor.set_weights(learner.get_weights())
    evals = evaluate(run.env, actor, run.eval_episodes, seed=run.seed + 10_000)
    return {
        "env": run.env,
        "seed": run.seed,
        "steps": run.steps,
        "eval_mean": float(np.mean(evals)),
        "eval_std": float(np.std(evals)),
        "wall_s": round(time.perf_counter() - start, 2),
        "train_s": round(train_s, 2),
        "learner_steps": learner.num_steps,
        "train_episodes": len(returns),
        "config": dataclasses.asdict(cfg),
    }


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    run, cfg = parse_args(argv)
    result = train(run, cfg)
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
