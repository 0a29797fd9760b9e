"""Decoupled stepping (``rate_tolerance`` > 0): a learner thread steps between inserts within
the tolerance band, an insert waits while more than the tolerance is owed, the ratio a run keeps
is the coupled one within the tolerance, and what the thread hits reaches the next caller."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import pytest

from robogym_ray.errors import ConfigError, DiskWriteError
from robogym_ray.learner.checkpoint import CHECKPOINT_NAME
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.rate_limiter import SamplesPerInsert
from robogym_ray.learner.service import LearnerService
from tests.learner.test_service_replay import ACT, OBS, SMALL, batch

TOLERANCE = 8


def decoupled(tmp_path: Path | None = None, **kw: object) -> LearnerService:
    d4pg = dataclasses.replace(SMALL, rate_tolerance=TOLERANCE, **kw)  # type: ignore[arg-type]
    return LearnerService(d4pg, OBS, ACT, checkpoint_dir=str(tmp_path) if tmp_path else None,
                          checkpoint_every=0)  # fmt: skip


def settled(service: LearnerService, timeout: float = 30.0) -> int:
    """The learner's steps once its thread has taken every step the band allows."""
    deadline = time.monotonic() + timeout
    chunk = service.config.sgd_steps_per_sample
    while service.limiter.may_step(chunk) and time.monotonic() < deadline:
        time.sleep(0.01)
    with service._exclusive():
        return service.version


def test_the_thread_keeps_the_ratio_within_the_tolerance_and_inserts_wait_beyond_it() -> None:
    service = decoupled()
    try:
        replies = 0
        for i in range(12):  # from the 2nd (64: warm), each 32 earn 32 steps (16 / 16 each)
            out = service.add(batch(32, seed=i))
            replies += int(out["steps_this_call"])
            # An insert returns only once no more than the tolerance is owed.
            assert service.limiter.earned <= TOLERANCE
            assert out["inserted"] == 32 * (i + 1)
        earned = 11 * 32 * SMALL.samples_per_insert / SMALL.batch_size  # 352 steps
        # Between inserts the thread ran ahead, never more than the tolerance: settled, it
        # stands exactly that far ahead.
        assert settled(service) == earned + TOLERANCE
        assert service.limiter.earned == -TOLERANCE
        # Every step taken is reported once, across the replies (the rest at the next); the
        # step the last insert earns may come after its reply.
        replies += int(service.add(batch(1, seed=99))["steps_this_call"])
        assert 0 <= service.version - replies <= 1
    finally:
        service.close()


def test_steps_run_between_inserts_not_inside_them() -> None:
    service = decoupled()
    try:
        service.add(batch(63, seed=0))  # not warm: no step can be taken
        assert settled(service, timeout=1.0) == 0
        service.add(batch(1, seed=1))  # warm: earns 1, and the thread runs T ahead of it
        assert settled(service) == 1 + TOLERANCE
        service.add(batch(16, seed=2))  # earns 16; 8 owed is within the band: add returns
        # With no further call, the thread takes them.
        assert settled(service) == 17 + TOLERANCE
    finally:
        service.close()


def test_blocks_of_sgd_steps_and_weights_and_checkpoints_beside_the_thread(tmp_path: Path) -> None:
    service = decoupled(tmp_path, sgd_steps_per_sample=4)
    try:
        for i in range(6):
            service.add(batch(32, seed=i))
            weights, version = service.get_weights()  # never a half-updated network
            assert version % 4 == 0 and weights  # never half a block
        path = service.checkpoint()
        assert path is not None and Path(path).exists()
        restored = LearnerService(SMALL, OBS, ACT, checkpoint_dir=str(tmp_path))
        assert restored.version == restored.restored_from_step > 0
    finally:
        service.close()


def test_a_checkpoint_the_thread_cannot_write_stops_it_and_the_next_insert_says_why(
    tmp_path: Path,
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    d4pg = dataclasses.replace(SMALL, rate_tolerance=TOLERANCE)
    service = LearnerService(d4pg, OBS, ACT, checkpoint_dir=str(blocker / "ckpt"),
                             checkpoint_every=4)  # fmt: skip
    try:
        with pytest.raises(DiskWriteError, match=CHECKPOINT_NAME):
            for i in range(20):
                service.add(batch(32, seed=i))
                time.sleep(0.05)
        with pytest.raises(DiskWriteError):  # and every call after it
            service.add(batch(4, seed=50))
    finally:
        service.close()


def test_the_coupled_limiter_is_unchanged_and_bad_tolerances_are_refused() -> None:
    limiter = SamplesPerInsert(32.0, 256)
    limiter.inserted(100, warm=True)  # 12.5 steps
    assert limiter.take(10) == 10 and limiter.take() == 2 and limiter.earned == pytest.approx(0.5)
    assert LearnerService(SMALL, OBS, ACT).background is None
    with pytest.raises(ConfigError, match="rate_tolerance"):
        D4PGConfig(rate_tolerance=-1)
    with pytest.raises(ConfigError, match="rate_tolerance"):
        D4PGConfig(rate_tolerance=2, sgd_steps_per_sample=4)
