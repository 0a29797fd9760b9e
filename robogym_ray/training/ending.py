"""How a run ended and what it adds up to, for ``summary.json`` and the short summary: why it
ended (``ended_by``), and its counts over the parts a ``--resume`` makes of it (``this_part``,
``whole_run``). Pure functions of counters and summaries: no Ray, unit-tested alone.

``summary.json``'s top-level ``env_steps``, ``episodes`` and ``wall_s`` stay this part's, and
``learner_steps`` the learner's own count (which goes on from the checkpoint a part starts
from), as readers of the older summaries expect.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

COUNTS = ("env_steps", "episodes", "learner_steps", "wall_s")
"""What ``this_part`` and ``whole_run`` count."""

ENDINGS = {
    "total_steps": "ended at --total-steps",
    "max_wall_s": "ended at --max-wall-s, before --total-steps",
    "no_workers": "ended with no rollout worker left",
}
"""``ended_by`` of a run that was not stopped or failed, as the short summary says it."""
NO_STEP_CAP_ENDING = "ended at --max-wall-s"
"""``max_wall_s``'s ending for a run given no step total (``summary.json``'s ``total_steps``
null): there was no total to end before."""


def end_reason(
    *,
    failed: bool,
    stopped_by: str | None,
    env_steps: int,
    total_steps: int | None,
    out_of_time: bool,
) -> str:
    """Why a run ended (``summary.json``'s ``ended_by``): ``error`` (``ended`` is failed), the
    signal that stopped it (``SIGINT``, ``SIGTERM``: ``ended`` is stopped), its step total
    reached (``total_steps``), its wall limit (``max_wall_s``) or no worker left to collect
    (``no_workers``; the last three: ``ended`` is completed). ``total_steps`` None: no step
    cap (a run given only ``max_wall_s``)."""
    if failed:
        return "error"
    if stopped_by:
        return stopped_by
    if total_steps is not None and env_steps >= total_steps:
        return "total_steps"
    return "max_wall_s" if out_of_time else "no_workers"


def run_parts(
    part: Mapping[str, float],
    earlier: Mapping[str, Any] | None,
    resumed: bool,
    first_learner_step: int = 0,
    checkpointed: Mapping[str, Any] | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(this_part, whole_run)`` of ``summary.json``.

    Args:
        part: this part's ``COUNTS`` (its learner steps: those it took itself).
        earlier: the summary the run's previous part wrote (read before this one replaces
            it); one written before parts were counted (no ``whole_run``) counts as one part.
        resumed: this part continued the run from its checkpoint (``--resume``).
        first_learner_step: the learner's count at this part's start: a resumed run whose
            earlier part wrote no summary (killed) counts those steps, and not its other
            counts (``whole_run.complete`` is false), unless ``checkpointed`` has them.
        checkpointed: the earlier parts' ``COUNTS`` (and ``parts``) as the checkpoint this
            part started from recorded them (a Tune trial's). When the earlier part wrote no
            summary, the whole run counts from them and is complete: its counts are the
            trial's own, which its step budget went on from.
    """
    if earlier is not None and isinstance(earlier.get("whole_run"), Mapping):
        before = dict(earlier["whole_run"])
    elif earlier is not None:
        before = {**{k: earlier.get(k, 0) for k in COUNTS}, "parts": 1, "complete": True}
    elif checkpointed is not None:
        before = {k: checkpointed.get(k, 0) for k in COUNTS}
        # The learner's own count at this part's start (the steps its checkpoint holds),
        # not the record's, which may count steps taken after that checkpoint was written.
        before["learner_steps"] = first_learner_step or int(before["learner_steps"])
        before.update(parts=int(checkpointed.get("parts", 1)), complete=True)
    elif resumed:
        before = {"parts": 1, "learner_steps": first_learner_step, "complete": False}
    else:
        before = {"parts": 0, "complete": True}
    number = int(before.get("parts", 1)) + 1
    whole = {k: _add(before.get(k, 0), part[k], k) for k in COUNTS}
    complete = bool(before.get("complete", True))
    return {"part": number, **part}, {"parts": number, **whole, "complete": complete}


def _add(a: float, b: float, key: str) -> float:
    return round(a + b, 2) if key == "wall_s" else int(a + b)


def counts_text(counts: Mapping[str, Any]) -> str:
    """``1,200 env steps, 6 episodes, 300 learner steps in 9.5 s``."""
    return (
        f"{counts['env_steps']:,} env steps, {counts['episodes']:,} episodes, "
        f"{counts['learner_steps']:,} learner steps in {counts['wall_s']:.1f} s"
    )


def first_line(summary: Mapping[str, Any]) -> str:
    """The short summary's first line: what was trained, how much, and why it ended."""
    this = summary.get("this_part", summary)  # an older summary: its own counts
    part = f" part {this['part']} (resumed)" if summary.get("resumed") else ""
    done = counts_text(this)
    if summary.get("ended") == "stopped":
        by = summary.get("stopped_by", "a signal")
        return f"Stopped early by {by}: {summary['task']}{part} trained {done}."
    ended_by = summary.get("ended_by", "")
    why = ENDINGS.get(ended_by)
    if ended_by == "max_wall_s" and "total_steps" in summary and summary["total_steps"] is None:
        why = NO_STEP_CAP_ENDING
    return f"Trained {summary['task']}{part}: {done}" + (f"; {why}." if why else ".")


def whole_run_line(summary: Mapping[str, Any]) -> str | None:
    """``  whole run:   2 parts, ...`` for a run in more than one part, else None."""
    whole = summary.get("whole_run")
    if not isinstance(whole, Mapping) or whole.get("parts", 1) <= 1:
        return None
    missing = "" if whole.get("complete", True) else " (an earlier part wrote no summary)"
    return f"  whole run:   {whole['parts']} parts, {counts_text(whole)}{missing}"
