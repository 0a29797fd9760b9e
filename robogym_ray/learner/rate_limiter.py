"""The samples-per-insert ratio: how many learner steps each inserted transition pays for."""

from __future__ import annotations


class SamplesPerInsert:
    """Learner steps are earned per inserted transition, once replay is warm.

    Each of ``n`` transitions earns ``samples_per_insert / batch_size`` learner steps, so every
    transition is sampled ``samples_per_insert`` times on average.

    Two ways to spend them:

    * coupled (``tolerance`` 0): the learner runs what it has earned, when it is called
      (``take``), inside the call that brought the transitions;
    * decoupled (``tolerance`` T > 0, Reverb's ``SampleToInsertRatio`` with an error buffer of
      T steps on either side): a learner thread steps whenever ``may_step`` allows it - up to T
      steps ahead of what inserts have paid for - and an insert waits while more than T steps
      are owed (``owes_too_much``). Over a whole run the steps taken stay within T of the
      steps earned, so the ratio a run keeps does not change; what changes is *when* the
      learner steps: between inserts instead of inside them.
    """

    def __init__(self, samples_per_insert: float, batch_size: int, tolerance: float = 0.0) -> None:
        self.steps_per_insert = samples_per_insert / batch_size
        self.tolerance = tolerance
        self.earned = 0.0
        """Steps earned and not yet taken; negative when a decoupled learner ran ahead."""

    def inserted(self, n: int, warm: bool) -> None:
        """``n`` transitions went in; before replay is warm they earn nothing."""
        if warm:
            self.earned += n * self.steps_per_insert

    def take(self, cap: int | None = None) -> int:
        """The whole learner steps earned (at most ``cap``); the rest carries over."""
        steps = int(self.earned) if cap is None else min(int(self.earned), cap)
        self.earned -= steps
        return steps

    def may_step(self, steps: int) -> bool:
        """Whether ``steps`` more stay within the tolerance ahead of what was earned."""
        return self.earned - steps >= -self.tolerance

    def took(self, steps: int) -> None:
        """A decoupled learner took ``steps`` (``may_step`` allowed them)."""
        self.earned -= steps

    def owes_too_much(self) -> bool:
        """Whether the learner is more than the tolerance behind: an insert then waits."""
        return self.earned > self.tolerance
