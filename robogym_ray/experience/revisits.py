"""Revisiting failed starts: a rollout worker re-runs the resets of episodes it recently failed.

Why: a policy's failures concentrate on a few hard starts. Five navigation policies of one
seed (four recipes) each failed 10-13 of the same 300 evaluation episodes; two episodes were
failed by all five and seven by at least three, where independent failures would give about
0.15 (``docs/results-log.md``, ``experiments/compare.py --policy``). Uniform resets show the
policy such a start about as rarely as the evaluation does. This is a small form of
prioritized level replay (Jiang et al., 2021). The "level" is the reset seed: the Sim envs draw
start, goal and obstacles from the seed given to ``reset``, so the same seed gives the same
scene again.

A worker with revisits resets every episode with an explicit seed, drawn from
``[FIRST_SEED, 2**31)`` so training never resets into the small seeds evaluations use
(``robogym-ray evaluate`` starts at 1000). A failed episode's seed goes into a small pool. A
later reset re-uses a pool seed with probability ``probability``. A revisit that succeeds
removes its seed; a seed is revisited at most ``max_revisits`` times.
"""

from __future__ import annotations

import math

import numpy as np

from robogym_ray.envs.outcomes import NOT_THE_POLICY, SUCCESS
from robogym_ray.errors import ConfigError

FIRST_SEED = 2**20
"""Lowest reset seed a worker draws: evaluation seeds stay below it."""


class FailedStartRevisits:
    """One worker's pool of failed reset seeds and the draw between a new start and a revisit."""

    def __init__(
        self, probability: float, capacity: int = 64, max_revisits: int = 2, seed: int = 0
    ) -> None:
        """Args:
        probability: chance that a reset re-runs a pooled failed start (when the pool is not
            empty), in [0, 1].
        capacity: failed starts kept; when full, the oldest is forgotten.
        max_revisits: times one failed start is re-run at most.
        seed: seeds this worker's draws (new reset seeds and the choice of revisits).
        """
        if not (math.isfinite(probability) and 0.0 <= probability <= 1.0):
            raise ConfigError(f"revisit probability = {probability!r}; expected in [0, 1]")
        if capacity < 1 or max_revisits < 1:
            raise ConfigError(
                f"revisit capacity = {capacity}, max_revisits = {max_revisits}; expected >= 1"
            )
        self.probability = probability
        self.capacity = capacity
        self.max_revisits = max_revisits
        self.rng = np.random.default_rng([seed, 0x5EED])
        self.pool: dict[int, int] = {}
        """Failed reset seed -> times revisited so far (insertion order = age)."""

    def next_start(self) -> tuple[int, bool]:
        """(reset seed, whether it revisits a failed start) for the next episode."""
        if self.pool and self.rng.random() < self.probability:
            seed = list(self.pool)[int(self.rng.integers(len(self.pool)))]
            self.pool[seed] += 1
            return seed, True
        return int(self.rng.integers(FIRST_SEED, 2**31)), False

    def record(self, seed: int, revisit: bool, final_status: str) -> None:
        """Book an episode's end: pool a new failure, retire a solved or used-up revisit."""
        if not final_status or final_status in NOT_THE_POLICY:
            return  # an env without final_status, or a failure that was not the policy's
        failed = final_status != SUCCESS
        if revisit:
            if seed in self.pool and (not failed or self.pool[seed] >= self.max_revisits):
                del self.pool[seed]
        elif failed:
            self.pool[seed] = 0
            if len(self.pool) > self.capacity:
                del self.pool[next(iter(self.pool))]
