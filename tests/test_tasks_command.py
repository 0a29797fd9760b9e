"""``robogym-ray tasks``: every training task with its env id and a line on what it is, and every
registered env id; ``train --help`` points to it (until 2026-11-27 ``--help`` pointed into a
source file)."""

from __future__ import annotations

import re

import pytest

from robogym_ray.cli import main
from robogym_ray.envs import SIM_ENV_IDS
from robogym_ray.training.presets import TASKS


def test_tasks_lists_every_task_and_env_id(capsys: pytest.CaptureFixture) -> None:
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    for name, preset in TASKS.items():
        line = next(line for line in lines if line.split()[:1] == [name])
        assert line.split()[1] == preset.env_id and preset.description in line
        assert len(preset.description) > 20
    listed = {line.split()[0] for line in lines if line.startswith("  RoboGymRay/")}
    assert listed == set(SIM_ENV_IDS)
    ours = [line for line in lines if line.startswith("  RoboGymRay/")]
    assert all(len(line.split()) > 3 for line in ours)  # each with its class's summary
    nav = next(line for line in ours if "ObstacleAvoidanceMir100Sim-v0 " in line)
    assert "cross the 6 x 8 m lab to a target, avoiding three cubes" in nav


def test_train_help_points_to_the_tasks_command(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    # argparse wraps lines at spaces and after hyphens ("robogym-" / "ray")
    text = re.sub(r"-\s+", "-", " ".join(capsys.readouterr().out.split()))
    assert "`robogym-ray tasks` lists them all" in text and "presets.py" not in text
