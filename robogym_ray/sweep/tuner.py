"""Running a checked ``SweepPlan`` on Ray Tune: each trial a ``TrainingTrial`` in a placement
group of its own, ASHA when asked, the experiment's state and every trial's files in the
sweep's folder, so ``--resume`` can continue it after its driver died."""

from __future__ import annotations

import json
import logging
import os
from typing import Any

import ray
from ray import tune

from robogym_ray.errors import ConfigError
from robogym_ray.sweep.plan import (
    FINISHED,
    SWEEP_RECORD,
    SweepPlan,
    asha_grace,
    check_trial_cpus,
    read_record,
)
from robogym_ray.sweep.trial import TrainingTrial, trial_needs, trial_resources
from robogym_ray.training.resources import describe
from robogym_ray.training.setup import ensure_ray

log = logging.getLogger(__name__)

KEEP_CHECKPOINTS = 2
"""Tune checkpoints kept per trial (each a copy of the learner's, a few MB)."""


def run_sweep(plan: SweepPlan, argv: list[str]) -> Any:
    """Start or continue the sweep; returns Tune's ``ResultGrid`` when every trial has ended
    (or the sweep was interrupted: Ctrl-C stops the trials as a stopped run ends)."""
    cfg = plan.cfg
    # Tune warns each time trials checkpoint faster than it snapshots the experiment; a
    # trial's checkpoint every few seconds is this program's way (a learner.pt copy, MBs).
    os.environ.setdefault("TUNE_WARN_EXCESSIVE_EXPERIMENT_CHECKPOINT_SYNC_THRESHOLD_S", "0")
    started = ensure_ray(cfg.address, cfg.num_cpus)
    try:
        trainable = tune.with_resources(TrainingTrial, trial_resources)
        if cfg.resume:
            tuner = tune.Tuner.restore(
                plan.folder.location(), trainable, resume_unfinished=True, resume_errored=True
            )
        else:
            check_cluster(plan)
            plan.folder.write_bytes(SWEEP_RECORD, plan.record(argv), "sweep record")
            tuner = tune.Tuner(
                trainable,
                param_space=plan.param_space(),
                tune_config=tune_config(plan),
                run_config=run_config(plan),
            )
        grid = tuner.fit()
        note_finished(plan, grid)
        return grid
    finally:
        if started:
            ray.shutdown()


def note_finished(plan: SweepPlan, grid: Any) -> None:
    """Mark the sweep's record finished when every trial it plans has ended without an error
    (completed, or stopped by ASHA): ``--resume`` then has nothing to do and says so. An
    interrupted sweep (Ctrl-C) has trials that are not terminated, or not yet made."""
    record = read_record(plan.folder)
    if grid.num_terminated == len(grid) == record.get("trials"):
        marked = json.dumps({**record, FINISHED: True}, indent=2).encode()
        plan.folder.write_bytes(SWEEP_RECORD, marked, "sweep record")


def check_cluster(plan: SweepPlan) -> None:
    """Every trial's bundles fit the cluster Ray has now (a joined one: the local check ran
    before Ray started), and a GPU learner has a GPU to fit: a trial that can never be placed
    would wait forever."""
    total = ray.cluster_resources()
    for setup in plan.checked:
        check_trial_cpus(setup, plan.cfg, float(total.get("CPU", 0.0)))
        needs = trial_needs(setup)
        gpus = sum(n.gpus * n.count for n in needs)
        if gpus > total.get("GPU", 0.0) + 1e-9:
            raise ConfigError(
                f"a trial needs {describe(needs)} but the cluster has "
                f"{total.get('GPU', 0.0):g} GPUs"
            )


def tune_config(plan: SweepPlan) -> tune.TuneConfig:
    cfg, scheduler = plan.cfg, None
    if cfg.scheduler == "asha":
        from ray.tune.schedulers import ASHAScheduler

        scheduler = ASHAScheduler(
            time_attr=cfg.time_attr,
            metric=cfg.metric,
            mode=cfg.mode,
            # Trials end themselves at their budget; a result at max_t would be stopped, and a
            # run's last window (its final evaluation) can be at or past its budget.
            max_t=2 * max(plan.budget(), asha_grace(plan)),
            grace_period=asha_grace(plan),
            reduction_factor=cfg.reduction_factor,
        )
    return tune.TuneConfig(
        num_samples=cfg.samples,
        scheduler=scheduler,
        max_concurrent_trials=cfg.max_concurrent or None,
    )


def run_config(plan: SweepPlan) -> tune.RunConfig:
    return tune.RunConfig(
        name=plan.name,
        storage_path=plan.root,
        checkpoint_config=tune.CheckpointConfig(num_to_keep=KEEP_CHECKPOINTS),
        verbose=1,
    )
