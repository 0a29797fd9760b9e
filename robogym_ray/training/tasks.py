"""``robogym-ray tasks``: the training tasks (``train --task NAME``) and the registered env ids,
each with one line on what it is.

Read from the two tables (``presets.TASKS``, ``envs.registration.TASKS``); an env's line is the
first sentence of its class docstring, read from the source: no env module is imported, so no
PyBullet loads to print a list.
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
from pathlib import Path

from robogym_ray.envs import registration
from robogym_ray.training.presets import TASKS


def class_summary(entry_point: str) -> str:
    """The first sentence of the docstring of the class ``module:Class`` (``""`` without one)."""
    module, _, name = entry_point.partition(":")
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        return ""
    tree = ast.parse(Path(spec.origin).read_text())
    node = next((n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == name), None)
    doc = (ast.get_docstring(node) or "") if node is not None else ""
    paragraph = " ".join(doc.split("\n\n")[0].split()).replace("``", "")
    return paragraph.split(". ")[0].removesuffix(".")


def task_lines() -> list[str]:
    """One line per training task: its name, env id and description."""
    name_w = max(map(len, TASKS)) + 2
    id_w = max(len(p.env_id) for p in TASKS.values()) + 2
    return [f"  {name:<{name_w}}{p.env_id:<{id_w}}{p.description}" for name, p in TASKS.items()]


def env_lines() -> list[str]:
    """One line per registered Sim env id (each has a Rob twin) with its class's summary."""
    rows = [
        (registration.env_id(task, robot, "Sim"), class_summary(entry_point))
        for task, entry_point, robots in registration.TASKS
        for robot, _ in robots
    ]
    width = max(len(env_id) for env_id, _ in rows) + 2
    return [f"  {env_id:<{width}}{summary}" for env_id, summary in rows]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    del parser  # no options: it prints the two lists


def run(args: argparse.Namespace) -> int:
    del args
    print("Training tasks (robogym-ray train --task NAME; D4PG settings fitted to each):")
    print("\n".join(task_lines()))
    print(
        "\nRegistered env ids (--task takes any, or any Gymnasium id with Box spaces, with the "
        "default\nD4PG settings; each ...Sim-v0 has a ...Rob-v0 twin that drives a robot server "
        "at rs_address):"
    )
    print("\n".join(env_lines()))
    return 0
