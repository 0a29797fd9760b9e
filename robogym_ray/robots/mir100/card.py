"""The MiR100's card: what code outside ``robots/mir100/`` may know about the robot.

The drive limits here are the defaults of ``Mir100Config`` and the footprint the base's collision
box; the state slots are ``state.py``'s. Plain data: importing this module imports no PyBullet.
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
from robogym_ray.robots.mir100 import state

VELOCITY = (1.0, 1.5)
"""Diff-drive controller limits |v| (m/s), |omega| (rad/s): robo-gym's MiR100 (spec e.1)."""
ACCELERATION = (2.0, 2.5)
"""Diff-drive controller limits |dv/dt| (m/s^2), |domega/dt| (rad/s^2)."""


def _slot(name: str, where: slice | int) -> StateSlot:
    if isinstance(where, int):
        return StateSlot(name, where, where + 1)
    return StateSlot(name, where.start, where.stop)


CARD = RobotCard(
    name="mir100",
    family="mir100",
    kind="base",
    limits=Limits(names=("linear", "angular"), velocity=VELOCITY, acceleration=ACCELERATION),
    # The real MiR takes a twist [v, omega]: the drive's own limits (spec e.1).
    safety=SafetyLimits(low=tuple(-v for v in VELOCITY), high=VELOCITY),
    emulation=EmulationHooks(
        velocity_fields=("max_linear_velocity", "max_angular_velocity"),
        acceleration_fields=("max_linear_acceleration", "max_angular_acceleration"),
        laser_groups=("f_scan", "b_scan"),
        fixed_obstacles="obstacles",
    ),
    geometry=Geometry(footprint=(0.9, 0.58, 0.3)),
    launch=LaunchFamily("sim_robot_server.launch"),
    state=StateLayout(
        length=state.STATE_LEN,
        slots=(
            _slot("target", state.TARGET),
            _slot("pose", state.POSE),
            _slot("twist", state.TWIST),
            _slot("f_scan", state.F_SCAN),
            _slot("b_scan", state.B_SCAN),
            _slot("collision", state.COLLISION),
            _slot("obstacles", state.OBSTACLES),
        ),
    ),
    factory="robogym_ray.robots.mir100.model:make_mir100",
    option_parser="robogym_ray.robots.mir100.config:parse_options",
)

CARDS = {CARD.name: CARD}
"""Registry name -> card (what ``robots/registry.py`` reads)."""
