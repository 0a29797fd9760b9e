"""Sim-to-sim: an FR3 policy trained on PyBullet, evaluated there and on franky-sim (MuJoCo).

The second evaluation goes the way a real FR3 would: ``robogym-ray evaluate --rs-address`` at
``robogym-ray serve --robot fr3 --hardware franky`` whose arm is franky-sim, speaking
libfranka's network protocol, in real time. The same 100 seeded episodes on both, so the pair
differs only in what is behind the server: PyBullet's kinematic arm, or libfranka's joint
impedance controller on a MuJoCo arm with dynamics.

    python experiments/fr3_sim_to_sim.py runs/fr3/fr3-seed0 --out docs/results/fr3-sim-to-sim

It runs the three commands a user would type in three terminals (franky-sim, serve, evaluate),
then prints the pair: success rates and median final position errors.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from robogym_ray.robots.panda.franky_sim import FrankySim
from robogym_ray.robots.serve import serve_process

ROB_ID = "RoboGymRay/EndEffectorPositioningFR3Rob-v0"


def evaluate(policy: str, out: Path, extra: list[str], episodes: int) -> dict:
    cmd = [sys.executable, "-m", "robogym_ray.cli", "evaluate", policy,
           "--episodes", str(episodes), "--out", str(out), *extra]  # fmt: skip
    print("$", " ".join(cmd[2:]), flush=True)
    subprocess.run(cmd, check=True)
    return json.loads((out / "evaluation.json").read_text())


def summary(result: dict) -> dict:
    keys = ("n_episodes", "median_position_error", "mean_length", "wall_s")
    return {"success_rate": result["rates"]["success_rate"], **{k: result.get(k) for k in keys}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("policy", help="the run's folder or its learner.pt")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--dynamics-factor", default="0.3", help="serve's reset dynamics")
    args = parser.parse_args()
    pybullet = evaluate(args.policy, args.out / "pybullet", [], args.episodes)
    with FrankySim() as sim:
        serve = ["--robot", "fr3", "--hardware", "franky", "--fci-host", sim.host,
                 "--dynamics-factor", args.dynamics_factor]  # fmt: skip
        print("$ python -m franky_sim.run_server -s mujoco --hostname", sim.host)
        print("$ robogym-ray serve", " ".join(serve), flush=True)
        with serve_process(serve, timeout_s=60.0) as address:
            extra = ["--env-id", ROB_ID, "--rs-address", address]
            franky = evaluate(args.policy, args.out / "franky-sim", extra, args.episodes)
    pair = {"pybullet": summary(pybullet), "franky-sim": summary(franky)}
    (args.out / "pair.json").write_text(json.dumps(pair, indent=2) + "\n")
    print(json.dumps(pair, indent=2))


if __name__ == "__main__":
    main()
