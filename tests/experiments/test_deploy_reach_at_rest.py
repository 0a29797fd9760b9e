"""experiments/deploy_reach_at_rest.py on the real UR10e servo: an arm held still measures as
still at every window's end and a policy that swings its actions as moving, and the script
writes its summary and rows."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from tests.experiments.conftest import save_learner
from tests.experiments.test_scripts import script


@pytest.fixture
def env():
    made = gym.make(script("deploy_reach_at_rest").ENV_ID)
    yield made
    made.close()


def test_an_arm_held_still_measures_still_and_a_swinging_one_moving(env) -> None:
    rest = script("deploy_reach_at_rest")
    held = rest.episode(env, lambda obs: np.zeros(6), seed=0)
    assert len(held) == 3  # 12 s of 4-s windows
    for row in held:
        assert row["step_motion"] < 1e-6 and row["mean_abs_action"] == 0.0
        # Still: where it hovers is where it ends, and each window's closest is its end.
        assert row["hover_centre"] == pytest.approx(row["end"], abs=1e-6)
        assert row["closest"] == pytest.approx(row["end"], abs=1e-6)
    steps = iter(range(10**6))
    swing = rest.episode(env, lambda obs: np.full(6, 0.5 * (-1) ** next(steps)), seed=0)
    assert len(swing) == 3
    for row in swing:
        assert row["step_motion"] > 1e-3 and row["mean_abs_action"] == pytest.approx(0.5)
        assert row["closest"] <= row["end"] + 1e-9


def test_the_script_prints_its_summary_and_keeps_every_window(tmp_path: Path, capsys) -> None:
    save_learner(tmp_path / "learner.pt", 19, 6)
    out = tmp_path / "rest.json"
    argv = [str(tmp_path / "learner.pt"), "--episodes", "1", "--out", str(out)]
    assert script("deploy_reach_at_rest").main(argv) == 0
    printed = capsys.readouterr().out
    printed = json.loads(printed[printed.find("{") :])  # after pybullet's banner, if any
    record = json.loads(out.read_text())
    assert record["summary"]["windows"] == 3 and len(record["windows"]) == 3
    assert all(np.isfinite(row["end"]) for row in record["windows"])
    assert printed == record["summary"]
