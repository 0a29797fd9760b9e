"""RLlib's PPO and SAC as peers (``experiments/peers.py --algo rllib-ppo|rllib-sac``).

RLlib is what a Ray user reaches for, so it runs the way its documentation shows: the new API
stack's ``PPOConfig()`` / ``SACConfig()`` with their defaults, one env runner per core
(``num_env_runners = os.cpu_count()``, one env each), the learner in the driver, the env made
by ``gymnasium.make`` on our Sim id. Nothing about the algorithm is tuned.

``ray[rllib]==2.60.0`` pins ``gymnasium==1.2.2`` while this project's lock has 1.4.0, so RLlib
gets its own virtual environment (``docs/results-log.md``, "Seeds and peers side by side", has
the commands); this module imports RLlib only inside its functions, and ``peers.py`` imports it
only for an ``rllib-*`` algorithm.

A snapshot is ``Algorithm.save_to_path`` (RLlib's own checkpoint); its evaluation loads only
the RLModule from it and acts as RLlib's env runner does with ``explore=False``: the inference
distribution's deterministic action, clipped to [-1, 1] (``normalize_actions``, RLlib's default,
maps [-1, 1] linearly onto the action bounds and clips, which is what ``run_episodes`` does).
For SAC that is the squashed Gaussian's pre-tanh mean, clipped, not tanh of it: RLlib 2.60's
``TorchSquashedGaussian.to_deterministic`` returns ``loc`` unsquashed, and its env runner's
greedy episodes act with that, so the evaluation does too.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np


def _make_env(env_id: str) -> Callable[[dict[str, Any]], Any]:
    def creator(_config: dict[str, Any]) -> Any:
        import gymnasium as gym

        import robogym_ray  # noqa: F401 - registers the ids in the env runner's process

        return gym.make(env_id)

    return creator


def build(
    algo: str, env_id: str, seed: int, env_runners: int | None = None, envs_per_runner: int = 1
) -> Any:
    """The algorithm with RLlib's defaults on its own local Ray. Its layout: ``env_runners``
    (default one per core) of ``envs_per_runner`` envs each (RLlib's default 1); a user short
    of cores tries one runner of several envs instead, so both layouts are measured."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.algorithms.sac import SACConfig
    from ray.tune.registry import register_env

    from robogym_ray.distributed.local_ray import start_local_ray

    cpus = os.cpu_count() or 1
    start_local_ray(num_cpus=cpus)
    register_env(env_id, _make_env(env_id))
    config = {"rllib-ppo": PPOConfig, "rllib-sac": SACConfig}[algo]()
    config = (
        config.environment(env_id)
        .framework("torch")
        .env_runners(
            num_env_runners=cpus if env_runners is None else env_runners,
            num_envs_per_env_runner=envs_per_runner,
        )
        .debugging(seed=seed)
    )
    return config.build_algo()


def counters(result: dict[str, Any]) -> dict[str, Any]:
    """Env steps and trained samples from an ``algo.train()`` result (new API stack keys)."""
    from ray.rllib.core import DEFAULT_MODULE_ID
    from ray.rllib.utils.metrics import (
        ENV_RUNNER_RESULTS,
        LEARNER_RESULTS,
        NUM_ENV_STEPS_SAMPLED_LIFETIME,
        NUM_MODULE_STEPS_TRAINED_LIFETIME,
    )

    learner = result.get(LEARNER_RESULTS, {}).get(DEFAULT_MODULE_ID, {})
    return {
        "env_steps": int(result.get(ENV_RUNNER_RESULTS, {}).get(NUM_ENV_STEPS_SAMPLED_LIFETIME, 0)),
        "samples_trained": int(learner.get(NUM_MODULE_STEPS_TRAINED_LIFETIME, 0)),
        "iterations": int(result.get("training_iteration", 0)),
    }


def batch_sizes(algo_obj: Any) -> dict[str, Any]:
    """What turns samples trained into gradient updates: the minibatch (PPO) or train batch."""
    cfg = algo_obj.config
    minibatch = cfg.minibatch_size or cfg.train_batch_size_per_learner
    return {
        "train_batch_size": cfg.train_batch_size_per_learner,
        "minibatch_size": minibatch,
        "num_epochs": cfg.num_epochs,
        "num_env_runners": cfg.num_env_runners,
        "num_envs_per_env_runner": cfg.num_envs_per_env_runner,
    }


def _module(snapshot: Path) -> Any:
    """The RLModule of an RLlib checkpoint (``Algorithm.save_to_path``)."""
    from ray.rllib.core import (
        COMPONENT_LEARNER,
        COMPONENT_LEARNER_GROUP,
        COMPONENT_RL_MODULE,
        DEFAULT_MODULE_ID,
    )
    from ray.rllib.core.rl_module.rl_module import RLModule

    # RLlib reads checkpoints through pyarrow's filesystems, which take a relative path for a
    # URI without a scheme and refuse it: `peers.py evaluate runs/peers/RUN` needs it absolute.
    path = snapshot.resolve() / COMPONENT_LEARNER_GROUP / COMPONENT_LEARNER / COMPONENT_RL_MODULE
    return RLModule.from_checkpoint(path / DEFAULT_MODULE_ID)


def gaussian(snapshot: Path, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A PPO checkpoint's diagonal Gaussian at each of ``obs`` (a batch): its means and standard
    deviations, in the normalised action space, before RLlib clips a sample to [-1, 1]."""
    import torch
    from ray.rllib.core.columns import Columns

    with torch.no_grad():
        batch = {Columns.OBS: torch.as_tensor(obs, dtype=torch.float32)}
        inputs = _module(snapshot).forward_inference(batch)[Columns.ACTION_DIST_INPUTS]
    mean, log_std = inputs.chunk(2, dim=-1)  # RLlib's TorchDiagGaussian: means, then log stds
    return mean.numpy(), log_std.exp().numpy()


def load_policy(snapshot: Path) -> Callable[[np.ndarray], np.ndarray]:
    """The greedy policy of an RLlib checkpoint, answering in [-1, 1]."""
    import torch
    from ray.rllib.core.columns import Columns

    module = _module(snapshot)
    dist_cls = module.get_inference_action_dist_cls()

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            batch = {Columns.OBS: torch.as_tensor(obs, dtype=torch.float32)[None]}
            out = module.forward_inference(batch)
            if Columns.ACTIONS in out:
                action = out[Columns.ACTIONS]
            else:
                dist = dist_cls.from_logits(out[Columns.ACTION_DIST_INPUTS])
                action = dist.to_deterministic().sample()
        return np.clip(action[0].numpy().astype(np.float64), -1.0, 1.0)

    return policy
