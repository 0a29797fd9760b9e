"""``robogym-ray run-policy``: drive a robot with an exported policy (on the robot PC).

The same episodes and report as ``robogym-ray evaluate`` (``robogym_ray.evaluation``), for a
policy file that needs no training run directory and no Ray (unless ``--via-actor``): one of
ours (``robogym-ray export``: TorchScript with its ``.json`` sidecar, or its ONNX twin), or an
Isaac Lab export (``--isaac-lab``: rsl_rl ``play.py``'s ``policy.pt`` or ``policy.onnx``).

    robogym-ray run-policy --isaac-lab logs/rsl_rl/reach_ur10/RUN/exported/policy.pt \\
        --env-id RoboGymRay/IsaacReachUR10Sim-v0 --episodes 10        # our simulation
    robogym-ray run-policy --isaac-lab policy.onnx --env-id RoboGymRay/IsaacReachUR10Rob-v0 \\
        --rs-address ROBOT:50051 --token T --via-actor                # the robot, filtered

An Isaac Lab policy's outputs reach the env through Isaac ROS's decoder (clamp, optional EMA
``--ema-alpha``, scale, stream: ``robogym_ray.isaac_lab``); ``--io-descriptors`` (Isaac Lab 3's
``<task>_IO_descriptors.yaml``) checks the policy against the env before the first action and
gives the scale, offset and clip (docs/isaac-lab.md).

Without ``--rs-address`` the task's Sim variant runs in this process; with it, the robot server
at that address (real or ``serve --emulate-hardware``) is driven through the Rob variant, and
``--via-actor`` puts the real-robot safety filter in between.
"""

from __future__ import annotations

import argparse

from robogym_ray.config import add_config_args, config_from_args
from robogym_ray.errors import ConfigError
from robogym_ray.evaluation import EvaluationConfig, evaluate, report
from robogym_ray.export import sidecar_path
from robogym_ray.storage import local_file

DESCRIPTION = """Drive a robot with a policy file, as on the robot PC. POLICY is one of ours
exported with `robogym-ray export` (its .json beside it) or, with --isaac-lab, an Isaac Lab
export (play.py's policy.pt or policy.onnx), whose outputs pass Isaac ROS's decoder (clamp,
--ema-alpha, scale, stream). The episodes, options, table and JSON are those of `robogym-ray
evaluate`; what differs is the input: evaluate also reads a training run's folder or learner.pt
(policy and env id from the run), run-policy only a file that stands alone, so nothing of a
training run need be on the robot PC. Neither starts Ray unless --via-actor."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = DESCRIPTION
    parser.add_argument("policy_file", nargs="?", metavar="POLICY", help="The policy file.")
    parser.add_argument("--policy", default=None, help="The policy file (same as POLICY).")
    add_config_args(parser, EvaluationConfig)


def run(args: argparse.Namespace) -> int:
    cfg = config_from_args(EvaluationConfig, args)
    if (args.policy is None) == (args.policy_file is None):
        raise ConfigError("run-policy takes one policy file: POLICY or --policy PATH")
    policy = local_file(args.policy or args.policy_file, "policy")  # s3://... downloaded
    if not cfg.isaac_lab and not sidecar_path(policy).exists():
        raise ConfigError(
            f"{policy} has no {sidecar_path(policy).name}: export it with "
            "`robogym-ray export CHECKPOINT OUT` first (an Isaac Lab file: --isaac-lab)"
        )
    result = evaluate(policy, cfg)
    report(result, cfg.out)
    return 0
