"""What the ``experiments/`` scripts share: a training from a config file, with shortening flags.

``experiments/train_navigation.py`` and ``experiments/train_positioning.py`` are one line each
over ``train_main``; the hyperparameters live in ``experiments/configs/*.json`` (the format
``robogym-ray train --config`` reads: ``{"train": {...TrainConfig}, "d4pg": {...D4PGConfig},
"emulation": {...EmulationConfig}}``, the last for ``emulated_workers``; a variant names its
base recipe with ``"extends"`` and holds only what it changes).
``--smoke`` shrinks everything (steps, networks, replay) for a CI run of about a minute; a smoke
run checks the plumbing, not learning.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

SMOKE_TRAIN: dict[str, Any] = {
    "workers": 1, "total_steps": 300, "random_steps": 100, "steps_per_call": 50,
    "weight_sync_steps": 100, "checkpoint_every": 50, "log_every_s": 1.0, "progress": False,
    "worker_cpus": 0.2, "learner_cpus": 0.3, "server_cpus": 0.1, "evaluator_cpus": 0.1,
    "final_eval_episodes": 2,
}  # fmt: skip
"""TrainConfig overrides of ``--smoke`` (fits the test suite's 2-CPU Ray)."""
SMOKE_D4PG: dict[str, Any] = {
    "policy_hidden": [64, 64], "critic_hidden": [64, 64], "batch_size": 32,
    "min_replay_size": 64, "replay_capacity": 10_000, "samples_per_insert": 8.0,
    "num_threads": 1,
}  # fmt: skip
"""D4PGConfig overrides of ``--smoke``."""


def build_parser(default_config: Path, description: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument(
        "--config",
        default=str(default_config),
        help=f"Experiment config file (default: {default_config}).",
    )
    parser.add_argument("--total-steps", type=int, help="Env steps (shortens the run).")
    parser.add_argument("--workers", type=int, help="Simulated rollout workers.")
    parser.add_argument("--logdir", help="TensorBoard root (run dir = LOGDIR/RUN_NAME).")
    parser.add_argument("--run-name", help="Run directory name.")
    parser.add_argument("--seed", type=int, help="Seed of the run.")
    parser.add_argument("--address", help="Ray address ('auto' joins a running cluster).")
    parser.add_argument("--num-cpus", type=float, help="CPUs of the embedded local Ray.")
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="Tiny run for CI (300 steps, small nets); checks plumbing only.",
    )
    parser.add_argument("--no-progress", action="store_true", help="No progress bar.")
    return parser


def experiment_configs(args: argparse.Namespace) -> tuple[Any, dict[str, Any], Any]:
    """``(TrainConfig, d4pg overrides, EmulationConfig)``: file <- ``--smoke`` <- flags."""
    from robogym_ray.config import merge_config
    from robogym_ray.robots.emulation import EmulationConfig
    from robogym_ray.training.config import TrainConfig
    from robogym_ray.training.settings import read_sections

    sections = read_sections(args.config)
    train, d4pg = sections["train"], sections["d4pg"]
    if args.smoke:
        train.update(SMOKE_TRAIN)
        d4pg.update(SMOKE_D4PG)
    flags = {
        "total_steps": args.total_steps, "workers": args.workers, "logdir": args.logdir,
        "run_name": args.run_name, "seed": args.seed, "address": args.address,
        "num_cpus": args.num_cpus,
    }  # fmt: skip
    train.update({k: v for k, v in flags.items() if v is not None})
    if args.no_progress:
        train["progress"] = False
    return (
        merge_config(TrainConfig, train, source=args.config),
        d4pg,
        merge_config(EmulationConfig, sections["emulation"], source=args.config),
    )


def train_main(
    default_config: Path, argv: Sequence[str] | None = None, description: str = ""
) -> dict[str, Any]:
    """Parse the flags, train, print and return the run summary."""
    from robogym_ray.config import FLAGS
    from robogym_ray.training.api import run_checked
    from robogym_ray.training.settings import TrainSetup

    args = build_parser(default_config, description).parse_args(argv)
    cfg, d4pg, emulation = experiment_configs(args)
    # The command's checks, before Ray starts: a bad task, a taken run name, too few CPUs, ...
    summary = run_checked(TrainSetup(cfg, d4pg, emulation), FLAGS)
    print(json.dumps(summary), flush=True)
    return summary
