"""robo-gym's roslaunch-style ``cmd`` strings -> which robot server to start (spec b.3-b.5).

robo-gym's ServerManager client sends e.g. ``roslaunch ur_robot_server ur_robot_server.launch
world_name:=empty.world ... ur_model:=ur5`` (with runs of 9 spaces between tokens, so the string
is only ever taken apart with ``split()``). The launch file names the robot family and a model
argument (``ur_model``) the model, as the robots' cards say (``RobotCard.launch``); the
remaining ``name:=value`` tokens (``world_name`` included) are robot options that the robot
factories accept as they are, except the few that only steer ROS tooling.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.robots.card import RobotCard
from robogym_ray.robots.registry import CARDS

_TOOLING_ARGUMENTS = frozenset({"gui", "rviz_gui", "gazebo_gui", "server_port", "real_robot"})
"""Launch arguments that only steer ROS tooling: GUI switches, where to listen, real or not."""


def launch_families(cards: Mapping[str, RobotCard] = CARDS) -> dict[str, list[RobotCard]]:
    """Launch file (the third token of ``cmd``) -> the cards that answer it (the robot family)."""
    families: dict[str, list[RobotCard]] = {}
    for card in cards.values():
        families.setdefault(card.launch.launch_file, []).append(card)
    return families


_FAMILIES = launch_families()

# Launch arguments that are not robot options: the tooling ones and the model arguments (the
# model becomes the robot name). ``world_name`` stays: the robot factories map it to their scenes.
NOT_ROBOT_OPTIONS = _TOOLING_ARGUMENTS | frozenset(
    c.launch.model_argument for c in CARDS.values() if c.launch.model_argument
)


@dataclass(frozen=True)
class LaunchSpec:
    """A robot server as one of robo-gym's launch commands describes it."""

    robot: str
    """Registry name (``mir100``, ``ur10`` ...)."""
    options: dict[str, str] = field(default_factory=dict)
    """Robot options: the launch arguments minus ``NOT_ROBOT_OPTIONS``."""


def parse_launch_args(tokens: list[str]) -> dict[str, str]:
    """``["a:=1", "b:=x"]`` -> ``{"a": "1", "b": "x"}``; anything else is a ConfigError."""
    args: dict[str, str] = {}
    for token in tokens:
        name, sep, value = token.partition(":=")
        if not sep or not name:
            raise ConfigError(f"launch argument {token!r} is not of the form name:=value")
        args[name] = value
    return args


def parse_launch_cmd(cmd: str) -> LaunchSpec:
    """Map robo-gym's ``cmd`` (spec b.4) to the robot, scene and options to serve.

    Raises:
        UnknownRobotError: the launch file or ``ur_model`` is not one we simulate (an unknown
            ``world_name`` is the robot factory's to refuse).
        ConfigError: the string is not ``roslaunch <package> <file> name:=value ...``.
    """
    tokens = cmd.split()
    if len(tokens) < 3 or tokens[0] != "roslaunch":
        raise ConfigError(f"cmd {cmd!r} is not 'roslaunch <package> <launch file> name:=value ...'")
    family = _FAMILIES.get(tokens[2])
    if family is None:
        raise UnknownRobotError(
            f"no simulated robot for launch file {tokens[2]!r} (package {tokens[1]!r}); "
            f"known launch files: {', '.join(sorted(_FAMILIES))}"
        )
    args = parse_launch_args(tokens[3:])
    robot = _pick_model(family, args)
    options = {k: v for k, v in args.items() if k not in NOT_ROBOT_OPTIONS}
    return LaunchSpec(robot=robot, options=options)


def _pick_model(family: list[RobotCard], args: Mapping[str, str]) -> str:
    """The card of ``family`` whose model argument ``args`` names (or the family's only card,
    or its default card when ``args`` leaves the argument out)."""
    argument = family[0].launch.model_argument
    if argument is None:
        return family[0].name
    value = args.get(argument, "")
    for card in family:
        if card.launch.model_value == value or (argument not in args and card.launch.default):
            return card.name
    known = ", ".join(str(c.launch.model_value) for c in family)
    raise UnknownRobotError(
        f"{argument}:={value or '<missing>'} is not a model we simulate for "
        f"{family[0].launch.launch_file}; known: {known}"
    )
