"""What rendering costs: stepping with and without it, and the time of one frame.

    nice python benchmarks/render.py [--steps 1500] [--rounds 5] [--before COMMIT]
    python benchmarks/render.py --png docs/img      # the README's frames (one per robot)

Three figures for the paper's two envs (Sim variant, embedded robot server, simulated time):

* **step cost of ``render_mode=None`` against the code before rendering existed**: the same
  step loop runs in child processes that import ``robogym_ray`` from this checkout or from
  ``--before`` (a commit exported with ``git archive`` to a temporary folder), alternating
  round by round so that the machine's drift hits both alike; ratio = now / before.
* **step cost of ``render_mode="rgb_array"`` when no frame is asked for** (the env keeps the
  robot's path for the next frame), against ``None`` in the same process, alternating.
* **frame time** of ``env.render()`` at 640x480 after each step (median and 95th percentile).

Each child times only ``env.step`` (random actions, resets excluded), so imports and server
start-up do not count.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PAPER_ENVS = (
    "RoboGymRay/ObstacleAvoidanceMir100Sim-v0",
    "RoboGymRay/EndEffectorPositioningUR10Sim-v0",
)
ROOT = Path(__file__).resolve().parent.parent


def step_seconds(env_id: str, steps: int, render_mode: str | None, frames: bool) -> dict:
    """Time ``steps`` env steps (and a render after each when ``frames``) in this process."""
    import gymnasium as gym

    import robogym_ray  # noqa: F401 - registers the ids

    kwargs = {} if render_mode is None else {"render_mode": render_mode}
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)
    step_s, frame_s = 0.0, []
    for _ in range(steps):
        action = env.action_space.sample()
        start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        step_s += time.perf_counter() - start
        if frames:
            start = time.perf_counter()
            frame = env.render()
            frame_s.append(time.perf_counter() - start)
            assert frame.shape == (480, 640, 3)
        if terminated or truncated:
            env.reset()
    env.close()
    return {"steps_per_s": steps / step_s, "frame_s": frame_s}


def child(env_id: str, steps: int, render_mode: str | None, pythonpath: str | None) -> dict:
    """``step_seconds`` in a fresh interpreter that imports robogym_ray from ``pythonpath``
    (this checkout when None); the result says which copy it imported."""
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath + os.pathsep + env.get("PYTHONPATH", "")
    code = (
        "import json, sys; import robogym_ray; from render import step_seconds; "
        "mode = None if sys.argv[3] == 'None' else sys.argv[3]; "
        "out = step_seconds(sys.argv[1], int(sys.argv[2]), mode, False); "
        "print(json.dumps(out | {'package': robogym_ray.__file__}))"
    )
    here = Path(__file__).parent  # the cwd: `-c` puts it first on sys.path, not a checkout
    out = subprocess.run(
        [sys.executable, "-c", code, env_id, str(steps), str(render_mode)],
        env=env, cwd=here, check=True, capture_output=True, text=True,
    )  # fmt: skip
    result = json.loads(out.stdout.strip().splitlines()[-1])
    expected = Path(pythonpath) if pythonpath else ROOT
    if not Path(result["package"]).is_relative_to(expected):
        raise RuntimeError(f"imported {result['package']}, wanted the copy under {expected}")
    return result


def export(commit: str, into: Path) -> None:
    """The package as it was at ``commit``, unpacked into ``into``."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", commit, "robogym_ray"], check=True, capture_output=True
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)


def spread(ratios: list[float]) -> str:
    """Median of the round-by-round ratios, and their range."""
    return f"{statistics.median(ratios):.2f} ({min(ratios):.2f}-{max(ratios):.2f})"


def compare(args: argparse.Namespace) -> list[str]:
    rows = [
        "| env | steps/s before | `None` now | now / before (min-max) | `rgb_array`, no frame "
        "| rgb_array / None (min-max) | frame at 640x480: median | p95 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    with tempfile.TemporaryDirectory() as old:
        export(args.before, Path(old))
        for env_id in PAPER_ENVS:
            runs: dict[str, list[float]] = {"before": [], "none": [], "rgb": []}
            for _ in range(args.rounds):  # A B C A B C ...: drift hits all three alike
                runs["before"].append(child(env_id, args.steps, None, old)["steps_per_s"])
                runs["none"].append(child(env_id, args.steps, None, None)["steps_per_s"])
                runs["rgb"].append(child(env_id, args.steps, "rgb_array", None)["steps_per_s"])
            ratio_old = [n / b for n, b in zip(runs["none"], runs["before"], strict=True)]
            ratio_rgb = [r / n for r, n in zip(runs["rgb"], runs["none"], strict=True)]
            frames = sorted(step_seconds(env_id, args.steps, "rgb_array", True)["frame_s"])
            med, p95 = statistics.median(frames), frames[int(0.95 * (len(frames) - 1))]
            rows.append(
                f"| `{env_id}` | {statistics.median(runs['before']):,.0f} "
                f"| {statistics.median(runs['none']):,.0f} | {spread(ratio_old)} "
                f"| {statistics.median(runs['rgb']):,.0f} | {spread(ratio_rgb)} "
                f"| {1e3 * med:.1f} ms | {1e3 * p95:.1f} ms |"
            )
            print(rows[-1], flush=True)
    return rows


def write_pngs(directory: Path) -> None:
    """One frame of each robot at 640x480, mid-episode, for the README."""
    import gymnasium as gym
    import numpy as np
    from PIL import Image

    import robogym_ray  # noqa: F401

    directory.mkdir(parents=True, exist_ok=True)
    shots = {
        # A straight drive: the frame shows the path behind the robot and its laser returns.
        "mir100.png": ("RoboGymRay/ObstacleAvoidanceMir100Sim-v0", 3, np.array([0.6, 0.0]), 40),
        # Shoulder and elbow turning: the arm leaves its start pose toward the camera.
        "ur10.png": (
            "RoboGymRay/EndEffectorPositioningUR10Sim-v0", 1,
            np.array([0.3, -0.4, 0.5, 0.0, 0.0, 0.0]), 25,
        ),
    }  # fmt: skip
    for name, (env_id, seed, action, steps) in shots.items():
        env = gym.make(env_id, render_mode="rgb_array")
        env.reset(seed=seed)
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(action.astype(np.float32))
            if terminated or truncated:
                break
        Image.fromarray(env.render()).save(directory / name, optimize=True)
        env.close()
        print(directory / name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=1500, help="env steps per child run")
    parser.add_argument("--rounds", type=int, default=5, help="alternating rounds")
    parser.add_argument(
        "--before", default="8712143", help="commit before rendering (the last one without it)"
    )
    parser.add_argument("--png", type=Path, help="write the README's frames here and stop")
    args = parser.parse_args()
    if args.png:
        write_pngs(args.png)
        return
    rows = compare(args)
    cmd = "python benchmarks/render.py " + " ".join(sys.argv[1:])
    print(f"\n{datetime.date.today()}, {platform.node()}, {os.cpu_count()} CPUs: `{cmd}`")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
