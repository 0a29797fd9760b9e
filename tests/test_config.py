"""Configs: field docstrings become --help; malformed configs fail with clear messages."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from robogym_ray.config import add_config_args, config_from_args, load_config_file, merge_config
from robogym_ray.errors import ConfigError
from robogym_ray.robots.serve import ServeConfig, is_loopback, parse_options


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
    good.write_text(json.dumps({"robot": "ur10", "port": 5}))
    assert load_config_file(ServeConfig, good).robot == "ur10"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"robto": "ur10"}))
    with pytest.raises(ConfigError, match="robto"):
        load_config_file(ServeConfig, bad)
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(ConfigError, match="broken.json"):
        load_config_file(ServeConfig, broken)
    with pytest.raises(ConfigError, match="unknown"):
        merge_config(ServeConfig, {"nope": 1})


def test_launch_style_options() -> None:
    assert parse_options(["rs_mode:=1object", "a=b=c"]) == {"rs_mode": "1object", "a": "b=c"}
    with pytest.raises(ConfigError, match="key=value"):
        parse_options(["novalue"])


def test_loopback_detection() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.2")
