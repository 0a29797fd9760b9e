"""Fixtures of the experiment tests: the session's local Ray (shared with tests/distributed)."""

from __future__ import annotations

import pytest

from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from tests.distributed.conftest import ray_cluster  # noqa: F401

POSITIONING = "RoboGymRay/EndEffectorPositioningUR10Sim-v0"
NAVIGATION = "RoboGymRay/ObstacleAvoidanceMir100Sim-v0"


def save_learner(path, obs_dim: int, act_dim: int, layer_norm: bool = True, seed: int = 0):
    """A small untrained learner's checkpoint (what training writes as learner.pt)."""
    cfg = D4PGConfig(
        policy_hidden=(32, 16),
        critic_hidden=(32,),
        layer_norm=layer_norm,
        replay_capacity=256,
        batch_size=8,
    )
    learner = D4PGLearner(cfg, obs_dim, act_dim, seed=seed)
    learner.save(path)
    return learner


@pytest.fixture
def positioning_checkpoint(tmp_path):
    path = tmp_path / "learner.pt"
    return path, save_learner(path, 15, 6)
