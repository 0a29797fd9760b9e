"""Peers: what a robo-gym user would run instead of this project's D4PG, on the same Sim ids,
on the same machine, for the same wall-clock budget, scored the same way.

    pip install -e ".[peers]"
    python experiments/peers.py train --algo sb3-td3 --problem navigation --minutes 50 --seed 0
    python experiments/peers.py evaluate runs/peers/navigation-sb3-td3-seed0

``train`` runs the algorithm as its users run it — Stable-Baselines3's documented defaults on one
env made with ``gymnasium.make`` (robo-gym's own example is ``TD3(MlpPolicy, env)``; TD3 gets the
Gaussian action noise, sigma 0.1, of SB3's TD3 example, without which it does not explore) — and
saves the policy every ``--save-every-min`` minutes of wall time, named by that time. Nothing is
evaluated on the training's clock. ``evaluate`` then scores every snapshot on ``--episodes``
greedy episodes with reset seeds ``--seed``, ``--seed`` + 1, ... (1000-1099, as ``robogym-ray
evaluate``), outcomes from ``info["final_status"]``, and writes ``curve.json``: success against
wall time, like the D4PG evaluator's curve. ``run.json`` has what explains a curve: env steps,
gradient updates per env step, env steps/s, the load average.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

PROBLEMS = {
    "navigation": "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
    "positioning": "RoboGymRay/EndEffectorPositioningUR10Sim-v0",
}
ALGOS = ("sb3-td3", "sb3-sac")
SNAPSHOT = "policy-{minutes:06.2f}min.zip"


def _sb3_class(algo: str) -> Any:
    import stable_baselines3 as sb3

    return {"sb3-td3": sb3.TD3, "sb3-sac": sb3.SAC}[algo]


def build(algo: str, env: gym.Env, seed: int) -> Any:
    """The algorithm with its library's defaults (see the module docstring for TD3's noise)."""
    kwargs: dict[str, Any] = {"seed": seed, "device": "cpu"}
    if algo == "sb3-td3":
        from stable_baselines3.common.noise import NormalActionNoise

        dims = env.action_space.shape[0]
        kwargs["action_noise"] = NormalActionNoise(np.zeros(dims), 0.1 * np.ones(dims))
    return _sb3_class(algo)("MlpPolicy", env, **kwargs)


def train(algo: str, problem: str, minutes: float, seed: int, out: Path,
          save_every_min: float = 5.0) -> dict[str, Any]:  # fmt: skip
    """Train until ``minutes`` of wall time are spent; snapshots under ``out/snapshots``."""
    from stable_baselines3.common.callbacks import BaseCallback

    import robogym_ray  # noqa: F401 - registers the ids

    snapshots = out / "snapshots"
    snapshots.mkdir(parents=True, exist_ok=True)
    env = gym.make(PROBLEMS[problem])
    model = build(algo, env, seed)
    load_before = os.getloadavg()

    class WallClock(BaseCallback):
        """Saves the policy at each ``save_every_min`` of wall time; stops at the budget."""

        def __init__(self) -> None:
            super().__init__()
            self.start = time.perf_counter()
            self.saved: list[dict[str, float]] = []

        def save(self, minutes: float) -> None:
            self.model.save(snapshots / SNAPSHOT.format(minutes=minutes))
            self.saved.append({"wall_min": round(minutes, 2), "env_steps": self.num_timesteps})

        def _on_step(self) -> bool:
            elapsed = (time.perf_counter() - self.start) / 60.0
            if elapsed >= save_every_min * (len(self.saved) + 1) and elapsed < minutes:
                self.save(save_every_min * (len(self.saved) + 1))
            if elapsed >= minutes:
                self.save(minutes)
                return False
            return True

    clock = WallClock()
    try:
        model.learn(total_timesteps=10**10, callback=clock)
    finally:
        env.close()
    wall_s = time.perf_counter() - clock.start
    record = {
        "algo": algo, "problem": problem, "env_id": PROBLEMS[problem], "seed": seed,
        "minutes": minutes, "wall_s": round(wall_s, 1), "env_steps": int(model.num_timesteps),
        "env_steps_per_s": round(model.num_timesteps / wall_s, 1),
        "gradient_updates": int(model._n_updates),
        "updates_per_env_step": round(model._n_updates / max(model.num_timesteps, 1), 3),
        "snapshots": clock.saved, "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "machine": f"{platform.node()}, {os.cpu_count()} cpus",
        "command": f"python experiments/peers.py train --algo {algo} --problem {problem} "
                   f"--minutes {minutes:g} --seed {seed}",
    }  # fmt: skip
    (out / "run.json").write_text(json.dumps(record, indent=2))
    return record


def evaluate(run_dir: Path, episodes: int = 100, seed: int = 1000) -> list[dict[str, Any]]:
    """Score every snapshot of a run on the same greedy episodes; writes ``curve.json``."""
    import robogym_ray  # noqa: F401 - registers the ids
    from robogym_ray.envs import outcomes
    from robogym_ray.evaluation import run_episodes
    from robogym_ray.learner.behaviour import from_env_action

    record = json.loads((run_dir / "run.json").read_text())
    algo_class = _sb3_class(record["algo"])
    env = gym.make(record["env_id"])
    low, high = env.action_space.low, env.action_space.high
    curve = []
    try:
        for snap in record["snapshots"]:
            path = run_dir / "snapshots" / SNAPSHOT.format(minutes=snap["wall_min"])
            model = algo_class.load(path, device="cpu")

            def policy(obs: np.ndarray, model: Any = model) -> np.ndarray:
                # SB3 answers in the env's units; run_episodes takes [-1, 1].
                return from_env_action(model.predict(obs, deterministic=True)[0], low, high)

            statuses = [e.final_status for e in run_episodes(policy, env, episodes, seed)]
            curve.append({**snap, "episodes": episodes, **outcomes.rates(statuses)})
            print(json.dumps(curve[-1]), flush=True)
    finally:
        env.close()
    (run_dir / "curve.json").write_text(json.dumps(curve, indent=2))
    return curve


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="train one peer for a wall-clock budget")
    t.add_argument("--algo", choices=ALGOS, required=True)
    t.add_argument("--problem", choices=sorted(PROBLEMS), required=True)
    t.add_argument("--minutes", type=float, default=50.0, help="wall-clock budget")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--save-every-min", type=float, default=5.0)
    t.add_argument("--out", default=None, help="default: runs/peers/PROBLEM-ALGO-seedSEED")
    e = sub.add_parser("evaluate", help="score a run's snapshots (writes curve.json)")
    e.add_argument("run_dir")
    e.add_argument("--episodes", type=int, default=100)
    e.add_argument("--seed", type=int, default=1000, help="first reset seed")
    args = parser.parse_args(argv)
    if args.command == "train":
        out = Path(args.out or f"runs/peers/{args.problem}-{args.algo}-seed{args.seed}")
        record = train(args.algo, args.problem, args.minutes, args.seed, out, args.save_every_min)
        print(json.dumps(record))
    else:
        evaluate(Path(args.run_dir), args.episodes, args.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
