"""`robogym-ray` entry point: help for every command, clear errors and exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robogym_ray.cli import COMMANDS, main


def test_help_lists_every_command(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert all(name in out for name in COMMANDS)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_each_command_has_help(command: str, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    assert "--" in capsys.readouterr().out  # documented options


def refused(capfd: pytest.CaptureFixture, *argv: str) -> str:
    """``robogym-ray ARGV`` run in this process (a fresh process per call cost ~1.5 s of
    imports each): exit code 2 and what it wrote to stderr, Ray never started."""
    capfd.readouterr()
    assert exit_code(*argv) == 2
    return capfd.readouterr().err


def exit_code(*argv: str) -> int | str | None:
    """``main``'s exit code, whether returned or raised (argparse exits with 2 itself)."""
    try:
        return main(list(argv))
    except SystemExit as exit:
        return exit.code


@pytest.mark.usefixtures("ray_must_not_start")
def test_train_rejects_an_unknown_task_before_starting_ray(capfd: pytest.CaptureFixture) -> None:
    err = refused(capfd, "train", "--task", "NoSuchTask-v9", "--total-steps", "10")
    assert "NoSuchTask-v9" in err and "navigation" in err


@pytest.mark.usefixtures("ray_must_not_start")
def test_train_rejects_a_malformed_config(capfd: pytest.CaptureFixture, tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"train": {"workerz": 2}}))
    assert "workerz" in refused(capfd, "train", "--config", str(bad))
    bad.write_text(json.dumps({"d4pg": {"num_atoms": 1}, "train": {"task": "pendulum"}}))
    assert "num_atoms" in refused(capfd, "train", "--config", str(bad), "--total-steps", "10")
    assert "workers" in refused(capfd, "train", "--workers", "-1")
    assert "HOST:PORT" in refused(capfd, "train", "--real-robot", "nohostport")
    capfd.readouterr()
    assert exit_code("serve", "--port", "-1") == 2  # gRPC alone would listen on 65535
    out = capfd.readouterr()
    assert "--port" in out.err and "listening" not in out.out


@pytest.mark.usefixtures("ray_must_not_start")
def test_train_rejects_bad_emulation_settings_before_starting_ray(
    capfd: pytest.CaptureFixture, tmp_path: Path
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"emulation": {"laser_noise_sigmaa": 0.1}}))
    assert "laser_noise_sigmaa" in refused(capfd, "train", "--config", str(bad))
    bad.write_text(json.dumps({"emulaton": {}}))
    assert "emulation" in refused(capfd, "train", "--config", str(bad))
    err = refused(capfd, "train", "--workers", "2", "--emulated-workers", "3")
    assert "--emulated-workers 3: expected in [0, workers=2]" in err
    err = refused(capfd, "train", "--emulated-workers", "1", "--emu-laser-noise-sigma", "nan")
    assert "--emu-laser-noise-sigma nan: expected a number" in err
    err = refused(capfd, "train", "--task", "pendulum", "--workers", "1", "--emulated-workers", "1")
    assert "robot task" in err


@pytest.mark.usefixtures("ray_must_not_start")
def test_resume_robot_without_a_ray_answers_in_one_line_and_names_the_sweeps_resume(
    capfd: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    import socket

    import ray._private.services as ray_services

    sweeps = "a sweep resumes with `robogym-ray sweep --resume arm --storage DIR`"
    with socket.socket() as held:  # bound, not listening: a port where no Ray answers
        held.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{held.getsockname()[1]}"
        (line,) = refused(capfd, "resume-robot", "arm", "--ray-address", address).splitlines()
        assert f"no Ray answers at {address}" in line and line.endswith(sweeps)
        monkeypatch.setenv("RAY_ADDRESS", address)  # --ray-address auto reads it first
        (line,) = refused(capfd, "resume-robot", "arm").splitlines()
        assert f"--ray-address auto: no Ray answers at {address}" in line
    # No Ray on the machine at all (the suite's own Ray and any other are hidden from the lookup).
    monkeypatch.delenv("RAY_ADDRESS")
    monkeypatch.setattr(ray_services, "find_gcs_addresses", lambda: [])
    monkeypatch.setattr(ray_services, "find_bootstrap_address", lambda temp_dir=None: None)
    (line,) = refused(capfd, "resume-robot", "arm").splitlines()
    assert "no Ray runs on this machine" in line and line.endswith(sweeps)
    # The command's former name answers what it became and where a sweep is resumed.
    (line,) = refused(capfd, "resume", "arm").splitlines()
    assert "now `resume-robot` (a paused real robot)" in line and "sweep --resume NAME" in line


def test_train_merges_emulation_from_config_file_and_flags(tmp_path: Path) -> None:
    import argparse

    from robogym_ray.training import command as train_cmd

    path = tmp_path / "dr.json"
    path.write_text(
        json.dumps(
            {
                "train": {"workers": 2, "emulated_workers": 1},
                "emulation": {"laser_noise_sigma": 0.05, "latency_ticks": 2},
            }
        )
    )
    parser = argparse.ArgumentParser()
    train_cmd.add_arguments(parser)
    setup = train_cmd.build_config(
        parser.parse_args(["--config", str(path), "--emu-latency-ticks", "0"])
    )
    assert setup.train.emulated_workers == 1
    assert setup.emulation.laser_noise_sigma == 0.05 and setup.emulation.latency_ticks == 0
    assert setup.emulation.velocity_scale == 0.95  # the rest: EmulationConfig's defaults


@pytest.mark.usefixtures("ray_must_not_start")
def test_a_config_extends_another_field_by_field(
    capfd: pytest.CaptureFixture, tmp_path: Path
) -> None:
    from robogym_ray.errors import ConfigError
    from robogym_ray.training.settings import read_sections

    (tmp_path / "base.json").write_text(
        json.dumps({"train": {"workers": 2, "seed": 3}, "d4pg": {"sigma": 0.3, "n_step": 5}})
    )
    (tmp_path / "variants").mkdir()
    mid = tmp_path / "variants" / "mid.json"
    mid.write_text(json.dumps({"extends": "../base.json", "train": {"seed": 4}}))
    leaf = tmp_path / "variants" / "leaf.json"
    leaf.write_text(json.dumps({"extends": "mid.json", "d4pg": {"sigma": 0.2}, "emulation": {}}))
    sections = read_sections(leaf)
    assert sections["train"] == {"workers": 2, "seed": 4}
    assert sections["d4pg"] == {"sigma": 0.2, "n_step": 5}
    assert read_sections(tmp_path / "base.json")["d4pg"]["sigma"] == 0.3  # base untouched

    (tmp_path / "a.json").write_text(json.dumps({"extends": "b.json"}))
    (tmp_path / "b.json").write_text(json.dumps({"extends": "a.json"}))
    with pytest.raises(ConfigError, match="cycle"):
        read_sections(tmp_path / "a.json")
    leaf.write_text(json.dumps({"extends": "nowhere.json"}))
    with pytest.raises(ConfigError, match=r"leaf.json extends nowhere.json: cannot read"):
        read_sections(leaf)
    leaf.write_text(json.dumps({"extends": ["mid.json"]}))
    with pytest.raises(ConfigError, match="'extends' must be a config file name"):
        read_sections(leaf)
    mid.write_text(json.dumps({"extends": "../base.json", "train": {"workerz": 1}}))
    leaf.write_text(json.dumps({"extends": "mid.json"}))
    # A bad field in a base fails before Ray (ray_must_not_start).
    assert "workerz" in refused(capfd, "train", "--config", str(leaf))


def test_train_prints_a_short_summary_and_json_on_request() -> None:
    import argparse

    from robogym_ray.training import command as train_cmd

    committed = Path("docs/results/navigation-sectors-average-100min/training-summary.json")
    summary = json.loads(committed.read_text())
    text = train_cmd.summary_text(summary)
    lines = text.splitlines()
    assert lines[0].startswith(f"Trained {summary['task']}: 1,822,950 env steps, 12,816 episodes")
    assert "training episodes (last 100): success 97.0 %  collision 2.0 %  timeout 1.0 %" in text
    assert "greedy evaluation (last 100 of 398 episodes): success 98.0 %" in text
    assert f"checkpoint:  {summary['checkpoint']}" in text
    assert f"tensorboard --logdir {summary['logdir']}" in text
    # A summary that names its folder only as storage.root (before logdir was the one field).
    older = {k: v for k, v in summary.items() if k != "logdir"}
    older["storage"] = {**summary.get("storage", {}), "root": summary["logdir"]}
    assert train_cmd.summary_text(older) == text
    assert len(text) < 1000 and len(lines) <= 8  # a few lines, not the 3 KB JSON
    # A run too short to evaluate has no eval/ rates: the line is left out, nothing fails.
    short = {k: v for k, v in summary.items() if not k.startswith("eval/")}
    assert "greedy evaluation" not in train_cmd.summary_text(short)

    parser = argparse.ArgumentParser()
    train_cmd.add_arguments(parser)
    assert parser.parse_args(["--json"]).json and not parser.parse_args([]).json
