"""A sweep's plan, made and checked before Ray starts: where it goes, its base, its search
space, and every trial it can run checked as ``train`` checks its input (the task, the D4PG
settings, the storage, a local Ray's CPUs); a bad space is refused in one line."""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, replace
from typing import Any

from robogym_ray.config import quote
from robogym_ray.errors import ConfigError
from robogym_ray.storage import RunStorage, resolve_root
from robogym_ray.sweep.config import SweepConfig
from robogym_ray.sweep.space import (
    Axis,
    corner_points,
    param_space,
    parse_set,
    parse_space,
    with_values,
)
from robogym_ray.training.command import TrainSetup, check_inputs, read_sections, setup_of
from robogym_ray.training.resources import actor_needs, describe, total_cpus

STATE = "tuner.pkl"
"""The file Tune's experiment folder holds once a sweep has started (``Tuner.can_restore``)."""
RECORD = "sweep.json"
"""The sweep's own record beside Tune's files: its searched keys, metric and command."""


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

    @property
    def folder(self) -> RunStorage:
        return RunStorage(self.root).child(self.name)

    @property
    def runs(self) -> str:
        """The trials' run folders' root."""
        return self.folder.location("runs")

    def param_space(self) -> dict[str, Any]:
        meta = {"runs": self.runs, "trial_cpus": self.cfg.trial_cpus,
                "placement": self.cfg.placement}  # fmt: skip
        return param_space(self.base, self.axes, meta)

    def budget(self) -> float:
        """The longest trial's total ``--time-attr``: ASHA's ``max_t``."""
        if self.cfg.time_attr == "env_steps":
            return float(max(s.train.total_steps for s in self.checked))
        return float(max(s.train.max_wall_s or 0.0 for s in self.checked))

    def record(self, argv: list[str]) -> bytes:
        cfg = self.cfg
        return json.dumps({
            "name": self.name, "searched": [a.key for a in self.axes], "metric": cfg.metric,
            "mode": cfg.mode, "scheduler": cfg.scheduler, "time_attr": cfg.time_attr,
            "command": ["robogym-ray", "sweep", *argv],
        }, indent=2).encode()  # fmt: skip


def plan_sweep(cfg: SweepConfig) -> SweepPlan:
    """The checked plan of ``cfg`` (``resume_plan`` for ``--resume``). Raises ConfigError."""
    if cfg.resume:
        return resume_plan(cfg)
    base = read_sections(cfg.config) if cfg.config else {}
    for section, values in parse_set(cfg.set).items():
        base = with_values(base, {(section, k): v for k, v in values.items()})
    axes = tuple(parse_space(cfg.space, cfg.seeds))
    train = base.get("train", {})
    root = resolve_root(cfg.storage or train.get("storage") or train.get("logdir") or "runs")
    name = cfg.name or f"sweep-{time.strftime('%Y%m%d-%H%M%S')}"
    plan = SweepPlan(cfg, root, name, base, axes)
    if plan.folder.exists(STATE):
        raise ConfigError(f"sweep {plan.folder.location()} exists: pass --resume {name} to "
                          "continue it, or another --name")  # fmt: skip
    checked, seen = [], set()
    for point in corner_points(axes):
        setup = trial_check(plan, point)
        if repr(setup) not in seen:
            seen.add(repr(setup))
            checked.append(setup)
    wall = cfg.scheduler == "asha" and cfg.time_attr == "wall_s"
    if wall and any(s.train.max_wall_s is None for s in checked):
        raise ConfigError("--scheduler asha --time-attr wall_s: every trial needs "
                          "train.max_wall_s (--set train.max_wall_s=SECONDS)")  # fmt: skip
    return replace(plan, checked=tuple(checked))


def trial_check(plan: SweepPlan, point: dict[tuple[str, str], Any]) -> TrainSetup:
    """One trial's settings, checked as ``train`` checks its own before Ray starts; an error
    names the trial by its searched values."""
    label = ", ".join(f"{s}.{f}={quote(v)}" for (s, f), v in point.items()) or "the base"
    sections = with_values(plan.base, point)
    # The sweep places every trial's run folder; the trials join the sweep's Ray.
    sections["train"].update(storage=plan.runs, run_name=None, resume=False,
                             address=plan.cfg.address, num_cpus=plan.cfg.num_cpus)  # fmt: skip
    try:
        setup = setup_of(sections, f"trial {label}")
        if setup.train.real_robot:
            raise ConfigError("train.real_robot: a real robot cannot be shared by trials; "
                              "sweep in simulation")  # fmt: skip
        check_inputs(setup)
        if plan.cfg.address is None:
            fits_cpus(setup, plan.cfg, plan.cfg.num_cpus or float(os.cpu_count() or 1))
    except ConfigError as exc:
        raise ConfigError(f"trial {label}: {exc}") from None
    return setup


def fits_cpus(setup: TrainSetup, cfg: SweepConfig, available: float) -> None:
    """A trial that needs more CPUs than the cluster has would wait forever: refused."""
    needs = actor_needs(setup.train)
    want = total_cpus(needs) + cfg.trial_cpus
    if want > available + 1e-9:
        raise ConfigError(
            f"a trial reserves {want:.2f} Ray CPUs ({describe(needs)} + its own "
            f"{cfg.trial_cpus:g}) but the cluster has {available:g}: lower train.workers or "
            "the actors' CPUs, or add nodes"
        )


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
    if given:  # fmt: skip
        raise ConfigError(f"--resume continues the sweep as it was started: drop "
                          f"{', '.join(given)}")  # fmt: skip
    assert cfg.resume is not None
    plan = SweepPlan(cfg, resolve_root(cfg.storage or "runs"), cfg.resume, {})
    if not plan.folder.exists(STATE):
        raise ConfigError(f"--resume {cfg.resume}: no sweep in {plan.folder.location()} "
                          f"(no {STATE}; --storage names where the sweeps are)")  # fmt: skip
    return plan


def asha_grace(plan: SweepPlan) -> float:
    return plan.cfg.grace_period or max(1.0, math.floor(plan.budget() / 8))
