"""``robogym-ray run-policy``: drive a robot server with an exported policy (on the robot PC).

The same episodes and report as ``robogym-ray evaluate`` (``robogym_ray.evaluation``), but the
robot server's address is required and the policy is an exported TorchScript file, so the robot
PC needs neither a training run directory nor Ray (unless ``--via-actor``).
"""

from __future__ import annotations

import argparse

from robogym_ray.config import add_config_args, config_from_args
from robogym_ray.errors import ConfigError
from robogym_ray.evaluation import EvaluationConfig, evaluate, report
from robogym_ray.export import sidecar_path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--policy", required=True, help="Exported policy (robogym-ray export).")
    add_config_args(parser, EvaluationConfig)


def run(args: argparse.Namespace) -> int:
    cfg = config_from_args(EvaluationConfig, args)
    if not cfg.rs_address:
        raise ConfigError("run-policy needs --rs-address HOST:PORT of the robot server")
    if not sidecar_path(args.policy).exists():
        raise ConfigError(
            f"{args.policy} has no {sidecar_path(args.policy).name}: export it with "
            "`robogym-ray export CHECKPOINT OUT` first"
        )
    result = evaluate(args.policy, cfg)
    report(result, cfg.out)
    return 0
