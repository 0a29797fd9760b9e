"""Full training, old experience path against the new one, side by side on this machine.

    nice python benchmarks/fast_training.py [--config experiments/configs/navigation-average.json]
        [--wall-s 200] [--warm-s 70] [--window-s 90] [--rounds 2]

Runs ``robogym-ray train`` (embedded Ray) for ``--wall-s`` seconds per variant, alternating:

* ``grpc-1``: the old path - every simulated env talks over gRPC to its own supervised robot-
  server actor, one env per rollout worker (``--sim-path grpc --envs-per-worker 1``);
* ``inprocess``: the new default - the robots run inside their worker, K envs per worker;
* ``inprocess-2t`` (only with ``--variants``): the new default with two torch threads for the
  learner (``D4PGConfig.num_threads``; Ray gives a fractional-CPU actor one OpenMP thread).

Both with the config's recipe (samples per insert included), 2 workers, no ``--init-from``.
During each run ``benchmarks/cpu_split.py`` measures a ``--window-s`` window from ``--warm-s``
on: CPU per env step by role. The env side is the rollout workers plus the robot servers.
Prints one table row per run and writes nothing else.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
VARIANTS: dict[str, tuple[list[str], dict[str, object]]] = {
    "grpc-1": (["--sim-path", "grpc", "--envs-per-worker", "1"], {}),
    "inprocess": ([], {}),
    "inprocess-2t": ([], {"num_threads": 2}),
}
"""Variant -> (train flags, D4PG settings over the config's)."""
ENV_SIDE = ("rollout workers", "robot servers")


def per_step(table: str, role: str) -> float:
    """``ms CPU per env step`` of ``role`` in cpu_split's table (0 when absent)."""
    match = re.search(rf"^\| {re.escape(role)} \| [^|]+ \| [^|]+ \| ([0-9.]+) \|", table, re.M)
    return float(match.group(1)) if match else 0.0


def run(name: str, args: argparse.Namespace, logdir: str, index: int) -> dict[str, object]:
    run_name = f"{name}-{index}"
    flags, d4pg = VARIANTS[name]
    config = args.config
    if d4pg:  # a config of its own that extends the given one
        config = f"{logdir}/{name}.json"
        extends = str(Path(args.config).resolve())
        Path(config).write_text(json.dumps({"extends": extends, "d4pg": d4pg}))
    cmd = ["robogym-ray", "train", "--config", config, "--workers", "2",
           "--total-steps", "1000000000", "--max-wall-s", str(args.wall_s),
           "--logdir", logdir, "--run-name", run_name, "--no-progress",
           "--num-cpus", "2", *flags]  # fmt: skip
    env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
    train = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    time.sleep(args.warm_s)
    split = subprocess.run(
        [sys.executable, str(HERE / "cpu_split.py"), "--run-dir", f"{logdir}/{run_name}",
         "--seconds", str(args.window_s)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    _, err = train.communicate(timeout=args.wall_s + 600)
    if train.returncode != 0:
        raise SystemExit(f"{name} failed: {err.decode()[-2000:]}")
    summary = json.loads((Path(logdir) / run_name / "summary.json").read_text())
    table = split.stdout
    rate = re.search(r"run: (\d+) env steps/s, ([0-9.]+) learner", table)
    return {
        "variant": name,
        "env_steps_per_s": round(summary["throughput/env_steps_per_s"], 1),
        "learner_steps_per_s": round(summary["throughput/learner_steps_per_s"], 1),
        "window_env_steps_per_s": float(rate.group(1)) if rate else 0.0,
        "env_side_ms": round(sum(per_step(table, role) for role in ENV_SIDE), 3),
        "learner_ms": per_step(table, "learner"),
        "table": table,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="experiments/configs/navigation-average.json")
    parser.add_argument("--wall-s", type=float, default=200.0)
    parser.add_argument("--warm-s", type=float, default=70.0)
    parser.add_argument("--window-s", type=float, default=90.0)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--variants", nargs="+", default=["grpc-1", "inprocess"],
                        choices=list(VARIANTS))  # fmt: skip
    args = parser.parse_args()
    logdir = tempfile.mkdtemp(prefix="fast-training-")
    rows = []
    for index in range(args.rounds):
        for name in args.variants:
            row = run(name, args, logdir, index)
            rows.append(row)
            print(row.pop("table"), flush=True)
            print(json.dumps(row), flush=True)
    print("\n| variant | round | env steps/s (run) | learner steps/s | env steps/s (window) | "
          "env-side ms CPU / env step | learner ms CPU / env step |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows):
        print(f"| {r['variant']} | {i // len(args.variants)} | {r['env_steps_per_s']} | "
              f"{r['learner_steps_per_s']} | {r['window_env_steps_per_s']:.0f} | "
              f"{r['env_side_ms']} | {r['learner_ms']} |")  # fmt: skip


if __name__ == "__main__":
    main()
