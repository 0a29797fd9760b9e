"""A sweep's plan, made and checked before Ray starts: where it goes, its base, its search
space, and every trial it can run checked as ``train`` checks its input (the task, the D4PG
settings, the storage, a local Ray's CPUs); a bad space is refused in one line.

``training.setup`` (the checks) is imported where it is used: it imports Ray, which
``sweep summary`` (``report.py``, reading this module's names) does without."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from robogym_ray.config import merge_config, quote
from robogym_ray.errors import ConfigError
from robogym_ray.storage import RunStorage
from robogym_ray.sweep.config import SweepConfig
from robogym_ray.sweep.space import (
    Axis,
    corner_points,
    param_space,
    parse_set,
    parse_space,
    with_values,
)
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.settings import TrainSetup, read_sections, setup_of

STATE = "tuner.pkl"
"""The file Tune's experiment folder holds once a sweep has started (``Tuner.can_restore``)."""
SWEEP_RECORD = "sweep.json"
"""The sweep's own record beside Tune's files: its space, metric and command, and whether it
finished (``FINISHED``)."""
FINISHED = "finished"
"""The record's mark of a sweep whose every trial ended (completed, or stopped by ASHA)."""
CPU_HINT = "lower train.workers or the actors' CPUs (train.worker_cpus, ...)"
"""What a sweep's user may lower when a trial needs more CPUs than the cluster has."""


@dataclass(frozen=True)
class SweepPlan:
    cfg: SweepConfig
    root: str
    """Where the sweep's folder is (``--storage``), as every node sees it."""
    name: str
    base: dict[str, dict[str, Any]]
    axes: tuple[Axis, ...] = ()
    checked: tuple[TrainSetup, ...] = ()
    """The corner trials (``space.corner_points``), each checked."""
    finished: bool = False
    """A ``--resume``'d sweep whose every trial had ended (its record says so): nothing to do."""

    @property
    def folder(self) -> RunStorage:
        return RunStorage(self.root).child(self.name)

    @property
    def runs(self) -> str:
        """The trials' run folders' root."""
        return self.folder.location("runs")

    def param_space(self) -> dict[str, Any]:
        meta = {
            "runs": self.runs,
            "trial_cpus": self.cfg.trial_cpus,
            "placement": self.cfg.placement,
            "metric": self.cfg.metric,
            "report_every_steps": self.cfg.report_every_steps,
        }
        return param_space(self.base, self.axes, meta)

    def budget(self) -> float:
        """The longest trial's total ``--time-attr``: ASHA's ``max_t``."""
        if self.cfg.time_attr == "env_steps":
            return float(max(s.train.total_steps or 0 for s in self.checked))
        return float(max(s.train.max_wall_s or 0.0 for s in self.checked))

    def trial_count(self) -> int:
        """Trials the sweep runs: every grid combination (seeds included), ``samples`` times."""
        return self.cfg.samples * math.prod(len(a.values) for a in self.axes if a.kind == "grid")

    def record(self, argv: list[str]) -> bytes:
        cfg = self.cfg
        return json.dumps(
            {
                "name": self.name,
                "searched": [a.key for a in self.axes],
                "space": [a.spec for a in self.axes],
                "trials": self.trial_count(),
                "metric": cfg.metric,
                "mode": cfg.mode,
                "scheduler": cfg.scheduler,
                "time_attr": cfg.time_attr,
                "command": ["robogym-ray", "sweep", *argv],
            },
            indent=2,
        ).encode()


def plan_sweep(cfg: SweepConfig) -> SweepPlan:
    """The checked plan of ``cfg`` (``resume_plan`` for ``--resume``). Raises ConfigError."""
    if cfg.resume:
        return resume_plan(cfg)
    base = read_sections(cfg.config) if cfg.config else {}
    for section, values in parse_set(cfg.set).items():
        base = with_values(base, {(section, k): v for k, v in values.items()})
    axes = tuple(parse_space(cfg.space, cfg.seeds))
    train = base.get("train", {})
    root = sweeps_root(cfg.storage, train)
    name = cfg.name or f"sweep-{time.strftime('%Y%m%d-%H%M%S')}"
    plan = SweepPlan(cfg, root, name, base, axes)
    if plan.folder.exists(STATE):
        raise ConfigError(
            f"sweep {plan.folder.location()} exists: pass --resume {name} to "
            "continue it, or another --name"
        )
    checked, seen = [], set()
    for point in corner_points(axes):
        setup = trial_check(plan, point)
        if repr(setup) not in seen:
            seen.add(repr(setup))
            checked.append(setup)
    if cfg.scheduler == "asha":  # ASHA's max_t is the longest trial's limit (budget)
        limits = {"env_steps": ("total_steps", "STEPS"), "wall_s": ("max_wall_s", "SECONDS")}
        limit, unit = limits[cfg.time_attr]
        if any(getattr(s.train, limit) is None for s in checked):
            raise ConfigError(
                f"--scheduler asha --time-attr {cfg.time_attr}: every trial needs "
                f"train.{limit} (--set train.{limit}={unit})"
            )
    return replace(plan, checked=tuple(checked))


def trial_check(plan: SweepPlan, point: dict[tuple[str, str], Any]) -> TrainSetup:
    """One trial's settings, checked as ``train`` checks its own before Ray starts; an error
    names the trial by its searched values."""
    from robogym_ray.training.setup import check_inputs

    label = ", ".join(f"{s}.{f}={quote(v)}" for (s, f), v in point.items()) or "the base"
    sections = with_values(plan.base, point)
    # The sweep places every trial's run folder; the trials join the sweep's Ray.
    sections["train"].update(
        storage=plan.runs,
        run_name=None,
        resume=False,
        address=plan.cfg.address,
        num_cpus=plan.cfg.num_cpus,
    )
    try:
        setup = setup_of(sections, f"trial {label}")
        if setup.train.real_robot:
            raise ConfigError(
                "train.real_robot: a real robot cannot be shared by trials; sweep in simulation"
            )
        # The local Ray's CPUs are checked here (a joined cluster's: check_trial_cpus once
        # the sweep has joined it), with the trial's own actor counted.
        check_inputs(setup, own_cpus=plan.cfg.trial_cpus, cpu_hint=CPU_HINT)
    except ConfigError as exc:
        raise ConfigError(f"trial {label}: {exc}") from None
    return setup


def check_trial_cpus(setup: TrainSetup, cfg: SweepConfig, available: float) -> None:
    """A trial whose actors and own actor (``trial_cpus``) need more CPUs than ``available``
    would wait forever: refused, as ``train`` refuses its run."""
    from robogym_ray.training.setup import check_resources

    check_resources(setup.train, available, own=cfg.trial_cpus, hint=CPU_HINT)


def sweeps_root(storage: str | None, train: Mapping[str, Any] | None = None) -> str:
    """Where the sweeps' folders are, as every node sees it: ``storage`` (``--storage``), else
    where ``train`` would put a run of the base's ``train`` section (``setup.storage_root``)."""
    from robogym_ray.training.setup import storage_root

    given = {k: v for k, v in (train or {}).items() if k in ("storage", "logdir")}
    if storage:
        given["storage"] = storage
    return storage_root(merge_config(TrainConfig, given, "the base's train section"))


def resume_plan(cfg: SweepConfig) -> SweepPlan:
    given = [
        flag
        for flag, value in (
            ("--config", cfg.config),
            ("--set", cfg.set),
            ("--space", cfg.space),
            ("--seeds", cfg.seeds),
            ("--name", cfg.name),
        )
        if value
    ]
    if given:
        raise ConfigError(
            f"--resume continues the sweep as it was started: drop {', '.join(given)}"
        )
    assert cfg.resume is not None
    plan = SweepPlan(cfg, sweeps_root(cfg.storage), cfg.resume, {})
    if not plan.folder.exists(STATE):
        raise ConfigError(
            f"--resume {cfg.resume}: no sweep in {plan.folder.location()} "
            f"(no {STATE}; --storage names where the sweeps are)"
        )
    return replace(plan, finished=bool(read_record(plan.folder).get(FINISHED)))


def read_record(folder: RunStorage) -> dict[str, Any]:
    """The sweep's record (``SWEEP_RECORD``) in ``folder``; empty when it has none."""
    return json.loads(folder.read_bytes(SWEEP_RECORD)) if folder.exists(SWEEP_RECORD) else {}


def asha_grace(plan: SweepPlan) -> float:
    return plan.cfg.grace_period or max(1.0, math.floor(plan.budget() / 8))
