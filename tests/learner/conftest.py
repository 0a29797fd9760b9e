"""What the learner's tests share: a small config, random transitions, a learner filled with
them, and the comparison of two learners' networks and priorities."""

from __future__ import annotations

import numpy as np
import torch

from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner

OBS, ACT = 3, 2


def small_config(**kw: object) -> D4PGConfig:
    """A learner small enough for a CPU test (hard target copies every 3 steps); ``kw`` on top."""
    base = dict(
        policy_hidden=(32, 32),
        critic_hidden=(32, 32),
        batch_size=16,
        replay_capacity=512,
        min_replay_size=32,
        v_min=-10.0,
        v_max=10.0,
        target_update_period=3,
        device="cpu",
    )
    return D4PGConfig(**{**base, **kw})  # type: ignore[arg-type]


def transitions(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``n`` random transitions of ``OBS``/``ACT`` sizes, about half of them terminal."""
    rng = np.random.default_rng(seed)
    return {
        "obs": rng.standard_normal((n, OBS), dtype=np.float32),
        "action": rng.uniform(-1, 1, (n, ACT)).astype(np.float32),
        "reward": rng.uniform(-1, 1, n).astype(np.float32),
        "discount": rng.choice([0.0, 0.95], n).astype(np.float32),
        "next_obs": rng.standard_normal((n, OBS), dtype=np.float32),
    }


def filled_learner(**kw: object) -> D4PGLearner:
    """A learner of ``small_config(**kw)``, seed 7, with 300 transitions in its replay."""
    learner = D4PGLearner(small_config(**kw), OBS, ACT, seed=7)
    for i in range(3):
        learner.add(transitions(100, seed=i))
    return learner


def net_params(learner: D4PGLearner) -> list[torch.Tensor]:
    """Copies of the online and target networks' parameters, in a fixed order."""
    nets = (learner.policy, learner.critic, learner.target_policy, learner.target_critic)
    return [p.detach().clone() for net in nets for p in net.parameters()]


def assert_same(a: D4PGLearner, b: D4PGLearner, atol: float = 0.0) -> None:
    """Equal networks, targets and replay priorities: bit for bit, or within ``atol``."""
    for x, y in zip(net_params(a), net_params(b), strict=True):
        torch.testing.assert_close(x, y, atol=atol, rtol=0 if atol == 0 else 1e-4)
    leaves = np.arange(len(a.replay))
    np.testing.assert_allclose(
        a.replay.backend.to_numpy(a.replay.sum_tree.leaves(leaves)),
        b.replay.backend.to_numpy(b.replay.sum_tree.leaves(leaves)),
        rtol=1e-5 if atol else 0,
    )
