"""The samples-per-insert ratio: how many learner steps each inserted transition pays for."""

from __future__ import annotations


class SamplesPerInsert:
    """Learner steps are earned per inserted transition, once replay is warm.

    Each of ``n`` transitions earns ``samples_per_insert / batch_size`` learner steps, so every
    transition is sampled ``samples_per_insert`` times on average (Acme's ``SampleToInsertRatio``
    without the blocking: the trainer here runs what it has earned, when it is called).
    """

    def __init__(self, samples_per_insert: float, batch_size: int) -> None:
        self.steps_per_insert = samples_per_insert / batch_size
        self.earned = 0.0

    def inserted(self, n: int, warm: bool) -> None:
        """``n`` transitions went in; before replay is warm they earn nothing."""
        if warm:
            self.earned += n * self.steps_per_insert

    def take(self, cap: int | None = None) -> int:
        """The whole learner steps earned (at most ``cap``); the rest carries over."""
        steps = int(self.earned) if cap is None else min(int(self.earned), cap)
        self.earned -= steps
        return steps
