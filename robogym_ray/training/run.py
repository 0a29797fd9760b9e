"""The distributed training program: rollout workers -> learner -> weights -> workers.

``run_training`` is the driver. It joins or starts Ray, starts the supervisor (robot servers),
the learner actor, the rollout-worker actors and the evaluator, then moves data between them:
each worker result (n-step transitions) goes to the learner, which trains at its
samples-per-insert ratio and publishes weights through the object store; workers pull those
weights every ``weight_sync_steps`` of their steps. Everything the user watches goes to
TensorBoard under ``logdir/run_name``.
"""

from __future__ import annotations

import json
import logging
import time
from collections import Counter, deque
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import ray
from ray.exceptions import RayActorError

from robogym_ray.distributed import remote
from robogym_ray.distributed.real_client import RealRobotClientFactory
from robogym_ray.envs.outcomes import rates
from robogym_ray.envs.registration import variant_id
from robogym_ray.errors import ConfigError
from robogym_ray.experience.evaluator import VIDEO_KEY
from robogym_ray.experience.rollout import RolloutResult, box_dims, make_gym_env
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.realrobot.safety import safety_for
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training import setup
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.presets import TaskPreset, d4pg_for, resolve_task
from robogym_ray.training.selection import SnapshotSelector
from robogym_ray.training.stats import RunStats, WorkerSlot

log = logging.getLogger(__name__)


class TrainingRun:
    """Owns the actors of one run; ``run()`` drives it to ``total_steps``."""

    def __init__(
        self,
        cfg: TrainConfig,
        d4pg: D4PGConfig,
        preset: TaskPreset,
        emulation: EmulationConfig | None = None,
    ) -> None:
        self.cfg, self.d4pg, self.preset = cfg, d4pg, preset
        self.emulation = emulation or EmulationConfig()
        self.run_dir = Path(cfg.logdir) / (
            cfg.run_name or f"{preset.env_id.split('/')[-1]}-{time.strftime('%Y%m%d-%H%M%S')}"
        )
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.stats = RunStats()
        setup.check_resources(cfg)
        self.supervision = setup.start_supervision(cfg, preset.env_id, self.run_dir.name)
        self.learner: Any = None
        self.evaluator: Any = None
        self.workers: list[Any] = []
        self.real_robots: list[Any] = []
        try:
            self._start_actors()
        except BaseException:
            # Ray would end these actors too once their handles are collected (ownership), but
            # only when garbage collection gets there; the one cleanup path stops them now.
            self.shutdown()
            raise

    def _start_actors(self) -> None:
        cfg, d4pg, preset = self.cfg, self.d4pg, self.preset
        probe = make_gym_env(preset.env_id, self._env_kwargs(0, probe=True))()
        self.obs_dim, self.act_dim = box_dims(probe)
        probe.close()
        if cfg.init_from:
            setup.seed_checkpoint(
                cfg.init_from, self.run_dir / "checkpoints", d4pg, self.obs_dim, self.act_dim
            )
        self.learner = remote.LearnerActor.options(
            num_cpus=cfg.learner_cpus,
            num_gpus=setup.learner_gpus(cfg),
            max_restarts=3,
            max_task_retries=0,
            name=f"learner-{self.run_dir.name}",
            namespace=remote.NAMESPACE,
        ).remote(
            d4pg,
            self.obs_dim,
            self.act_dim,
            seed=cfg.seed,
            checkpoint_dir=str(self.run_dir / "checkpoints"),
            checkpoint_every=cfg.checkpoint_every,
        )
        # A continued run starts at the checkpoint's step count; rates count this run's steps.
        self.first_learner_step = ray.get(self.learner.status.remote())["version"]
        self.workers = self._start_workers()
        if cfg.evaluator:
            kwargs = self._env_kwargs(10_000) | setup.evaluator_env_kwargs(cfg, preset.env_id)
            self.evaluator = remote.EvaluatorActor.options(num_cpus=cfg.evaluator_cpus).remote(
                make_gym_env(preset.env_id, kwargs),
                d4pg,
                seed=cfg.seed + 10_000,
                video_every_s=cfg.video_interval_s,
            )
        self.weights_ref = self.learner.get_weights.remote()
        self._weights_stale = False
        self._eval_weights_ref: Any = None
        self._next_eval_at = 0.0
        self.selector = (
            SnapshotSelector(self.run_dir / "checkpoints")
            if cfg.select_episodes and self.evaluator is not None
            else None
        )

    def _env_kwargs(self, index: int, probe: bool = False) -> dict[str, Any]:
        """Sim envs lease their servers from the supervisor (the probe env never resets); the
        first ``emulated_workers`` lease emulated robots."""
        if self.supervision is None or probe:
            return {}
        emulated = index < self.cfg.emulated_workers
        return {"provider": self.supervision.provider(self.emulation if emulated else None)}

    def config_record(self) -> dict[str, Any]:
        """What ``config.json`` holds: a config file ``--config`` reads back."""
        record = {"train": asdict(self.cfg), "d4pg": asdict(self.d4pg)}
        if self.cfg.emulated_workers:
            record["emulation"] = asdict(self.emulation)
        return record

    def restart_counts(self) -> dict[str, int]:
        return {} if self.supervision is None else self.supervision.restart_counts()

    def _start_workers(self) -> list[WorkerSlot]:
        cfg = self.cfg
        n = cfg.workers + len(cfg.real_robot)
        sigmas = setup.worker_sigmas(self.d4pg, cfg, n)
        slots = []
        for i in range(n):
            if i < cfg.workers:
                factory, kind = make_gym_env(self.preset.env_id, self._env_kwargs(i)), "sim"
            else:
                factory, kind = self._real_env(i - cfg.workers), "real"
            handle = remote.RolloutActor.options(num_cpus=cfg.worker_cpus).remote(
                factory,
                self.d4pg,
                index=i,
                sigma=sigmas[i],
                seed=cfg.seed + i,
                random_steps=cfg.random_steps,
                revisits=setup.revisits_for(cfg, i) if kind == "sim" else None,
            )
            slots.append(WorkerSlot(i, handle, kind))
        return slots

    def _real_env(self, k: int) -> Any:
        """A Rob-variant env that reaches the robot only through its real-robot actor."""
        address = self.cfg.real_robot[k]
        name = f"real-{self.run_dir.name}-{k}"
        env_id = variant_id(self.preset.env_id, "rob")
        self.real_robots.append(remote.start_real_robot(name, address, safety_for(env_id)))
        kwargs = {"rs_address": address, "client_factory": RealRobotClientFactory(name)}
        return make_gym_env(env_id, kwargs)

    # -- the loop ---------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        from robogym_ray.training.logger import RunLogger  # imports tensorboard lazily

        cfg = self.cfg
        logger = RunLogger(self.run_dir, total=cfg.total_steps, progress=cfg.progress)
        pending = {self._collect(slot): slot for slot in self.workers}
        learner_calls: deque[Any] = deque()
        self.started = start = time.perf_counter()
        eval_ref = self._start_eval()
        while pending:
            [ref], _ = ray.wait(list(pending), num_returns=1)
            slot = pending.pop(ref)
            try:
                result: RolloutResult = ray.get(ref)
            except RayActorError:
                self.stats.worker_failures += 1
                log.warning("rollout worker %d died; it is not replaced", slot.index)
                continue
            self._record(result, logger)
            if result.batch is not None:
                learner_calls.append(self.learner.add.remote(result.batch))
            self._drain_learner(learner_calls, block=len(learner_calls) > 2)
            self._maybe_sync(slot, result.steps)
            in_flight = len(pending) * cfg.steps_per_call
            out_of_time = (
                cfg.max_wall_s is not None and time.perf_counter() - start > cfg.max_wall_s
            )
            if self.stats.env_steps + in_flight < cfg.total_steps and not out_of_time:
                pending[self._collect(slot)] = slot
            eval_ref = self._poll_eval(eval_ref, logger)
            if logger.due(cfg.log_every_s):  # scalars cost a supervisor round trip
                logger.write(self._scalars(start), self.stats.env_steps)
        self._drain_learner(learner_calls, block=True, all_=True)
        summary = self._finish(start, logger)
        return summary

    def _collect(self, slot: WorkerSlot) -> Any:
        scale = setup.noise_scale(self.cfg, self.stats.env_steps)
        return slot.handle.collect.remote(self.cfg.steps_per_call, scale)

    def _record(self, result: RolloutResult, logger: Any) -> None:
        s = self.stats
        s.env_steps += result.steps
        s.dropped_steps += result.dropped
        s.robot_errors += result.robot_errors
        s.worker_steps[result.worker] = s.worker_steps.get(result.worker, 0) + result.steps
        for ep in result.episodes:
            s.episodes += 1
            if ep.revisit:  # harder than the task's own starts: kept out of train/ rates
                s.revisits += 1
                s.revisit_statuses.append(ep.final_status)
                continue
            s.statuses.append(ep.final_status)
            s.returns.append(ep.ret)
            logger.scalar("episode/return", ep.ret, s.env_steps)
            logger.scalar("episode/length", ep.length, s.env_steps)
        logger.advance(result.steps)

    def _drain_learner(self, calls: deque[Any], block: bool, all_: bool = False) -> None:
        while calls and (block or ray.wait([calls[0]], timeout=0)[0]):
            ref = calls.popleft()
            try:
                metrics = ray.get(ref)
            except RayActorError:
                # The learner died mid-call; Ray restarts it from its checkpoint. This batch
                # is lost (counted), the next ones go to the restarted learner.
                self.stats.learner_failures += 1
                log.warning("learner actor failed; Ray restarts it from its last checkpoint")
                continue
            self.stats.learner.update(metrics)
            if metrics.get("steps_this_call", 0) > 0:
                self._weights_stale = True
            if not all_:
                block = False

    def _maybe_sync(self, slot: WorkerSlot, steps: int) -> None:
        slot.steps_since_sync += steps
        if slot.steps_since_sync >= self.cfg.weight_sync_steps or slot.weights_version < 0:
            if self._weights_stale:  # fetched only when a worker is due, not per learner call
                self.weights_ref = self.learner.get_weights.remote()
                self._weights_stale = False
            slot.handle.set_weights.remote(self.weights_ref)
            slot.steps_since_sync = 0
            slot.weights_version = int(self.stats.learner.get("learner_steps", 0))

    def _start_eval(self) -> Any:
        if self.evaluator is None:
            return None
        # Its own fetch: with policy averaging the evaluator scores the average, not the
        # online weights the workers act with.
        self._eval_weights_ref = self.learner.get_eval_weights.remote()  # a selector may keep it
        self._next_eval_at = time.perf_counter() + self.cfg.eval_interval_s
        if self.selector is not None:
            # The same episodes for every snapshot: seeds the workers and `evaluate` never use.
            n, base = self.cfg.select_episodes, self.cfg.seed + 20_000
            return self.evaluator.evaluate.remote(self._eval_weights_ref, n, base)
        return self.evaluator.evaluate.remote(self._eval_weights_ref)

    def _poll_eval(self, ref: Any, logger: Any) -> Any:
        if ref is None:  # between two calls (eval_interval_s), or the evaluator is gone
            due = self.evaluator is not None and time.perf_counter() >= self._next_eval_at
            return self._start_eval() if due else None
        if not ray.wait([ref], timeout=0)[0]:
            return ref
        try:
            self.stats.eval = ray.get(ref)
            if (gif := self.stats.eval.pop(VIDEO_KEY, None)) is not None:
                logger.gif("eval/video", gif, self.stats.env_steps)
            self.stats.eval_history.append(
                {
                    "wall_s": round(time.perf_counter() - self.started, 2),
                    "env_steps": self.stats.env_steps,
                    "learner_steps": int(self.stats.learner.get("learner_steps", 0)),
                    "return": round(self.stats.eval["eval_return"], 2),
                    "success_rate": self.stats.eval["eval_success_rate"],
                    "snapshot_success_rate": self.stats.eval["eval_snapshot_success_rate"],
                }
            )
            if self.selector is not None and self.selector.better(self.stats.eval):
                weights, version = ray.get(self._eval_weights_ref)
                self.selector.keep(self.stats.eval, weights, version, self.stats.env_steps)
        except RayActorError:
            log.warning("evaluator failed; evaluation stops")
            self.evaluator = None
            return None
        return self._poll_eval(None, logger)

    def _scalars(self, start: float) -> dict[str, float]:
        s, wall = self.stats, max(1e-9, time.perf_counter() - start)
        learner_steps = s.learner.get("learner_steps", 0.0)
        # No rate before the first finished episode: a 0 there would read as "never succeeds".
        statuses = list(s.statuses)
        out = {f"train/{k}": v for k, v in rates(statuses).items()} if statuses else {}
        out.update({f"eval/{k.removeprefix('eval_')}": v for k, v in s.eval.items()})
        if s.revisit_statuses:
            out["explore/revisit_success_rate"] = rates(s.revisit_statuses)["success_rate"]
        if self.selector is not None and self.selector.best is not None:
            out["eval/best_snapshot_success_rate"] = self.selector.best[0]
        out.update(
            {
                "train/return_last100": float(np.mean(s.returns)) if s.returns else 0.0,
                "throughput/env_steps_per_s": s.env_steps / wall,
                "throughput/learner_steps_per_s": (
                    max(0.0, learner_steps - self.first_learner_step) / wall
                ),
                "replay/size": s.learner.get("replay_size", 0.0),
                "replay/mean_priority": s.learner.get("mean_priority", 0.0),
                "loss/critic": s.learner.get("critic_loss", 0.0),
                "loss/policy": s.learner.get("policy_loss", 0.0),
                "learner/mean_q": s.learner.get("mean_q", 0.0),
                "learner/lr_scale": s.learner.get("lr_scale", 1.0),
                "explore/noise_scale": setup.noise_scale(self.cfg, s.env_steps),
                "explore/revisit_fraction": s.revisits / max(1, s.episodes),
                "learner/steps": learner_steps,
                "weights/lag": learner_steps - min(w.weights_version for w in self.workers),
                "faults/dropped_steps": float(s.dropped_steps),
                "faults/learner_failures": float(s.learner_failures),
                "faults/worker_failures": float(s.worker_failures),
                "faults/robot_errors": float(s.robot_errors),
            }
        )
        for cause, count in self.restart_counts().items():
            out[f"restarts/{cause}"] = float(count)
        return out

    def _finish(self, start: float, logger: Any) -> dict[str, Any]:
        checkpoint = ray.get(self.learner.checkpoint.remote(self.cfg.save_replay))
        learner_status = ray.get(self.learner.status.remote())
        wall = time.perf_counter() - start
        scalars = self._scalars(start)
        logger.write(scalars, self.stats.env_steps)
        logger.close()
        summary = {
            "task": self.preset.env_id,
            "env_steps": self.stats.env_steps,
            "episodes": self.stats.episodes,
            "wall_s": round(wall, 2),
            "learner_steps": int(scalars["learner/steps"]),
            "checkpoint": checkpoint,
            "restarts": self.restart_counts(),
            "learner_restored_from_step": learner_status["restored_from_step"],
            "dropped_steps": self.stats.dropped_steps,
            "worker_steps": {str(k): v for k, v in sorted(self.stats.worker_steps.items())},
            "robot_errors": self.stats.robot_errors,
            "eval_history": self.stats.eval_history,
            "best_snapshot": None if self.selector is None else self.selector.summary(),
            "server_nodes": [] if self.supervision is None else self.supervision.server_nodes(),
            "final_status_counts": dict(Counter(self.stats.statuses)),
            "revisited_episodes": self.stats.revisits,
            "logdir": str(self.run_dir),
            **{k: round(v, 4) for k, v in scalars.items()},
        }
        (self.run_dir / "summary.json").write_text(json.dumps(summary, indent=2))
        return summary

    def shutdown(self) -> None:
        for slot in self.workers:
            ray.kill(slot.handle)
        for actor in (self.evaluator, self.learner, *self.real_robots):
            if actor is not None:
                ray.kill(actor)
        if self.supervision is not None:
            self.supervision.stop()


def run_training(
    cfg: TrainConfig,
    d4pg_overrides: Mapping[str, Any] | None = None,
    emulation: EmulationConfig | None = None,
) -> dict:
    """Run one training to completion; returns the summary (also in ``run_dir/summary.json``).

    ``emulation`` is what the ``cfg.emulated_workers`` workers' robots differ by (default
    ``EmulationConfig()``, the emulated robot ``robogym-ray serve --emulate-hardware`` serves).
    """
    preset = resolve_task(cfg.task)
    d4pg = d4pg_for(preset, d4pg_overrides)
    if cfg.emulated_workers and not preset.env_id.startswith("RoboGymRay/"):
        raise ConfigError(f"--emulated-workers needs a robot task; {preset.env_id} has none")
    started_ray = setup.ensure_ray(cfg)
    try:
        run = TrainingRun(cfg, d4pg, preset, emulation)
    except BaseException:
        if started_ray:
            ray.shutdown()
        raise
    try:
        (run.run_dir / "config.json").write_text(json.dumps(run.config_record(), indent=2))
        return run.run()
    finally:
        run.shutdown()
        if started_ray:
            ray.shutdown()
