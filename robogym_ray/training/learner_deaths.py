"""The learner's deaths as the training loop counts them: one per process Ray restarted, however
many calls in flight that death failed."""

from __future__ import annotations

import time
from typing import Any

import ray
from ray.exceptions import ActorUnavailableError, GetTimeoutError, RayActorError


class LearnerDeaths:
    """Counts the learner's deaths, not its failed calls: one death fails every call in flight
    to it (several workers' batches at once), and a call also fails when the worker that sent
    it died. A death is a change of the learner's pid (Ray restarted it), seen by asking it
    after a failed call or in what a call returned."""

    def __init__(self, learner: Any, wait_s: float = 120.0) -> None:
        self.learner, self.wait_s = learner, wait_s
        self.count = 0
        self.pid = self._ask()
        # Every pid the learner ever had: a late answer from a dead process is not a new death.
        self._seen: set[int] = set() if self.pid is None else {self.pid}
        # The learner did not answer after a failure: that death is counted already, so the
        # pid it comes back with (slower than wait_s) is not another.
        self._unanswered = self.pid is None

    def _ask(self) -> int | None:
        """The learner's pid; waits out a restart (restoring a checkpoint and replay takes
        seconds). None: it did not answer (dead for good after ``max_restarts``, or slower)."""
        deadline = time.monotonic() + self.wait_s
        while True:
            try:
                left = max(0.0, deadline - time.monotonic())
                return int(ray.get(self.learner.ping.remote(), timeout=left))
            except ActorUnavailableError:  # sent before Ray saw it restart: ask the new one
                if time.monotonic() >= deadline:
                    return None
                time.sleep(0.1)
            except (RayActorError, GetTimeoutError):
                return None

    def call_failed(self) -> bool:
        """A learner call failed; True when that is a death not counted yet."""
        now = self._ask()
        if now is not None:
            return self._new_pid(now)  # same pid: an earlier death, or the sender's
        if self._unanswered:
            return False
        self._unanswered = True
        self.count += 1
        return True

    def answered(self, pid: int) -> bool:
        """A call returned from ``pid``: a new pid is a death whose calls never failed here.
        True when ``pid`` is a process not seen before (a restarted learner to look at)."""
        return self._new_pid(pid)

    def _new_pid(self, pid: int) -> bool:
        if pid in self._seen:
            return False
        self._seen.add(pid)
        self.pid = pid
        if self._unanswered:  # its death was counted when the old process stopped answering
            self._unanswered = False
        else:
            self.count += 1
        return True
