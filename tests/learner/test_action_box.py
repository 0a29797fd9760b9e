"""The learner's action box (``D4PGConfig.action_box_low`` / ``_high``): the policy acts inside
it, the critic reads actions on its scale, the workers' noise is scaled to it, and checkpoints,
exports and the workers carry it without being told."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from robogym_ray.errors import ConfigError, FieldError
from robogym_ray.export import load_checkpoint_policy
from robogym_ray.learner.behaviour import BehaviourPolicy
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.networks import DistributionalCritic, Policy
from robogym_ray.training.setup import learner_networks
from tests.learner.conftest import ACT, OBS, small_config, transitions

LOW, HIGH = (-0.2, 0.5), (0.2, 0.7)  # centres 0 and 0.6, half-widths 0.2 and 0.1


def _boxed_learner() -> D4PGLearner:
    learner = D4PGLearner(small_config(action_box_low=LOW, action_box_high=HIGH), OBS, ACT, 0)
    learner.add(transitions(200))
    for _ in range(5):
        learner.step()
    return learner


def _obs(n: int) -> torch.Tensor:
    values = np.random.default_rng(1).standard_normal((n, OBS)) * 5
    return torch.as_tensor(values, dtype=torch.float32)


def test_without_a_box_the_nets_are_the_whole_box_exactly() -> None:
    torch.manual_seed(0)
    policy, critic = Policy(OBS, ACT, (8,)), DistributionalCritic(OBS, ACT, (8,), 5)
    obs, action = _obs(16), torch.rand(16, ACT) * 2 - 1
    assert torch.equal(policy(obs), torch.tanh(policy.net(obs)))
    assert torch.equal(critic(obs, action), critic.net(torch.cat([obs, action], -1)))


def test_the_policy_acts_inside_its_box_and_the_critic_reads_the_boxs_scale() -> None:
    learner = _boxed_learner()
    with torch.no_grad():
        actions = learner.policy(_obs(256)).numpy()
    assert (actions >= np.array(LOW) - 1e-6).all() and (actions <= np.array(HIGH) + 1e-6).all()
    # The same weights without the box read u where the boxed critic reads centre + half * u.
    plain = DistributionalCritic(OBS, ACT, (32, 32), learner.config.num_atoms)
    plain.load_state_dict(
        {k: v for k, v in learner.critic.state_dict().items() if not k.startswith("box_")}
    )
    u, obs = torch.rand(16, ACT) * 2 - 1, _obs(16)
    center, half = torch.tensor([0.0, 0.6]), torch.tensor([0.2, 0.1])
    with torch.no_grad():
        torch.testing.assert_close(learner.critic(obs, center + half * u), plain(obs, u))


def test_workers_get_the_box_with_the_weights_and_scale_their_noise_to_it() -> None:
    learner = _boxed_learner()
    worker = BehaviourPolicy(OBS, ACT, (32, 32), sigma=0.05, seed=0)
    worker.set_weights(learner.get_weights())  # the box travels as two buffers
    obs = np.zeros(OBS, np.float32)
    greedy = worker.act(obs, explore=False)
    with torch.no_grad():
        np.testing.assert_allclose(greedy, learner.policy(torch.zeros(1, OBS))[0].numpy())
    noisy = np.array([worker.act(obs, explore=True) for _ in range(2000)])
    assert (noisy >= np.array(LOW)).all() and (noisy <= np.array(HIGH)).all()
    # sigma is on the box's own scale: each dimension's spread is sigma x its half-width
    # (greedy actions well inside the box, so clipping hardly touches the 0.05 spread).
    spread = (noisy - greedy).std(axis=0)
    np.testing.assert_allclose(spread, [0.05 * 0.2, 0.05 * 0.1], rtol=0.1)


def test_checkpoints_and_exports_carry_the_box_and_old_weights_load_as_the_whole_box(
    tmp_path: Path,
) -> None:
    learner = _boxed_learner()
    learner.save(tmp_path / "learner.pt")
    loaded, _ = load_checkpoint_policy(tmp_path / "learner.pt")  # evaluate's and export's
    obs = _obs(32)
    with torch.no_grad():
        assert torch.equal(loaded(obs), learner.policy(obs))
    restored = D4PGLearner(small_config(), OBS, ACT, seed=3)  # a config without the box
    restored.restore(tmp_path / "learner.pt")
    torch.testing.assert_close(restored.critic.box_half, torch.tensor([0.2, 0.1]))
    # Weights saved before the box existed have no box_* entries: the whole Box.
    old = {k: v for k, v in Policy(OBS, ACT, (8,)).state_dict().items() if "box" not in k}
    fresh = Policy(OBS, ACT, (8,))
    fresh.load_state_dict(old)
    assert torch.equal(fresh.box_half, torch.ones(ACT))


@pytest.mark.parametrize(
    "low, high",
    [((-0.5,), (0.5, 0.5)), ((0.5, 0.0), (0.4, 0.5)), ((-1.5, 0.0), (0.0, 0.5)), ((0.0,), ())],
)
def test_a_malformed_box_is_refused_by_its_field(low: tuple, high: tuple) -> None:
    with pytest.raises(FieldError, match="action_box_low"):
        D4PGConfig(action_box_low=low, action_box_high=high)


def test_a_box_for_another_number_of_actions_is_a_config_error_before_any_actor() -> None:
    d4pg = D4PGConfig(policy_hidden=(8,), critic_hidden=(8,), action_box_low=(0.0,),
                      action_box_high=(0.5,))  # fmt: skip
    with pytest.raises(ConfigError, match="action_box_low/high: an action box of 1 and 1"):
        learner_networks(d4pg, OBS, ACT)
