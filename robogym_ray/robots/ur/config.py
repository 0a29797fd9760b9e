"""Configuration of a simulated UR arm and its parsing from launch-argument options (spec b.5)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from robogym_ray.errors import ConfigError, UnknownRobotError
from robogym_ray.robots.scenes import SCENES, WORLDS
from robogym_ray.robots.ur.card import CARDS
from robogym_ray.robots.ur.geometry import BASE_LINK_HEIGHT, UR_MODELS
from robogym_ray.robots.ur.state import RS_MODES
from robogym_ray.robots.validation import (
    check_option_names,
    check_range,
    parse_cycle_option,
    parse_option_bool,
    parse_option_number,
    resolve_scene,
)

DEFAULT_SCENE = "empty"
"""The launch file's default world is empty.world."""
BASE_HEIGHTS = (-2.0, 2.0)
"""Accepted base heights (m, option ``z``). robo-gym sends 0.0 (IsaacReach) or leaves the
default 0.1; beyond a couple of metres the arm is nowhere near the ground or a table, and a
base 3e38 m up is a client bug, not a pose."""

IGNORED_OPTIONS = frozenset(
    {"gui", "rviz_gui", "gazebo_gui", "server_port", "object_0_model_name", "object_0_frame",
     "object_1_model_name", "object_1_frame", "object_trajectory_file_name", "target_mode"}
)  # fmt: skip
"""Accepted and ignored: GUIs do not exist in DIRECT mode; object models/frames are fixed by the
scene (spheres of 0.025 m, frame ``target``); target_mode only matters via rs_mode."""
_MUST_BE_FALSE = ("real_robot", "use_voxel_occupancy")
"""Accepted only as false: there is no real robot or voxel occupancy behind a simulated arm."""

ACTION_CYCLE_RATES = (1.0, 1000.0)
"""Accepted ``action_cycle_rate`` (Hz). robo-gym uses 10-25 Hz. Each SendAction simulates one
action cycle of 125 Hz controller ticks, so a rate of 0.001 Hz would make every call simulate
1,000 s (125,000 ticks); below 1 Hz an arm is not being controlled any more. Rates above the
controller's 125 Hz are refused by URConfig with their own message."""

ACTION_MODES = ("abs_pos", "delta_pos", "servo_pos")
"""robo-gym's two trajectory modes, and the streaming servo of Isaac Lab's deploy tasks."""

_HANDLED = frozenset(
    {"world_name", "rs_mode", "action_mode", "reference_frame", "max_velocity_scale_factor",
     "action_cycle_rate", "objects_controller", "n_objects", "ur_model", "ee_frame"}
)  # fmt: skip
"""The options handled here; the base height's (``z``) comes from the card."""


@dataclass(frozen=True)
class URConfig:
    """One simulated UR arm (the ur_robot_server launch arguments we honour)."""

    model: str = "ur5"
    """ur3 | ur3e | ur5 | ur5e | ur10 | ur10e | ur16e."""
    scene: str = DEFAULT_SCENE
    """A scene of ``robots/scenes.py`` (``world_name`` picks it through ``WORLDS``)."""
    rs_mode: str = "only_robot"
    """only_robot | 1object | 1moving2points | 2objects2points: which state keys are served
    (default as ur_robot_server.launch: rs_mode false -> target_mode only_robot)."""
    action_mode: str = "abs_pos"
    """abs_pos: actions are absolute joint targets; delta_pos: targets = current + action (both
    followed as robo-gym's trajectories of >= 0.5 s); servo_pos (ours, not robo-gym's): absolute
    targets streamed to a PD servo that tracks each until the next (``servo.py``)."""
    reference_frame: str = "base_link"
    """base_link, or base (base_link rotated pi about z: x and y negated)."""
    ee_frame: str = "tool0"
    """The frame reported as ``ee_to_ref_*``: one of the card's ``ee_frames`` (tool0, or
    IsaacLab's tool1)."""
    base_height: float = BASE_LINK_HEIGHT
    """base_link's height above the world origin (m; option ``z``)."""
    max_velocity_scale_factor: float = 1.0
    """vmax_j = factor x Vabs_j for the trajectory durations."""
    action_cycle: float = 0.04
    """Seconds per action (the paper's 25 Hz); option action_cycle_rate (Hz) sets 1/rate."""
    actuation_cycle: float = 0.008
    """Seconds per controller tick (the trajectory controller's 125 Hz); servo_pos ticks at
    the servo's physics step instead (1/120 s, or the action cycle split evenly below it)."""
    repeat: int | None = None
    """Ticks a command is published; None = one action cycle's worth."""
    objects_controller: bool = True
    """Accepted for compatibility; objects of the rs_mode always follow their trajectories."""
    n_objects: int = 0
    """Accepted for compatibility; the rs_mode decides how many objects exist."""

    def __post_init__(self) -> None:
        _choice("ur_model", self.model, UR_MODELS)
        _choice("scene", self.scene, SCENES)
        _choice("rs_mode", self.rs_mode, RS_MODES)
        _choice("action_mode", self.action_mode, ACTION_MODES)
        _choice("reference_frame", self.reference_frame, ("base_link", "base"))
        _choice("ee_frame", self.ee_frame, CARDS[self.model].geometry.ee_frames)
        option = CARDS[self.model].geometry.base_height_option
        check_range(f"base_height (option {option})", self.base_height, *BASE_HEIGHTS, "m",
                    ConfigError)  # fmt: skip
        for name in ("max_velocity_scale_factor", "action_cycle", "actuation_cycle"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive finite number, got {value!r}")
        if self.actuation_cycle > self.action_cycle + 1e-12:
            raise ConfigError(
                f"action_cycle ({self.action_cycle} s) must not be shorter than "
                f"actuation_cycle ({self.actuation_cycle} s): action_cycle_rate <= 125 Hz"
            )


def _choice(name: str, value: str, known: Iterable[str]) -> None:
    if value not in known:
        error = UnknownRobotError if name in ("ur_model", "scene") else ConfigError
        raise error(f"unknown {name} {value!r}; known: {', '.join(sorted(known))}")


def parse_options(model: str, scene: str | None, options: Mapping[str, str]) -> URConfig:
    """Build a URConfig from launch-argument style options; unknown options raise ConfigError."""
    opts = dict(options)
    _choice("ur_model", model, UR_MODELS)
    height_option = CARDS[model].geometry.base_height_option
    known = _HANDLED | IGNORED_OPTIONS | set(_MUST_BE_FALSE)
    check_option_names("UR", opts, known | ({height_option} if height_option else set()))
    for key in _MUST_BE_FALSE:
        if key in opts and parse_option_bool(key, opts[key]):
            raise ConfigError(f"option {key}=true is not supported by the simulated UR")
    if "ur_model" in opts and opts["ur_model"] != model:
        raise ConfigError(f"option ur_model={opts['ur_model']!r} contradicts robot {model!r}")
    kwargs: dict[str, object] = {"model": model}
    if height_option in opts:
        kwargs["base_height"] = parse_option_number(height_option, opts[height_option])
    kwargs["scene"] = resolve_scene(
        "UR", scene, opts.get("world_name"), SCENES, WORLDS, DEFAULT_SCENE
    )
    # rs_mode:=false (the launch default) means "use target_mode", as in the launch file.
    rs_mode = opts.get("rs_mode", "false")
    if rs_mode == "false":
        rs_mode = opts.get("target_mode", URConfig.rs_mode)
    kwargs["rs_mode"] = rs_mode
    for key in ("action_mode", "reference_frame", "ee_frame"):
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
        kwargs["objects_controller"] = parse_option_bool(
            "objects_controller", opts["objects_controller"]
        )
    if "n_objects" in opts:
        # the launch file does int(float(x))
        kwargs["n_objects"] = int(parse_option_number("n_objects", opts["n_objects"]))
    return URConfig(**kwargs)  # type: ignore[arg-type]
