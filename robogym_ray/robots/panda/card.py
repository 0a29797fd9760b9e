"""The Panda's card: what code outside ``robots/panda/`` may know about it.

Everything is read from ``model.py`` (Franka's DH table and limits) and ``state.py`` (the key
set), so each number is written once. Plain data plus numpy: importing this module imports no
PyBullet. The joint position limits are asymmetric (``Limits.lower`` / ``upper``); the real
robot's commands are absolute joint targets in joint order 1-7, as robo-gym 2.1.0 sends them.
"""

from __future__ import annotations

from robogym_ray.robots.card import (
    EmulationHooks,
    Geometry,
    LaunchFamily,
    Limits,
    RobotCard,
    SafetyLimits,
    StateLayout,
    StateSlot,
)
from robogym_ray.robots.panda.model import (
    DH,
    EE_FRAMES,
    FLANGE_D,
    JOINT_NAMES,
    LOWER,
    MAX_VELOCITY,
    UPPER,
)
from robogym_ray.robots.panda.state import RS_MODE_KEYS

_LOWER = tuple(float(v) for v in LOWER)
_UPPER = tuple(float(v) for v in UPPER)

CARD = RobotCard(
    name="panda",
    family="panda",
    kind="arm",
    limits=Limits(
        names=JOINT_NAMES,
        lower=_LOWER,
        upper=_UPPER,
        velocity=tuple(float(v) for v in MAX_VELOCITY),
    ),
    safety=SafetyLimits(low=_LOWER, high=_UPPER),
    # The controller is kinematic: no acceleration limit to scale.
    emulation=EmulationHooks(
        velocity_fields=("max_velocity_scale_factor",), joint_group="joints", joint_count=7
    ),
    # Franka's modified-DH rows (a, d, alpha) of joints 1-7, flattened, then the flange offset.
    # The base stays at the world origin: panda_robot_server.launch accepts x ... yaw (robo-gym's
    # IsaacReachPanda sends z:=0.0) but ignores them, so base_height_option is None.
    geometry=Geometry(dh=tuple(v for row in DH for v in row) + (FLANGE_D,), ee_frames=EE_FRAMES),
    # panda_robot_server.launch serves one robot: no model argument.
    launch=LaunchFamily("panda_robot_server.launch"),
    state=StateLayout(
        length=len(RS_MODE_KEYS["only_robot"]),
        slots=(
            StateSlot("joint_positions", 0, 7),
            StateSlot("joint_velocities", 7, 14),
            StateSlot("joint_efforts", 14, 21),
            StateSlot("ee", 21, 28),
            StateSlot("collision", 28, 29),
        ),
        keys=RS_MODE_KEYS["only_robot"],
    ),
    factory="robogym_ray.robots.panda.robot:make_panda",
    option_parser="robogym_ray.robots.panda.config:parse_options",
)
CARDS: dict[str, RobotCard] = {CARD.name: CARD}
"""Registry name -> card (what ``robots/registry.py`` reads)."""
