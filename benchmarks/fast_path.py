"""The fast experience path: a rollout worker with K in-process envs, and ``make_vec``.

    nice python benchmarks/fast_path.py [--steps 1000] [--rounds 3] [--write FILE]

For each of the paper's envs, in one process on one core, rounds alternate between:

* ``core``: the bare robot core (``RobotServerCore.send_action_get_state``), the ceiling;
* ``worker K``: ``RolloutWorker.collect`` with K = 1, 2, 4, 8, 16 in-process envs, the policy's
  forward pass included (random weights, exploring: what a training worker does per step,
  n-step accumulation and batching included);
* ``make_vec``: ``gymnasium.make_vec(id, num_envs=8)`` stepped with random batched actions,
  beside Gymnasium's ``SyncVectorEnv`` of 8 envs on the gRPC path (each with an embedded robot
  server, as every env was before in-process simulation) and of 8 default (in-process) envs.

The best round of each is reported (env steps per second). Beside it, ``core share``: the
part of the bench's time spent inside the robot cores' SendActionGetState and SetState (timed
by wrapping ``RobotServerCore``'s methods in this process) - the simulation under exactly the
bench's workload (its scene, its actions, its resets); 1 - core share is the overhead of
everything else (env, task, policy, n-step, batching). The ``core`` row is a standalone core
with a constant action and no resets, as ``benchmarks/envs.py`` measures it.
"""

from __future__ import annotations

import argparse
import datetime
import sys
import time

import gymnasium as gym
import torch
from envs import machine, run_paper_envs, server_benches

import robogym_ray  # noqa: F401 - registers the ids
from robogym_ray.envs.servers import EmbeddedServerProvider
from robogym_ray.experience.rollout import RolloutWorker, make_gym_env
from robogym_ray.learner.config import D4PGConfig
from robogym_ray.robots.server import RobotServerCore

KS = (1, 2, 4, 8, 16)
CORE_SECONDS = [0.0]
"""Seconds spent inside robot cores since the last reset of this counter."""


def time_cores() -> None:
    """Count the time of every core call of this process in ``CORE_SECONDS``."""
    for name in ("send_action_get_state", "set_state"):
        method = getattr(RobotServerCore, name)

        def timed(self, *args, _method=method):  # type: ignore[no-untyped-def]
            start = time.perf_counter()
            try:
                return _method(self, *args)
            finally:
                CORE_SECONDS[0] += time.perf_counter() - start

        setattr(RobotServerCore, name, timed)


def worker_bench(env_id: str, k: int):  # type: ignore[no-untyped-def]
    worker = RolloutWorker(make_gym_env(env_id), D4PGConfig(), num_envs=k, seed=0)
    weights = {n: t.numpy() for n, t in worker.actor.policy.state_dict().items()}
    worker.set_weights(weights, 0)  # the policy acts (no random warm-up actions)
    worker.collect(50)

    def run(steps: int) -> float:
        return worker.collect(steps).wall_s

    return run


def vec_bench(env_id: str, **kwargs):  # type: ignore[no-untyped-def]
    vec = gym.make_vec(env_id, num_envs=8, **kwargs)
    vec.reset(seed=0)
    vec.action_space.seed(0)

    def run(steps: int) -> float:
        start = time.perf_counter()
        for _ in range(max(1, steps // 8)):
            vec.step(vec.action_space.sample())
        return time.perf_counter() - start

    return run


def measure(env_id: str, steps: int, rounds: int) -> dict[str, float]:
    _, core = server_benches(env_id)
    benches = {"core": core}
    benches |= {f"worker {k}": worker_bench(env_id, k) for k in KS}
    benches["make_vec 8"] = vec_bench(env_id)
    benches["SyncVectorEnv 8 (in-process)"] = vec_bench(env_id, vectorization_mode="sync")
    benches["SyncVectorEnv 8 (gRPC)"] = vec_bench(
        env_id, vectorization_mode="sync", provider=EmbeddedServerProvider()
    )
    best = dict.fromkeys(benches, 0.0)
    share = dict.fromkeys(benches, 0.0)
    for _ in range(rounds):
        for name, run in benches.items():
            n = steps if not name.startswith(("make_vec", "Sync")) else steps // 8 * 8
            CORE_SECONDS[0] = 0.0
            seconds = run(n)
            if n / seconds > best[name]:
                best[name], share[name] = n / seconds, min(1.0, CORE_SECONDS[0] / seconds)
    return {**best, **{f"{name} share": value for name, value in share.items()}}


def report(results: dict[str, dict[str, float]], args: argparse.Namespace) -> str:
    names = [n for n in next(iter(results.values())) if not n.endswith(" share")]
    head = (
        "| | "
        + " | ".join(f"`{e.split('/')[1]}` steps/s | x core | core share" for e in results)
        + " |"
    )
    rows = []
    for name in names:
        cells = []
        for r in results.values():
            cells.append(f"{r[name]:.0f} | {r[name] / r['core']:.2f} | {r[name + ' share']:.2f}")
        rows.append(f"| {name} | " + " | ".join(cells) + " |")
    vec = [
        f"| `{e.split('/')[1]}` | {r['make_vec 8'] / r['SyncVectorEnv 8 (gRPC)']:.2f} | "
        f"{r['make_vec 8'] / r['SyncVectorEnv 8 (in-process)']:.2f} |"
        for e, r in results.items()
    ]
    return "\n".join([
        "## The fast experience path: K envs per worker, make_vec",
        "",
        f"Date {datetime.date.today().isoformat()}; machine: {machine()}; Python "
        f"{sys.version.split()[0]}.",
        f"Command: `nice python benchmarks/fast_path.py --steps {args.steps} --rounds "
        f"{args.rounds}` (env steps/s, best of the alternating rounds, one process, one core).",
        "",
        head, "|---|" + "---|---|---|" * len(results), *rows,
        "",
        "| env | make_vec(8) / SyncVectorEnv(8, gRPC envs) | make_vec(8) / SyncVectorEnv(8, "
        "in-process envs) |",
        "|---|---|---|",
        *vec,
        "",
    ])  # fmt: skip


if __name__ == "__main__":
    torch.set_num_threads(1)  # one core, as in a Ray actor (Ray sets OMP_NUM_THREADS=1)
    time_cores()
    run_paper_envs(__doc__, measure, report, steps=1000)
