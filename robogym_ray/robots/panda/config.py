"""Configuration of the simulated Franka arm (Panda or FR3) and its parsing from
``panda_robot_server.launch`` arguments (robo-gym-robot-servers 2.1.0)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.robots.panda.model import EE_FRAMES, LABELS, LIMITS, ArmLimits
from robogym_ray.robots.panda.state import RS_MODES
from robogym_ray.robots.scenes import SCENES, WORLDS
from robogym_ray.robots.validation import (
    check_option_names,
    parse_cycle_option,
    parse_option_bool,
    parse_option_number,
    quote,
    resolve_scene,
)

DEFAULT_WORLD = "empty.world"
"""The launch file's default; ``robots/scenes.py`` has the worlds (shared with the UR)."""
PANDA_WORLDS: dict[str, str] = {
    **WORLDS,
    "tabletop_sphere50_no_collision_no_gravity.world": "isaactabletop",
}
"""``WORLDS`` with one deliberate difference. robo-gym's EndEffectorPositioningPanda loads the
UR's tabletop world, whose table top is 0.1 m above the Panda's base (the Panda stands at the
origin, its launch file ignores ``z``): the table would enclose link 1, and every contact check
would report a collision from the first step. We serve the demo table instead, whose top is
level with the Panda's base, so the task stays the task (docs/protocol.md)."""

REFERENCE_FRAMES = ("world", "base", "panda_link0")
"""All three coincide in robo-gym's Panda launch files (identity static transforms)."""
ACTION_MODES = ("abs_pos", "delta_pos")
"""The velocity modes of the ROS bridge are not simulated (robo-gym 2.1.0's envs assert
abs_pos)."""
ACTION_CYCLE_RATES = (1.0, 1000.0)
"""Accepted ``action_cycle_rate`` (Hz); robo-gym's Panda envs send 30."""
TICK = 0.01
"""Target controller tick (s): each action is split into round(cycle / TICK) equal ticks."""

IGNORED_OPTIONS = frozenset(
    {"gui", "rviz_gui", "gazebo_gui", "server_port", "object_0_model_name", "object_0_frame",
     "object_1_model_name", "object_1_frame", "object_trajectory_file_name", "pos_action_impl",
     "subsampling_factor", "static_subsamples", "custom_joint_states_handler", "new_vel_weight",
     "new_eff_weight", "history_limit", "x", "y", "z", "roll", "pitch", "yaw"}
)  # fmt: skip
"""Accepted and ignored: GUIs; the object is a 50 mm sphere with frame ``target``; the ROS
bridge's ways of publishing position commands and averaging joint states (the kinematic
controller has no such noise); the base pose (the launch file itself ignores it: the card's
``base_height_option`` is None)."""
_HANDLED = frozenset(
    {"world_name", "rs_mode", "action_mode", "reference_frame", "ee_frame",
     "max_velocity_scale_factor", "action_cycle_rate", "objects_controller", "n_objects",
     "real_robot"}
)  # fmt: skip


@dataclass(frozen=True)
class PandaConfig:
    """One simulated Franka arm (the launch arguments we honour; defaults are the launch
    file's)."""

    model: str = "panda"
    """panda | fr3: the arm, whose joint limits (``model.LIMITS``) the robot keeps."""
    scene: str = "empty"
    rs_mode: str = "only_robot"
    """only_robot | 1object (adds the target object's pose)."""
    action_mode: str = "delta_pos"
    """abs_pos: actions are joint targets; delta_pos: targets = current + action."""
    reference_frame: str = "base"
    ee_frame: str = "panda_hand"
    max_velocity_scale_factor: float = 1.0
    """Joint speed limit = factor x the model's published limit."""
    action_cycle: float = 1.0 / 25.0
    """Seconds per action (1 / action_cycle_rate)."""

    def __post_init__(self) -> None:
        for name, value, known in (
            ("model", self.model, LIMITS),
            ("scene", self.scene, SCENES),
            ("rs_mode", self.rs_mode, RS_MODES),
            ("action_mode", self.action_mode, ACTION_MODES),
            ("reference_frame", self.reference_frame, REFERENCE_FRAMES),
            ("ee_frame", self.ee_frame, EE_FRAMES),
        ):
            if value not in known:
                error = UnknownRobotError if name in ("model", "scene") else ConfigError
                label = LABELS.get(self.model, "Panda")
                raise error(f"unknown {label} {name} {quote(value)}; known: {', '.join(known)}")
        for name in ("max_velocity_scale_factor", "action_cycle"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive finite number, got {value!r}")

    @property
    def limits(self) -> ArmLimits:
        """The model's joint limits."""
        return LIMITS[self.model]

    @property
    def label(self) -> str:
        """The model's name in messages (``Panda``, ``FR3``)."""
        return LABELS[self.model]

    @property
    def actuation_cycle(self) -> float:
        """Controller tick (s): an integral fraction of the action cycle close to ``TICK``."""
        return self.action_cycle / max(1, round(self.action_cycle / TICK))


def parse_options(model: str, scene: str | None, options: Mapping[str, str]) -> PandaConfig:
    """A PandaConfig from launch-argument options; unknown options or values raise ConfigError.

    ``model`` is the registry name (``panda`` or ``fr3``); the signature is the registry's
    option parser's.
    """
    label = LABELS.get(model, "Panda")
    opts = dict(options)
    check_option_names(label, opts, _HANDLED | IGNORED_OPTIONS)
    if parse_option_bool("real_robot", opts.get("real_robot", "false")):
        raise ConfigError(f"option real_robot=true is not supported by the simulated {label}")
    world_name = opts.get("world_name")
    kwargs: dict[str, object] = {
        "model": model,
        "scene": resolve_scene(
            label, scene, world_name, SCENES, PANDA_WORLDS, PANDA_WORLDS[DEFAULT_WORLD]
        ),
    }
    for key in ("rs_mode", "action_mode", "reference_frame", "ee_frame"):
        if key in opts:
            kwargs[key] = opts[key]
    if "max_velocity_scale_factor" in opts:
        kwargs["max_velocity_scale_factor"] = parse_option_number(
            "max_velocity_scale_factor", opts["max_velocity_scale_factor"]
        )
    if "action_cycle_rate" in opts:
        kwargs["action_cycle"] = parse_cycle_option(
            "action_cycle_rate", opts["action_cycle_rate"], ACTION_CYCLE_RATES
        )
    if "objects_controller" in opts:
        parse_option_bool("objects_controller", opts["objects_controller"])  # value checked
    if "n_objects" in opts:
        parse_option_number("n_objects", opts["n_objects"])
    return PandaConfig(**kwargs)  # type: ignore[arg-type]
