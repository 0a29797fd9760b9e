"""``robogym-ray train``: distributed D4PG on local Ray or a cluster."""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from robogym_ray.config import (
    add_config_args,
    check_dir_path,
    check_fields,
    check_keys,
    flags_of,
    merge_config,
    quote,
    read_json,
)
from robogym_ray.envs.outcomes import WINDOW_KEYS
from robogym_ray.errors import ConfigError
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training import ending
from robogym_ray.training.config import TrainConfig

SECTIONS = {"train": TrainConfig, "d4pg": D4PGConfig, "emulation": EmulationConfig}
"""Keys a config file may hold, and the config class whose fields each section holds."""


@dataclass(frozen=True)
class TrainSetup:
    """Everything ``robogym-ray train`` was asked for."""

    train: TrainConfig
    d4pg: dict[str, Any]
    """D4PGConfig overrides on top of the task's preset."""
    emulation: EmulationConfig
    """What the emulated workers' robots differ by (used when train.emulated_workers > 0)."""


HELP_GROUPS: dict[str, tuple[str, ...]] = {
    "run": ("task", "total_steps", "max_wall_s", "seed", "config", "run_name", "resume",
            "logdir", "log_every_s", "progress"),
    "workers and paths": ("workers", "envs_per_worker", "sim_path", "emulated_workers",
                          "address", "num_cpus", "worker_cpus", "learner_cpus", "server_cpus",
                          "evaluator_cpus", "learner_gpus", "batch_per_worker",
                          "learner_resource",
                          "worker_resource", "spread_workers", "evaluator_resource",
                          "server_resource"),
    "D4PG (the workers' side; the learner's settings are the config file's d4pg section)": (
        "steps_per_call", "weight_sync_steps", "random_steps", "sigma_min",
        "sigma_decay_start", "sigma_decay_steps", "sigma_final_scale", "revisit_failed",
        "revisit_pool", "revisit_max"),
    "evaluation": ("evaluator", "eval_interval_s", "final_eval_episodes", "video_interval_s",
                   "select_episodes", "policy_snapshot_every_s"),
    "faults and storage": ("storage", "init_from", "checkpoint_every", "save_replay",
                           "replay_snapshot_every_s", "worker_deadline_s"),
    "real robots": ("real_robot", "token", "real_robot_wait_s"),
}  # fmt: skip
"""``train --help``'s sections: every TrainConfig field in one (a new field in none fails the
parser's build, so every CLI test; add it here)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # The full usage would list every flag (~50 lines) above the sections that list them.
    parser.usage = "%(prog)s [--task TASK] [--workers N] [--config FILE] [options]"
    # Only flags given on the command line override the config file.
    sections = add_config_args(parser, TrainConfig, only_given=True, groups=HELP_GROUPS)
    add_config_args(parser, EmulationConfig, prefix="emu-", only_given=True,
                    title="emulated robots (for --emulated-workers)")  # fmt: skip
    sections["run"].add_argument(
        "--json",
        action="store_true",
        help="print the run's summary as one JSON line (it is always in RUN_DIR/summary.json)",
    )


def _given(args: argparse.Namespace, cls: type) -> dict[str, Any]:
    given = {f.name: getattr(args, f.name) for f in fields(cls) if hasattr(args, f.name)}
    return {k: tuple(v) if isinstance(v, list) else v for k, v in given.items()}


def read_sections(path: str | Path, _chain: tuple[Path, ...] = ()) -> dict[str, dict[str, Any]]:
    """The sections of a config file ({"train": {...}, "d4pg": {...}, "emulation": {...}}).

    A file may name another with ``"extends": "base.json"`` (a path relative to the file): it
    starts from the base's sections and overrides them field by field, so a variant of a recipe
    holds only what it changes and the two cannot drift apart unnoticed.
    """
    path = Path(path)
    chain = (*_chain, path.resolve())
    if chain[-1] in _chain:
        raise ConfigError(f"{path}: 'extends' forms a cycle: {' -> '.join(map(str, chain))}")
    return sections_of(read_json(path), str(path), path.parent, chain)


def sections_of(
    data: object, source: str, base_dir: Path, chain: tuple[Path, ...] = ()
) -> dict[str, dict[str, Any]]:
    """The sections of a config's JSON object (a file's, or the same dict given in Python),
    each checked against its config class; ``"extends"`` is read relative to ``base_dir``.
    ``source`` names the config in errors."""
    if not isinstance(data, dict):
        raise ConfigError(
            f"{source}: expected a JSON object with keys among {', '.join(SECTIONS)} and "
            f"'extends', got a JSON {type(data).__name__}"
        )
    check_keys(data, (*SECTIONS, "extends"), source, "top-level key(s)")
    for name, section in data.items():
        if name != "extends" and not isinstance(section, dict):
            raise ConfigError(f"{source}: section {name!r} must be a JSON object")
        if name != "extends":
            # Each file is checked on its own, so an error names the file that holds the key.
            check_fields(SECTIONS[name], section, f"{source}: {name}")
    base: dict[str, dict[str, Any]] = {name: {} for name in SECTIONS}
    if "extends" in data:
        parent = data["extends"]
        if not isinstance(parent, str) or not parent:
            raise ConfigError(
                f"{source}: 'extends' must be a config file name, got {quote(parent)}"
            )
        try:
            base = read_sections(base_dir / parent, chain)
        except ConfigError as exc:
            raise ConfigError(f"{source} extends {parent}: {exc}") from None
    return {name: {**base[name], **data.get(name, {})} for name in SECTIONS}


def setup_of(
    sections: Mapping[str, Mapping[str, Any]],
    source: str,
    train: Mapping[str, Any] | None = None,
    emulation: Mapping[str, Any] | None = None,
    d4pg: Mapping[str, Any] | None = None,
    flagged: bool = False,
) -> TrainSetup:
    """A config's ``sections`` with ``train``, ``emulation`` and ``d4pg`` values on top (the
    command line's flags, a Python call's keywords). ``flagged``: those values came as flags,
    so an error about one names the flag (``--workers 0``), not the field."""
    train, emulation, d4pg = dict(train or {}), dict(emulation or {}), dict(d4pg or {})
    check_fields(D4PGConfig, d4pg, f"{source}: d4pg")
    return TrainSetup(
        train=merge_config(TrainConfig, {**sections.get("train", {}), **train}, source,
                           flags=flags_of(train) if flagged else None),
        d4pg={**sections.get("d4pg", {}), **d4pg},
        emulation=merge_config(EmulationConfig, {**sections.get("emulation", {}), **emulation},
                               source, flags=flags_of(emulation, "emu-") if flagged else None),
    )  # fmt: skip


def build_config(args: argparse.Namespace) -> TrainSetup:
    train, emu = _given(args, TrainConfig), _given(args, EmulationConfig)
    source = train.get("config") or "command line"
    data = read_sections(source) if train.get("config") else {}
    return setup_of(data, source, train, emu, flagged=True)


def check_inputs(setup: TrainSetup) -> None:
    """Everything the run reads, checked before Ray starts or its run directory is made: the
    task, the D4PG settings, the log directory, the local Ray's CPUs, ``--init-from`` and that
    the storage can be written."""
    from robogym_ray.experience.rollout import box_dims, make_gym_env
    from robogym_ray.learner.checkpoint import CHECKPOINT_NAME
    from robogym_ray.storage import RunStorage, check_writable, is_uri
    from robogym_ray.training import setup as run_setup
    from robogym_ray.training.presets import d4pg_for, resolve_task

    cfg = setup.train
    try:
        preset = resolve_task(cfg.task)
    except ConfigError as exc:  # its message repeats the name whole: a 1 MB one too
        raise ConfigError(str(exc).replace(repr(cfg.task), quote(cfg.task))) from None
    d4pg = d4pg_for(preset, setup.d4pg, cfg)
    root = run_setup.storage_root(cfg)
    if not is_uri(root):
        local = Path(root) / cfg.run_name if cfg.run_name else Path(root)
        check_dir_path(local, "--storage/--logdir/--run-name")
    if cfg.address is None:  # the local Ray gets num_cpus, or (at most) all of this machine
        run_setup.check_resources(cfg, cfg.num_cpus or float(os.cpu_count() or 1))
    init_from, label = cfg.init_from, "--init-from"
    if cfg.run_name:  # a taken name without --resume, or --resume of another task: refused
        place = run_setup.run_place(cfg, preset.env_id)
        if cfg.resume:
            # A resumed run continues from its own checkpoint and ignores --init-from
            # (seed_checkpoint); checked the same way (other network sizes would otherwise
            # crash its learner actor after Ray started).
            own = place.storage.location(f"checkpoints/{CHECKPOINT_NAME}")
            init_from, label = own, "--resume: the run's checkpoint"
    # The file first: probing the env below imports pybullet, whose banner goes to stderr.
    state = run_setup.read_init_from(init_from, label) if init_from else None
    # A file written and removed at the root (made if missing, left empty by a refusal below).
    check_writable(RunStorage(root), "--storage" if cfg.storage else "--logdir")
    probe = make_gym_env(preset.env_id)()  # dimensions only: it never resets, so no server
    try:
        obs_dim, act_dim = box_dims(probe)
    finally:
        probe.close()
    if init_from:
        run_setup.check_init_from(init_from, d4pg, obs_dim, act_dim, state, label)
    else:
        run_setup.learner_networks(d4pg, obs_dim, act_dim)


def run(args: argparse.Namespace) -> int:
    from robogym_ray.training.api import train

    summary = train(build_config(args))  # the Python entry: checked before Ray starts
    print(json.dumps(summary) if args.json else summary_text(summary), flush=True)
    return 0


def _rates(summary: dict[str, Any], prefix: str) -> str:
    return "  ".join(
        f"{name} {100 * summary[f'{prefix}/{name}_rate']:.1f} %"
        for name in ("success", "collision", "timeout")
    )


def summary_text(summary: dict[str, Any]) -> str:
    """A few lines for a person: how the run ended, how it went, where its files are."""
    from robogym_ray.training.stats import run_root

    root = run_root(summary)
    whole = ending.whole_run_line(summary)  # a run in parts (--resume): all of them
    lines = [ending.first_line(summary), *([whole] if whole else [])]
    # A task with command windows ends only by time: success rates say nothing of it (100 %
    # timeout), its window-end errors (the evaluator's) are its measure.
    windows = f"eval/{WINDOW_KEYS[0]}" in summary
    if "train/success_rate" in summary and not windows:
        # Over the last 100 episodes that were not revisits (RunStats), fewer in a short run.
        counted = min(100, summary["episodes"] - summary.get("revisited_episodes", 0))
        lines.append(f"  training episodes (last {counted}): {_rates(summary, 'train')}")
    if "eval/success_rate" in summary:
        # The evaluator's rates are over its last 100 episodes (Evaluator's window).
        total = int(summary.get("eval/episodes", 0))
        last = f"last {min(100, total)} of {total}"
        measure = (
            f"window-end error median {summary[f'eval/{WINDOW_KEYS[0]}']:.4f} m, "
            f"{summary[f'eval/{WINDOW_KEYS[1]}']:.4f} rad"
            if windows
            else _rates(summary, "eval")
        )
        lines.append(f"  greedy evaluation ({last} episodes): {measure}")
    restarts = sum(summary["restarts"].values())
    node = summary.get("storage", {}).get("node", "")
    lines += [
        f"  faults: {restarts} server restarts, {summary['dropped_steps']} dropped steps, "
        f"{summary['robot_errors']} robot errors",
        f"  files:       {root}/" + (f"  (on {node})" if node else ""),
        f"  checkpoint:  {summary['checkpoint']}",
        f"  TensorBoard: tensorboard --logdir {root}",
        f"  summary:     {root}/summary.json (or pass --json)",
    ]
    return "\n".join(lines)
