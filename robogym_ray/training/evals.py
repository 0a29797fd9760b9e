"""When the evaluator runs during training, and what becomes of its results: the evaluation
history, the ``eval/video`` GIF, the snapshot the selector keeps, and the timed policy
snapshots."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from contextlib import suppress
from typing import Any

import ray
from ray.exceptions import RayActorError

from robogym_ray.errors import DiskWriteError
from robogym_ray.experience.evaluator import VIDEO_KEY
from robogym_ray.training import stats
from robogym_ray.training.program import Program
from robogym_ray.training.stats import RunStats

log = logging.getLogger(__name__)


class EvalSchedule:
    """One evaluator call in flight at a time, started at most every ``eval_interval_s``."""

    def __init__(
        self,
        program: Program,
        run_stats: RunStats,
        on_entry: Callable[[dict[str, float]], None] | None = None,
    ) -> None:
        self.p, self.cfg, self.stats = program, program.cfg, run_stats
        self.on_entry = on_entry
        """Called with each evaluation's ``eval_history`` entry as it is recorded."""
        self.weights_ref: Any = None
        self.next_at = 0.0
        self.failure: DiskWriteError | None = None
        """A policy file could not be written (a full disk): the loop ends the run on it."""
        self.snapshot_ask: tuple[Any, int, float] | None = None
        """A timed snapshot's weights asked of the learner: (ref, mark, wall s when asked)."""
        self.replacement_ping: Any = None
        """The first call to an evaluator that replaced a lost one, until it answers: one
        that no node left can place never does, and the run's end must not wait on it."""

    def start(self, episodes: int = 1) -> Any:
        """Start a call of ``episodes`` greedy episodes (a selector's own count when it has
        one); the call in flight, or None without an evaluator."""
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
        return evaluator.evaluate.remote(self.weights_ref, episodes)

    def poll(self, ref: Any, logger: Any, wall_s: float) -> Any:
        """Take a finished call's result and start the next when due; the call in flight."""
        if ref is None:  # between two calls (eval_interval_s), or the evaluator is gone
            due = self.p.evaluator is not None and time.perf_counter() >= self.next_at
            return self.start() if due else None
        if not ray.wait([ref], timeout=0)[0]:
            return ref
        self._take(ref, logger, wall_s)
        return self.poll(None, logger, wall_s)

    def snapshot(self, wall_s: float, final: bool = False) -> None:
        """Keep the evaluator's policy at each passed ``policy_snapshot_every_s`` mark: asked
        for without waiting (the learner may be writing a replay snapshot, on the same 300 s
        clock), written when it answers; ``final`` waits, so the run's last mark is kept."""
        snapshots = self.p.snapshots
        while True:
            if self.snapshot_ask is None:
                mark = snapshots.due(wall_s)
                if mark is None:
                    return
                self.snapshot_ask = (self.p.learner.get_eval_weights.remote(), mark, wall_s)
            ref, mark, asked_s = self.snapshot_ask
            if not final and not ray.wait([ref], timeout=0)[0]:
                return
            self.snapshot_ask = None
            try:
                weights, version = ray.get(ref, timeout=120)
            except (RayActorError, ray.exceptions.GetTimeoutError):
                # A learner that Ray is restarting: this mark is lost, the next one is taken.
                log.warning("policy snapshot at %.0f s lost: the learner did not answer", asked_s)
                snapshots.skip(mark)
                continue
            try:
                snapshots.keep(mark, weights, version, self.stats.env_steps, asked_s)
            except DiskWriteError as exc:
                self.failure = self.failure or exc
                return

    def final(self, ref: Any, logger: Any, wall_s: float) -> None:
        """Every run ends with an evaluation: the call in flight is waited for, and when the
        evaluator has finished no episode yet (a short run, or a slow machine), the final
        policy plays ``final_eval_episodes`` greedy episodes now, so ``eval/*`` and the
        summary always have rates. ``eval_final_episodes`` says which it was: the episodes
        of that final call, 0 when the rates are the evaluator's running window."""
        if ref is not None and self._will_answer(ref):
            # Lost now, it is replaced only if the run has no rates yet: else they stand.
            self._take(ref, logger, wall_s, replace=not self.stats.eval)
        if self.p.evaluator is None:
            return
        final_episodes = 0
        if not self.stats.eval:
            final_episodes = self.cfg.final_eval_episodes
            last = self.start(final_episodes)
            if self._will_answer(last):
                self._take(last, logger, wall_s)
        if self.stats.eval:  # empty only when that call was lost with its actor
            self.stats.eval["eval_final_episodes"] = float(final_episodes)

    def _will_answer(self, ref: Any) -> bool:
        """Whether to wait for ``ref`` (without a bound): yes, unless its evaluator is a
        replacement that has not started within ``worker_deadline_s``, which is given up."""
        ping = self.replacement_ping
        if ping is None or ray.wait([ping], timeout=self.cfg.worker_deadline_s)[0]:
            return True
        log.warning("the evaluator that replaced a lost one did not start in %g s (no node "
                    "left to place it?); the run ends without its evaluation",
                    self.cfg.worker_deadline_s)  # fmt: skip
        self.p.drop_evaluator()
        return False

    def _replacement_started(self) -> bool:
        """Whether the last replacement answered its first call (True when there is none)."""
        ping = self.replacement_ping
        if ping is not None and ray.wait([ping], timeout=0)[0]:
            with suppress(RayActorError):
                ray.get(ping)
                self.replacement_ping = None
        return self.replacement_ping is None

    def _take(self, ref: Any, logger: Any, wall_s: float, replace: bool = True) -> None:
        """Record a call's result (blocks until it is done): rates, history, GIF, snapshot.
        A lost evaluator is replaced (``replace``) unless its own replacement never started."""
        try:
            self.stats.eval = ray.get(ref)
            if (gif := self.stats.eval.pop(VIDEO_KEY, None)) is not None:
                logger.gif("eval/video", gif, self.stats.env_steps)
            self.stats.eval_history.append(stats.eval_entry(self.stats, wall_s))
            if self.on_entry is not None:
                self.on_entry(self.stats.eval_history[-1])
            selector = self.p.selector
            if selector is not None and selector.better(self.stats.eval):
                weights, version = ray.get(self.weights_ref)
                try:
                    selector.keep(self.stats.eval, weights, version, self.stats.env_steps)
                except DiskWriteError as exc:  # the last good policy-best.pt is kept
                    self.failure = self.failure or exc
        except RayActorError:
            # The call fails too when its weights came from a learner that died (Ray restarts
            # it): then only this evaluation is lost. A dead evaluator is replaced.
            if self._evaluator_alive():
                log.warning("an evaluation was lost with its weights (learner restarted)")
                return
            self.stats.evaluator_failures += 1
            if not self._replacement_started():  # it cannot start: another would not either
                log.warning("the evaluator that replaced a lost one failed before it started; "
                            "evaluation stops")  # fmt: skip
                self.p.drop_evaluator()
            elif replace:
                # Its process or its node is gone. It held nothing a new one cannot rebuild
                # but its window of rates, which starts again; its count and seeds go on.
                played = int(self.stats.eval.get("eval_episodes", 0))
                self.p.replace_evaluator(self.stats.evaluator_failures, first_episode=played)
                self.replacement_ping = self.p.evaluator.ping.remote()
                log.warning("evaluator failed; replaced (%d so far)", self.stats.evaluator_failures)
            else:
                log.warning("evaluator failed at the run's end; its last rates stand")

    def _evaluator_alive(self) -> bool:
        try:
            ray.get(self.p.evaluator.ping.remote(), timeout=30)
            return True
        except (RayActorError, ray.exceptions.GetTimeoutError):
            return False
