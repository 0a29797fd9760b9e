"""Learner service (plain class): D4PG learner + replay + insert ratio + checkpoints.

The Ray program wraps it in an actor with automatic restarts; a restarted actor runs
``__init__`` again, which restores the latest checkpoint, so training resumes where it was.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext, suppress
from pathlib import Path
from typing import Any

import numpy as np

from robogym_ray.errors import DiskWriteError
from robogym_ray.learner.checkpoint import CHECKPOINT_NAME, replay_path
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.learner.learner import D4PGLearner
from robogym_ray.learner.rate_limiter import SamplesPerInsert
from robogym_ray.learner.stepping import BackgroundSteps
from robogym_ray.storage import RunStorage

log = logging.getLogger(__name__)


class LearnerService:
    """Inserts actor batches and runs learner steps at ``samples_per_insert``: inside ``add``
    (coupled, the default), or on a thread of their own between inserts (``rate_tolerance`` >
    0, ``learner/stepping.py``)."""

    def __init__(
        self,
        d4pg: D4PGConfig,
        obs_dim: int,
        act_dim: int,
        *,
        seed: int = 0,
        checkpoint_dir: str | None = None,
        storage: RunStorage | None = None,
        checkpoint_every: int = 1000,
        max_steps_per_call: int = 1000,
        replay_snapshot_every_s: float = 0.0,
    ) -> None:
        """Args:
        checkpoint_dir: where ``learner.pt`` lives; restored from on start when present.
        storage: the run's storage, instead of ``checkpoint_dir``: its ``checkpoints/`` folder
            (on a path every node reaches, or an object store, staged on this node and
            uploaded after each checkpoint), so a learner that Ray restarts on another node
            restores what this one wrote.
        checkpoint_every: learner steps between checkpoints (0 disables).
        replay_snapshot_every_s: seconds between checkpoints that also write the replay, so a
            restarted learner restores it and loses only what came after (0: never).
        max_steps_per_call: cap on learner steps run inside one ``add`` (keeps the actor
            responsive; the debt carries over to the next call). Coupled stepping only.
        """
        self.learner = D4PGLearner(d4pg, obs_dim, act_dim, seed=seed)
        self.config = d4pg
        self.storage = storage.child("checkpoints") if storage is not None else None
        if self.storage is not None:
            checkpoint_dir = str(self.storage.staging(""))
            if not self.storage.is_local:  # an empty staging folder: fetch the latest
                for name in (replay_path(CHECKPOINT_NAME).name, CHECKPOINT_NAME):
                    self.storage.download(name, Path(checkpoint_dir) / name)
        self.checkpoint_dir = Path(checkpoint_dir) if checkpoint_dir else None
        self.checkpoint_every = checkpoint_every
        self.max_steps_per_call = max_steps_per_call
        self.inserted = 0
        self.limiter = SamplesPerInsert(
            d4pg.samples_per_insert, d4pg.batch_size, tolerance=d4pg.rate_tolerance
        )
        self._last_checkpoint_step = 0
        self.restored_from_step = -1
        self.restored_replay = 0
        self._step_time = 0.0
        self.replay_snapshot_every_s = replay_snapshot_every_s
        self._next_snapshot = time.monotonic() + replay_snapshot_every_s
        if self.checkpoint_dir is not None and (self.checkpoint_dir / CHECKPOINT_NAME).exists():
            self.learner.restore(self.checkpoint_dir / CHECKPOINT_NAME)
            self.restored_from_step = self._last_checkpoint_step = self.learner.num_steps
            self.restored_replay = len(self.learner.replay)
            log.warning("learner restored from checkpoint at step %d", self.restored_from_step)
        self.background: BackgroundSteps | None = None
        if d4pg.rate_tolerance > 0:  # last: the thread may step (and checkpoint) at once
            # torch's thread count is process-wide: the new thread uses the learner's.
            self.background = BackgroundSteps(
                self.limiter, self.learner.can_step, self.train, d4pg.sgd_steps_per_sample
            )

    @property
    def version(self) -> int:
        """Weights version = learner steps taken (monotonic, survives restarts)."""
        return self.learner.num_steps

    def add(self, batch: dict[str, np.ndarray], priorities: np.ndarray | None = None) -> dict:
        """Insert transitions, then run the learner steps they pay for (coupled) or wait until
        the stepping thread owes no more than the tolerance (decoupled); returns metrics: the
        last step's, with ``steps_this_call`` the steps taken since the previous reply."""
        n = len(batch["reward"])
        if self.background is None:
            self._insert(batch, priorities, n)
            return self.train(self.limiter.take(self.max_steps_per_call))
        self.background.raise_error()
        with self.background.exclusive():
            self._insert(batch, priorities, n)
            self.background.wait_within_tolerance()
            out, steps = self.background.reply()
            return self._counted(out, steps)

    def _insert(self, batch: dict[str, np.ndarray], priorities: np.ndarray | None, n: int) -> None:
        self.learner.add(batch, priorities)
        self.inserted += n
        self.limiter.inserted(n, warm=self.learner.can_step())

    def _counted(self, out: dict, steps: int) -> dict:
        """``out`` with the counters every reply carries."""
        out.update(
            learner_steps=float(self.version),
            steps_this_call=float(steps),
            replay_size=float(len(self.learner.replay)),
            inserted=float(self.inserted),
            learner_time_s=self._step_time,
            pid=float(os.getpid()),  # the driver counts a learner restart once, by its pid
        )
        return out

    def _exclusive(self) -> AbstractContextManager[None]:
        """The learner's state to this caller alone (a stepping thread waits)."""
        return nullcontext() if self.background is None else self.background.exclusive()

    def close(self) -> None:
        """Stop a stepping thread (after its step in progress)."""
        if self.background is not None:
            self.background.close()

    def train(self, steps: int) -> dict:
        """Take ``steps`` learner steps now, and the checkpoints they make due."""
        start = time.perf_counter()
        out = self.learner.run(steps)
        self._step_time += time.perf_counter() - start
        self._counted(out, steps)
        if (
            self.checkpoint_every
            and self.version - self._last_checkpoint_step >= self.checkpoint_every
        ):
            self.checkpoint()
        if self.replay_snapshot_every_s > 0 and time.monotonic() >= self._next_snapshot:
            self.checkpoint(include_replay=True)
            self._next_snapshot = time.monotonic() + self.replay_snapshot_every_s
        return out

    def initial_priorities(self, batch: dict[str, np.ndarray]) -> np.ndarray:
        with self._exclusive():
            return self.learner.compute_initial_priorities(batch)

    def get_weights(self) -> tuple[dict[str, np.ndarray], int]:
        with self._exclusive():
            return self.learner.get_weights(), self.version

    def get_eval_weights(self) -> tuple[dict[str, np.ndarray], int]:
        """What the evaluator scores: the policy average when the learner keeps one."""
        with self._exclusive():
            return self.learner.get_eval_weights(), self.version

    def checkpoint(self, include_replay: bool = False, final: bool = False) -> str | None:
        """Write the checkpoint atomically (a crash mid-write never leaves a broken file).

        With ``include_replay`` the replay goes to ``learner.pt.replay.npz`` beside it, so a
        continued run (or this learner, restarted) starts with it. Without, a replay file left
        there is removed, because it would no longer belong to these networks - except a
        snapshot during a run (``replay_snapshot_every_s``): a restart restores it with the
        newer networks, which only costs the transitions inserted since. The ``final``
        checkpoint of a run keeps a replay only when asked to.
        """
        if self.checkpoint_dir is None:
            return None
        with self._exclusive():
            return self._checkpoint(include_replay, final)

    def _checkpoint(self, include_replay: bool, final: bool) -> str:
        # Not named ``final``: that is the parameter the replay decision below reads.
        path = self.checkpoint_dir / CHECKPOINT_NAME
        tmp = self.checkpoint_dir / f".{CHECKPOINT_NAME}.{os.getpid()}.tmp"
        with _replacing(path, tmp):
            self.checkpoint_dir.mkdir(parents=True, exist_ok=True)
            self.learner.save(tmp, include_replay=include_replay)  # both renamed into place last
            if include_replay:
                os.replace(replay_path(tmp), replay_path(path))
            elif final or self.replay_snapshot_every_s <= 0:
                replay_path(path).unlink(missing_ok=True)
            os.replace(tmp, path)
            if self.storage is not None:  # an object store: the replay first, as renamed above
                self.storage.publish(replay_path(path), replay_path(path).name, "learner replay")
                self.storage.publish(path, path.name, "learner checkpoint")
        self._last_checkpoint_step = self.version
        return self.storage.location(path.name) if self.storage is not None else str(path)

    def ping(self) -> int:
        return os.getpid()

    def status(self) -> dict[str, Any]:
        """Counters that survive (version) or reveal (restored_from_step) a restart."""
        with self._exclusive():
            return {
                "pid": os.getpid(),
                "version": self.version,
                "inserted": self.inserted,
                "restored_from_step": self.restored_from_step,
                "total_added": int(self.learner.replay.total_added),
                "restored_replay": self.restored_replay,
            }


@contextmanager
def _replacing(path: Path, tmp: Path) -> Iterator[None]:
    """Around a checkpoint written to ``tmp`` (and its replay) and renamed to ``path``: when
    anything fails, the temporary files are removed, so a full disk leaves the last good
    checkpoint and nothing else, and the error (a ``DiskWriteError``) names ``path``, the file
    a user knows, not the temporary name it failed on."""
    try:
        yield
    except BaseException as exc:
        for leftover in (tmp, replay_path(tmp)):
            with suppress(OSError):
                leftover.unlink(missing_ok=True)
        if isinstance(exc, DiskWriteError):
            what, where = "learner checkpoint", path
            if exc.what == "replay":
                what, where = "learner replay", replay_path(path)
            message = f"cannot write {what} {where}: {exc.reason}"
            raise type(exc)(message, path=str(where), reason=exc.reason, what=what) from None
        if isinstance(exc, OSError):
            raise DiskWriteError.of("learner checkpoint", path, exc) from None
        raise
