"""Peers: what a robo-gym user would run instead of this project's D4PG, on the same Sim ids,
on the same machine, for the same wall-clock budget, scored the same way.

    pip install -e ".[peers]"
    python experiments/peers.py train --algo sb3-td3 --problem navigation --minutes 50 --seed 0
    python experiments/peers.py evaluate runs/peers/navigation-sb3-td3-seed0
    python experiments/peers.py evaluate RUN   # a robogym-ray train run: its timed snapshots
    python experiments/peers.py exploration RUN   # an SB3 SAC or RLlib PPO run's exploration

``train`` runs the algorithm as its users run it — Stable-Baselines3's documented defaults on one
env made with ``gymnasium.make`` (robo-gym's own example is ``TD3(MlpPolicy, env)``; TD3 gets the
Gaussian action noise, sigma 0.1, of SB3's TD3 example, without which it does not explore), or
RLlib's PPO / SAC defaults with one env runner per core (``peers_rllib.py``; RLlib needs its own
virtual environment, ``requirements/peers-rllib.txt``) — and saves the policy every
``--save-every-min`` minutes of wall time, named by that time. Nothing is evaluated on the
training's clock. ``run.json``, rewritten at every snapshot, has what explains a curve: env
steps, gradient updates per env step, env steps/s, the load average.

``evaluate`` scores every snapshot on ``--episodes`` greedy episodes with reset seeds
``--seed``, ``--seed`` + 1, ... (1000-1099, as ``robogym-ray evaluate``), outcomes from
``info["final_status"]``, and writes ``curve.json``: success against wall time. Given a
``robogym-ray train`` run it scores the policies that run kept every ``policy_snapshot_every_s``
(default 300 s), so D4PG's curve and the peers' are measured alike.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

PROBLEMS = {
    "navigation": "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
    "positioning": "RoboGymRay/EndEffectorPositioningUR10Sim-v0",
}
SB3_ALGOS = ("sb3-td3", "sb3-sac")
ALGOS = (*SB3_ALGOS, "rllib-ppo", "rllib-sac")


@functools.cache  # executed once: evaluate and exploration ask for it at every snapshot
def _rllib() -> Any:
    """``peers_rllib.py`` beside this file (imported by path: tests load this script by path)."""
    import importlib.util

    path = Path(__file__).with_name("peers_rllib.py")
    spec = importlib.util.spec_from_file_location("peers_rllib", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def snapshot_path(run_dir: Path, algo: str, minutes: float) -> Path:
    """Named as a training run's timed snapshots are, + ".zip" (SB3) or a folder (RLlib)."""
    from robogym_ray.training.selection import TIMED_NAME

    name = TIMED_NAME.format(minutes=minutes)
    return run_dir / "snapshots" / (f"{name}.zip" if algo in SB3_ALGOS else name)


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
    model = _sb3_class(algo)("MlpPolicy", env, **kwargs)
    # SB3's default logger writes nothing at verbose 0 yet makes an empty /tmp/SB3-<date>
    # folder per run; the same logger without a folder records the same values, leaves none.
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


class Run:
    """What ``run.json`` says of a run, rewritten at every snapshot: a run cut short (a reboot, a
    kill) keeps the record of what it saved, and its snapshots can still be evaluated."""

    def __init__(self, algo: str, problem: str, minutes: float, seed: int, out: Path,
                 save_every_min: float) -> None:  # fmt: skip
        if save_every_min < 1 / 60:  # names have 0.01-minute resolution
            raise SystemExit(f"--save-every-min {save_every_min:g}: at least 1/60 (one second)")
        self.out, self.start, self.saved = out, time.perf_counter(), []
        self.minutes, self.every_min, self.taken = minutes, save_every_min, 0
        self.head = {
            "algo": algo, "problem": problem, "env_id": PROBLEMS[problem], "seed": seed,
            "minutes": minutes, "load_average_before": list(os.getloadavg()),
            "machine": f"{platform.node()}, {os.cpu_count()} cpus",
            "command": f"python experiments/peers.py train --algo {algo} --problem {problem} "
                       f"--minutes {minutes:g} --seed {seed}",
        }  # fmt: skip

    def elapsed_min(self) -> float:
        return (time.perf_counter() - self.start) / 60.0

    def due(self) -> float | None:
        """The mark (minutes) to save now: the budget's end, or the latest mark passed and not
        yet saved (a long iteration that passes two marks saves the later one only: a name
        never holds later weights than its time), else None."""
        elapsed = self.elapsed_min()
        if elapsed >= self.minutes:
            return self.minutes
        mark = int(elapsed // self.every_min)
        if mark <= self.taken:
            return None
        self.taken = mark
        return mark * self.every_min

    def saved_mark(self, mark: float, env_steps: int) -> None:
        self.saved.append({"wall_min": round(mark, 2), "env_steps": int(env_steps),
                           "saved_at_min": round(self.elapsed_min(), 2)})  # fmt: skip

    def write(self, counters: dict[str, Any], complete: bool) -> dict[str, Any]:
        """``counters``: env_steps, updates_per_env_step and what explains them."""
        wall_s = time.perf_counter() - self.start
        record = {
            **self.head, "complete": complete, "wall_s": round(wall_s, 1), **counters,
            "env_steps_per_s": round(counters["env_steps"] / wall_s, 1),
            "snapshots": list(self.saved), "load_average_after": list(os.getloadavg()),
        }  # fmt: skip
        from robogym_ray.storage import write_bytes

        # Replaced whole: a reader never sees half a record.
        data = json.dumps(record, indent=2).encode()
        write_bytes(self.out / "run.json", data, "run record")
        return record


def train(algo: str, problem: str, minutes: float, seed: int, out: Path,
          save_every_min: float = 5.0, layout: tuple[int | None, int] = (None, 1),
          ) -> dict[str, Any]:  # fmt: skip
    """Train until ``minutes`` of wall time are spent; snapshots under ``out/snapshots``.

    ``layout``: RLlib's (env runners, envs per runner); None runners is one per core."""
    import robogym_ray  # noqa: F401 - registers the ids

    (out / "snapshots").mkdir(parents=True, exist_ok=True)
    if algo in SB3_ALGOS:
        if layout != (None, 1):
            raise SystemExit(f"--env-runners / --envs-per-runner are RLlib's; {algo} has one env")
        return _train_sb3(algo, problem, minutes, seed, out, save_every_min)
    return _train_rllib(algo, problem, minutes, seed, out, save_every_min, layout)


def _train_sb3(algo: str, problem: str, minutes: float, seed: int, out: Path,
               save_every_min: float) -> dict[str, Any]:  # fmt: skip
    from stable_baselines3.common.callbacks import BaseCallback

    env = gym.make(PROBLEMS[problem])
    model = build(algo, env, seed)

    def counters() -> dict[str, Any]:
        steps, updates = int(model.num_timesteps), int(model._n_updates)
        return {"env_steps": steps, "gradient_updates": updates,
                "updates_per_env_step": round(updates / max(steps, 1), 3)}  # fmt: skip

    run = Run(algo, problem, minutes, seed, out, save_every_min)

    class WallClock(BaseCallback):
        """Saves the policy at each ``save_every_min`` of wall time; stops at the budget."""

        def _on_step(self) -> bool:
            mark = run.due()
            if mark is not None:
                self.model.save(snapshot_path(out, algo, mark))
                run.saved_mark(mark, self.num_timesteps)
                run.write(counters(), complete=False)
            return mark != minutes

    try:
        model.learn(total_timesteps=10**10, callback=WallClock())
    finally:
        env.close()
    return run.write(counters(), complete=True)


def _train_rllib(algo: str, problem: str, minutes: float, seed: int, out: Path,
                 save_every_min: float, layout: tuple[int | None, int],
                 ) -> dict[str, Any]:  # fmt: skip
    rllib = _rllib()
    algo_obj = rllib.build(algo, PROBLEMS[problem], seed, *layout)
    sizes = rllib.batch_sizes(algo_obj)
    run = Run(algo, problem, minutes, seed, out, save_every_min)
    if layout != (None, 1):
        run.head["command"] += f" --env-runners {layout[0]} --envs-per-runner {layout[1]}"

    def counters(c: dict[str, Any]) -> dict[str, Any]:
        # Samples trained count every minibatch of every epoch: / minibatch = gradient updates.
        updates = c["samples_trained"] / sizes["minibatch_size"]
        return {**c, **sizes, "gradient_updates": int(updates),
                "updates_per_env_step": round(updates / max(c["env_steps"], 1), 3)}  # fmt: skip

    try:
        while True:
            # An iteration is RLlib's unit of work: a snapshot comes at the first iteration's
            # end past its mark ("saved_at_min" says when; curves are drawn at that time).
            c = rllib.counters(algo_obj.train())
            mark = run.due()
            if mark is not None:
                algo_obj.save_to_path(snapshot_path(out, algo, mark).resolve())
                run.saved_mark(mark, c["env_steps"])
                record = run.write(counters(c), complete=mark == minutes)
                if mark == minutes:
                    return record
    finally:
        algo_obj.stop()


def evaluate(run_dir: str | Path, episodes: int = 100, seed: int = 1000) -> list[dict[str, Any]]:
    """Score every snapshot of a run on the same greedy episodes; writes ``curve.json``.

    ``run_dir``: a peer's (it has ``run.json``) or a ``robogym-ray train`` run's (its timed
    ``checkpoints/policy-MMM.MMmin.pt``, ``--policy-snapshot-every-s``): every curve is then
    scored the same way.
    """
    import robogym_ray  # noqa: F401 - registers the ids
    from robogym_ray.envs import outcomes
    from robogym_ray.evaluation import run_episodes
    from robogym_ray.storage import RunStorage, is_uri, local_run

    location, run_dir = str(run_dir), local_run(run_dir)  # an object store's: downloaded
    env_id, snapshots = _snapshots(run_dir)
    env = gym.make(env_id)
    curve = []
    try:
        for snap, load in snapshots:
            statuses = [e.final_status for e in run_episodes(load(env), env, episodes, seed)]
            curve.append({**snap, "episodes": episodes, **outcomes.rates(statuses)})
            print(json.dumps(curve[-1]), flush=True)
    finally:
        env.close()
    (run_dir / "curve.json").write_text(json.dumps(curve, indent=2))
    if is_uri(location):  # back beside the snapshots it scored
        data = json.dumps(curve, indent=2).encode()
        RunStorage(location).write_bytes("curve.json", data, "curve")
    return curve


def exploration(run_dir: Path, episodes: int = 100, seed: int = 1000,
                samples: int = 100) -> list[dict[str, Any]]:  # fmt: skip
    """How much an SB3 SAC or RLlib PPO run still explores at each snapshot, on the first
    observations of the evaluation episodes: its policy's mean standard deviation (SAC: before
    tanh; PPO: of its Gaussian, before RLlib clips a sample to [-1, 1]) and the standard
    deviation of its sampled actions in [-1, 1] (``samples`` per observation, a fixed torch
    seed): the one comparable with TD3's Gaussian noise (sigma 0.1) and D4PG's workers'
    sigmas. SAC adds its entropy coefficient (tuned by SAC itself), PPO the share of sampled
    action components clipped to a bound. Writes ``exploration.json``."""
    import torch

    import robogym_ray  # noqa: F401 - registers the ids

    record = json.loads((run_dir / "run.json").read_text())
    if (algo := record["algo"]) not in ("sb3-sac", "rllib-ppo"):
        raise SystemExit(
            f"{run_dir}: exploration is measured for sb3-sac and rllib-ppo runs, not {algo}"
        )
    env = gym.make(record["env_id"])
    try:
        obs = np.stack([env.reset(seed=seed + i)[0] for i in range(episodes)])
    finally:
        env.close()
    points = []
    for snap in record["snapshots"]:
        path = snapshot_path(run_dir, algo, snap["wall_min"])
        if algo == "sb3-sac":
            model = _sb3_class(algo).load(path, device="cpu")
            with torch.no_grad():
                mean, log_std, _ = model.actor.get_action_dist_params(
                    model.policy.obs_to_tensor(obs)[0]
                )
            std, squash = log_std.exp(), torch.tanh  # SAC's squashed Gaussian
            extra = {"ent_coef": round(float(model.log_ent_coef.detach().exp()), 5)}
        else:
            mean, std = (torch.as_tensor(a) for a in _rllib().gaussian(path, obs))
            extra, squash = {}, lambda a: a.clamp(-1.0, 1.0)  # RLlib clips (normalize_actions)
        noise = torch.randn((samples, *mean.shape), generator=torch.Generator().manual_seed(0))
        actions = squash(mean + std * noise)
        if algo == "rllib-ppo":
            extra["clipped_share"] = round(float((actions.abs() >= 1.0).float().mean()), 4)
        points.append({"wall_min": snap["wall_min"], "env_steps": snap["env_steps"], **extra,
                       "policy_std": round(float(std.mean()), 4),
                       "action_std": round(float(actions.std(0).mean()), 4)})  # fmt: skip
        print(json.dumps(points[-1]), flush=True)
    (run_dir / "exploration.json").write_text(json.dumps(points, indent=2))
    return points


Loader = Callable[[gym.Env], Callable[[np.ndarray], np.ndarray]]


def _snapshots(run_dir: Path) -> tuple[str, list[tuple[dict[str, Any], Loader]]]:
    """The run's env id, and each snapshot's record with a loader of its greedy policy
    (``obs -> action in [-1, 1]``, what ``run_episodes`` takes)."""
    if (run_dir / "run.json").exists():
        record = json.loads((run_dir / "run.json").read_text())
        algo = record["algo"]

        def load(snap: dict[str, Any]) -> Loader:
            path = snapshot_path(run_dir, algo, snap["wall_min"])
            if algo not in SB3_ALGOS:
                return lambda env: _rllib().load_policy(path)
            from robogym_ray.learner.behaviour import from_env_action

            def sb3(env: gym.Env) -> Callable[[np.ndarray], np.ndarray]:
                model = _sb3_class(algo).load(path, device="cpu")
                low, high = env.action_space.low, env.action_space.high
                # SB3 answers in the env's units.
                return lambda obs: from_env_action(model.predict(obs, deterministic=True)[0],
                                                   low, high)  # fmt: skip

            return sb3

        return record["env_id"], [(snap, load(snap)) for snap in record["snapshots"]]
    from robogym_ray.export import env_id_of_run, load_policy
    from robogym_ray.learner.checkpoint import CHECKPOINT_NAME, read
    from robogym_ray.training.selection import mark_minutes

    named = [(mark_minutes(p.name), p) for p in (run_dir / "checkpoints").glob("policy-*min.pt")]
    paths = [p for m, p in sorted((m, p) for m, p in named if m is not None)]  # by time
    if not paths:
        raise SystemExit(
            f"{run_dir}: no run.json (a peer's run) and no checkpoints/policy-*min.pt (a "
            "robogym-ray train run with --policy-snapshot-every-s)"
        )
    env_id = env_id_of_run(paths[0])
    if env_id is None:
        raise SystemExit(f"{run_dir}: no config.json with the run's task")
    snaps = []
    for path in paths:
        if "snapshot" not in (state := read(path)):
            raise SystemExit(f"{path}: not a timed snapshot (no snapshot record in it)")
        snap = {k: v for k, v in state["snapshot"].items() if k != "path"}
        snaps.append((snap, lambda env, path=path: load_policy(path)))
    # The run's final policy (learner.pt: the average, as the snapshots), at the time the run
    # ended, when that is past the last mark: a run's curve ends where its training did.
    summary = run_dir / "summary.json"
    if summary.exists():
        end = json.loads(summary.read_text())
        last = max((s.get("saved_at_min", s["wall_min"]) for s, _ in snaps), default=0.0)
        final = run_dir / "checkpoints" / CHECKPOINT_NAME
        if final.is_file() and end["wall_s"] / 60 > last + 0.1:
            at = round(end["wall_s"] / 60, 2)
            snap = {"wall_min": at, "saved_at_min": at, "learner_steps": end["learner_steps"],
                    "env_steps": end["env_steps"], "final": True}  # fmt: skip
            snaps.append((snap, lambda env: load_policy(final)))
    return env_id, snaps


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
    t.add_argument(
        "--env-runners",
        type=int,
        default=None,
        metavar="N",
        help="RLlib only: env runners (default: one per core, RLlib's example)",
    )
    t.add_argument("--envs-per-runner", type=int, default=1, metavar="K",
                   help="RLlib only: envs in each env runner (default 1, RLlib's)")  # fmt: skip
    e = sub.add_parser("evaluate", help="score a run's snapshots (writes curve.json)")
    x = sub.add_parser("exploration", help="an SB3 SAC or RLlib PPO run's policy std and "
                       "sampled actions' std per snapshot (SAC: its entropy coefficient; PPO: "
                       "the share of samples clipped), on the evaluation episodes' first "
                       "observations (writes exploration.json)")  # fmt: skip
    for p in (e, x):  # the same episodes: exploration reads where evaluate scores
        p.add_argument("run_dir")
        p.add_argument("--episodes", type=int, default=100)
        p.add_argument("--seed", type=int, default=1000, help="first reset seed")
    args = parser.parse_args(argv)
    if args.command == "train":
        out = Path(args.out or f"runs/peers/{args.problem}-{args.algo}-seed{args.seed}")
        for flag, value, low in (("--env-runners", args.env_runners, 0),
                                 ("--envs-per-runner", args.envs_per_runner, 1)):  # fmt: skip
            if value is not None and value < low:
                parser.error(f"{flag} {value}: expected >= {low}")
        layout = (args.env_runners, args.envs_per_runner)
        record = train(args.algo, args.problem, args.minutes, args.seed, out,
                       args.save_every_min, layout)  # fmt: skip
        print(json.dumps(record))
    elif args.command == "exploration":
        exploration(Path(args.run_dir), args.episodes, args.seed)
    else:
        evaluate(args.run_dir, args.episodes, args.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
