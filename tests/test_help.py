"""``--help`` a new user reads: sections, each default once, an accurate command list, and the
README's commands still parse as written."""

from __future__ import annotations

import argparse
import ast
import dataclasses
import re
import shlex
from pathlib import Path

import pytest

import robogym_ray
from robogym_ray.cli import COMMANDS, build_parser, main
from robogym_ray.config import add_config_args, help_text
from robogym_ray.errors import ConfigError
from robogym_ray.robots.emulation import EmulationConfig
from robogym_ray.training.api import settings
from robogym_ray.training.command import HELP_GROUPS, build_config
from robogym_ray.training.config import DEFAULT_TOTAL_STEPS, TrainConfig
from robogym_ray.training.setup import check_inputs

ROOT = Path(__file__).resolve().parents[1]


def help_of(argv: list[str], capsys: pytest.CaptureFixture) -> str:
    with pytest.raises(SystemExit) as info:
        main([*argv, "--help"])
    assert info.value.code == 0
    return capsys.readouterr().out


def test_train_help_is_in_sections_with_every_default_once(
    capsys: pytest.CaptureFixture,
) -> None:
    text = help_of(["train"], capsys)
    headings = [line[:-1] for line in text.splitlines() if re.fullmatch(r"\S.*:", line)]
    wanted = ["options", *HELP_GROUPS, "emulated robots (for --emulated-workers)"]
    assert headings == wanted
    # Shorter than the one flat list it was (argparse's usage names every flag).
    flat = argparse.ArgumentParser(prog="robogym-ray train")
    add_config_args(flat, TrainConfig, only_given=True)
    add_config_args(flat, EmulationConfig, prefix="emu-", only_given=True)
    assert len(text.splitlines()) < len(flat.format_help().splitlines())
    assert text.splitlines()[0].startswith("usage: robogym-ray train [--task TASK]")


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_no_option_prints_its_default_twice(command: str, capsys: pytest.CaptureFixture) -> None:
    text = help_of([command], capsys)
    # One entry per option: its lines up to the next "  -..." line or section.
    for entry in re.split(r"\n(?=  -|\S)", text):
        assert len(re.findall(r"default:", entry, re.IGNORECASE)) <= 1, entry


def test_every_train_field_has_one_section() -> None:
    listed = [name for names in HELP_GROUPS.values() for name in names]
    fields = [f.name for f in dataclasses.fields(TrainConfig)]
    assert sorted(listed) == sorted(fields)  # a new field: add it to HELP_GROUPS


def test_a_field_with_no_section_fails_the_build() -> None:
    groups = {title: tuple(n for n in names if n != "seed") for title, names in HELP_GROUPS.items()}
    with pytest.raises(ValueError, match=r"fields in none \['seed'\]"):
        add_config_args(argparse.ArgumentParser(), TrainConfig, groups=groups)


def test_help_text_states_a_default_once_as_typed() -> None:
    assert help_text("Run name (default: the task and time).", None).count("default") == 1
    assert help_text("Where. Default: --logdir.", None).count("efault") == 1
    assert help_text("Task.", "navigation") == "Task. (default: navigation)"
    assert help_text("Hosts.", ()) == "Hosts. (default: none)"
    assert help_text("15-20 %.", 1) == "15-20 %%. (default: 1)"  # argparse %-formats help


def test_top_level_help_says_what_each_command_writes(capsys: pytest.CaptureFixture) -> None:
    text = help_of([], capsys)
    assert "ONNX" in text.split("export", 1)[1].splitlines()[0]


def readme_commands() -> list[list[str]]:
    """The ``robogym-ray`` lines of README.md's "Using it" block, as argv lists."""
    readme = (ROOT / "README.md").read_text()
    block = readme.split("## Using it", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    joined = re.sub(r"\\\n\s*", " ", block)
    lines = [line.split("#", 1)[0].strip() for line in joined.splitlines()]
    return [shlex.split(line)[1:] for line in lines if line.startswith("robogym-ray ")]


@pytest.mark.parametrize("argv", readme_commands(), ids=" ".join)
def test_the_readmes_commands_parse_as_written(argv: list[str]) -> None:
    if argv == ["--help"]:
        return  # test_top_level_help_says_what_each_command_writes
    args = build_parser(argv).parse_args(argv)
    if args.command == "train":  # flags and config file merged into the run's config
        build_config(args)


def test_a_time_given_alone_ends_the_run_not_the_default_step_total(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``--max-wall-s`` alone lifts the 3,000-step default (a user who gives a time means the
    time); given neither, a run stops at 3,000 steps; given both, the steps given stay."""

    def cli(*argv: str) -> int | None:
        args = build_parser(["train", *argv]).parse_args(["train", *argv])
        return build_config(args).train.total_steps

    assert cli("--max-wall-s", "150") is None  # no step cap: the time ends the run
    assert cli() == DEFAULT_TOTAL_STEPS == 3000
    assert cli("--max-wall-s", "150", "--total-steps", "500") == 500
    assert settings(task="pendulum", max_wall_s=150).train.total_steps is None
    assert settings(task="pendulum").train.total_steps == 3000
    assert settings(task="pendulum", max_wall_s=150, total_steps=500).train.total_steps == 500
    assert TrainConfig(max_wall_s=150).total_steps is None
    config = tmp_path / "timed.json"
    config.write_text('{"train": {"max_wall_s": 150}}')
    assert cli("--config", str(config)) is None
    config.write_text('{"train": {"max_wall_s": 150, "total_steps": 800}}')
    assert cli("--config", str(config)) == 800
    assert cli("--config", str(config), "--total-steps", "900") == 900
    # Told in --help, where the user reads the default.
    text = " ".join(help_of(["train"], capsys).split())
    assert "(default: 3000; none when --max-wall-s is given alone" in text


def readme_train_calls() -> list[ast.expr]:
    """The ``robogym_ray.train(...)`` calls of README.md's Python example and of the sentence
    after it."""
    readme = (ROOT / "README.md").read_text()
    calls = re.findall(r"robogym_ray\.train\((?:[^()]|\([^()]*\))*\)", readme.replace("\n", " "))
    return [ast.parse(call, mode="eval").body for call in calls]


@pytest.mark.usefixtures("ray_must_not_start")
def test_the_readmes_python_trainings_fit_two_cores(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each passes every check that runs before Ray starts, on the 2 CPUs the README's machine
    has (the navigation config alone asks for 8 workers: refused there, naming the keyword)."""
    monkeypatch.chdir(ROOT)  # the config file's path is the clone's
    with pytest.raises(ConfigError, match=r"cluster has 2: lower workers=8, "):
        robogym_ray.train("experiments/configs/navigation.json", num_cpus=2, logdir=str(tmp_path))
    calls = readme_train_calls()
    assert len(calls) == 2
    for call in calls:
        assert isinstance(call, ast.Call)
        args = [ast.literal_eval(arg) for arg in call.args]
        kwargs = {k.arg: ast.literal_eval(k.value) for k in call.keywords if k.arg}
        setup = settings(*args, **{**kwargs, "num_cpus": 2, "logdir": str(tmp_path)})
        check_inputs(setup)
