"""The MiR100's worlds: robo-gym's ``lab_6x8.world`` and ``empty_world_target.world``.

Everything is static (mass 0): the base is kinematic and the cubes are only ever teleported by
SetState, so no body needs dynamics and the world is never physics-stepped. Unlike Gazebo, where
the 1 kg cubes can be pushed, here a cube stops the robot like a wall does.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from robogym_ray.errors import UnknownRobotError

if TYPE_CHECKING:  # the option parser reads the scenes without PyBullet
    from robogym_ray.robots.sim import PyBulletWorld

OBSTACLES = ("obstacle_0", "obstacle_1", "obstacle_2")
"""Body names of the cubes SetState places (state[1021:1030])."""
CUBE_SIZE = 0.5
"""Edge of an obstacle cube (m); its centre sits at half that height."""
TARGET_MARKER_Z = 0.25
"""Height of the visual target marker (m); it has no collision shape, so lasers ignore it."""

LAB_ORIGIN = (-0.027, 0.014)
"""Position of the Gazebo ``lab_6x8`` wall model in the world (m)."""
WALL_THICKNESS = 0.15
WALL_HEIGHT = 0.5
# (name, centre in the wall model's frame, half extents along x and y)
LAB_WALLS = (
    ("wall_north", (0.0, 3.925), (3.0, WALL_THICKNESS / 2)),
    ("wall_south", (0.0, -3.925), (3.0, WALL_THICKNESS / 2)),
    ("wall_east", (2.925, 0.0), (WALL_THICKNESS / 2, 4.0)),
    ("wall_west", (-2.925, 0.0), (WALL_THICKNESS / 2, 4.0)),
)
# Start-up cube positions, clear of the default robot pose (0, 0); envs move them on reset.
_INITIAL_CUBES = ((-2.0, 1.5), (0.0, 1.5), (2.0, 1.5))

SCENES = ("lab_6x8", "empty")
"""Known scene names; the first is the default."""
WORLD_NAMES: Mapping[str, str] = {
    "lab_6x8.world": "lab_6x8",
    "empty_world_target.world": "empty",
}
"""robo-gym ``world_name:=`` launch values and the scene each maps to."""


def check_scene(scene: str) -> str:
    """Return ``scene`` if known, else raise UnknownRobotError naming the known scenes."""
    if scene not in SCENES:
        raise UnknownRobotError(
            f"unknown MiR100 scene {scene!r}; known scenes: {', '.join(SCENES)}"
        )
    return scene


def scene_for_world(world_name: str) -> str:
    """Map a robo-gym ``world_name`` launch value to a scene name."""
    try:
        return WORLD_NAMES[world_name]
    except KeyError:
        raise UnknownRobotError(
            f"unknown MiR100 world_name {world_name!r}; known worlds: {', '.join(WORLD_NAMES)}"
        ) from None


def build_scene(world: PyBulletWorld, scene: str) -> tuple[str, ...]:
    """Add ground, target marker and (lab) walls and cubes to ``world``.

    Returns:
        The names of the bodies the robot can collide with (walls and cubes).
    """
    check_scene(scene)
    world.add_plane("ground")
    world.add_sphere(
        "target", 0.1, (0.0, 0.0, TARGET_MARKER_Z), collision=False, rgba=(0.9, 0.1, 0.1, 0.8)
    )
    if scene == "empty":
        return ()
    ox, oy = LAB_ORIGIN
    for name, (cx, cy), (hx, hy) in LAB_WALLS:
        world.add_box(name, (hx, hy, WALL_HEIGHT / 2), (ox + cx, oy + cy, WALL_HEIGHT / 2))
    half = CUBE_SIZE / 2
    for name, (x, y) in zip(OBSTACLES, _INITIAL_CUBES, strict=True):
        world.add_box(name, (half, half, half), (x, y, half), rgba=(0.2, 0.4, 0.8, 1.0))
    return tuple(name for name, _, _ in LAB_WALLS) + OBSTACLES
