"""The training loop, read top to bottom: worker results -> learner, weights -> workers,
weights -> evaluator, counters -> TensorBoard, until ``total_steps``.

Each arrow is one call: ``RolloutWorker.collect`` (K envs stepped together; the worker sends its
batch of n-step transitions to ``LearnerService.add`` itself, worker -> learner through Ray's
object store, and the driver gets counters plus the reference of the learner's answer) ->
``LearnerService.add`` (insert, then the learner steps it pays for) ->
``get_weights`` -> ``RolloutWorker.set_weights`` every ``weight_sync_steps`` of a worker's
steps; ``get_eval_weights`` -> ``Evaluator.evaluate`` every ``eval_interval_s``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from contextlib import suppress
from typing import Any

import ray
from ray.exceptions import (
    GetTimeoutError,
    OwnerDiedError,
    RayActorError,
    RayError,
    RayTaskError,
)

from robogym_ray.errors import LearnerLostError, RunStoppedError
from robogym_ray.experience.rollout import RolloutResult
from robogym_ray.supervision.restart_policy import FaultCause
from robogym_ray.training import setup, stats
from robogym_ray.training.evals import EvalSchedule
from robogym_ray.training.finish import disk_error, finish
from robogym_ray.training.learner_deaths import LearnerDeaths
from robogym_ray.training.program import Program
from robogym_ray.training.stats import RunStats, WorkerSlot

log = logging.getLogger(__name__)


class TrainingLoop:
    """Drives a built ``Program`` to ``cfg.total_steps``; ``run()`` returns the summary.

    ``on_eval``: called (in the loop's thread: it must not block) with each evaluator window's
    figures, those of ``eval_history``, the training episodes and the rates so far (a Tune
    trial's report). ``progress``: (N, call): ``call`` gets the counts and rates every N env
    steps, between windows. ``checkpointed``: the earlier parts' counts as the caller's
    checkpoint recorded them, for ``whole_run`` when the earlier part wrote no summary."""

    def __init__(
        self,
        program: Program,
        on_eval: Callable[[dict[str, float]], None] | None = None,
        checkpointed: Mapping[str, Any] | None = None,
        progress: tuple[int, Callable[[dict[str, float]], None]] | None = None,
    ) -> None:
        self.p, self.cfg = program, program.cfg
        self.stats = RunStats()
        self.weights_ref = program.learner.get_weights.remote()
        self.learner_deaths = LearnerDeaths(program.learner)
        self.weights_stale = False
        self.on_eval, self.progress, self._progress_mark = on_eval, progress, 0
        self.checkpointed = checkpointed
        self.evals = EvalSchedule(program, self.stats, on_entry=self._eval_window)
        self.stop = threading.Event()
        """Set (e.g. by a SIGINT/SIGTERM handler) to end the run early, with checkpoint and
        summary."""
        self.stopped_by: str | None = None
        """What asked for that stop (``SIGINT``, ``SIGTERM``), for the summary."""
        self.failure: RunStoppedError | None = None
        """What ends the run without retrying: a file it could not write (a full disk), a
        learner restarted with nothing to restore."""
        self._lost_status: dict[str, Any] = {}
        """The status of a learner restarted with nothing to restore (killed since)."""
        self._replies: list[Any] = []
        """Calls whose answers are not needed but whose errors must be taken (``set_weights``
        after a learner death fails): Ray prints an "Unhandled error" for any it drops."""
        self._real_deadline: float | None = None

    def run(self) -> dict[str, Any]:
        from robogym_ray.training.logger import RunLogger  # imports tensorboard lazily

        cfg, p = self.cfg, self.p
        uploads = None if p.storage.is_local else p.storage  # events staged in run_dir
        logger = RunLogger(p.run_dir, total=cfg.total_steps, progress=cfg.progress,
                           stop=self.stop, storage=uploads, max_wall_s=cfg.max_wall_s)  # fmt: skip
        pending = {self._collect(slot): slot for slot in p.workers}
        learner_calls: deque[Any] = deque()
        self.started = time.perf_counter()
        eval_ref = self.evals.start()
        while pending:
            ready = self._wait(pending)
            if not ready:  # only real-robot calls left, past real_robot_wait_s: paused robots
                self.stats.abandoned_real_calls += len(pending)
                log.warning("%d real-robot call(s) did not return; abandoned", len(pending))
                break
            slot = pending.pop(ready[0])
            try:
                result: RolloutResult = ray.get(ready[0])
            except RayActorError:
                self.stats.worker_failures += 1
                slot.alive = not self._done() and p.replace_worker(slot)
                self.stats.worker_replacements += slot.alive
                log.warning("rollout worker %d died; %s", slot.index,
                            "replaced" if slot.alive else "not replaced")  # fmt: skip
                if slot.alive:
                    pending[self._collect(slot)] = slot
                continue
            supervised = p.supervision is not None and slot.kind == "sim"
            for ep in stats.record(self.stats, result, supervised, slot.kind):
                logger.scalar("episode/return", ep.ret, self.stats.env_steps)
                logger.scalar("episode/length", ep.length, self.stats.env_steps)
            logger.advance(result.steps)
            self._report_progress()
            self.stats.transitions_sent += result.transitions
            self.stats.relabelled_transitions += result.relabelled
            if result.learner_call is not None:  # the worker sent its batch to the learner
                learner_calls.append(result.learner_call)
            elif result.batch is not None:
                learner_calls.append(p.learner.add.remote(result.batch))
            self._drain_learner(learner_calls, block=len(learner_calls) > 2)
            self._maybe_sync(slot, result.steps)
            # Real robots' calls are not counted in flight: a paused one may never return.
            in_flight = sum(s.kind == "sim" for s in pending.values()) * cfg.steps_per_call
            if not self._done(in_flight):
                pending[self._collect(slot)] = slot
            self._take_replies()
            eval_ref = self.evals.poll(eval_ref, logger, self._wall())
            self.evals.snapshot(self._wall())
            self._check_disk(logger)
            if logger.due(cfg.log_every_s):  # scalars cost a supervisor round trip
                logger.write(self._scalars(), self.stats.env_steps)
        out_of_time = self._out_of_time()  # why collection ended, for the summary
        self._drain_learner(learner_calls, block=True, all_=True)
        self._take_replies(wait_s=30.0)
        if isinstance(self.failure, LearnerLostError):  # nothing of the run's to snapshot
            return finish(self.p, self.stats, logger, self._scalars, self._wall, self.failure,
                          learner_status=self._lost_status,
                          checkpointed=self.checkpointed)  # fmt: skip
        self.evals.snapshot(self._wall(), final=True)  # the mark the run ended on
        if not self._check_disk(logger):  # a full disk's run reports that, not a policy
            self.evals.final(eval_ref, logger, self._wall())  # the final policy, evaluated
            self._check_disk(logger)
        return finish(self.p, self.stats, logger, self._scalars, self._wall, self.failure,
                      stopped_by=self.stopped_by, out_of_time=out_of_time,
                      checkpointed=self.checkpointed)  # fmt: skip

    def request_stop(self, by: str) -> None:
        """End the run early, from any thread, the way a signal does (final checkpoint and
        summary, ``ended`` stopped, ``stopped_by`` ``by``); the first asker is the one named."""
        if self.stopped_by is None:
            self.stopped_by = by
        self.stop.set()

    def _eval_window(self, entry: dict[str, float]) -> None:
        if self.on_eval is not None:
            eval_episodes = self.stats.eval.get("eval_episodes", 0.0)
            self.on_eval(self._rates({**entry, "eval_episodes": eval_episodes}))

    def _report_progress(self) -> None:
        if self.progress is None:
            return
        every, call = self.progress
        if self.stats.env_steps // every > self._progress_mark:
            self._progress_mark = self.stats.env_steps // every
            call(self._rates({"wall_s": round(self._wall(), 2), "env_steps": self.stats.env_steps,
                              "learner_steps": self._trained()}))  # fmt: skip

    def _trained(self) -> int:
        """The learner's step as last reported; a resumed run's learner starts from its
        checkpoint's step, not 0, before it has answered."""
        return max(int(self.stats.learner.get("learner_steps", 0)), self.p.first_learner_step)

    def _rates(self, counts: dict[str, float]) -> dict[str, float]:
        """``counts`` (wall_s, env and learner steps) with the episodes and the rates so far."""
        wall = max(counts["wall_s"], 1e-9)
        learned = max(0, counts["learner_steps"] - self.p.first_learner_step)
        return {**counts, "episodes": self.stats.episodes,
                "env_steps_per_s": counts["env_steps"] / wall,
                "learner_steps_per_s": learned / wall}  # fmt: skip

    def _take_replies(self, wait_s: float = 0.0) -> None:
        """Take the answers (and errors) of the calls in ``_replies`` that have finished
        (waiting up to ``wait_s`` for the rest)."""
        if not self._replies:
            return
        done, self._replies = ray.wait(self._replies, num_returns=len(self._replies),
                                       timeout=wait_s)  # fmt: skip
        for ref in done:
            with suppress(RayError):  # a worker or the learner that died: counted where seen
                ray.get(ref)

    def _check_disk(self, logger: Any) -> bool:
        """Whether a file could not be written (a full disk): a checkpoint, TensorBoard's
        events or the best policy. The first such failure stops the run; finish() reports it."""
        self.failure = self.failure or logger.error or self.evals.failure
        if self.failure is not None:
            self.stop.set()
        return self.failure is not None

    def _done(self, in_flight: int = 0) -> bool:
        """Whether collecting should stop: enough steps (counting those in flight; a run with
        no step cap has none), the wall budget spent, or a stop asked for (SIGTERM)."""
        total = self.cfg.total_steps
        return (
            self.stop.is_set()
            or self._out_of_time()
            or (total is not None and self.stats.env_steps + in_flight >= total)
        )

    def _out_of_time(self) -> bool:
        """Whether the run's wall budget (``max_wall_s``) is spent."""
        return self.cfg.max_wall_s is not None and self._wall() > self.cfg.max_wall_s

    def _wait(self, pending: dict[Any, WorkerSlot]) -> list[Any]:
        """The next finished call; once collecting is done and only real-robot calls remain,
        waits for them at most ``real_robot_wait_s`` (empty list: they did not return)."""
        if not (self._done() and all(s.kind == "real" for s in pending.values())):
            return self._wait_watched(pending)
        if self._real_deadline is None:
            self._real_deadline = time.perf_counter() + self.cfg.real_robot_wait_s
        left = max(0.0, self._real_deadline - time.perf_counter())
        return ray.wait(list(pending), num_returns=1, timeout=left)[0]

    def _wait_watched(self, pending: dict[Any, WorkerSlot]) -> list[Any]:
        """The next finished call. A simulated worker's call older than ``worker_deadline_s``
        is stuck (a simulation hung in a physics step cannot be cut off from inside): its
        worker is killed, so its call fails and the worker is replaced like a dead one."""
        deadline = self.cfg.worker_deadline_s
        while True:
            now = time.perf_counter()
            sims = [s for s in pending.values() if s.kind == "sim" and s.call_started < now]
            left = min((s.call_started + deadline - now for s in sims), default=None)
            ready = ray.wait(list(pending), num_returns=1,
                             timeout=None if left is None else max(left, 0.0))[0]  # fmt: skip
            if ready:
                return ready
            for slot in sims:
                if now - slot.call_started >= deadline:
                    log.warning("rollout worker %d: no answer in %g s; killed as hung",
                                slot.index, deadline)  # fmt: skip
                    self.stats.restarts[FaultCause.HUNG.value] += 1
                    slot.call_started = float("inf")  # killed once; its call fails next
                    ray.kill(slot.handle)

    def _wall(self) -> float:
        return time.perf_counter() - self.started

    def _collect(self, slot: WorkerSlot) -> Any:
        scale = setup.noise_scale(self.cfg, self.stats.env_steps)
        slot.call_started = time.perf_counter()
        return slot.handle.collect.remote(self.cfg.steps_per_call, scale)

    def _drain_learner(self, calls: deque[Any], block: bool, all_: bool = False) -> None:
        while calls and (block or ray.wait([calls[0]], timeout=0)[0]):
            ref = calls.popleft()
            try:
                metrics = ray.get(ref)
            except (RayActorError, OwnerDiedError):  # learner died, or the worker that sent it
                # This batch is lost (lost_transitions counts it); the next ones go to the
                # learner Ray restarted from its checkpoint. One death, one failure.
                if isinstance(self.failure, LearnerLostError):
                    continue  # the learner was killed on purpose: not another death
                failed_at = self._wall()
                if self.learner_deaths.call_failed():
                    self.stats.learner_failures = self.learner_deaths.count
                    log.warning("learner actor failed; Ray restarts it from its last checkpoint")
                    self._learner_restarted(failed_at)
                continue
            except RayTaskError as exc:
                # A checkpoint the learner could not write (a full disk): the next would fail
                # the same way, so the run stops; finish() reports it.
                failure = disk_error(exc)
                if failure is None:
                    raise
                self.failure = self.failure or failure
                self.stop.set()
                continue
            if "pid" in metrics:
                if self.learner_deaths.answered(int(metrics.pop("pid"))):
                    self._learner_restarted()
                self.stats.learner_failures = self.learner_deaths.count
            self.stats.learner.update(metrics)
            if metrics.get("steps_this_call", 0) > 0:
                self.weights_stale = True
            if not all_:
                block = False

    def _learner_restarted(self, failed_at: float | None = None) -> None:
        """After a learner death: the new process's weights from now on, and what it restored
        (``stats.learner_restarts``: when a call first failed, when the new one answered, where
        and from what). One that restored no checkpoint although the old one had trained ends
        the run (``LearnerLostError``): training on from scratch would pass for the same run."""
        self._replies.append(self.weights_ref)  # the dead process's, maybe never produced
        self.weights_stale = True
        if self.failure is not None:
            return
        try:
            status = ray.get(self.p.learner.status.remote(), timeout=120)
        except (RayActorError, GetTimeoutError):  # dead for good: its calls keep failing
            return
        trained = self._trained()
        self.stats.learner_restarts.append({
            "failed_at_wall_s": None if failed_at is None else round(failed_at, 2),
            "answered_at_wall_s": round(self._wall(), 2), "node": status["node"],
            "restored_from_step": status["restored_from_step"],
            "restored_replay": status["restored_replay"], "steps_before": trained,
        })  # fmt: skip
        if status["restored_from_step"] >= 0:
            log.warning(
                "learner restarted on %s from its checkpoint at step %d (%d transitions)",
                status["node"], status["restored_from_step"], status["restored_replay"],
            )  # fmt: skip
            return
        if trained <= 0:
            log.warning("learner restarted on %s before its first step: nothing learned is lost",
                        status["node"])  # fmt: skip
            return
        self._lost_status = {**status, "total_added": self.p.first_total_added}
        self.failure = LearnerLostError(
            f"the learner restarted on {status['node']} and found no checkpoint in "
            f"{self.p.storage.location('checkpoints')}: the {trained:,} learner steps it had "
            "taken and its replay are lost, so the run stopped instead of training on from "
            "scratch (a checkpoint is written every --checkpoint-every learner steps to "
            "--storage, which every node must reach)"
        )
        ray.kill(self.p.learner, no_restart=True)  # no checkpoint of fresh networks, ever
        self.stop.set()

    def _maybe_sync(self, slot: WorkerSlot, steps: int) -> None:
        slot.steps_since_sync += steps
        if slot.steps_since_sync >= self.cfg.weight_sync_steps or slot.weights_version < 0:
            if self.weights_stale:  # fetched only when a worker is due, not per learner call
                self.weights_ref = self.p.learner.get_weights.remote()
                self.weights_stale = False
            self._replies.append(slot.handle.set_weights.remote(self.weights_ref))
            slot.steps_since_sync = 0
            slot.weights_version = int(self.stats.learner.get("learner_steps", 0))

    def _scalars(self) -> dict[str, float]:
        best = self.p.selector.best if self.p.selector is not None else None
        return stats.scalars(
            self.stats,
            wall_s=self._wall(),
            first_learner_step=self.p.first_learner_step,
            noise_scale=setup.noise_scale(self.cfg, self.stats.env_steps),
            weights_versions=[w.weights_version for w in self.p.workers if w.alive],
            restarts=stats.all_restarts(self.stats, self.p.restart_counts()),
            best_snapshot_rate=None if best is None else best[0],
        )
