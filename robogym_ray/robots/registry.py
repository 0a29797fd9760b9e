"""Robot registry: name -> factory. A new robot is one module plus one line here.

Factories are referenced by import path so that importing the registry does not import
PyBullet models that are not used.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping

from robogym_ray.errors import UnknownRobotError
from robogym_ray.robots.base import SimRobot

RobotFactory = Callable[..., SimRobot]
"""``factory(model: str, scene: str | None, seed: int | None, options: Mapping[str, str])``.

``options`` are launch-argument style strings (``rs_mode``, ``action_cycle_rate``, ...); a factory
raises ConfigError on an option or value it does not know.
"""

ROBOTS: dict[str, str] = {
    "mir100": "robogym_ray.robots.mir100.model:make_mir100",
    "ur3": "robogym_ray.robots.ur.model:make_ur",
    "ur3e": "robogym_ray.robots.ur.model:make_ur",
    "ur5": "robogym_ray.robots.ur.model:make_ur",
    "ur5e": "robogym_ray.robots.ur.model:make_ur",
    "ur10": "robogym_ray.robots.ur.model:make_ur",
    "ur10e": "robogym_ray.robots.ur.model:make_ur",
    "ur16e": "robogym_ray.robots.ur.model:make_ur",
}


OPTION_PARSERS: dict[str, str] = {
    "robogym_ray.robots.mir100.model:make_mir100": "robogym_ray.robots.mir100.config:parse_options",
    "robogym_ray.robots.ur.model:make_ur": "robogym_ray.robots.ur.config:parse_options",
}
"""Factory -> the option parser that factory builds its config with: ``parser(model, scene,
options)`` raises ConfigError exactly as the factory would, without PyBullet or a server."""


def check_options(
    name: str, scene: str | None = None, options: Mapping[str, str] | None = None
) -> None:
    """Raise what ``make_robot(name, scene=scene, options=options)`` would raise for a bad name,
    scene or option, without building the robot (the server manager checks before it starts
    a server process).

    Raises:
        UnknownRobotError: unknown robot, scene or world.
        ConfigError: an unknown option or a bad option value.
    """
    module_name, _, attr = OPTION_PARSERS[_factory_path(name)].partition(":")
    getattr(importlib.import_module(module_name), attr)(name, scene, dict(options or {}))


def _factory_path(name: str) -> str:
    try:
        return ROBOTS[name]
    except KeyError:
        raise UnknownRobotError(
            f"unknown robot {name!r}; known robots: {', '.join(sorted(ROBOTS))}"
        ) from None


def make_robot(
    name: str,
    *,
    scene: str | None = None,
    seed: int | None = None,
    options: Mapping[str, str] | None = None,
) -> SimRobot:
    """Build the simulated robot ``name`` (see ``ROBOTS``) in ``scene`` (None = its default)."""
    module_name, _, attr = _factory_path(name).partition(":")
    factory: RobotFactory = getattr(importlib.import_module(module_name), attr)
    return factory(model=name, scene=scene, seed=seed, options=dict(options or {}))
