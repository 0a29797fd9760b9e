"""A learner that steps between inserts: the decoupled side of ``SamplesPerInsert``.

Coupled (the default), the learner takes its steps inside the ``add`` call that paid for them:
while a batch travels to it, it idles, and a worker's batch waits for the steps of the one
before. Decoupled (``D4PGConfig.rate_tolerance`` T > 0), a thread of the learner's process
steps whenever the limiter allows - up to T steps ahead of what was paid for - and an ``add``
only inserts and returns once no more than T steps are owed. Torch releases the GIL inside its
kernels, so the actor's own thread receives and unpacks the next batch while a step runs.

One lock guards the learner's state. The stepping thread holds it for a step at a time and
yields it between steps to anyone waiting (an insert, a weights read, a checkpoint), so a
caller waits for at most one step.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from robogym_ray.learner.rate_limiter import SamplesPerInsert


class BackgroundSteps:
    """Runs ``train(chunk)`` on its own thread whenever ``limiter`` and ``can_step`` allow."""

    def __init__(
        self,
        limiter: SamplesPerInsert,
        can_step: Callable[[], bool],
        train: Callable[[int], dict[str, Any]],
        chunk: int = 1,
    ) -> None:
        """Args:
        limiter: the run's ratio, with ``tolerance`` >= ``chunk`` (else no step could start).
        can_step: whether the replay is warm.
        train: takes that many learner steps (and any checkpoint they are due), returns metrics.
        chunk: steps per turn (``sgd_steps_per_sample``: one sampled block).
        """
        if limiter.tolerance < chunk:
            raise ValueError(f"tolerance {limiter.tolerance} < {chunk} steps per turn")
        self.limiter, self.can_step, self.train, self.chunk = limiter, can_step, train, chunk
        self._cond = threading.Condition()  # an RLock: train's checkpoint re-enters it
        self._count = threading.Lock()
        self._wanted = 0  # callers blocked on the lock: the thread yields after its step
        self._band_waiters = 0  # inserts waiting for the owed steps to come within tolerance
        self._stop = False
        self.error: BaseException | None = None
        """What ended the thread (e.g. a checkpoint a full disk refused); raised to callers."""
        self._last: dict[str, Any] = {}
        self._since = 0
        self._thread = threading.Thread(target=self._loop, name="learner-steps", daemon=True)
        self._thread.start()

    @contextmanager
    def exclusive(self) -> Iterator[None]:
        """The learner's state to the caller alone, after the step in progress."""
        with self._count:
            self._wanted += 1
        try:
            self._cond.acquire()
        finally:
            with self._count:
                self._wanted -= 1
        try:
            yield
        finally:
            self._cond.notify_all()
            self._cond.release()

    def wait_within_tolerance(self) -> None:
        """Inside ``exclusive``: wait while more than the tolerance is owed (an insert's
        backpressure, so the workers cannot outrun the ratio); raise what stopped the thread."""
        self._band_waiters += 1
        try:
            while self.error is None and not self._stop and self.limiter.owes_too_much():
                self._cond.notify_all()
                self._cond.wait(0.5)
        finally:
            self._band_waiters -= 1
        self.raise_error()

    def reply(self) -> tuple[dict[str, Any], int]:
        """Inside ``exclusive``: the last step's metrics and the steps taken since the last
        reply."""
        out, steps = dict(self._last), self._since
        self._since = 0
        return out, steps

    def raise_error(self) -> None:
        if self.error is not None:
            raise self.error

    def close(self, timeout: float = 30.0) -> None:
        """Stop after the step in progress and join the thread."""
        with self.exclusive():
            self._stop = True
        self._thread.join(timeout)

    def _may_go(self) -> bool:
        if self._wanted or (self._band_waiters and not self.limiter.owes_too_much()):
            return False  # someone waits for the lock, or an insert may now return
        return self.can_step() and self.limiter.may_step(self.chunk)

    def _loop(self) -> None:
        with self._cond:
            while True:
                while not self._stop and not self._may_go():
                    self._cond.wait(0.5)
                if self._stop:
                    return
                self.limiter.took(self.chunk)
                try:
                    self._last = self.train(self.chunk)
                except BaseException as exc:  # noqa: BLE001 - handed to the next caller
                    self.error, self._stop = exc, True
                    self._cond.notify_all()
                    return
                self._since += self.chunk
                self._cond.notify_all()
