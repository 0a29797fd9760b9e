"""How a run ended, for ``summary.json`` and the short summary: why it ended (``ended_by``)
and whether it went on from an earlier part (``resumed``). Pure functions of counters and
summaries: no Ray, unit-tested alone."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

ENDINGS = {
    "total_steps": "ended at --total-steps",
    "max_wall_s": "ended at --max-wall-s, before --total-steps",
    "no_workers": "ended with no rollout worker left",
}
"""``ended_by`` of a run that was not stopped or failed, as the short summary says it."""


def end_reason(
    *,
    failed: bool,
    stopped_by: str | None,
    env_steps: int,
    total_steps: int,
    out_of_time: bool,
) -> str:
    """Why a run ended (``summary.json``'s ``ended_by``): ``error`` (``ended`` is failed), the
    signal that stopped it (``SIGINT``, ``SIGTERM``: ``ended`` is stopped), its step total
    reached (``total_steps``), its wall limit (``max_wall_s``) or no worker left to collect
    (``no_workers``; the last three: ``ended`` is completed)."""
    if failed:
        return "error"
    if stopped_by:
        return stopped_by
    if env_steps >= total_steps:
        return "total_steps"
    return "max_wall_s" if out_of_time else "no_workers"


def counts_text(counts: Mapping[str, Any]) -> str:
    """``1,200 env steps, 6 episodes, 300 learner steps in 9.5 s``."""
    return (
        f"{counts['env_steps']:,} env steps, {counts['episodes']:,} episodes, "
        f"{counts['learner_steps']:,} learner steps in {counts['wall_s']:.1f} s"
    )


def first_line(summary: Mapping[str, Any]) -> str:
    """The short summary's first line: what was trained, how much, and why it ended."""
    part = " (resumed)" if summary.get("resumed") else ""
    done = counts_text(summary)
    if summary.get("ended") == "stopped":
        by = summary.get("stopped_by", "a signal")
        return f"Stopped early by {by}: {summary['task']}{part} trained {done}."
    why = ENDINGS.get(summary.get("ended_by", ""))
    return f"Trained {summary['task']}{part}: {done}" + (f"; {why}." if why else ".")
