"""Observation normalisation (``obs_norm``): the running statistics, the learner keeping every
network's normaliser equal, and the statistics travelling with the weights (workers,
checkpoints, exports)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from robogym_ray.errors import ConfigError
from robogym_ray.export import export_policy, load_checkpoint_policy, load_exported
from robogym_ray.learner.behaviour import BehaviourPolicy
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.networks import ObsNormalizer
from robogym_ray.training.setup import check_init_from
from tests.learner.conftest import ACT, OBS, small_config, transitions


def _scaled(n: int, seed: int) -> dict[str, np.ndarray]:
    """``transitions`` whose observations are far from zero mean, unit scale: one feature
    around 3 (an absolute joint angle), one in the thousands, one constant."""
    batch = transitions(n, seed)
    obs = batch["obs"].astype(np.float64)
    obs[:, 0] = 3.0 + 0.1 * obs[:, 0]
    obs[:, 1] = 1000.0 * obs[:, 1]
    obs[:, 2] = 0.5
    batch["obs"] = obs.astype(np.float32)
    return batch


def test_statistics_are_those_of_all_the_data_in_any_split() -> None:
    data = np.random.default_rng(0).normal([3.0, -2.0], [0.1, 50.0], size=(1000, 2))
    norm = ObsNormalizer(2)
    x = torch.as_tensor(data[:5], dtype=torch.float32)
    torch.testing.assert_close(norm(x), (x / 1.01).clamp(-5, 5))  # no data yet: mean 0, std 1
    for part in np.split(data, [1, 7, 300, 301]):  # uneven batches, one of a single row
        norm.update(torch.as_tensor(part))
    assert float(norm.count) == 1000
    np.testing.assert_allclose(norm.mean.numpy(), data.mean(0), rtol=1e-12)
    np.testing.assert_allclose(norm.std().numpy(), data.std(0), rtol=1e-10)
    row = torch.tensor([[3.1, -2.0], [3.0, 1e6]])
    expected = (row.double() - data.mean(0)) / (torch.as_tensor(data.std(0)) + 0.01)
    torch.testing.assert_close(norm(row), expected.clamp(-5, 5).float())
    assert norm(row)[1, 1] == 5.0  # an outlier is clipped
    norm.update(torch.zeros(0, 2))  # an empty batch changes nothing
    assert float(norm.count) == 1000


def test_the_learner_normalises_for_every_network_and_the_workers_get_it() -> None:
    plain = D4PGLearner(small_config(), OBS, ACT, seed=0)
    assert plain.policy.norm is None and "norm.mean" not in plain.get_weights()
    learner = D4PGLearner(small_config(obs_norm=True, policy_average_tau=0.1), OBS, ACT, seed=0)
    first, second = _scaled(100, 0), _scaled(100, 1)
    learner.add(first)
    learner.add(second)
    seen = np.concatenate([first["obs"], second["obs"]]).astype(np.float64)
    norm = learner.policy.norm
    assert float(norm.count) == 200
    np.testing.assert_allclose(norm.mean.numpy(), seen.mean(0), rtol=1e-9)
    np.testing.assert_allclose(norm.std().numpy(), seen.std(0), rtol=1e-9, atol=1e-12)
    for name in ("critic", "target_policy", "target_critic", "policy_average"):
        other = getattr(learner, name).norm
        for a, b in zip(other.buffers(), norm.buffers(), strict=True):
            assert torch.equal(a, b), name
    # What the networks see is on a unit scale, the constant feature at 0.
    x = torch.as_tensor(seen, dtype=torch.float32)
    seen_by_net = norm(x)
    assert torch.all(seen_by_net[:, 2] == 0)
    assert torch.all((seen_by_net[:, :2].std(0) > 0.85) & (seen_by_net[:, :2].std(0) < 1.01))
    # Both networks read the normalised observation, not the raw one.
    action = torch.as_tensor(first["action"].repeat(2, 0))
    with torch.no_grad():
        torch.testing.assert_close(learner.policy(x), torch.tanh(learner.policy.net(seen_by_net)))
        torch.testing.assert_close(
            learner.critic(x, action), learner.critic.net(torch.cat([seen_by_net, action], -1))
        )
        assert not torch.allclose(learner.policy(x), torch.tanh(learner.policy.net(x)))
    for _ in range(4):
        metrics = learner.step()
    assert np.isfinite(metrics["critic_loss"]) and np.isfinite(metrics["policy_loss"])
    # A worker (BehaviourPolicy.of the same settings) acts exactly as the learner's policy.
    worker = BehaviourPolicy.of(learner.config, OBS, ACT, sigma=0.0)
    worker.set_weights(learner.get_weights())
    with torch.no_grad():
        expected = learner.policy(torch.as_tensor(first["obs"][:8])).numpy()
    np.testing.assert_allclose(worker.act_batch(first["obs"][:8], explore=False), expected)


def test_statistics_survive_a_checkpoint_and_reach_the_exports(tmp_path: Path) -> None:
    learner = D4PGLearner(small_config(obs_norm=True), OBS, ACT, seed=0)
    learner.add(_scaled(200, 0))
    learner.step()
    path = tmp_path / "learner.pt"
    learner.save(path)
    clone = D4PGLearner(small_config(obs_norm=True), OBS, ACT, seed=3)
    clone.restore(path)
    for name in ("policy", "critic", "target_policy", "target_critic"):
        for a, b in zip(
            getattr(clone, name).norm.buffers(), learner.policy.norm.buffers(), strict=True
        ):
            assert torch.equal(a, b), name
    clone.add(_scaled(50, 1))  # and the restored statistics go on from where they were
    assert float(clone.policy.norm.count) == 250

    obs = torch.as_tensor(_scaled(16, 2)["obs"])
    with torch.no_grad():
        expected = learner.policy(obs)
    module, info = load_checkpoint_policy(path)
    assert info.obs_norm
    torch.testing.assert_close(module(obs), expected, rtol=0, atol=0)
    exported = export_policy(path, tmp_path / "policy.pt")
    assert exported.obs_norm
    loaded, sidecar = load_exported(tmp_path / "policy.pt")
    assert sidecar.obs_norm
    torch.testing.assert_close(loaded(obs), expected, rtol=0, atol=1e-6)
    pytest.importorskip("onnxruntime")
    export_policy(path, tmp_path / "policy.onnx")
    onnx, _ = load_exported(tmp_path / "policy.onnx")
    np.testing.assert_allclose(onnx(obs.numpy()), expected.numpy(), atol=1e-5)


def test_a_checkpoint_and_a_run_that_differ_in_obs_norm_are_told_apart(tmp_path) -> None:
    D4PGLearner(small_config(), OBS, ACT, seed=0).save(tmp_path / "plain.pt")
    assert not load_checkpoint_policy(tmp_path / "plain.pt")[1].obs_norm
    with pytest.raises(ConfigError, match=r"not a D4PG checkpoint for .*obs_norm=True"):
        check_init_from(str(tmp_path / "plain.pt"), small_config(obs_norm=True), OBS, ACT)
    check_init_from(str(tmp_path / "plain.pt"), small_config(), OBS, ACT)  # the same: loads
