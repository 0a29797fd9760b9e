"""``robogym-ray train``: distributed D4PG on local Ray or a cluster."""

from __future__ import annotations

import argparse
import json
from dataclasses import fields

from robogym_ray.actors.train_config import TrainConfig
from robogym_ray.config import add_config_args, merge_config
from robogym_ray.errors import ConfigError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # Only flags given on the command line override the config file.
    add_config_args(parser, TrainConfig, only_given=True)


def build_config(args: argparse.Namespace) -> tuple[TrainConfig, dict]:
    given = {f.name: getattr(args, f.name) for f in fields(TrainConfig) if hasattr(args, f.name)}
    given = {k: tuple(v) if isinstance(v, list) else v for k, v in given.items()}
    d4pg: dict = {}
    if given.get("config"):
        path = given["config"]
        try:
            data = json.loads(open(path).read())  # noqa: SIM115 - tiny file
        except (OSError, json.JSONDecodeError) as exc:
            raise ConfigError(f"cannot read config file {path}: {exc}") from None
        if not isinstance(data, dict) or set(data) - {"train", "d4pg"}:
            raise ConfigError(f"{path}: expected a JSON object with keys 'train' and/or 'd4pg'")
        d4pg = dict(data.get("d4pg", {}))
        return merge_config(TrainConfig, {**data.get("train", {}), **given}, source=path), d4pg
    return merge_config(TrainConfig, given, source="command line"), d4pg


def run(args: argparse.Namespace) -> int:
    from robogym_ray.actors.tasks import resolve_task
    from robogym_ray.actors.training import run_training

    cfg, d4pg = build_config(args)
    resolve_task(cfg.task)  # fail fast, before Ray starts, on a bad task name
    summary = run_training(cfg, d4pg)
    print(json.dumps(summary), flush=True)
    return 0
