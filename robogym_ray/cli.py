"""``robogym-ray``: one command-line entry point with a sub-command per job.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int`` (``args.argv``: the command line as given); the table below is the only
place that lists them, and modules are imported only when their command runs (``--help`` stays
fast and does not import Ray or torch).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from collections.abc import Sequence

from robogym_ray.errors import RoboGymRayError

COMMANDS: dict[str, tuple[str, str]] = {
    "serve": ("robogym_ray.serve", "Start a standalone robot server (robo-gym protocol)."),
    "manager": ("robogym_ray.distributed.manager", "Serve robo-gym's server manager (supervised)."),
    "resume-robot": (
        "robogym_ray.distributed.resume",
        "Resume a paused real robot of a running training (operator).",
    ),
    "train": ("robogym_ray.training.command", "Train D4PG with rollout workers on Ray."),
    "sweep": ("robogym_ray.sweep.command", "Run trainings over a search space (Ray Tune)."),
    "tasks": ("robogym_ray.training.tasks", "List the training tasks and the env ids."),
    "evaluate": ("robogym_ray.evaluation", "Evaluate a policy for N episodes (success rates)."),
    "export": ("robogym_ray.export", "Export a policy as TorchScript or ONNX, plus JSON."),
    "run-policy": ("robogym_ray.run_policy", "Drive a robot server with an exported policy."),
    "isaac-lab-sample": (
        "robogym_ray.isaac_lab_sample",
        "Write an untrained Isaac Lab (rsl_rl) policy.pt and policy.onnx to try them with.",
    ),
}
RETIRED: dict[str, str] = {
    "resume": "`robogym-ray resume` is now `resume-robot` (a paused real robot); a sweep resumes "
    "with `robogym-ray sweep --resume NAME --storage DIR`",
}
"""Former command names, not listed: each answers one line that names what to run instead."""


def build_parser(argv: Sequence[str]) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="robogym-ray",
        description="Distributed deep RL on real and simulated robots (Ray + PyBullet).",
    )
    parser.add_argument("--log-level", default="WARNING", help="Python logging level.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    # Only the chosen command's module is imported; the others get a stub for the listing.
    chosen = next((a for a in argv if a in COMMANDS), None)
    for name, (module, summary) in COMMANDS.items():
        cmd = sub.add_parser(name, help=summary, description=summary)
        if name == chosen:
            importlib.import_module(module).add_arguments(cmd)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    # gRPC's C core logs each failed TLS handshake at INFO on stderr, a line beside ours that
    # says the same; it reads the level once, when grpc is first imported (after this line).
    os.environ.setdefault("GRPC_VERBOSITY", "ERROR")
    argv = list(sys.argv[1:] if argv is None else argv)
    named = next((a for a in argv if a in COMMANDS or a in RETIRED), None)
    if named in RETIRED:
        print(f"error: {RETIRED[named]}", file=sys.stderr)
        return 2
    args = build_parser(argv).parse_args(argv)
    args.argv = argv  # the command line as given (sys.argv's or a caller's): a sweep records it
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s")
    module = importlib.import_module(COMMANDS[args.command][0])
    try:
        return int(module.run(args) or 0)
    except RoboGymRayError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
