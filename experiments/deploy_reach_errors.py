"""Tracking errors of a policy on Isaac Lab's deploy reach: ``wrist_3_link``'s position and
rotation error to each pose command at the end of its 4-s window (3 windows per 12-s episode),
median and 90th percentile over all windows of N episodes (episode i resets with seed + i).

    # a trained run's policy (learner.pt, or an exported policy.pt / policy.onnx with its .json)
    python experiments/deploy_reach_errors.py \\
        runs/deploy/isaac-deploy-reach-ur10e/checkpoints/learner.pt --out results/deploy-reach-d4pg
    # the baseline: uniformly random actions over the env's action space
    python experiments/deploy_reach_errors.py --random --out results/deploy-reach-random
    # and the arm holding still (action 0), what a policy that learned only to spare its
    # action penalty scores
    python experiments/deploy_reach_errors.py --hold --out results/deploy-reach-hold
    # the reference line: the scripted expert (damped least-squares IK, envs/ur_deploy_expert.py)
    python experiments/deploy_reach_errors.py --expert --out results/deploy-reach-expert
    # an Isaac Lab export, checked against its IO descriptors first
    python experiments/deploy_reach_errors.py policy.pt --isaac-lab \\
        --io-descriptors exported/isaac_deploy_reach_ur10e_v0_IO_descriptors.yaml

Writes OUT/errors.json (the summary and every window's errors) and prints the summary as JSON.

    # the figure: cumulative distributions of the window-end errors, policies side by side
    python experiments/deploy_reach_errors.py plot docs/img/deploy_reach_errors.png \
        D4PG=results/deploy-reach-d4pg/errors.json random=results/deploy-reach-random/errors.json
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

ENV_ID = "RoboGymRay/IsaacDeployReachUR10eSim-v0"


def summarize(windows: Sequence[tuple[float, float]]) -> dict[str, Any]:
    """Median and 90th percentile of the position (m) and rotation (rad) errors."""
    arr = np.asarray(windows, dtype=np.float64).reshape(-1, 2)
    out: dict[str, Any] = {"windows": len(arr)}
    for i, name in enumerate(("position_error_m", "rotation_error_rad")):
        col = arr[:, i]
        out[name] = {
            "median": round(float(np.median(col)), 4) if col.size else None,
            "p90": round(float(np.percentile(col, 90)), 4) if col.size else None,
        }
    return out


def window_errors(
    env: Any, policy: Callable[[np.ndarray], np.ndarray], episodes: int, seed: int
) -> list[list[tuple[float, float]]]:
    """Each episode's window-end errors (m, rad), from the one greedy-episode loop."""
    from robogym_ray.experience.episodes import greedy_episode

    episodes_run = (greedy_episode(env, policy, seed + i) for i in range(episodes))
    return [[(p, r) for p, r in ep.window_errors or []] for ep in episodes_run]


def load(args: argparse.Namespace, env: Any) -> tuple[Callable[[np.ndarray], np.ndarray], str]:
    """The policy on the [-1, 1] scale of the greedy loop, and its label."""
    if args.random:
        rng = np.random.default_rng(args.seed)
        return (lambda obs: rng.uniform(-1.0, 1.0, env.action_space.shape)), "random"
    if args.hold:  # action 0 (the bounds are symmetric): every target the measured joints
        return (lambda obs: np.zeros(env.action_space.shape)), "hold"
    if args.expert:  # its actions are the env's, [-1, 1]
        from robogym_ray.envs.ur_deploy_expert import DeployReachExpert, numpy_policy

        order = getattr(env.unwrapped, "quat_order", "xyzw")
        return numpy_policy(DeployReachExpert(order)), "expert"
    if args.isaac_lab:
        from robogym_ray.isaac_lab import IsaacLabPolicy

        return IsaacLabPolicy(args.policy, args.io_descriptors).unit_policy(env), args.policy
    from robogym_ray.export import load_policy

    return load_policy(args.policy), args.policy


def plot(errors: dict[str, str], out: str | Path) -> Path:
    """Cumulative distributions of the window-end errors of each ``LABEL=errors.json``: the
    share of command windows that ended within x metres (left) and x radians (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    legend = 0.3 * -(-len(errors) // 2)  # inches: a row of two policies each 0.3
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8 + legend))
    for label, path in errors.items():
        record = json.loads(Path(path).read_text())
        arr = np.asarray([w for ep in record["per_episode"] for w in ep]).reshape(-1, 2)
        share = np.arange(1, len(arr) + 1) / len(arr)
        for ax, col in zip(axes, arr.T, strict=True):
            ax.plot(np.sort(col), share, label=f"{label} ({len(arr)} windows)")
    units = ("position error at the window's end (m)", "rotation error at the window's end (rad)")
    for ax, unit in zip(axes, units, strict=True):
        ax.set_xlabel(unit)
        ax.set_ylabel("share of command windows")
        ax.grid(alpha=0.3)
    # Below the axes: with more than a few policies a legend inside covers the curves.
    fig.legend(*axes[0].get_legend_handles_labels(), loc="lower center", ncol=2, frameon=False)
    fig.suptitle("IsaacDeployReachUR10e: wrist_3_link against each 4-s pose command")
    fig.tight_layout(rect=(0, legend / (3.8 + legend), 1, 1))
    out = Path(out)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    import gymnasium as gym

    import robogym_ray  # noqa: F401 - registers the ids

    if argv is None:
        argv = sys.argv[1:]
    if argv and argv[0] == "plot":  # plot OUT.png LABEL=errors.json ...
        pairs = dict(item.split("=", 1) for item in argv[2:])
        print(plot(pairs, argv[1]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy", nargs="?", help="learner.pt, exported policy, or Isaac Lab's.")
    parser.add_argument("--random", action="store_true", help="Uniformly random actions.")
    parser.add_argument("--hold", action="store_true", help="Action 0: the arm holds still.")
    parser.add_argument("--expert", action="store_true", help="The scripted IK expert.")
    parser.add_argument("--isaac-lab", action="store_true", help="POLICY is an Isaac Lab export.")
    parser.add_argument("--io-descriptors", default=None, help="Its IO descriptors (YAML).")
    parser.add_argument("--quat-order", default="xyzw", choices=("xyzw", "wxyz"),
                        help="The command quaternion's order the policy takes (wxyz: Isaac Lab "
                        "2.x).")  # fmt: skip
    parser.add_argument("--env-id", default=ENV_ID, help="The task (default: %(default)s).")
    parser.add_argument("--episodes", type=int, default=100, help="Episodes (default 100).")
    parser.add_argument("--seed", type=int, default=1000, help="Episode i resets with seed + i.")
    parser.add_argument("--max-steps", type=int, default=None, help="Step limit (default 720).")
    parser.add_argument("--out", default=None, help="Folder for errors.json.")
    args = parser.parse_args(argv)
    if args.random + args.hold + args.expert + (args.policy is not None) != 1:
        parser.error("give one of POLICY, --random, --hold or --expert")
    kwargs: dict[str, Any] = {"isaac_quat_order": args.quat_order}
    if args.max_steps is not None:
        kwargs["max_steps"] = args.max_steps
    env = gym.make(args.env_id, **kwargs)
    try:
        policy, label = load(args, env)
        per_episode = window_errors(env, policy, args.episodes, args.seed)
    finally:
        env.close()
    summary = {
        "env_id": args.env_id,
        "policy": label,
        "episodes": args.episodes,
        **summarize([w for ep in per_episode for w in ep]),
    }
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        record = {**summary, "per_episode": per_episode}
        (Path(args.out) / "errors.json").write_text(json.dumps(record, indent=1))
    print(json.dumps(summary), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
