"""The end of a run: the final checkpoint, the last TensorBoard write, and ``summary.json``."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import ray

from robogym_ray.training import stats
from robogym_ray.training.program import Program
from robogym_ray.training.stats import RunStats


def finish(
    p: Program,
    run_stats: RunStats,
    logger: Any,
    scalars: Callable[[], dict[str, float]],
    wall: Callable[[], float],
) -> dict[str, Any]:
    """Checkpoint (with the replay only under ``save_replay``), write the final scalars and
    the summary; returns the summary."""
    checkpoint = ray.get(p.learner.checkpoint.remote(p.cfg.save_replay, final=True))
    learner_status = ray.get(p.learner.status.remote())
    wall_s = wall()
    final = scalars()
    logger.write(final, run_stats.env_steps)
    logger.close()
    summary = stats.summary(
        run_stats, final,
        task=p.preset.env_id, wall_s=round(wall_s, 2), checkpoint=checkpoint,
        restarts=stats.all_restarts(run_stats, p.restart_counts()),
        learner_restored_from_step=learner_status["restored_from_step"],
        learner_restored_replay=learner_status["restored_replay"],
        # Sent but not in the replay: lost with a learner that Ray restarted (what came after
        # its last replay snapshot, and the batch in flight).
        lost_transitions=run_stats.transitions_sent
        - (learner_status["total_added"] - p.first_total_added),
        best_snapshot=None if p.selector is None else p.selector.summary(),
        server_nodes=p.server_nodes(), logdir=str(p.run_dir),
    )  # fmt: skip
    (p.run_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
