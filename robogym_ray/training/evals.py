"""When the evaluator runs during training, and what becomes of its results: the evaluation
history, the ``eval/video`` GIF, and the snapshot the selector keeps."""

from __future__ import annotations

import logging
import time
from typing import Any

import ray
from ray.exceptions import RayActorError

from robogym_ray.experience.evaluator import VIDEO_KEY
from robogym_ray.training import stats
from robogym_ray.training.program import Program
from robogym_ray.training.stats import RunStats

log = logging.getLogger(__name__)


class EvalSchedule:
    """One evaluator call in flight at a time, started at most every ``eval_interval_s``."""

    def __init__(self, program: Program, run_stats: RunStats) -> None:
        self.p, self.cfg, self.stats = program, program.cfg, run_stats
        self.weights_ref: Any = None
        self.next_at = 0.0

    def start(self) -> Any:
        evaluator = self.p.evaluator
        if evaluator is None:
            return None
        # Its own fetch: with policy averaging the evaluator scores the average, not the
        # online weights the workers act with.
        self.weights_ref = self.p.learner.get_eval_weights.remote()  # a selector may keep it
        self.next_at = time.perf_counter() + self.cfg.eval_interval_s
        if self.p.selector is not None:
            # The same episodes for every snapshot: seeds the workers and `evaluate` never use.
            n, base = self.cfg.select_episodes, self.cfg.seed + 20_000
            return evaluator.evaluate.remote(self.weights_ref, n, base)
        return evaluator.evaluate.remote(self.weights_ref)

    def poll(self, ref: Any, logger: Any, wall_s: float) -> Any:
        """Take a finished call's result and start the next when due; the call in flight."""
        if ref is None:  # between two calls (eval_interval_s), or the evaluator is gone
            due = self.p.evaluator is not None and time.perf_counter() >= self.next_at
            return self.start() if due else None
        if not ray.wait([ref], timeout=0)[0]:
            return ref
        try:
            self.stats.eval = ray.get(ref)
            if (gif := self.stats.eval.pop(VIDEO_KEY, None)) is not None:
                logger.gif("eval/video", gif, self.stats.env_steps)
            self.stats.eval_history.append(stats.eval_entry(self.stats, wall_s))
            selector = self.p.selector
            if selector is not None and selector.better(self.stats.eval):
                weights, version = ray.get(self.weights_ref)
                selector.keep(self.stats.eval, weights, version, self.stats.env_steps)
        except RayActorError:
            # The call fails too when its weights came from a learner that died (Ray restarts
            # it): then only this evaluation is lost. Only a dead evaluator stops evaluating.
            if self._evaluator_alive():
                log.warning("an evaluation was lost with its weights (learner restarted)")
            else:
                log.warning("evaluator failed; evaluation stops")
                self.p.evaluator = None
            return None
        return self.poll(None, logger, wall_s)

    def _evaluator_alive(self) -> bool:
        try:
            ray.get(self.p.evaluator.ping.remote(), timeout=30)
            return True
        except (RayActorError, ray.exceptions.GetTimeoutError):
            return False
