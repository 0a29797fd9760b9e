"""The UR arms' cards, one per model: what code outside ``robots/ur/`` may know about them.

Everything is read from ``geometry.py`` (the DH table, joint limits, Vabs per model, the base
height and its launch argument, the end-effector frames) and ``state.py`` (the key sets), so
each number is written once. Plain data plus numpy: importing this module imports no PyBullet.
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
from robogym_ray.robots.ur.geometry import (
    BASE_HEIGHT_OPTION,
    BASE_LINK_HEIGHT,
    EE_FRAMES,
    JOINT_NAMES,
    POSITION_LIMITS,
    ROS_FROM_ENV,
    UR_MODELS,
    URModel,
)
from robogym_ray.robots.ur.state import RS_MODE_KEYS

LAUNCH_FILE = "ur_robot_server.launch"
MODEL_ARGUMENT = "ur_model"

_POSITION = tuple(float(v) for v in POSITION_LIMITS)
_ROS_POSITION = tuple(_POSITION[i] for i in ROS_FROM_ENV)
# The flat state of the default rs_mode (only_robot), spec c.2.1: joints in ROS order.
_STATE = StateLayout(
    length=len(RS_MODE_KEYS["only_robot"]),
    slots=(
        StateSlot("joint_positions", 0, 6),
        StateSlot("joint_velocities", 6, 12),
        StateSlot("ee", 12, 19),
        StateSlot("collision", 19, 20),
    ),
    keys=RS_MODE_KEYS["only_robot"],
)


def _card(model: URModel) -> RobotCard:
    return RobotCard(
        name=model.name,
        family="ur",
        kind="arm",
        limits=Limits(names=JOINT_NAMES, position=_POSITION, velocity=model.max_velocity),
        # Absolute joint targets on the wire, ROS order (spec e.2).
        safety=SafetyLimits(low=tuple(-h for h in _ROS_POSITION), high=_ROS_POSITION),
        # The controller is kinematic: no acceleration limit to scale.
        emulation=EmulationHooks(
            velocity_fields=("max_velocity_scale_factor",), joint_group="joints", joint_count=6
        ),
        geometry=Geometry(
            dh=model.dh,
            base_height=BASE_LINK_HEIGHT,
            base_height_option=BASE_HEIGHT_OPTION,
            ee_frames=EE_FRAMES,
        ),
        launch=LaunchFamily(LAUNCH_FILE, MODEL_ARGUMENT, model.name),
        state=_STATE,
        # The README's UR10 env, whose options (rs_mode 1object, 10 Hz, ...) are the same for
        # every model; the launch file's defaults (rs_mode only_robot, 25 Hz) serve no task
        # but EmptyEnvironment, and that one at another rate.
        serve_env="RoboGymRay/EndEffectorPositioningUR10Rob-v0",
        factory="robogym_ray.robots.ur.model:make_ur",
        option_parser="robogym_ray.robots.ur.config:parse_options",
    )


CARDS: dict[str, RobotCard] = {name: _card(model) for name, model in UR_MODELS.items()}
"""Registry name (ur3 ... ur16e) -> card (what ``robots/registry.py`` reads)."""
