"""The critic's own inputs (``learner/features.py``): the deploy reach's pose features are the
env's keypoint error where the joints are, move with the action as the kinematics say, carry the
policy's gradient; a learner with them steps, saves and restores; a learner without them is the
one it was; bad names and sizes are refused in one line."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs.ur_deploy_features import DeployReachPose
from robogym_ray.errors import ConfigError
from robogym_ray.learner.features import critic_features
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.training.setup import learner_networks
from tests.learner.conftest import small_config

SIM = "RoboGymRay/IsaacDeployReachUR10eSim-v0"
NOW, SENT = slice(0, 13), slice(13, 26)
"""The features of the joints where they are, and of where the action sends them."""


def test_pose_features_are_the_envs_keypoint_error_and_follow_the_action() -> None:
    env = gym.make(SIM)
    features = DeployReachPose()
    try:
        env.reset(seed=2)
        action = np.array([0.9, -0.7, 0.5, -0.3, 0.8, -1.0], dtype=np.float32)
        obs, _, _, _, info = env.step(action)  # mid-window: the observed command is scored
        x, a = torch.from_numpy(obs[None]), torch.from_numpy(action[None])
        out = features(x, a)[0].detach().numpy()
        # The kinematics of the observed joints give the pose PyBullet measured.
        assert out[NOW][12] == pytest.approx(info["keypoint_error"], abs=1e-4)
        # Where the action sends the joints: the same as the joints moved there.
        moved = obs.copy()
        moved[:6] += 0.0625 * action
        sent = features(torch.from_numpy(moved[None]), torch.zeros(1, 6))[0].detach().numpy()
        np.testing.assert_allclose(out[SENT], sent[NOW], atol=1e-5)
        # No action: both halves alike.
        still = features(x, torch.zeros(1, 6))[0].detach().numpy()
        np.testing.assert_allclose(still[NOW], still[SENT], atol=1e-6)
    finally:
        env.close()


def test_the_actions_gradient_flows_through_the_kinematics() -> None:
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(8, 19)).astype(np.float32)
    obs[:, 15:] /= np.linalg.norm(obs[:, 15:], axis=1, keepdims=True)
    action = torch.tensor(rng.uniform(-0.9, 0.9, (8, 6)), dtype=torch.float32, requires_grad=True)
    features = DeployReachPose()
    distance = features(torch.from_numpy(obs), action)[:, SENT][:, 12]
    (grad,) = torch.autograd.grad(distance.sum(), action)
    assert torch.isfinite(grad).all() and float(grad.abs().min()) > 0
    step = torch.zeros(8, 6)
    step[:, 2] = 1e-2  # the elbow: finite difference against the gradient
    with torch.no_grad():
        ahead = features(torch.from_numpy(obs), action + step)[:, SENT][:, 12]
    np.testing.assert_allclose(
        ((ahead - distance) / 1e-2).detach().numpy(), grad[:, 2].numpy(), rtol=0.05, atol=1e-3
    )


def transitions(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(2 * n, 19)).astype(np.float32)
    obs[:, 15:] /= np.linalg.norm(obs[:, 15:], axis=1, keepdims=True)
    return {
        "obs": obs[:n],
        "action": rng.uniform(-1, 1, (n, 6)).astype(np.float32),
        "reward": rng.uniform(-1, 0, n).astype(np.float32),
        "discount": np.full(n, 0.95, np.float32),
        "next_obs": obs[n:],
    }


def test_a_learner_with_pose_features_steps_saves_and_restores(tmp_path) -> None:
    config = small_config(critic_features="ur10e-deploy-pose")
    learner = D4PGLearner(config, 19, 6, seed=0)
    assert learner.critic.net[0].in_features == 19 + 6 + DeployReachPose.dim
    learner.add(transitions(64))
    metrics = learner.run(5)
    assert np.isfinite(metrics["critic_loss"]) and metrics["policy_grad_norm"] > 0
    assert not any("features" in k for k in learner.critic.state_dict())  # no state saved
    learner.save(tmp_path / "learner.pt")
    clone = D4PGLearner(config, 19, 6, seed=1)
    clone.restore(tmp_path / "learner.pt")
    batch = {k: torch.from_numpy(v) for k, v in transitions(4, seed=3).items()}
    torch.testing.assert_close(
        clone.critic(batch["obs"], batch["action"]),
        learner.critic(batch["obs"], batch["action"]),
    )


def test_without_features_the_learner_is_unchanged() -> None:
    """'' builds the critic it always did: the same layers, drawn in the same order."""
    plain = D4PGLearner(small_config(), 19, 6, seed=4)
    featured = D4PGLearner(small_config(critic_features="ur10e-deploy-pose"), 19, 6, seed=4)
    assert plain.critic.features is None
    assert plain.critic.net[0].in_features == 25
    for a, b in zip(
        plain.policy.state_dict().values(), featured.policy.state_dict().values(), strict=True
    ):
        torch.testing.assert_close(a, b)


def test_unknown_names_and_other_tasks_are_refused_in_one_line() -> None:
    assert critic_features("", 3, 2) is None
    with pytest.raises(ConfigError, match="unknown \\(did you mean 'ur10e-deploy-pose'\\?\\)"):
        critic_features("ur10e-deploy-poses", 19, 6)
    with pytest.raises(ConfigError, match="reads 19 observations and 6 actions; the task has 25"):
        learner_networks(small_config(critic_features="ur10e-deploy-pose"), 25, 6)
