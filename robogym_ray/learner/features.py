"""Inputs the critic computes for itself from an observation and an action (``D4PGConfig.
critic_features``): what a task's known structure says the return depends on, given to the
critic instead of left for it to learn. The policy never sees them, so it stays ``obs ->
action`` and every file it is exported to runs on the env's unchanged spaces.

A feature module is ``(obs [B, N], action [B, M]) -> [B, dim]``, differentiable in the action
(the policy's gradient flows through it), with a ``dim`` attribute; the action is on the
[-1, 1] scale that maps onto the env's whole Box (the critic's input before any action box).
Its buffers are not persistent: checkpoints hold no feature state. One registry
line names each, by module path as the robot registry names its cards: a feature knows a
task's robot, and the learner stays below the envs and the robots (``tests/test_layers.py``).
"""

from __future__ import annotations

import importlib

from torch import nn

from robogym_ray.errors import ConfigError
from robogym_ray.text import did_you_mean, quote

CRITIC_FEATURES: dict[str, str] = {
    "ur10e-deploy-pose": "robogym_ray.envs.ur_deploy_features:DeployReachPose",
}
"""``D4PGConfig.critic_features`` names -> ``module:class`` of feature modules (each with
``OBS_DIM`` and ``ACT_DIM``, the task's sizes it reads)."""


def critic_features(name: str, obs_dim: int, act_dim: int) -> nn.Module | None:
    """The feature module ``name`` names (None for ``""``), checked against the task's sizes."""
    if not name:
        return None
    kind = feature_class(name)
    if (obs_dim, act_dim) != (kind.OBS_DIM, kind.ACT_DIM):
        raise ConfigError(
            f"d4pg.critic_features {quote(name)} reads {kind.OBS_DIM} observations and "
            f"{kind.ACT_DIM} actions; the task has {obs_dim} and {act_dim}"
        )
    return kind()


def feature_class(name: str) -> type[nn.Module]:
    """The class ``name`` names in ``CRITIC_FEATURES`` (a clear error for an unknown name)."""
    if name not in CRITIC_FEATURES:
        raise ConfigError(
            f"d4pg.critic_features {quote(name)}: unknown{did_you_mean(name, CRITIC_FEATURES)}; "
            f"known: {', '.join(CRITIC_FEATURES)} (or '' for none)"
        )
    module, cls = CRITIC_FEATURES[name].split(":")
    return getattr(importlib.import_module(module), cls)
