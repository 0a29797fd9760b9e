"""The Franka arms' cards: what code outside ``robots/panda/`` may know about them.

Two models, one family: the Panda and the Franka Research 3 (``fr3``) share Franka's DH table,
frames, state layout, launch options and simulated robot class; their cards differ in the
joint limits (``model.LIMITS``) and in the ``robot`` launch argument that picks them.

Everything is read from ``model.py`` (Franka's DH table and limits) and ``state.py`` (the key
set), so each number is written once. Plain data plus numpy: importing this module imports no
PyBullet. The joint position limits are asymmetric (``Limits.lower`` / ``upper``); the real
robot's commands are absolute joint targets in joint order 1-7, as robo-gym 2.1.0 sends them.
"""

from __future__ import annotations

from robogym_ray.robots.card import (
    EmulationHooks,
    Geometry,
    HardwareBackends,
    LaunchFamily,
    Limits,
    RobotCard,
    SafetyLimits,
    StateLayout,
    StateSlot,
)
from robogym_ray.robots.panda.model import DH, EE_FRAMES, FLANGE_D, JOINT_NAMES, LIMITS
from robogym_ray.robots.panda.state import RS_MODE_KEYS

LAUNCH_FILE = "panda_robot_server.launch"
"""robo-gym's Panda launch file; ``robot:=fr3`` asks it for the FR3 (robo-gym's own launch file
has no FR3, so only our server manager answers that)."""


HARDWARE = HardwareBackends(
    factories={"franky": "robogym_ray.robots.panda.franky_arm:make_franky_arm"},
    max_dynamics_factor=0.3,
)
"""The real FR3 behind ``serve --hardware franky``; resets at no more than 30 % of its limits."""


def _card(model: str) -> RobotCard:
    limits = LIMITS[model]
    lower = tuple(float(v) for v in limits.lower)
    upper = tuple(float(v) for v in limits.upper)
    return RobotCard(
        name=model,
        family="panda",
        kind="arm",
        limits=Limits(
            names=JOINT_NAMES,
            lower=lower,
            upper=upper,
            velocity=tuple(float(v) for v in limits.velocity),
        ),
        safety=SafetyLimits(low=lower, high=upper),
        # The controller is kinematic: no acceleration limit to scale.
        emulation=EmulationHooks(
            velocity_fields=("max_velocity_scale_factor",), joint_group="joints", joint_count=7
        ),
        # Franka's modified-DH rows (a, d, alpha) of joints 1-7, flattened, then the flange
        # offset. The base stays at the world origin: panda_robot_server.launch accepts x ... yaw
        # (robo-gym's IsaacReachPanda sends z:=0.0) but ignores them, so base_height_option is
        # None.
        geometry=Geometry(
            dh=tuple(v for row in DH for v in row) + (FLANGE_D,), ee_frames=EE_FRAMES
        ),
        # robo-gym's commands carry no model argument: they ask for the Panda, the default.
        launch=LaunchFamily(
            LAUNCH_FILE, model_argument="robot", model_value=model, default=model == "panda"
        ),
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
        # The FR3 through franky (libfranka 0.21, FR3 system 5.9+). A Panda (system 4.x) needs
        # libfranka < 0.10, which franky publishes only on its own index: untested, not offered.
        hardware=HARDWARE if model == "fr3" else None,
        # A plain `serve --robot fr3` (with or without --hardware) serves what the FR3's
        # positioning env expects; the Panda keeps its launch file's defaults, as before.
        serve_env="RoboGymRay/EndEffectorPositioningFR3Rob-v0" if model == "fr3" else None,
        factory="robogym_ray.robots.panda.robot:make_panda",
        option_parser="robogym_ray.robots.panda.config:parse_options",
    )


CARDS: dict[str, RobotCard] = {model: _card(model) for model in LIMITS}
"""Registry name -> card (what ``robots/registry.py`` reads): ``panda`` and ``fr3``."""
CARD = CARDS["panda"]
"""The Panda's card."""
