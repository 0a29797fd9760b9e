"""Episode outcomes: the ``final_status`` names the envs report, and the one place that turns
a list of them into counts and rates (training scalars, the evaluator, ``evaluate``)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

SUCCESS = "success"
COLLISION = "collision"
MAX_STEPS = "max_steps_exceeded"
"""The step limit ended the episode (``truncated=True``)."""
SERVER_RESTARTED = "server_restarted"
"""The robot server failed mid-episode; the supervisor restarts it (``truncated=True``)."""
ROBOT_ERROR = "robot_error"
"""A rollout worker abandoned the episode after a robot error."""
TRUNCATED, TERMINATED = "truncated", "terminated"
"""What an env that sets no ``final_status`` (e.g. Pendulum) ended with."""
TIMEOUTS = frozenset({MAX_STEPS, TRUNCATED})
NOT_THE_POLICY = frozenset({SERVER_RESTARTED, ROBOT_ERROR})
"""Ends that say nothing about the policy or its start."""
CATEGORIES = ("success", "collision", "timeout", "other")
"""What a report counts: every status falls in exactly one."""
WINDOW_KEYS = ("window_position_error", "window_rotation_error")
"""A task with a new command every few seconds (the deploy reach) ends only by time: its
measure is what it puts in ``info`` at each window's end (m, rad)."""


def final_status(info: Mapping[str, Any], truncated: bool) -> str:
    """The status of an episode's last step (``info["final_status"]`` when the env sets it)."""
    return str(info.get("final_status", TRUNCATED if truncated else TERMINATED))


def category(status: str) -> str:
    if status in (SUCCESS, COLLISION):
        return status
    return "timeout" if status in TIMEOUTS else "other"


def counts(statuses: Iterable[str]) -> dict[str, int]:
    """Episodes per category (all four, zeros included)."""
    found = Counter(category(s) for s in statuses)
    return {c: found.get(c, 0) for c in CATEGORIES}


def rates(statuses: Iterable[str]) -> dict[str, float]:
    """``success_rate``, ``collision_rate``, ``timeout_rate``, ``other_rate`` (0..1; 0 if none)."""
    statuses = list(statuses)
    n = max(1, len(statuses))
    return {f"{c}_rate": v / n for c, v in counts(statuses).items()}


def window_medians(windows: Iterable[Sequence[float]]) -> dict[str, float]:
    """The medians of ``WINDOW_KEYS`` over (position, rotation) window-end errors; empty for
    none (a task without windows)."""
    errors = np.asarray(list(windows), dtype=np.float64).reshape(-1, len(WINDOW_KEYS))
    if not len(errors):
        return {}
    return {key: float(np.median(errors[:, i])) for i, key in enumerate(WINDOW_KEYS)}
