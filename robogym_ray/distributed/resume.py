"""``robogym-ray resume-robot NAME``: an operator resumes a paused real robot on the running
cluster (a training's Ray). A sweep is resumed by ``robogym-ray sweep --resume NAME``."""

from __future__ import annotations

import argparse
import sys

from robogym_ray.errors import ConfigError, RayNotFoundError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", help="The real robot's name (its actor's name).")
    parser.add_argument(
        "--ray-address", default="auto", help="Ray cluster to connect to (default: auto)."
    )
    parser.add_argument(
        "--status", action="store_true", help="Only print the robot's status; do not resume."
    )


def run(args: argparse.Namespace) -> int:
    import ray  # lazy: `robogym-ray --help` must not import Ray

    from robogym_ray.config import check_ray_address
    from robogym_ray.distributed.local_ray import join_ray
    from robogym_ray.distributed.robot_actors import NAMESPACE, get_real_robot

    if not args.name.strip():
        raise ConfigError("resume-robot NAME: empty; name the real robot (its actor's name)")
    check_ray_address(args.ray_address, "--ray-address")  # before Ray is asked to join it
    try:
        join_ray(args.ray_address, namespace=NAMESPACE, logging_level="ERROR")
    except RayNotFoundError as exc:
        # Said in one line, and the user may have meant a sweep: its command is named too.
        raise RayNotFoundError(
            f"--ray-address {args.ray_address}: {exc}; resume-robot resumes a paused real robot "
            f"of a running training, a sweep resumes with `robogym-ray sweep --resume "
            f"{args.name} --storage DIR`"
        ) from None
    try:
        robot = get_real_robot(args.name)
    except ValueError:
        print(f"error: no real robot named {args.name!r} in namespace {NAMESPACE}", file=sys.stderr)
        return 2
    method = robot.status if args.status else robot.resume
    try:
        status = ray.get(method.remote())
    except Exception as exc:  # noqa: BLE001 - a failed health check keeps the robot paused
        print(f"error: {exc}", file=sys.stderr)
        return 1
    state = "paused" if status["paused"] else "running"
    print(f"{status['name']} at {status['address']}: {state} {status['reason']}".rstrip())
    return 0
