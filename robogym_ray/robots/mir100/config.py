"""Configuration of the simulated MiR100 (one frozen dataclass, field docstrings = help)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.robots.command_handler import CommandHandlerConfig
from robogym_ray.robots.mir100.card import ACCELERATION, VELOCITY
from robogym_ray.robots.mir100.drive import DriveLimits
from robogym_ray.robots.mir100.scenes import check_scene, scene_for_world
from robogym_ray.robots.validation import parse_option_number
from robogym_ray.text import preview

LASER_CASTERS = ("boxes", "bullet")
"""Ray casters ``Mir100Config.laser_caster`` accepts (see ``lasers``)."""


@dataclass(frozen=True)
class Mir100Config:
    """Everything that defines one simulated MiR100."""

    scene: str = "empty"
    """``empty`` (ground + target marker) or ``lab_6x8`` (walls + 3 cubes). The default is the
    one of robo-gym's ``sim_robot_server.launch`` (``empty_world_target.world``)."""
    max_linear_velocity: float = VELOCITY[0]
    """Diff-drive controller limit on |v| (m/s)."""
    max_angular_velocity: float = VELOCITY[1]
    """Diff-drive controller limit on |omega| (rad/s)."""
    max_linear_acceleration: float = ACCELERATION[0]
    """Diff-drive controller limit on |dv/dt| (m/s^2)."""
    max_angular_acceleration: float = ACCELERATION[1]
    """Diff-drive controller limit on |domega/dt| (rad/s^2)."""
    laser_noise_sigma: float = 0.0
    """Std. dev. of Gaussian laser range noise (m); 0.0 = clean sim (Gazebo uses 0.01)."""
    laser_range_min: float = 0.05
    """Lower range clip of both scanners (m)."""
    laser_range_max: float = 29.0
    """Upper range clip (m); a beam that hits nothing reads this."""
    laser_caster: str = "boxes"
    """``boxes``: exact numpy ray/box test (fast; every collidable body must be an upright box
    spanning the scan plane, true of both scenes) or ``bullet``: PyBullet's rayTestBatch
    (any shape, ~5x slower in ``lab_6x8``)."""
    scan_period: float = 0.08
    """Seconds between laser scans in real-time mode (12.5 Hz, the S300 rate)."""
    action_cycle: float = 0.1
    """Seconds between agent actions (the MiR command handler runs at 10 Hz)."""
    actuation_cycle: float = 0.1
    """Seconds between twist publications to the controller."""
    repeat: int | None = None
    """Publications per action; None = action_cycle / actuation_cycle."""
    substep: float = 0.01
    """Integration and contact-check step (s); 1 cm per substep at full speed."""
    initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Start pose (x, y, yaw) before the first SetState (launch args robot_x/y/yaw)."""
    max_abs_position: float = 50.0
    """SetState refuses poses with |x| or |y| above this (m)."""

    def __post_init__(self) -> None:
        check_scene(self.scene)
        if self.laser_caster not in LASER_CASTERS:
            raise ConfigError(
                f"Mir100Config.laser_caster = {self.laser_caster!r}; expected one of "
                f"{list(LASER_CASTERS)}"
            )
        positive = {
            "max_linear_velocity": self.max_linear_velocity,
            "max_angular_velocity": self.max_angular_velocity,
            "max_linear_acceleration": self.max_linear_acceleration,
            "max_angular_acceleration": self.max_angular_acceleration,
            "laser_range_max": self.laser_range_max,
            "scan_period": self.scan_period,
            "substep": self.substep,
            "max_abs_position": self.max_abs_position,
        }
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"Mir100Config.{name} = {value}; expected a finite value > 0")
        if not 0.0 <= self.laser_range_min < self.laser_range_max:
            raise ConfigError(
                f"Mir100Config.laser_range_min = {self.laser_range_min}; expected in "
                f"[0, laser_range_max={self.laser_range_max})"
            )
        x, y, yaw = self.initial_pose
        if not all(math.isfinite(v) for v in (x, y, yaw)) or max(abs(x), abs(y)) > (
            self.max_abs_position
        ):
            raise ConfigError(
                f"Mir100Config.initial_pose = {self.initial_pose}; expected finite values with "
                f"|x|, |y| <= {self.max_abs_position}"
            )
        if not (math.isfinite(self.laser_noise_sigma) and self.laser_noise_sigma >= 0):
            raise ConfigError(
                f"Mir100Config.laser_noise_sigma = {self.laser_noise_sigma}; expected >= 0"
            )

    @property
    def limits(self) -> DriveLimits:
        return DriveLimits(
            self.max_linear_velocity,
            self.max_angular_velocity,
            self.max_linear_acceleration,
            self.max_angular_acceleration,
        )

    def handler_config(self) -> CommandHandlerConfig:
        try:
            return CommandHandlerConfig(self.action_cycle, self.actuation_cycle, self.repeat)
        except ValueError as err:
            raise ConfigError(f"Mir100Config command-handler timing: {err}") from err


_IGNORED_OPTIONS = frozenset({"gui", "gazebo_gui", "rviz_gui", "server_port"})
"""Launch arguments that only concern GUIs or the manager."""
_POSE_OPTIONS = ("robot_x", "robot_y", "robot_yaw")


def parse_options(model: str, scene: str | None, options: Mapping[str, str]) -> Mir100Config:
    """A Mir100Config from robo-gym launch arguments, without building anything (no PyBullet),
    so the server manager can refuse bad options before it starts a server.

    Args:
        model: must be ``mir100``.
        scene: ``empty`` or ``lab_6x8``; None = from ``world_name`` (default
            ``empty_world_target.world``, as ``sim_robot_server.launch``).
        options: ``world_name``, ``robot_x``, ``robot_y``, ``robot_yaw``; GUI arguments and
            ``server_port`` are ignored; anything else raises ConfigError.
    """
    if model != "mir100":
        raise UnknownRobotError(f"make_mir100 builds model 'mir100', got {model!r}")
    known = {"world_name", *_POSE_OPTIONS}
    unknown = sorted(k for k in options if k not in known and k not in _IGNORED_OPTIONS)
    if unknown:
        raise ConfigError(
            f"unknown MiR100 options {preview(unknown)}; known: {sorted(known | _IGNORED_OPTIONS)}"
        )
    resolved = _resolve_scene(scene, options.get("world_name"))
    pose = tuple(_float_option(options, name) for name in _POSE_OPTIONS)
    try:
        return Mir100Config(scene=resolved, initial_pose=pose)  # type: ignore[arg-type]
    except ConfigError as err:  # only the pose can be wrong here: say which options made it
        raise ConfigError(f"MiR100 options robot_x, robot_y, robot_yaw: {err}") from None


def _resolve_scene(scene: str | None, world_name: str | None) -> str:
    from_world = scene_for_world(world_name) if world_name is not None else None
    if scene is not None and from_world is not None and check_scene(scene) != from_world:
        raise ConfigError(
            f"scene {scene!r} contradicts world_name {world_name!r} (scene {from_world!r})"
        )
    return check_scene(scene or from_world or Mir100Config.scene)


def _float_option(options: Mapping[str, str], name: str) -> float:
    return parse_option_number(name, options.get(name, "0.0"))  # range: Mir100Config checks it
