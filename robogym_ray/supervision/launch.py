"""robo-gym's roslaunch-style ``cmd`` strings -> which robot server to start (spec b.3-b.5).

robo-gym's ServerManager client sends e.g. ``roslaunch ur_robot_server ur_robot_server.launch
world_name:=empty.world ... ur_model:=ur5`` (with runs of 9 spaces between tokens, so the string
is only ever taken apart with ``split()``). The launch file names the robot family and
``ur_model`` the arm; the remaining ``name:=value`` tokens (``world_name`` included) are robot
options that the robot factories accept as they are, except the few that only steer ROS tooling.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from robogym_ray.errors import ConfigError, UnknownRobotError

# launch file (the third token) -> robot family
_LAUNCH_FILES: dict[str, str] = {
    "sim_robot_server.launch": "mir100",
    "ur_robot_server.launch": "ur",
}
_UR_MODELS = ("ur3", "ur3e", "ur5", "ur5e", "ur10", "ur10e", "ur16e")

# Launch arguments that are not robot options: GUI switches, where to listen, and the model
# (it becomes the robot name). ``world_name`` stays: the robot factories map it to their scenes.
NOT_ROBOT_OPTIONS = frozenset(
    {"gui", "rviz_gui", "gazebo_gui", "server_port", "ur_model", "real_robot"}
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
    family = _LAUNCH_FILES.get(tokens[2])
    if family is None:
        raise UnknownRobotError(
            f"no simulated robot for launch file {tokens[2]!r} (package {tokens[1]!r}); "
            f"known launch files: {', '.join(sorted(_LAUNCH_FILES))}"
        )
    args = parse_launch_args(tokens[3:])
    if family == "ur":
        robot = args.get("ur_model", "")
        if robot not in _UR_MODELS:
            raise UnknownRobotError(
                f"ur_model:={robot or '<missing>'} is not a UR model we simulate; "
                f"known: {', '.join(_UR_MODELS)}"
            )
    else:
        robot = family
    options = {k: v for k, v in args.items() if k not in NOT_ROBOT_OPTIONS}
    return LaunchSpec(robot=robot, options=options)
