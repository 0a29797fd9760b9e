"""experiments/reach_at_rest.py on the real UR10 server and the real UR10e servo: an arm held
still measures as still and a policy that alternates its targets (or swings its actions) as
moving, and the script writes its summary and rows for both tasks."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from robogym_ray.learner.behaviour import from_env_action
from tests.experiments.conftest import save_learner
from tests.experiments.test_scripts import script


@pytest.fixture
def env():
    rest = script("reach_at_rest")
    made = gym.make(rest.ENV_ID, ee_distance_threshold=1e-6, ee_rotation_threshold=1e-6)
    yield made
    made.close()


def _policy(env, offset_rad):
    """On the [-1, 1] scale: target every joint where it is observed, plus ``offset_rad(t)``."""
    low, high = env.action_space.low, env.action_space.high
    scale, steps = env.unwrapped.scale, iter(range(10**6))

    def act(obs):
        return from_env_action((obs[:6] + offset_rad(next(steps))) / scale, low, high)

    return act


def test_an_arm_held_still_measures_still_and_an_alternating_one_moving(env) -> None:
    rest = script("reach_at_rest")
    held = rest.episode(env, _policy(env, lambda t: 0.0), seed=0)
    assert held["steps"] == 600 and held["at_success"] is None  # the command is elsewhere
    assert max(held["target_gap"]) < 1e-4 and held["step_motion"] < 1e-5
    # Still: the distance at the end is the closest ever and where it hovers.
    assert held["end"] == pytest.approx(held["closest"], abs=1e-5)
    assert held["hover_centre"] == pytest.approx(held["end"], abs=1e-4)
    # Targets 0.2 rad to either side by turns: the arm jitters and the measure says so.
    swing = rest.episode(env, _policy(env, lambda t: 0.2 * (-1) ** t), seed=0)
    assert min(swing["target_gap"]) > 0.1 and swing["step_motion"] > 1e-3
    assert held["end"] == pytest.approx(swing["hover_centre"], abs=0.02)  # about where it was


def test_a_deploy_arm_held_still_measures_still_at_each_window_and_a_swinging_one_moving() -> None:
    rest = script("reach_at_rest")
    env = gym.make(rest.DEPLOY_ENV_ID)
    try:
        held = rest.deploy_windows(env, lambda obs: np.zeros(6), seed=0)
        steps = iter(range(10**6))
        swing = rest.deploy_windows(env, lambda obs: np.full(6, 0.5 * (-1) ** next(steps)), 0)
    finally:
        env.close()
    assert len(held) == 3 and len(swing) == 3  # 12 s of 4-s windows
    for row in held:
        assert row["step_motion"] < 1e-6 and row["mean_abs_action"] == 0.0
        # Still: where it hovers is where it ends, and each window's closest is its end.
        assert row["hover_centre"] == pytest.approx(row["end"], abs=1e-6)
        assert row["closest"] == pytest.approx(row["end"], abs=1e-6)
    for row in swing:
        assert row["step_motion"] > 1e-3 and row["mean_abs_action"] == pytest.approx(0.5)
        assert row["closest"] <= row["end"] + 1e-9


@pytest.mark.parametrize(
    ("flags", "obs_dim", "rows", "count"),
    [([], 25, "episodes", 1), (["--deploy"], 19, "windows", 3)],  # a row an episode / window
)
def test_the_script_prints_its_summary_and_keeps_every_row(
    tmp_path: Path, capsys, flags: list[str], obs_dim: int, rows: str, count: int
) -> None:
    save_learner(tmp_path / "learner.pt", obs_dim, 6)
    out = tmp_path / "rest.json"
    argv = [str(tmp_path / "learner.pt"), *flags, "--episodes", "1", "--out", str(out)]
    assert script("reach_at_rest").main(argv) == 0
    printed = capsys.readouterr().out
    printed = json.loads(printed[printed.find("{") :])  # after pybullet's banner, if any
    record = json.loads(out.read_text())
    assert record["summary"][rows] == count and len(record[rows]) == count
    assert all(np.isfinite(row["end"]) for row in record[rows])
    if not flags:
        assert len(record["episodes"][0]["target_gap"]) == 6
    assert printed == record["summary"]
