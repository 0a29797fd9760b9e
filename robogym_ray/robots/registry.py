"""Robot registry: name -> ``RobotCard``. A new robot is its folder plus one line here.

Each module in ``CARD_MODULES`` is a robot family's ``card.py`` with a ``CARDS`` dict (name ->
card). Cards are plain data, so importing the registry imports no PyBullet; the factory a card
names is imported only by ``make_robot``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping

from robogym_ray.errors import UnknownRobotError
from robogym_ray.robots.base import SimRobot
from robogym_ray.robots.card import RobotCard
from robogym_ray.text import did_you_mean, quote

CARD_MODULES: tuple[str, ...] = (
    "robogym_ray.robots.mir100.card",
    "robogym_ray.robots.ur.card",
    "robogym_ray.robots.panda.card",
)
"""The robot families: one ``card.py`` each."""

RobotFactory = Callable[..., SimRobot]
"""``factory(model: str, scene: str | None, seed: int | None, options: Mapping[str, str])``.

``options`` are launch-argument style strings (``rs_mode``, ``action_cycle_rate``, ...); a factory
raises ConfigError on an option or value it does not know.
"""


def _load_cards() -> dict[str, RobotCard]:
    cards: dict[str, RobotCard] = {}
    for module in CARD_MODULES:
        for name, card in importlib.import_module(module).CARDS.items():
            if name in cards or name != card.name:
                raise ValueError(f"{module}: robot {name!r} is registered twice or misnamed")
            cards[name] = card
    return cards


CARDS: dict[str, RobotCard] = _load_cards()
"""Every robot by registry name (``mir100``, ``ur3`` ... ``ur16e``)."""


def robot_card(name: str) -> RobotCard:
    """The card of robot ``name``.

    Raises:
        UnknownRobotError: no robot of that name is registered.
    """
    try:
        return CARDS[name]
    except KeyError:
        raise UnknownRobotError(
            f"unknown robot {quote(name)}{did_you_mean(name, CARDS)}; "
            f"known robots: {', '.join(sorted(CARDS))}"
        ) from None


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
    robot_card(name).load_option_parser()(name, scene, dict(options or {}))


def make_robot(
    name: str,
    *,
    scene: str | None = None,
    seed: int | None = None,
    options: Mapping[str, str] | None = None,
) -> SimRobot:
    """Build the simulated robot ``name`` (see ``CARDS``) in ``scene`` (None = its default)."""
    factory: RobotFactory = robot_card(name).load_factory()
    return factory(model=name, scene=scene, seed=seed, options=dict(options or {}))
