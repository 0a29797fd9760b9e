"""A training as a Ray Tune trial: ``TrainingTrial`` runs the program ``robogym-ray train`` runs
(learner, rollout workers, evaluator, supervisor) inside the trial's placement group, whose
bundles ``trial_resources`` makes from the builder's table (``training/resources.py``).

Each evaluator window is one Tune result (success rate, return, env and learner steps/s, env
steps so far); with the sweep's ``report_every_steps``, so is every that many env steps between
windows (the counts, and the sweep's metric as the last window left it). A result after which
the learner has written a new checkpoint (every ``checkpoint_every`` learner steps) carries a
Tune checkpoint: a copy of ``learner.pt`` and the trial's counts so far. The run's own folder
- config, summary, TensorBoard, checkpoints and the replay snapshot as
``replay_snapshot_every_s`` says - is ``<sweep>/runs/<trial name>``.

A trial that Tune stops (an ASHA decision, the sweep interrupted) ends the way a stopped run
ends: final checkpoint and ``summary.json`` with ``ended: stopped``, ``stopped_by: scheduler``.
A trial restored from a checkpoint (``sweep --resume``, or a retry) continues its run folder
from the run's own newest checkpoint (``train --resume``), or from the Tune checkpoint's copy
when the folder has none; its env steps and wall time go on from the checkpoint's.

Why a class trainable and not a function one: Tune stops a function trainable by raising
``SystemExit`` in its thread at its next report and then removes the actor at once, so the run
could not write its final checkpoint and summary; a class trainable's ``cleanup`` may wait.
"""

from __future__ import annotations

import json
import queue
import shutil
import tempfile
import threading
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import ray
from ray import tune

from robogym_ray.envs.outcomes import WINDOW_KEYS
from robogym_ray.learner.checkpoint import CHECKPOINT_NAME, RUN_CHECKPOINT
from robogym_ray.storage import RunStorage
from robogym_ray.sweep.bundles import bundles, check_fit
from robogym_ray.sweep.config import SweepConfig
from robogym_ray.sweep.report import BETWEEN_WINDOWS
from robogym_ray.training.ending import COUNTS
from robogym_ray.training.program import learner_gpus
from robogym_ray.training.resources import ActorNeed, actor_needs
from robogym_ray.training.run import RunControl, run_training
from robogym_ray.training.settings import SECTIONS, TrainSetup, setup_of
from robogym_ray.training.setup import storage_root

STOPPED_BY = "scheduler"
"""``summary.json``'s ``stopped_by`` of a run that Tune stopped."""
STOP_WAIT_S = 600.0
"""How long a stopped trial waits for its run's final checkpoint and summary (Tune itself
kills a trial actor that has not stopped after ``TUNE_FORCE_TRIAL_CLEANUP_S``, 600 s)."""
TRIAL_RECORD = "trial.json"
"""A Tune checkpoint's record beside its copy of the learner's checkpoint: the trial's run
name and counts so far."""


def trial_setup(config: Mapping[str, Any]) -> TrainSetup:
    """A trial's training settings, from its config's ``train``, ``d4pg`` and ``emulation``.

    Two are the trial's own: no progress bar (trials share one console), and workers not
    placed with Ray's SPREAD (an explicit strategy would take them out of the trial's
    placement group; the group's own strategy places them)."""
    setup = setup_of({name: config.get(name, {}) for name in SECTIONS}, "trial config")
    return replace(setup, train=replace(setup.train, progress=False, spread_workers=False))


def trial_needs(setup: TrainSetup) -> tuple[ActorNeed, ...]:
    return actor_needs(setup.train, learner_gpus(setup.train))


def trial_resources(config: Mapping[str, Any]) -> Any:
    """The trial's ``PlacementGroupFactory``: bundle 0 its own (``sweep.trial_cpus``), then one
    per actor, under ``sweep.placement`` (Ray's PACK, SPREAD, ...).

    Use it with your own Tuner: ``tune.with_resources(TrainingTrial, trial_resources)``."""
    meta = config.get("sweep", {})
    own = {"CPU": float(meta.get("trial_cpus", SweepConfig.trial_cpus))}
    return tune.PlacementGroupFactory(
        bundles(trial_needs(trial_setup(config)), own), strategy=meta.get("placement", "PACK")
    )


class TrainingTrial(tune.Trainable):
    """One training per trial (module docstring); its config is a config file's sections
    (``train``, ``d4pg``, ``emulation``) and the sweep's own (``sweep``: ``runs``, the folder of
    the trials' run folders, default the train section's storage)."""

    def setup(self, config: dict[str, Any]) -> None:
        self.settings = trial_setup(config)
        group = ray.util.get_current_placement_group()
        # Bundle 0 is this actor's; the run's actors must fit the others (a ConfigError here
        # is the trial's one-line error, before any actor starts).
        check_fit(trial_needs(self.settings), group.bundle_specs[1:] if group else [])
        sweep = config.get("sweep", {})
        self.runs = sweep.get("runs") or storage_root(self.settings.train)
        self.metric = str(sweep.get("metric", ""))
        self.before = {"env_steps": 0, "episodes": 0, "wall_s": 0.0}
        self.part = 1  # the run's part (a restored trial continues its run: the next part)
        self.run_name: str | None = None
        self.copy: str | None = None  # a restored Tune checkpoint's learner.pt
        self.events: queue.Queue[tuple[str, Any]] = queue.Queue()
        self.control = RunControl(
            on_eval=lambda window: self.events.put(("window", window)),
            on_progress=lambda counts: self.events.put(("progress", counts)),
            progress_every=int(sweep.get("report_every_steps", 0)),
        )
        self.thread: threading.Thread | None = None
        self.last: dict[str, Any] = {}
        self.checkpointed = 0  # checkpoint_every marks passed at the last reported checkpoint

    # -- Tune's calls -------------------------------------------------------------------------
    def step(self) -> dict[str, Any]:
        if self.thread is None:
            self._start()
        while True:
            kind, data = self.events.get()
            if kind == "error":
                raise data
            if kind == "end":
                return self._final(data)
            if kind == "window":
                return self._window(data)
            if (result := self._progress(data)) is not None:
                return result

    def save_checkpoint(self, checkpoint_dir: str) -> None:
        folder = RunStorage(self.runs).child(self.run_name or self.trial_name)
        folder.download(RUN_CHECKPOINT, Path(checkpoint_dir) / CHECKPOINT_NAME)
        record = {
            "run_name": self.run_name,
            "parts": self.part,
            # The metric as the last window left it, for results between a restored part's
            # windows before its first one.
            **self._last_metric(),
            **{k: self.last.get(k, 0) for k in COUNTS},
        }
        (Path(checkpoint_dir) / TRIAL_RECORD).write_text(json.dumps(record))

    def load_checkpoint(self, checkpoint: str | dict | None) -> None:
        folder = Path(str(checkpoint))
        record = json.loads((folder / TRIAL_RECORD).read_text())
        counts = {k: record.get(k, 0) for k in COUNTS}  # no episodes in an older record
        self.before = {k: counts[k] for k in ("env_steps", "episodes", "wall_s")}
        self.part = int(record.get("parts", 1)) + 1
        # The run's summary counts its whole from these when the killed part wrote none.
        self.control.checkpointed = {**counts, "parts": self.part - 1}
        self.last = dict(record)
        self.run_name = record.get("run_name")
        every = self.settings.train.checkpoint_every
        self.checkpointed = int(record["learner_steps"]) // every if every else 0
        if (folder / CHECKPOINT_NAME).is_file():  # Tune may remove its download after this call
            keep = Path(tempfile.mkdtemp(prefix="trial-checkpoint-")) / CHECKPOINT_NAME
            shutil.copyfile(folder / CHECKPOINT_NAME, keep)
            self.copy = str(keep)

    def cleanup(self) -> None:
        if self.thread is not None and self.thread.is_alive():
            self.control.stop(STOPPED_BY)  # final checkpoint and summary, then the actor goes
            self.thread.join(timeout=STOP_WAIT_S)

    # -- the run ------------------------------------------------------------------------------
    def _start(self) -> None:
        cfg, root = self.settings.train, RunStorage(self.runs)
        name = self.run_name
        resume = bool(name) and root.child(name).exists(RUN_CHECKPOINT)
        if not resume:  # a new trial, or its folder lost its checkpoint: the Tune copy
            name = _free_name(root, self.trial_name if name is None else name)
        self.run_name = name
        left_wall = None if cfg.max_wall_s is None else cfg.max_wall_s - self.before["wall_s"]
        cfg = replace(
            cfg,
            storage=self.runs,
            run_name=name,
            resume=resume,
            init_from=None if resume else (self.copy or cfg.init_from),
            total_steps=None
            if cfg.total_steps is None
            else max(1, cfg.total_steps - self.before["env_steps"]),
            max_wall_s=None if left_wall is None else max(1.0, left_wall),
        )
        settings = self.settings

        def train() -> None:
            try:
                summary = run_training(cfg, settings.d4pg, settings.emulation, self.control)
                self.events.put(("end", summary))
            except BaseException as exc:  # noqa: BLE001 - raised again in step(), Tune's thread
                self.events.put(("error", exc))

        self.thread = threading.Thread(target=train, name=f"training-{name}", daemon=True)
        self.thread.start()

    def _window(self, window: Mapping[str, float]) -> dict[str, Any]:
        return self._report(self._counted(window, {
            "eval/success_rate": window["success_rate"],
            "eval/return": window["return"],
            "eval/snapshot_success_rate": window["snapshot_success_rate"],
            "eval/episodes": int(window["eval_episodes"]),
            # a task with command windows: its measure (m, rad), for --metric and the figure
            **{f"eval/{key}": window[key] for key in WINDOW_KEYS if key in window},
        }))  # fmt: skip

    def _progress(self, counts: Mapping[str, float]) -> dict[str, Any] | None:
        """A result between windows: the counts, and the sweep's metric as the last window
        left it (the figure skips it). None while it cannot carry the metric (an eval/* one
        before the first window): Tune refuses a result without it."""
        metrics = self._counted(counts, {**self._last_metric(), BETWEEN_WINDOWS: True})
        return self._report(metrics) if self.metric in metrics else None

    def _last_metric(self) -> dict[str, Any]:
        """The sweep's metric as the last result left it (empty when it had none)."""
        return {self.metric: self.last[self.metric]} if self.metric in self.last else {}

    def _counted(self, counts: Mapping[str, float], rest: Mapping[str, Any]) -> dict[str, Any]:
        """A result: the run's counts (this part's, on top of the parts before) and ``rest``."""
        return {
            **rest,  # first: a metric that is a count (learner_steps) is this result's
            "env_steps": self.before["env_steps"] + int(counts["env_steps"]),
            "wall_s": round(self.before["wall_s"] + counts["wall_s"], 2),
            "learner_steps": int(counts["learner_steps"]),
            "episodes": self.before["episodes"] + int(counts["episodes"]),
            "throughput/env_steps_per_s": round(counts["env_steps_per_s"], 2),
            "throughput/learner_steps_per_s": round(counts["learner_steps_per_s"], 2),
            "run": RunStorage(self.runs).child(self.run_name or "").location(),
        }

    def _report(self, metrics: dict[str, Any]) -> dict[str, Any]:
        """``metrics`` as the trial's last result, with a Tune checkpoint when the learner has
        written a new one since the result before."""
        every = self.settings.train.checkpoint_every
        marks = metrics["learner_steps"] // every if every else 0
        if marks > self.checkpointed:  # the learner has written a checkpoint since the last
            self.checkpointed = marks
            metrics["should_checkpoint"] = True
        self.last = metrics
        return metrics

    def _final(self, summary: Mapping[str, Any]) -> dict[str, Any]:
        metrics = {
            **{k: v for k, v in self.last.items() if k != BETWEEN_WINDOWS},
            "env_steps": self.before["env_steps"] + int(summary["env_steps"]),
            "wall_s": round(self.before["wall_s"] + float(summary["wall_s"]), 2),
            "learner_steps": int(summary["learner_steps"]),
            "episodes": self.before["episodes"] + int(summary["episodes"]),
            "ended": summary["ended"],
            "ended_by": summary.get("ended_by", ""),
            "checkpoint": summary.get("checkpoint") or "",
        }
        evals = ("eval/success_rate", "eval/return", "eval/episodes")
        for key in (*evals, *(f"eval/{k}" for k in WINDOW_KEYS)):
            if key in summary:
                metrics[key] = summary[key]
        self.last = metrics
        return {**metrics, "should_checkpoint": bool(summary.get("checkpoint")), "done": True}


def _free_name(root: RunStorage, name: str) -> str:
    """``name``, or ``name-2``, ``-3``... when a run that wrote no checkpoint holds it (a trial
    started again from nothing keeps the earlier attempt's files)."""
    free, n = name, 1
    while root.child(free).holds_run():
        n += 1
        free = f"{name}-{n}"
    return free
