"""A robot card: everything the rest of the package may know about one robot, as plain data.

A robot is one folder, ``robogym_ray/robots/<family>/``, holding its model, config, state layout
and a ``card.py`` that defines one ``RobotCard`` per registry name (``CARDS``). The registry
(``robots/registry.py``) maps names to cards; everything outside the folder - the server
manager's launch-command parsing, the real-robot safety filter, hardware emulation, the envs'
joint limits - reads the card instead of naming the robot.

Cards are plain data: this module and every ``<family>/card.py`` import neither PyBullet nor the
robot's model, so the server manager, the real-robot client and the tests can read limits
without building a simulator. What must be built (the robot, its option parser) is named by an
import path (``"package.module:attribute"``) and imported only when used.

Writing a card for a new robot (an example: ``robots/ur/card.py``, ``robots/mir100/card.py``)::

    CARD = RobotCard(
        name="panda", family="panda",
        limits=Limits(names=(...7 joints...), lower=(...), upper=(...), velocity=(...)),
        safety=SafetyLimits(low=(...), high=(...)),           # None: no real robot behind it
        emulation=EmulationHooks(velocity_fields=("max_velocity_scale_factor",)),
        geometry=Geometry(dh=(...), ee_frames=("panda_hand", ...)),  # base: footprint=(l, w, h)
        launch=LaunchFamily("panda_robot_server.launch"),     # or with model_argument="..."
        state=StateLayout(length=..., slots=(StateSlot("joints", 0, 7), ...), keys=(...)),
        factory="robogym_ray.robots.panda.robot:make_panda",
        option_parser="robogym_ray.robots.panda.config:parse_options",
    )
    CARDS = {CARD.name: CARD}

and one line in ``registry.py``: ``"robogym_ray.robots.panda.card"`` in ``CARD_MODULES``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Limits:
    """What the simulated robot's controller allows, per command element.

    Arms: one entry per joint, in the robot's own (model/URDF) joint order. Mobile bases: one
    entry per twist element (``names`` e.g. ``("linear", "angular")``), no position limits.
    """

    names: tuple[str, ...]
    """Joint names (arms) or twist element names (bases), in the order of the other fields."""
    velocity: tuple[float, ...]
    """Largest |velocity| per element (rad/s, or m/s for a base's linear element)."""
    position: tuple[float, ...] | None = None
    """Largest |position| per joint (rad) when the limits are symmetric; None for a base or
    when ``lower`` / ``upper`` give them."""
    acceleration: tuple[float, ...] | None = None
    """Largest |acceleration| per element (rad/s^2, m/s^2); None when the controller has none
    (the UR's kinematic trajectory controller)."""
    lower: tuple[float, ...] | None = None
    """Lowest position per joint (rad), for asymmetric limits (with ``upper``, not ``position``)."""
    upper: tuple[float, ...] | None = None
    """Highest position per joint (rad), for asymmetric limits (with ``lower``)."""

    def __post_init__(self) -> None:
        n = len(self.names)
        for name in ("velocity", "position", "acceleration", "lower", "upper"):
            value = getattr(self, name)
            if value is not None and len(value) != n:
                raise ValueError(f"Limits.{name} has {len(value)} entries for {n} names")
        if (self.lower is None) != (self.upper is None):
            raise ValueError("Limits.lower and Limits.upper come together")
        if self.lower is not None and self.position is not None:
            raise ValueError("Limits: give position (symmetric) or lower/upper, not both")
        if self.lower is not None and self.upper is not None:
            pairs = zip(self.names, self.lower, self.upper, strict=True)
            bad = [name for name, lo, hi in pairs if not lo <= hi]
            if bad:
                raise ValueError(f"Limits: lower > upper for {bad}")

    @property
    def position_range(self) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
        """``(lower, upper)`` per joint (rad), symmetric or not; None without position limits."""
        if self.lower is not None and self.upper is not None:
            return self.lower, self.upper
        if self.position is not None:
            return tuple(-v for v in self.position), self.position
        return None


@dataclass(frozen=True)
class SafetyLimits:
    """Limits of the commands the *real* robot accepts (what ``realrobot.SafetyConfig`` takes).

    One entry per element of the action robo-gym sends on the wire (``SendAction``), in wire
    order (the UR: ROS order ``[elbow, lift, pan, wrist_1, wrist_2, wrist_3]``).
    """

    low: tuple[float, ...]
    """Lowest allowed value of each action element (m/s, rad/s or rad)."""
    high: tuple[float, ...]
    """Highest allowed value of each action element."""
    max_step: tuple[float, ...] | None = None
    """Largest allowed change of an element between two commands; None: no limit."""


@dataclass(frozen=True)
class EmulationHooks:
    """How ``robots/emulation.py`` makes this robot imperfect (``--emulate-hardware``).

    Dynamics are scaled by rebuilding the robot as ``type(robot)(replace(robot.config,
    **scaled), seed=seed)``, so the robot class must take ``(config, seed=...)``; the fields
    named here are multiplied by ``EmulationConfig.velocity_scale`` / ``acceleration_scale``.
    """

    velocity_fields: tuple[str, ...] = ()
    """Config fields scaled by ``velocity_scale``."""
    acceleration_fields: tuple[str, ...] = ()
    """Config fields scaled by ``acceleration_scale`` (none: the robot has no such limit)."""
    laser_groups: tuple[str, ...] = ()
    """Sensor groups of laser ranges: get range noise, clipped to the config's
    ``laser_range_min`` / ``laser_range_max``."""
    joint_group: str | None = None
    """Sensor group whose first ``joint_count`` values are encoder positions: get joint noise."""
    joint_count: int = 0
    """How many joint positions lead ``joint_group``."""
    fixed_obstacles: str | None = None
    """``StateLayout`` slot of write-only obstacle poses that an all-zero SetState leaves where
    they stand (a real server takes only the target); None: SetState moves everything."""


@dataclass(frozen=True)
class Geometry:
    """Shape of the robot, as far as code outside its folder needs it."""

    dh: tuple[float, ...] | None = None
    """Arms: the DH parameters (m), for the UR ``(d1, a2, a3, d4, d5, d6)`` of
    ``ur_description``'s ``default_kinematics.yaml``; the model module owns their meaning."""
    footprint: tuple[float, float, float] | None = None
    """Bases: collision box (length, width, height) in m."""
    base_height: float = 0.0
    """Height of the robot's base frame above the world origin (m), by default."""
    base_height_option: str | None = None
    """The launch argument that moves the base up or down (the UR's ``z``); None when the
    launch file pins the base at ``base_height`` (the Panda's accepts ``z`` and ignores it)."""
    ee_frames: tuple[str, ...] = ()
    """Arms: the frames the ``ee_frame`` launch argument may name (the state's ``ee_to_ref_*``
    pose), the launch file's default first."""


@dataclass(frozen=True)
class LaunchFamily:
    """The robo-gym launch command (ServerManager ``cmd``) that asks for this robot.

    ``roslaunch <package> <launch_file> ... [<model_argument>:=<model_value>] ...``: a card answers
    a command when the launch file matches and, if ``model_argument`` is set, that argument's
    value equals ``model_value`` (or the command leaves it out and the card is the ``default``).
    """

    launch_file: str
    """The third token, e.g. ``ur_robot_server.launch``."""
    model_argument: str | None = None
    """Launch argument that picks the model within the launch file (``ur_model``); None when
    the launch file serves one robot only."""
    model_value: str | None = None
    """The ``model_argument`` value of this card (``ur5``)."""
    default: bool = False
    """This card answers a command that leaves ``model_argument`` out (the launch file's
    default model: the Panda for ``panda_robot_server.launch``, whose ``robot`` argument names
    the Franka arm as franka_ros's launch files do, ``panda`` or ``fr3``)."""


@dataclass(frozen=True)
class StateSlot:
    """A named range ``[start, stop)`` of the flat robo-gym state vector."""

    name: str
    start: int
    stop: int

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)


@dataclass(frozen=True)
class StateLayout:
    """The robo-gym state this robot's server sends (``State.state`` and ``State.state_dict``).

    For a robot whose layout depends on a mode (the UR's ``rs_mode``) this is the default
    mode's layout; the state module in the robot's folder has the others.
    """

    length: int
    """Length of the flat ``state`` vector."""
    slots: tuple[StateSlot, ...] = ()
    """Named ranges of the flat vector, in order."""
    keys: tuple[str, ...] = ()
    """``state_dict`` keys (empty: the robot sends no state_dict)."""

    def slot(self, name: str) -> slice:
        """The range of the slot ``name`` (KeyError if the layout has none)."""
        for s in self.slots:
            if s.name == name:
                return s.slice
        raise KeyError(f"state slot {name!r}; slots: {[s.name for s in self.slots]}")


@dataclass(frozen=True)
class HardwareBackends:
    """A card's real-robot backends and the limits its resets keep to."""

    factories: Mapping[str, str] = field(default_factory=dict)
    """Backend name (``--hardware``) -> ``"module:function"``, called as
    ``factory(model, options, hardware: HardwareConfig)``."""
    max_dynamics_factor: float = 0.3
    """The highest ``--dynamics-factor`` a reset may use (fraction of the arm's published
    velocity, acceleration and jerk limits)."""


@dataclass(frozen=True)
class RobotCard:
    """One robot: its registry name and everything code outside its folder may know about it."""

    name: str
    """Registry name (``mir100``, ``ur5`` ...): what ``make_robot`` and the envs'
    ``server_spec()`` use."""
    family: str
    """The folder under ``robogym_ray/robots/`` (``mir100``, ``ur``); one family, many models."""
    kind: str
    """``arm`` or ``base``."""
    limits: Limits
    """The simulated controller's limits (defaults of the robot's config)."""
    launch: LaunchFamily
    """The robo-gym launch command that asks for this robot."""
    state: StateLayout
    """The state vector / dict layout on the wire."""
    factory: str
    """``"module:function"`` building the robot: ``factory(model=, scene=, seed=, options=)``."""
    option_parser: str
    """``"module:function"``: ``parser(model, scene, options)`` raises what ``factory`` would
    raise for bad options, without building anything."""
    geometry: Geometry = field(default_factory=Geometry)
    safety: SafetyLimits | None = None
    """Limits of the real robot's commands; None: no real robot known (Rob variants refuse)."""
    emulation: EmulationHooks = field(default_factory=EmulationHooks)
    """How hardware emulation scales and perturbs this robot."""
    hardware: HardwareBackends | None = None
    """The real robot's backends for ``serve --hardware`` (``robots/hardware.py``); None: the
    robot is served only simulated."""
    serve_env: str | None = None
    """The env id whose server a plain ``robogym-ray serve --robot NAME`` starts: the scene and
    launch options of its ``server_spec()`` are serve's defaults (``--scene`` and each
    ``--option`` replace theirs), so the robot's README env needs no option. None: the launch
    file's defaults. The server manager ignores it: robo-gym's envs send their options."""

    def __post_init__(self) -> None:
        if self.kind not in ("arm", "base"):
            raise ValueError(f"RobotCard {self.name}: kind {self.kind!r}, expected arm or base")
        if self.kind == "arm" and self.limits.position_range is None:
            raise ValueError(f"RobotCard {self.name}: an arm needs position limits")
        if self.kind == "arm" and not self.geometry.ee_frames:
            raise ValueError(f"RobotCard {self.name}: an arm names its end-effector frames")
        for path in (self.factory, self.option_parser):
            if path.count(":") != 1:
                raise ValueError(f"RobotCard {self.name}: {path!r} is not 'module:attribute'")

    def load_factory(self) -> Callable[..., Any]:
        """The robot factory (imports the robot's model, PyBullet included)."""
        return load(self.factory)

    def load_option_parser(self) -> Callable[..., Any]:
        """The option parser (no PyBullet)."""
        return load(self.option_parser)


def load(path: str) -> Any:
    """Import ``"package.module:attribute"`` and return the attribute."""
    module_name, _, attr = path.partition(":")
    return getattr(importlib.import_module(module_name), attr)
