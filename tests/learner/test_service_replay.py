"""A restarted ``LearnerService`` keeps the replay snapshot its timer wrote, whatever regular
checkpoints came between the snapshot and the restart (the production order of a run)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robogym_ray.learner.checkpoint import CHECKPOINT_NAME, replay_path
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.service import LearnerService

SMALL = D4PGConfig(
    policy_hidden=(16, 16),
    critic_hidden=(16, 16),
    batch_size=16,
    min_replay_size=64,
    samples_per_insert=16.0,
    replay_capacity=5_000,
)
OBS, ACT = 3, 1


def batch(n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "obs": rng.normal(size=(n, OBS)).astype(np.float32),
        "action": rng.uniform(-1, 1, size=(n, ACT)).astype(np.float32),
        "reward": rng.normal(size=n).astype(np.float32),
        "discount": np.full(n, 0.99, np.float32),
        "next_obs": rng.normal(size=(n, OBS)).astype(np.float32),
    }


def service(tmp_path: Path, **kw: float) -> LearnerService:
    # Snapshots on (as in a run), but their timer never fires here: the test takes the
    # snapshot itself, exactly as ``train`` does when the timer is due.
    return LearnerService(
        SMALL, OBS, ACT, checkpoint_dir=str(tmp_path), checkpoint_every=5,
        replay_snapshot_every_s=1e9, **kw,
    )  # fmt: skip


def test_regular_checkpoints_after_a_snapshot_keep_it_for_a_restart(tmp_path: Path) -> None:
    learner = service(tmp_path)
    learner.add(batch(200, 0))
    learner.checkpoint(include_replay=True)  # the snapshot timer's checkpoint
    snapshot = len(learner.learner.replay)
    assert snapshot == 200 and replay_path(tmp_path / CHECKPOINT_NAME).exists()
    after_snapshot = learner.version
    for seed in range(1, 4):  # each pays for >= checkpoint_every steps: a regular checkpoint
        learner.add(batch(20, seed))
    assert learner._last_checkpoint_step >= after_snapshot + 3 * learner.checkpoint_every
    # A restart (Ray re-runs the constructor on the same directory) restores the newest
    # networks and the snapshot's transitions; only those added since it are lost.
    restarted = service(tmp_path)
    assert restarted.restored_from_step == learner._last_checkpoint_step > after_snapshot
    assert restarted.restored_replay == len(restarted.learner.replay) >= snapshot
    assert restarted.status()["restored_replay"] >= snapshot


def test_the_final_checkpoint_keeps_a_replay_only_when_asked(tmp_path: Path) -> None:
    learner = service(tmp_path)
    learner.add(batch(100, 0))
    learner.checkpoint(include_replay=True)
    learner.checkpoint(final=True)  # a run's end without --save-replay: the snapshot goes
    assert not replay_path(tmp_path / CHECKPOINT_NAME).exists()
    learner.checkpoint(include_replay=True, final=True)  # with --save-replay
    assert len(service(tmp_path).learner.replay) == 100
