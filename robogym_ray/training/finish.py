"""The end of a run: the final checkpoint, the last TensorBoard write, and ``summary.json``.

A run stopped by a file it could not write (``DiskWriteError``: a full disk under the learner's
checkpoint, TensorBoard's events or the summary itself) ends here too: no final checkpoint (it
would fail the same way; the last good one stays), the summary when there is room for it, and
the error raised again with what was kept, for the command line's one ``error:`` line.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Mapping
from typing import Any

import ray
from ray.exceptions import RayTaskError

from robogym_ray.distributed.remote import node_label
from robogym_ray.errors import DiskWriteError, RunStoppedError
from robogym_ray.learner.checkpoint import CHECKPOINT_NAME
from robogym_ray.training import ending, stats
from robogym_ray.training.program import Program
from robogym_ray.training.stats import RunStats

log = logging.getLogger(__name__)


def disk_error(exc: RayTaskError) -> DiskWriteError | None:
    """The ``DiskWriteError`` a remote call (the learner's) failed with, else None.

    Ray raises it wrapped: a ``RayTaskError`` whose message is the remote traceback and whose
    ``cause`` is the error itself, which has the one line a user needs.
    """
    cause = getattr(exc, "cause", None)
    return cause if isinstance(cause, DiskWriteError) else None


def finish(
    p: Program,
    run_stats: RunStats,
    logger: Any,
    scalars: Callable[[], dict[str, float]],
    wall: Callable[[], float],
    failure: RunStoppedError | None = None,
    stopped_by: str | None = None,
    learner_status: dict[str, Any] | None = None,
    out_of_time: bool = False,
    checkpointed: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Checkpoint (with the replay only under ``save_replay``), write the final scalars and
    the summary; returns the summary. ``failure``: what stopped the run early; it, or one met
    here, is raised after the summary is written. ``stopped_by``: the signal that ended the run
    early (SIGINT, SIGTERM). ``learner_status``: the learner's, when it is not to be asked (a
    lost learner, killed). ``out_of_time``: collection stopped at ``max_wall_s``.
    ``checkpointed``: the earlier parts' counts as the caller's checkpoint recorded them
    (``ending.run_parts``)."""
    failure = failure or logger.error
    checkpoint = None
    if failure is None:
        try:
            checkpoint = ray.get(p.learner.checkpoint.remote(p.cfg.save_replay, final=True))
        except RayTaskError as exc:
            failure = disk_error(exc)
            if failure is None:
                raise
    if learner_status is None:
        learner_status = ray.get(p.learner.status.remote())
    wall_s = wall()
    final = scalars()
    logger.write(final, run_stats.env_steps)
    logger.close()
    failure = failure or logger.error
    kept = f"checkpoints/{CHECKPOINT_NAME}"
    if checkpoint is None and p.storage.exists(kept):
        checkpoint = p.storage.location(kept)  # the last good one, from before the failure
    ended = "failed" if failure is not None else "stopped" if stopped_by else "completed"
    ended_by = ending.end_reason(failed=failure is not None, stopped_by=stopped_by,
                                 env_steps=run_stats.env_steps, total_steps=p.cfg.total_steps,
                                 out_of_time=out_of_time)  # fmt: skip
    summary = stats.summary(
        run_stats, final,
        task=p.preset.env_id, eval_env_id=p.eval_env_id,
        wall_s=round(wall_s, 2), checkpoint=checkpoint,
        restarts=stats.all_restarts(run_stats, p.restart_counts()),
        # A server's fault past the restart policy's limit: given up, not restarted (its
        # holder leases another), so faults = sum(restarts) + servers_given_up.
        servers_given_up=p.servers_given_up(),
        learner_restored_from_step=learner_status["restored_from_step"],
        learner_restored_replay=learner_status["restored_replay"],
        learner_node=learner_status.get("node", ""),
        learner_threads=learner_status.get("threads", 0),
        learner_device=learner_status.get("device", ""),
        # Sent but not in the replay: lost with a learner that Ray restarted (what came after
        # its last replay snapshot, and the batch in flight).
        lost_transitions=run_stats.transitions_sent
        - (learner_status["total_added"] - p.first_total_added),
        best_snapshot=None if p.selector is None else p.selector.summary(),
        policy_snapshots=p.snapshots.written,
        # The run's folder once, as logdir: the name every summary has had (stats.run_root).
        server_nodes=p.server_nodes(), logdir=p.storage.location(),
        storage={"node": node_label() if p.storage.is_local else "(object store)"},
        ended=ended, ended_by=ended_by, **_parts(p, run_stats, final, wall_s, checkpointed),
        total_steps=p.cfg.total_steps,  # null: no step cap (a run given only --max-wall-s)
        eval_interval_s=p.cfg.eval_interval_s,  # > 0: eval/* span more of the run (summary_text)
    )  # fmt: skip
    if stopped_by:
        summary["stopped_by"] = stopped_by
    if failure is not None:
        summary["error"] = str(failure)
    where = p.storage.location("summary.json")
    try:
        p.storage.write_bytes("summary.json", json.dumps(summary, indent=2).encode(), "summary")
    except DiskWriteError as exc:
        if failure is None:
            raise exc.also(f"the run itself completed (checkpoint: {checkpoint})") from None
        raise failure.also(f"{_kept(run_stats, checkpoint)}; {exc}") from None
    if failure is not None:
        raise failure.also(f"{_kept(run_stats, checkpoint)}; summary: {where}")
    return summary


def _parts(
    p: Program,
    run_stats: RunStats,
    final: dict[str, float],
    wall_s: float,
    checkpointed: Mapping[str, Any] | None,
) -> dict[str, Any]:
    """``resumed``, ``this_part`` and ``whole_run`` (``ending.run_parts``): this part's counts
    added to the whole run's that the previous part's summary holds (else ``checkpointed``)."""
    part = {
        "env_steps": run_stats.env_steps, "episodes": run_stats.episodes,
        "learner_steps": max(0, int(final.get("learner/steps", 0)) - p.first_learner_step),
        "wall_s": round(wall_s, 2),
    }  # fmt: skip
    earlier = _earlier_summary(p) if p.cfg.resume else None
    this_part, whole_run = ending.run_parts(
        part, earlier, p.cfg.resume, p.first_learner_step, checkpointed
    )
    return {"resumed": p.cfg.resume, "this_part": this_part, "whole_run": whole_run}


def _earlier_summary(p: Program) -> dict[str, Any] | None:
    """The summary the run's previous part wrote (read before this part's replaces it); None
    when there is none, or none that reads as one."""
    if not p.storage.exists("summary.json"):
        return None
    try:
        earlier = json.loads(p.storage.read_bytes("summary.json"))
    except (OSError, ValueError) as exc:
        log.warning("the previous part's summary.json is unreadable (%s): not counted", exc)
        return None
    return earlier if isinstance(earlier, dict) else None


def _kept(run_stats: RunStats, checkpoint: str | None) -> str:
    kept = f"the last good checkpoint is kept: {checkpoint}" if checkpoint else "no checkpoint"
    return f"the run stopped at {run_stats.env_steps} env steps, {kept}"
