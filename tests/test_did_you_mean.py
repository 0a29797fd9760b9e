"""Errors that guide: an unknown task, robot, env id or config key is named, with the closest
known one."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robogym_ray.cli import main
from robogym_ray.envs.registration import env_robot, variant_id
from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.robots.registry import check_options, robot_card
from robogym_ray.text import did_you_mean


def cli_error(argv: list[str], capsys: pytest.CaptureFixture) -> str:
    """The one ``error:`` line of ``robogym-ray ARGV`` (exit 2)."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


def test_a_misspelt_task_gets_its_name(capsys: pytest.CaptureFixture) -> None:
    line = cli_error(["train", "--task", "navigaton"], capsys)
    assert "'navigaton' (did you mean 'navigation'?)" in line
    assert "AvoidanceRaad2022" not in line  # the example is a preset's id, not the first id


def test_a_misspelt_config_section_is_named(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    config = tmp_path / "run.json"
    config.write_text(json.dumps({"trian": {"workers": 1}}))
    line = cli_error(["train", "--config", str(config)], capsys)
    assert "['trian'] (did you mean 'train'?)" in line and str(config) in line
    config.write_text(json.dumps({"train": {"wrokers": 1}}))
    line = cli_error(["train", "--config", str(config)], capsys)
    assert "train: unknown field(s) ['wrokers'] (did you mean 'workers'?)" in line


def test_a_misspelt_robot_is_named_before_anything_starts(capsys: pytest.CaptureFixture) -> None:
    line = cli_error(["serve", "--robot", "UR10", "--port", "0"], capsys)
    assert "unknown robot 'UR10' (did you mean 'ur10'?)" in line
    with pytest.raises(UnknownRobotError, match=r"'mir10' \(did you mean 'mir100'\?\)"):
        robot_card("mir10")
    with pytest.raises(ConfigError, match=r"'rs_mod' \(did you mean 'rs_mode'\?\)"):
        check_options("ur10", options={"rs_mod": "1object"})
    with pytest.raises(UnknownRobotError, match=r"'tabletp' \(did you mean 'tabletop'\?\)"):
        check_options("ur10", scene="tabletp")


@pytest.mark.parametrize(
    "given",
    [
        "RoboGymRay/EndEfectorPositioningUR10Rob-v0",  # a letter
        "EndEffectorPositioningUR10Rob-v0",  # no namespace: gymnasium's own hint has none
        "RoboGymRay/EndEffectorPositioningUR10Rob",  # no version
    ],
)
def test_a_misspelt_env_id_gets_the_registered_one(given: str) -> None:
    wanted = "(did you mean 'RoboGymRay/EndEffectorPositioningUR10Rob-v0'?)"
    with pytest.raises(ConfigError) as info:
        env_robot(given)
    assert wanted in str(info.value)
    if not given.endswith("-v0"):
        with pytest.raises(ConfigError, match="is not a RoboGymRay") as info:
            variant_id(given, "sim")
        assert wanted in str(info.value)


def test_did_you_mean_only_for_a_close_name() -> None:
    assert did_you_mean("xyz", ["train", "d4pg"]) == ""
    assert did_you_mean("Navigation", ["navigation"]) == " (did you mean 'navigation'?)"
    assert did_you_mean("n" * 10_000, ["n" * 10]) == ""  # difflib is quadratic: not compared
    assert did_you_mean(None, ["none"]) == ""
