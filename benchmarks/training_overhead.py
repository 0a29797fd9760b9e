"""What the evaluator and emulated workers cost a training run on a small machine.

Runs the real training program (local Ray) for ``--wall-s`` seconds per variant, one after
another and ``--repeats`` times in turn (the machine is shared and noisy: compare variants
measured side by side, not across invocations), and prints env steps/s and learner steps/s of
each. Variants:

* ``no-eval``: rollout workers and learner only;
* ``eval``: plus the evaluator (one greedy episode per call, the default);
* ``select``: the evaluator scoring each snapshot on ``--select-episodes`` episodes;
* ``emulated``: no evaluator, worker 0 on an emulated robot (``--emulated-workers 1``);
* ``eval-256``: ``eval`` with (256, 256) policy and critic nets instead of the config's.

Start from a trained run (``--init-from RUN/checkpoints/learner.pt``, with its replay beside
it) so the learner trains from the first second, as in the middle of a real run. A checkpoint
fits one net size only, so ``eval-256`` runs from scratch: compare it with ``eval`` run from
scratch too (no ``--init-from``).

Usage: python benchmarks/training_overhead.py --config experiments/configs/navigation.json \
    --init-from /tmp/paper/navigation-dr/checkpoints/learner.pt [--wall-s 120] [--repeats 1]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from dataclasses import replace
from typing import Any

from robogym_ray.config import merge_config
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.run import run_training
from robogym_ray.training.settings import read_sections

VARIANTS: dict[str, dict[str, Any]] = {
    "no-eval": {"evaluator": False},
    "eval": {"evaluator": True},
    "select": {"evaluator": True, "select_episodes": -1},  # -1: replaced by --select-episodes
    "emulated": {"evaluator": False, "emulated_workers": 1},
    "eval-256": {"evaluator": True},
}
"""TrainConfig changes of each variant."""
D4PG_CHANGES: dict[str, dict[str, Any]] = {
    "eval-256": {"policy_hidden": [256, 256], "critic_hidden": [256, 256]},
}
"""D4PGConfig changes of the variants that have them."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="experiments/configs/navigation.json")
    parser.add_argument("--init-from", default=None)
    parser.add_argument("--wall-s", type=float, default=120.0)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--select-episodes", type=int, default=100)
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    args = parser.parse_args()
    if args.init_from and set(args.variants) & set(D4PG_CHANGES):
        parser.error(f"--init-from fits one net size; run {sorted(D4PG_CHANGES)} without it")
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    sections = read_sections(args.config)
    logdir = tempfile.mkdtemp(prefix="overhead-")
    base = merge_config(
        TrainConfig,
        {
            **sections["train"],
            "workers": 2,
            "num_cpus": 2,
            "total_steps": 10**9,
            "max_wall_s": args.wall_s,
            "random_steps": 0,
            "logdir": logdir,
            "progress": False,
            "log_every_s": 10.0,
            "init_from": args.init_from,
        },
        source=args.config,
    )
    rows = []
    for repeat in range(args.repeats):
        for name in args.variants:
            change = dict(VARIANTS[name])
            if change.get("select_episodes") == -1:
                change["select_episodes"] = args.select_episodes
            cfg = replace(base, run_name=f"{name}-{repeat}", **change)
            summary = run_training(cfg, {**sections["d4pg"], **D4PG_CHANGES.get(name, {})})
            row = {
                "variant": name,
                "repeat": repeat,
                "wall_s": summary["wall_s"],
                "env_steps_per_s": round(summary["throughput/env_steps_per_s"], 1),
                "learner_steps_per_s": round(summary["throughput/learner_steps_per_s"], 1),
                "eval_episodes": summary.get("eval/episodes", 0.0),
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
    print("\n| variant | repeat | env steps/s | learner steps/s | eval episodes |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['variant']} | {r['repeat']} | {r['env_steps_per_s']} | "
            f"{r['learner_steps_per_s']} | {r['eval_episodes']:.0f} |"
        )


if __name__ == "__main__":
    main()
