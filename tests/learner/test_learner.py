"""D4PGLearner: metrics, weights, targets, priorities, save/restore."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from robogym_ray.errors import ConfigError
from robogym_ray.learner.behaviour import BehaviourPolicy, from_env_action, to_env_action
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from tests.learner.conftest import ACT, OBS, small_config, transitions


def _learner(**kw: object) -> D4PGLearner:
    learner = D4PGLearner(small_config(**kw), OBS, ACT, seed=0)
    learner.add(transitions(200))
    return learner


def test_step_returns_finite_metrics_and_updates_priorities() -> None:
    learner = _learner()
    assert learner.can_step()
    before = learner.replay.sum_tree.root
    metrics = learner.step()
    for key in ("critic_loss", "policy_loss", "mean_q", "mean_priority", "beta", "steps"):
        assert np.isfinite(metrics[key]), key
    assert metrics["steps"] == 1 and learner.replay.sum_tree.root != before


def test_hard_target_copies_every_period_and_polyak_moves_slightly() -> None:
    learner = _learner()
    for _ in range(2):
        learner.step()
    assert not torch.equal(learner.policy.net[0].weight, learner.target_policy.net[0].weight)
    learner.step()  # step 3 == target_update_period
    assert torch.equal(learner.critic.net[0].weight, learner.target_critic.net[0].weight)
    polyak = _learner(target_tau=0.1)
    start = polyak.target_critic.net[0].weight.clone()
    polyak.step()
    moved = polyak.target_critic.net[0].weight - start
    online_delta = polyak.critic.net[0].weight - start
    torch.testing.assert_close(moved, 0.1 * online_delta)


def test_weights_reach_the_actor_and_actions_are_bounded() -> None:
    learner = _learner()
    learner.step()
    actor = BehaviourPolicy(OBS, ACT, (32, 32), sigma=0.5, seed=0)
    actor.set_weights(learner.get_weights())
    assert all(isinstance(v, np.ndarray) for v in learner.get_weights().values())
    obs = np.ones(OBS, np.float32)
    with torch.no_grad():
        expected = learner.policy(torch.as_tensor(obs)[None])[0].numpy()
    np.testing.assert_allclose(actor.act(obs, explore=False), expected, rtol=1e-6)
    noisy = np.array([actor.act(obs, explore=True) for _ in range(50)])
    assert noisy.std() > 0.1 and np.abs(noisy).max() <= 1.0
    np.testing.assert_allclose(
        to_env_action(np.array([-1.0, 1.0]), np.array([-2.0, 0.0]), np.array([2.0, 4.0])),
        [-2.0, 4.0],
    )
    low, high = np.array([-2.0, 0.0]), np.array([2.0, 4.0])
    a = np.array([0.3, -0.7])
    np.testing.assert_allclose(from_env_action(to_env_action(a, low, high), low, high), a)


def test_initial_priorities_are_positive_per_sample_losses() -> None:
    learner = _learner()
    priorities = learner.compute_initial_priorities(transitions(10, seed=1))
    assert priorities.shape == (10,) and (priorities > 0).all()
    learner.add(transitions(10, seed=1), priorities)


def test_save_restore_gives_identical_outputs_and_training_continues(tmp_path: Path) -> None:
    learner = _learner()
    for _ in range(5):
        learner.step()
    path = tmp_path / "ckpt.pt"
    learner.save(path, include_replay=True)
    clone = D4PGLearner(small_config(), OBS, ACT, seed=42)
    clone.restore(path)
    obs = torch.randn(7, OBS)
    act = torch.rand(7, ACT) * 2 - 1
    for name in ("policy", "target_policy"):
        torch.testing.assert_close(
            getattr(clone, name)(obs), getattr(learner, name)(obs), rtol=0, atol=0
        )
    for name in ("critic", "target_critic"):
        torch.testing.assert_close(
            getattr(clone, name)(obs, act), getattr(learner, name)(obs, act), rtol=0, atol=0
        )
    assert clone.num_steps == learner.num_steps == 5
    # Same replay, RNG, optimizer moments and counters: the next steps agree exactly.
    for _ in range(3):
        assert clone.step() == learner.step()
    assert clone.num_steps == 8


def test_restore_without_replay_keeps_the_networks(tmp_path: Path) -> None:
    learner = _learner()
    learner.step()
    learner.save(tmp_path / "nets.pt")
    assert not (tmp_path / "nets.pt.replay.npz").exists()
    clone = D4PGLearner(small_config(), OBS, ACT, seed=1)
    clone.restore(tmp_path / "nets.pt")
    assert len(clone.replay) == 0
    obs = torch.randn(4, OBS)
    torch.testing.assert_close(clone.policy(obs), learner.policy(obs), rtol=0, atol=0)


def test_uniform_replay_and_beta_annealing() -> None:
    learner = _learner(prioritized=False, importance_beta_steps=4)
    metrics = [learner.step() for _ in range(5)]
    assert metrics[0]["beta"] == pytest.approx(0.4) and metrics[-1]["beta"] == 1.0
    _, _, weights = learner.replay.sample(16, 1.0)
    np.testing.assert_allclose(weights, 1.0)


def test_config_validation_names_the_field() -> None:
    with pytest.raises(ConfigError, match="v_min"):
        D4PGConfig(v_min=1.0, v_max=0.0)


def test_policy_average_follows_the_online_policy_by_tau() -> None:
    learner = _learner(policy_average_tau=0.25)
    assert _learner().policy_average is None  # off by default: nothing extra per step
    avg = learner.policy_average
    assert avg is not None and not any(p.requires_grad for p in avg.parameters())
    start = avg.net[0].weight.clone()
    learner.step()
    moved = avg.net[0].weight - start
    torch.testing.assert_close(moved, 0.25 * (learner.policy.net[0].weight - start))
    for _ in range(3):
        learner.step()
    eval_weights, online = learner.get_eval_weights(), learner.get_weights()
    assert eval_weights.keys() == online.keys()
    assert not np.array_equal(eval_weights["net.0.weight"], online["net.0.weight"])
    np.testing.assert_array_equal(eval_weights["net.0.weight"], avg.net[0].weight.numpy())
    np.testing.assert_array_equal(
        _learner().get_eval_weights()["net.0.weight"], _learner().get_weights()["net.0.weight"]
    )


def test_policy_average_survives_checkpoints_with_and_without_it(tmp_path: Path) -> None:
    learner = _learner(policy_average_tau=0.25)
    for _ in range(4):
        learner.step()
    learner.save(tmp_path / "avg.pt")
    assert "policy_average" in torch.load(tmp_path / "avg.pt", weights_only=True)["nets"]
    clone = D4PGLearner(small_config(policy_average_tau=0.25), OBS, ACT, seed=3)
    clone.restore(tmp_path / "avg.pt")
    obs = torch.randn(5, OBS)
    torch.testing.assert_close(clone.policy_average(obs), learner.policy_average(obs))
    # Continuing with averaging from a run without it: the average starts at the policy.
    plain = _learner()
    plain.step()
    plain.save(tmp_path / "plain.pt")
    later = D4PGLearner(small_config(policy_average_tau=0.25), OBS, ACT, seed=4)
    later.restore(tmp_path / "plain.pt")
    torch.testing.assert_close(later.policy_average(obs), plain.policy(obs), rtol=0, atol=0)
    # And back: a learner without averaging ignores the stored average.
    off = D4PGLearner(small_config(), OBS, ACT, seed=5)
    off.restore(tmp_path / "avg.pt")
    assert off.policy_average is None
    torch.testing.assert_close(off.policy(obs), learner.policy(obs), rtol=0, atol=0)


@pytest.mark.parametrize("tau", [-0.1, 1.0, float("nan")])
def test_policy_average_tau_is_validated(tau: float) -> None:
    with pytest.raises(ConfigError, match="policy_average_tau"):
        small_config(policy_average_tau=tau)


def test_learning_rates_decay_linearly_by_learner_step(tmp_path: Path) -> None:
    cfg = dict(policy_lr=1e-3, critic_lr=2e-3, lr_decay_start=2, lr_decay_steps=4)
    learner = _learner(**cfg, lr_final_scale=0.25)
    scales = [learner.step()["lr_scale"] for _ in range(8)]
    # step() applies the rate for the step it is about to take (num_steps 0..7 here).
    assert scales == pytest.approx([1.0, 1.0, 1.0, 0.8125, 0.625, 0.4375, 0.25, 0.25])
    assert learner.policy_opt.param_groups[0]["lr"] == pytest.approx(0.25e-3)
    assert learner.critic_opt.param_groups[0]["lr"] == pytest.approx(0.5e-3)
    # A restored learner picks the schedule up where the checkpoint left it, not at the start.
    learner.save(tmp_path / "decayed.pt")
    clone = D4PGLearner(small_config(**cfg, lr_final_scale=0.25), OBS, ACT, seed=1)
    clone.add(transitions(200))
    clone.restore(tmp_path / "decayed.pt")
    assert clone.step()["lr_scale"] == pytest.approx(0.25)
    # Off by default: the rates stay at their base values.
    plain = _learner(policy_lr=1e-3)
    assert {plain.step()["lr_scale"] for _ in range(3)} == {1.0}
    assert plain.policy_opt.param_groups[0]["lr"] == 1e-3
    # Even when restored from the decayed checkpoint, whose optimizer state holds 0.25e-3.
    plain.restore(tmp_path / "decayed.pt")
    assert plain.policy_opt.param_groups[0]["lr"] == pytest.approx(0.25e-3)
    plain.step()
    assert plain.policy_opt.param_groups[0]["lr"] == 1e-3


@pytest.mark.parametrize(
    "field, value",
    [
        ("lr_final_scale", 0.0),
        ("lr_final_scale", 1.5),
        ("lr_final_scale", float("nan")),
        ("lr_decay_steps", -1),
        ("lr_decay_start", -5),
    ],
)
def test_learning_rate_decay_is_validated(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=field):
        small_config(**{field: value})
