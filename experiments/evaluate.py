"""Final evaluation of a trained policy: the paper's success / collision / timeout table.

    # 100 episodes in simulation (env id from the run's config.json)
    python experiments/evaluate.py runs/paper/positioning-average/checkpoints/learner.pt \
        --out results/pos-sim
    # on an emulated real robot started for the task (real-time pacing, latency, noise)
    python experiments/evaluate.py runs/paper/navigation-average/checkpoints/learner.pt --emulate \
        --out results/nav-emulated
    # the same robot in simulated time, episodes started and ended as in simulation (what the
    # results' "emulated robot" column is)
    python experiments/evaluate.py CHECKPOINT --emulate --simulated-time --variant sim \
        --episodes 100 --out results/nav-emulated-sim
    # on a robot server that is already running (real robot or `robogym-ray serve ...`)
    python experiments/evaluate.py policy.pt --rs-address 10.0.0.5:50051 --out results/nav-real

Writes OUT/evaluation.json (summary + per-episode status and target) and OUT/evaluation.md.
The logic is ``robogym_ray.evaluation`` (also ``robogym-ray evaluate``).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Sequence
from dataclasses import replace

from robogym_ray.config import add_config_args, config_from_args
from robogym_ray.errors import ConfigError
from robogym_ray.evaluation import EvaluationConfig, emulated_server, evaluate, report
from robogym_ray.export import load_policy


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy", help="learner.pt checkpoint or exported policy.")
    add_config_args(parser, EvaluationConfig)
    parser.add_argument(
        "--emulate",
        action="store_true",
        help="Start an emulated real robot for the task and evaluate on it.",
    )
    parser.add_argument("--serve-seed", type=int, default=0, help="Seed of the emulated robot.")
    parser.add_argument(
        "--simulated-time",
        action="store_true",
        help="--emulate without real-time pacing: the emulated robot's latency and noise, at "
        "simulation speed.",
    )
    parser.add_argument(
        "--serve-arg",
        action="append",
        default=[],
        help="Extra `robogym-ray serve` flag for --emulate (repeatable), "
        "e.g. --serve-arg=--emu-latency-ticks=2.",
    )
    args = parser.parse_args(argv)
    if args.simulated_time and not args.emulate:
        parser.error("--simulated-time is a setting of --emulate's robot; add --emulate")
    cfg = config_from_args(EvaluationConfig, args)
    with contextlib.ExitStack() as stack:
        if args.emulate:
            env_id = cfg.env_id or load_policy(args.policy, cfg.online_weights).info.env_id
            if env_id is None:
                raise ConfigError("--emulate needs --env-id (the policy does not name its env)")
            server = emulated_server(
                env_id, args.serve_seed, args.serve_arg, real_time=not args.simulated_time
            )
            address = stack.enter_context(server)
            cfg = replace(cfg, rs_address=address)
        result = evaluate(args.policy, cfg)
    report(result, cfg.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
