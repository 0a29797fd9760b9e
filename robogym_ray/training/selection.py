"""Snapshot selection: keep the policy snapshot that scored best on a fixed set of episodes.

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


def score(result: Mapping[str, float]) -> tuple[float, float]:
    """An evaluator result's rank: success rate on its episodes, then their mean return."""
    return float(result["eval_snapshot_success_rate"]), float(result["eval_return"])


class SnapshotSelector:
    """Tracks the best (success rate, mean return) and saves that snapshot's policy."""

    def __init__(self, checkpoint_dir: Path) -> None:
        self.path = checkpoint_dir / BEST_POLICY_NAME
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
            "path": str(self.path),
            "learner_steps": int(version),
            "env_steps": int(env_steps),
            "success_rate": best[0],
            "return": round(best[1], 3),
            "snapshots_scored": self.scored,
        }
        write_policy(self.path, weights, selection=record)
        self.best, self.record = best, record

    def summary(self) -> dict[str, Any]:
        return {**self.record, "snapshots_scored": self.scored}
