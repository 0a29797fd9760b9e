"""Snapshot selection: the evaluator's repeatable episodes and the kept best policy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from robogym_ray.errors import ConfigError
from robogym_ray.experience.evaluator import Evaluator
from robogym_ray.experience.rollout import make_gym_env
from robogym_ray.export import load_checkpoint_policy
from robogym_ray.learner.checkpoint import BEST_POLICY_NAME
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.service import LearnerService
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.selection import PolicySnapshots, SnapshotSelector

SMALL = D4PGConfig(policy_hidden=(16, 16), critic_hidden=(16, 16), num_atoms=11)


def test_evaluator_with_seed_base_scores_every_call_on_the_same_episodes() -> None:
    evaluator = Evaluator(make_gym_env("Pendulum-v1"), SMALL)
    weights, version = LearnerService(SMALL, 3, 1).get_weights()
    fixed = [evaluator.evaluate(weights, version, 2, seed_base=7)["eval_return"] for _ in "ab"]
    rolling = [evaluator.evaluate(weights, version, 2)["eval_return"] for _ in "ab"]
    evaluator.close()
    assert fixed[0] == fixed[1]  # same greedy policy, same episodes
    assert rolling[0] != rolling[1]  # new seeds each call
    assert evaluator.episodes == 8


def _result(success: float, ret: float) -> dict[str, float]:
    return {"eval_snapshot_success_rate": success, "eval_return": ret}


def test_selector_keeps_the_best_snapshot_where_evaluate_and_export_read_it(
    tmp_path: Path,
) -> None:
    first, _ = LearnerService(SMALL, 3, 1, seed=0).get_weights()
    second, _ = LearnerService(SMALL, 3, 1, seed=1).get_weights()
    selector = SnapshotSelector(tmp_path)
    assert selector.better(_result(0.5, 10.0))
    selector.keep(_result(0.5, 10.0), first, 100, 5000)
    assert not selector.better(_result(0.5, 9.0))  # same success, lower return
    assert not selector.better(_result(0.4, 99.0))
    assert selector.better(_result(0.6, -5.0))
    selector.keep(_result(0.6, -5.0), second, 300, 9000)
    assert selector.summary() == {
        "path": str(tmp_path / BEST_POLICY_NAME),
        "learner_steps": 300,
        "env_steps": 9000,
        "success_rate": 0.6,
        "return": -5.0,
        "snapshots_scored": 4,
    }
    policy, info = load_checkpoint_policy(tmp_path / BEST_POLICY_NAME)
    assert (info.obs_dim, info.act_dim, info.policy_hidden) == (3, 1, (16, 16))
    for name, value in policy.state_dict().items():
        assert np.array_equal(value.numpy(), second[name]), name
    assert not any(np.array_equal(policy.state_dict()[k].numpy(), v) for k, v in first.items()
                   if v.ndim == 2)  # fmt: skip
    assert not (tmp_path / "policy-best.tmp").exists()
    assert torch.load(tmp_path / BEST_POLICY_NAME, weights_only=True)["selection"]["env_steps"]


def test_selection_needs_the_evaluator() -> None:
    with pytest.raises(ConfigError, match="select_episodes"):
        TrainConfig(select_episodes=20, evaluator=False)
    with pytest.raises(ConfigError, match="select_episodes"):
        TrainConfig(select_episodes=-1)


def test_timed_snapshots_are_kept_at_each_mark_and_a_rerun_numbers_on(tmp_path: Path) -> None:
    weights, _ = LearnerService(SMALL, 3, 1, seed=0).get_weights()
    snapshots = PolicySnapshots(tmp_path, every_s=300.0)
    assert snapshots.due(299.9) is None and snapshots.due(300.0) == 1
    path = snapshots.keep(1, weights, 40, 1234, wall_s=301.5)
    assert path == tmp_path / "policy-005.00min.pt" and snapshots.due(599.0) is None
    # A loop stalled past two marks: only the latest is written, under its own time (the
    # 10-minute name never holds weights of minute 15).
    assert snapshots.due(905.0) == 3
    assert snapshots.keep(3, weights, 90, 5678, 905.0).name == "policy-015.00min.pt"
    snapshots.skip(4)  # the learner did not answer at 20 min
    assert snapshots.due(1210.0) is None and snapshots.due(1500.0) == 5
    assert [r["wall_min"] for r in snapshots.written] == [5.0, 15.0]
    assert snapshots.written[0] == {"path": str(path), "wall_min": 5.0, "saved_at_min": 5.03,
                                    "learner_steps": 40, "env_steps": 1234}  # fmt: skip
    policy, info = load_checkpoint_policy(path)  # what evaluate and export read
    assert info.obs_dim == 3
    for name, value in policy.state_dict().items():
        assert np.array_equal(value.numpy(), weights[name]), name
    # A re-run in the same directory numbers on instead of overwriting the first run's files;
    # a file of another name is not taken for one.
    (tmp_path / "policy-final-min.pt").write_bytes(b"")
    again = PolicySnapshots(tmp_path, every_s=300.0)
    assert again.keep(1, weights, 1, 1, 300.0).name == "policy-020.00min.pt"
    assert again.written[0]["saved_at_min"] == 20.0
    assert PolicySnapshots(tmp_path, every_s=0.0).due(1e9) is None
    for bad in (-1.0, 0.5):  # names have 0.01-minute resolution
        with pytest.raises(ConfigError, match="policy_snapshot_every_s"):
            TrainConfig(policy_snapshot_every_s=bad)
