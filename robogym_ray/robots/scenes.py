"""The worlds robo-gym's arm servers load, as PyBullet scenes (robo-gym-robot-servers 2.1.0).

The UR and Panda launch files both take ``world_name`` from the same ROS package
(``simulation_objects/worlds``), so the worlds are described once, here, and each arm's config
maps ``world_name`` through ``WORLDS``. What matters to a kinematic arm is what it can touch: the
ground, the tables, and whether the object spheres collide (``sphere50`` vs
``sphere50_no_collision``). Gravity does not (the ``_no_gravity`` twins map to the same scene),
and neither do lights or colours.

Every height is in the world frame. Where the robot stands is its own launch argument (the UR's
``z``, default 0.1 m, puts ``base_link`` at world (0, 0, z); the Panda is pinned at the origin).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the configs import this module, and they must not import PyBullet
    from robogym_ray.robots.sim import PyBulletWorld

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Box:
    """A static box, world frame."""

    half_extents: Vec3
    centre: Vec3


@dataclass(frozen=True)
class ArmScene:
    """What surrounds an arm."""

    ground_z: float = 0.0
    """Height of the ground plane (m)."""
    tables: tuple[Box, ...] = ()
    """Static boxes the arm can touch (contacts count like Gazebo's contact sensors)."""
    object_collision: bool = False
    """Whether the object spheres collide with the arm (``sphere50``; ``sphere50_no_collision``
    does not)."""


TABLETOP = Box((0.5, 0.5, 0.05), (-0.05, 0.2, 0.05))
"""``simulation_objects/models/tabletop``: 1.0 x 1.0 x 0.1 m, placed at (-0.05, 0.2, 0.05), so
its top is at z = 0.1, where the UR's base_link stands by default."""
ISAAC_DEMO_TABLE = Box((0.635, 0.45, 0.5), (0.4, 0.0, -0.5))
"""``isaac_demotable_cuboid``: 1.27 x 0.9 x 1 m, offset 0.4 m along x from its origin, which
the world puts at (0, 0, 0) - the robot's mounting point - so its top is at z = 0. Its Gazebo
collision has ``collide_without_contact``: no contact forces, but the contact sensors still
report touching it, so it counts as a collision here too."""

SCENES: dict[str, ArmScene] = {
    "empty": ArmScene(),
    "tabletop": ArmScene(tables=(TABLETOP,), object_collision=True),
    "tabletop_no_collision": ArmScene(tables=(TABLETOP,)),
    # The world lowers the ground 1 m "so we can see the table": it is the table's foot.
    "isaactabletop": ArmScene(ground_z=-1.0, tables=(ISAAC_DEMO_TABLE,)),
}
"""Scene name -> scene (a scene name is also accepted where a world file is)."""
WORLDS: dict[str, str] = {
    "empty.world": "empty",
    "empty_no_gravity.world": "empty",
    "tabletop_sphere50.world": "tabletop",
    "tabletop_sphere50_no_collision.world": "tabletop_no_collision",
    "tabletop_sphere50_no_collision_no_gravity.world": "tabletop_no_collision",
    "isaactabletop_sphere50_no_collision.world": "isaactabletop",
    "isaactabletop_sphere50_no_collision_no_gravity.world": "isaactabletop",
}
"""robo-gym ``world_name`` -> scene name."""


def add_scene(world: PyBulletWorld, scene: ArmScene) -> None:
    """Add the ground and the tables of ``scene`` to ``world``."""
    ground = world.add_plane("ground")
    if scene.ground_z:
        world.client.resetBasePositionAndOrientation(
            ground, [0.0, 0.0, scene.ground_z], [0.0, 0.0, 0.0, 1.0]
        )
    for i, table in enumerate(scene.tables):
        world.add_box(f"table_{i}" if i else "table", table.half_extents, table.centre)
