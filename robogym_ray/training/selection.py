"""Policy snapshots kept during training: the one that scored best on a fixed set of episodes
(``SnapshotSelector``), and one every ``policy_snapshot_every_s`` of wall time
(``PolicySnapshots``, for curves of success against wall time scored after the run).

A greedy policy's success rate moves by a few points from one weights snapshot to the next
(measured on UR10 positioning: 96.7 % after 108 minutes, 95.0 % twelve minutes later, each over
the same 300 episodes), so the learner's last state is one draw among many. With
``TrainConfig.select_episodes`` the evaluator scores every snapshot it gets on the same
episodes (paired comparison: the difference between two snapshots is not buried under
episode-to-episode variance), and ``SnapshotSelector`` writes the best one's policy to
``checkpoints/policy-best.pt``. Its score is selected on the evaluator's episodes, so it is
optimistic: judge the kept policy on other seeds (``robogym-ray evaluate`` uses 1000+).

Measured once, on MiR100 navigation (docs/results-log.md): 43 snapshots scored 0.84-0.96 on 100
episodes each; the kept one (0.96) scored 91.7 % on 300 held-out episodes, the run's final
state 92.7 %. Among many snapshots of similar quality the maximum of 100-episode scores is
mostly noise (the winner's curse); more episodes per snapshot make it worth more.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from robogym_ray.learner.checkpoint import BEST_POLICY_NAME, write_policy
from robogym_ray.storage import RunStorage

TIMED_NAME = "policy-{minutes:06.2f}min"
"""A timed snapshot's name, by its wall-clock mark, + ".pt" (the peers' snapshots: + ".zip", or
RLlib's checkpoint folder). 0.01-minute resolution: marks are at least a second apart."""


def score(result: Mapping[str, float]) -> tuple[float, float]:
    """An evaluator result's rank: success rate on its episodes, then their mean return."""
    return float(result["eval_snapshot_success_rate"]), float(result["eval_return"])


class SnapshotSelector:
    """Tracks the best (success rate, mean return) and saves that snapshot's policy."""

    def __init__(self, checkpoint_dir: Path, storage: RunStorage | None = None) -> None:
        """``storage``: where the file is published from ``checkpoint_dir`` (an object store's
        staging folder); None: ``checkpoint_dir`` is where it stays."""
        self.path = checkpoint_dir / BEST_POLICY_NAME
        self.storage = storage
        self.best: tuple[float, float] | None = None
        self.record: dict[str, Any] = {}
        self.scored = 0

    def better(self, result: Mapping[str, float]) -> bool:
        """Whether an evaluation result beats the best so far (counts it as scored)."""
        self.scored += 1
        return self.best is None or score(result) > self.best

    def keep(self, result: Mapping[str, float], weights: Mapping[str, np.ndarray], version: int,
             env_steps: int) -> None:  # fmt: skip
        """Write ``weights`` as the best policy (atomically: a crash never leaves half a file).

        Raises:
            DiskWriteError: the file could not be written; the best before it stays the record
                (its file untouched), so the summary never names a policy that is not there.
        """
        best = score(result)
        record = {
            "path": _location(self.storage, self.path),
            "learner_steps": int(version),
            "env_steps": int(env_steps),
            "success_rate": best[0],
            "return": round(best[1], 3),
            "snapshots_scored": self.scored,
        }
        write_policy(self.path, weights, selection=record)
        _publish(self.storage, self.path)
        self.best, self.record = best, record

    def summary(self) -> dict[str, Any]:
        return {**self.record, "snapshots_scored": self.scored}


class PolicySnapshots:
    """The evaluator's policy written at each ``every_s`` mark of wall time.

    Mark k (k x ``every_s`` seconds) is asked for at the loop's first pass after it, and written
    when the learner answers; the file records that wall time, learner and env steps. A mark
    that a stalled loop passed over is not written with later weights: only the latest passed
    mark is. A re-run in the same directory (it resumes from the checkpoint there) numbers its
    marks on from the last file found, rather than overwrite the first run's: its names then
    leave out the time the first run spent after its last mark.
    """

    def __init__(
        self, checkpoint_dir: Path, every_s: float, storage: RunStorage | None = None
    ) -> None:
        """``storage``: as ``SnapshotSelector``'s."""
        self.dir, self.every_s, self.taken = checkpoint_dir, every_s, 0
        self.storage = storage
        self.written: list[dict[str, Any]] = []
        names = (
            storage.names() if storage is not None else [p.name for p in checkpoint_dir.glob("*")]
        )
        self.offset_min = max(
            (m for name in names if name.startswith("policy-") and (m := mark_minutes(name))),
            default=0.0,
        )

    def due(self, wall_s: float) -> int | None:
        """The latest mark passed at ``wall_s`` if it is not taken yet, else None."""
        if self.every_s <= 0:
            return None
        mark = int(wall_s // self.every_s)
        return mark if mark > self.taken else None

    def skip(self, mark: int) -> None:
        """``mark`` passes without a file (the learner could not be asked)."""
        self.taken = max(self.taken, mark)

    def keep(self, mark: int, weights: Mapping[str, np.ndarray], version: int, env_steps: int,
             wall_s: float) -> Path:  # fmt: skip
        """Write ``mark``'s policy (the mark counts as taken either way).

        Raises:
            DiskWriteError: the file could not be written (nothing partial is left).
        """
        self.skip(mark)
        minutes = self.offset_min + self.every_s * mark / 60.0
        path = self.dir / (TIMED_NAME.format(minutes=minutes) + ".pt")
        record = {"path": _location(self.storage, path), "wall_min": round(minutes, 2),
                  "saved_at_min": round(self.offset_min + wall_s / 60.0, 2),
                  "learner_steps": int(version), "env_steps": int(env_steps)}  # fmt: skip
        write_policy(path, weights, snapshot=record)
        _publish(self.storage, path)
        self.written.append(record)
        return path


def _location(storage: RunStorage | None, path: Path) -> str:
    return str(path) if storage is None else storage.location(path.name)


def _publish(storage: RunStorage | None, path: Path) -> None:
    if storage is not None:
        storage.publish(path, path.name, "policy file")


def mark_minutes(name: str) -> float | None:
    """The minutes in a timed snapshot's file name (``policy-005.00min.pt`` -> 5.0), or None."""
    try:
        return float(name.removeprefix("policy-").removesuffix(".pt").removesuffix("min"))
    except ValueError:
        return None
