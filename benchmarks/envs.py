"""Env steps/s of the paper's two envs beside the raw robot-server rate underneath them.

    nice python benchmarks/envs.py [--steps 2000] [--rounds 3] [--write FILE]

For each env (Sim variant, simulated time) four rates are measured against the same robot,
scene and options, all in one process on one core:

* ``env``: ``env.step`` as ``gymnasium.make`` builds it (the robot core in process, no wire),
  random actions, resets excluded from the timing (their count is reported); includes
  gymnasium's wrappers, action checks, observation and reward.
* ``env (gRPC)``: the same env with ``provider=EmbeddedServerProvider()``: a robot server on
  loopback gRPC in between (the path before in-process simulation, and robo-gym's).
* ``grpc``: SendActionGetState calls per second through gRPC (our client, loopback) with a
  constant valid action - what the env pays per step at the wire.
* ``core``: ``RobotServerCore.send_action_get_state`` in-process, no gRPC - the simulation.

Rounds alternate between the four; the best round of each is reported.
"""

from __future__ import annotations

import argparse
import datetime
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs.servers import EmbeddedServerProvider
from robogym_ray.envs.ur_common import to_ros
from robogym_ray.protocol.client import RobotServerClient
from robogym_ray.robots.server import start_robot_server

PAPER_ENVS = (
    "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
    "RoboGymRay/EndEffectorPositioningUR10Sim-v0",
)
Bench = Callable[[int], float]
"""``run(steps) -> seconds``."""


def env_bench(env_id: str, **kwargs: Any) -> tuple[Bench, list[int]]:
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    resets = [0]

    def run(steps: int) -> float:
        actions = env.action_space.sample
        elapsed = 0.0
        for _ in range(steps):
            start = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(actions())
            elapsed += time.perf_counter() - start
            if terminated or truncated:
                env.reset()
                resets[0] += 1
        return elapsed

    return run, resets


def server_benches(env_id: str) -> tuple[Bench, Bench]:
    """(gRPC, core) benches on a fresh server with the env's robot, scene and options."""
    probe = gym.make(env_id).unwrapped
    robot, scene, options = probe.server_spec()
    probe.close()
    handle = start_robot_server(robot, scene=scene, seed=0, options=options)
    client = RobotServerClient(handle.address)
    state = client.get_state()
    if state.state_dict:  # UR: hold the current joints (ROS order)
        names = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")
        action = to_ros(np.array([state.state_dict[f"{n}_joint_position"] for n in names]))
    else:  # MiR: creep forward
        action = np.array([0.05, 0.0])

    def grpc_run(steps: int) -> float:
        start = time.perf_counter()
        for _ in range(steps):
            client.send_action_get_state(action)
        return time.perf_counter() - start

    def core_run(steps: int) -> float:
        start = time.perf_counter()
        for _ in range(steps):
            handle.core.send_action_get_state(action)
        return time.perf_counter() - start

    return grpc_run, core_run


def measure(env_id: str, steps: int, rounds: int) -> dict[str, float]:
    env_run, resets = env_bench(env_id)
    wire_env_run, _ = env_bench(env_id, provider=EmbeddedServerProvider())
    grpc_run, core_run = server_benches(env_id)
    benches = {"env": env_run, "env_grpc": wire_env_run, "grpc": grpc_run, "core": core_run}
    for run in benches.values():
        run(min(100, steps))  # warm-up
    best = dict.fromkeys(benches, 0.0)
    for _ in range(rounds):
        for name, run in benches.items():
            best[name] = max(best[name], steps / run(steps))
    return {**best, "resets": float(resets[0])}


def machine() -> str:
    out = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
    fields = dict(line.split(":", 1) for line in out.splitlines() if ":" in line)
    model = fields.get("Model name", "?").strip()
    return f"{model}, {fields.get('CPU(s)', '?').strip()} CPUs (lscpu)"


def report(results: dict[str, dict[str, float]], args: argparse.Namespace) -> str:
    rows = [
        f"| `{env_id}` | {r['core']:.0f} | {r['env']:.0f} | {r['env_grpc']:.0f} | "
        f"{r['grpc']:.0f} | {r['env'] / r['core']:.2f} | {r['env_grpc'] / r['core']:.2f} | "
        f"{r['resets']:.0f} |"
        for env_id, r in results.items()
    ]
    return "\n".join(
        [
            "## Env step rate vs robot-server rate",
            "",
            f"Date {datetime.date.today().isoformat()}; machine: {machine()}; Python "
            f"{sys.version.split()[0]}.",
            f"Command: `nice python benchmarks/envs.py --steps {args.steps} --rounds {args.rounds}`"
            " (best of the rounds, alternating; simulated time, one process, one core).",
            "",
            "| env | bare core calls/s | env steps/s (in-process) | env steps/s (gRPC) | "
            "SendActionGetState/s (gRPC) | in-process / core | gRPC env / core | resets |",
            "|---|---|---|---|---|---|---|---|",
            *rows,
            "",
            "The gap between an env and the bare core is gymnasium's wrappers, action checks,",
            "observation and reward (and, for the gRPC env, the loopback round trip: client and",
            "server share one process and its GIL); the core rate is the simulation itself (MiR:",
            "two 541-beam ray casts per 0.1 s cycle; UR: arm control ticks and contact checks).",
            "",
        ]
    )


def run_paper_envs(
    doc: str | None,
    measure: Callable[[str, int, int], dict[str, float]],
    report: Callable[[dict[str, dict[str, float]], argparse.Namespace], str],
    steps: int,
) -> None:
    """The command line of a per-env benchmark: ``--steps``, ``--rounds``, ``--write FILE``;
    ``measure`` each paper env, print the ``report`` (and write it)."""
    parser = argparse.ArgumentParser(description=(doc or "").splitlines()[0])
    parser.add_argument("--steps", type=int, default=steps, help="steps per round and bench")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--write", type=Path, default=None, help="markdown file to write")
    args = parser.parse_args()
    results = {env_id: measure(env_id, args.steps, args.rounds) for env_id in PAPER_ENVS}
    text = report(results, args)
    print(text)
    if args.write:
        args.write.parent.mkdir(parents=True, exist_ok=True)
        args.write.write_text(text)


if __name__ == "__main__":
    run_paper_envs(__doc__, measure, report, steps=2000)
