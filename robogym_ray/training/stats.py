"""Driver-side bookkeeping of a training run (plain data; ``training.py`` fills it)."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any


@dataclass
class WorkerSlot:
    """Driver-side bookkeeping of one rollout worker."""

    index: int
    handle: Any
    kind: str = "sim"
    steps_since_sync: int = 0
    weights_version: int = -1


@dataclass
class RunStats:
    """Counters of one run; ``statuses`` and ``returns`` keep the last 100 episodes."""

    env_steps: int = 0
    episodes: int = 0
    dropped_steps: int = 0
    learner_failures: int = 0
    worker_failures: int = 0
    robot_errors: int = 0
    worker_steps: dict[int, int] = field(default_factory=dict)
    statuses: deque[str] = field(default_factory=lambda: deque(maxlen=100))
    """Of the last 100 episodes that were not revisits (their rates are the task's)."""
    revisits: int = 0
    revisit_statuses: deque[str] = field(default_factory=lambda: deque(maxlen=100))
    returns: deque[float] = field(default_factory=lambda: deque(maxlen=100))
    learner: dict[str, float] = field(default_factory=dict)
    eval: dict[str, float] = field(default_factory=dict)
    eval_history: list[dict[str, float]] = field(default_factory=list)
