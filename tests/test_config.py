"""Configs: field docstrings become --help; malformed configs fail with clear messages."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from robogym_ray.config import add_config_args, config_from_args, merge_config
from robogym_ray.distributed.manager import ManagerConfig
from robogym_ray.errors import ConfigError
from robogym_ray.robots.serve import ServeConfig, is_loopback, parse_options
from robogym_ray.robots.server import start_robot_server
from robogym_ray.training.config import TrainConfig
from robogym_ray.training.settings import read_sections


def test_field_docstrings_become_help() -> None:
    parser = argparse.ArgumentParser()
    add_config_args(parser, ServeConfig)
    text = parser.format_help()
    assert "Interface to listen on" in text and "--real-time" in text
    cfg = config_from_args(
        ServeConfig, parser.parse_args(["--port", "7", "--option", "a=1", "b:=2"])
    )
    assert cfg.port == 7 and cfg.option == ("a=1", "b:=2")
    # A repeated list flag adds to the list (it must not silently drop the first ones).
    again = parser.parse_args(["--option", "a=1", "--option", "b=2", "c=3"])
    assert config_from_args(ServeConfig, again).option == ("a=1", "b=2", "c=3")
    assert config_from_args(ServeConfig, parser.parse_args([])).option == ()


def test_config_file_unknown_key_and_bad_json(tmp_path: Path) -> None:
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"train": {"workers": 3}}))
    assert merge_config(TrainConfig, read_sections(good)["train"]).workers == 3
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"train": {"wrokers": 3}}))
    with pytest.raises(ConfigError, match="wrokers"):
        merge_config(TrainConfig, read_sections(bad)["train"], source=str(bad))
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(ConfigError, match="broken.json"):
        read_sections(broken)
    with pytest.raises(ConfigError, match="unknown"):
        merge_config(ServeConfig, {"nope": 1})
    with pytest.raises(ConfigError, match="invalid ServeConfig"):
        merge_config(ServeConfig, {"port": -1})


@pytest.mark.parametrize("port", [-1, 65536, 70000, 1.5, True])
def test_ports_out_of_range_are_refused_not_wrapped(port: object) -> None:
    # gRPC binds port % 65536 without a word: -1 would listen on 65535.
    with pytest.raises(ConfigError, match="TCP port"):
        ServeConfig(port=port)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="TCP port"):
        ManagerConfig(port=port)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="robot server port"):
        start_robot_server("ur10", port=port)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="HOST:PORT"):
        TrainConfig(real_robot=(f"10.0.0.5:{port}",))


def test_manager_settings_are_checked() -> None:
    assert ManagerConfig(port=0).port == 0
    for bad in ({"num_cpus": 0}, {"probe_interval_s": float("nan")}, {"max_restarts": -1}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            ManagerConfig(**bad)


def test_launch_style_options() -> None:
    assert parse_options(["rs_mode:=1object", "a=b=c"]) == {"rs_mode": "1object", "a": "b=c"}
    with pytest.raises(ConfigError, match="key=value"):
        parse_options(["novalue"])


def test_loopback_detection() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.2")
