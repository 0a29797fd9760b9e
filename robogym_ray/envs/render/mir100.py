"""The MiR100's scene from above: lab walls, cubes, target, footprint and heading, laser returns.

Everything comes from the 1030-float state message (target 0:3, pose 3:6, ranges 8:1020, cubes
1021:1030, spec c.1) and the published geometry the robot side uses (walls, cube edge,
footprint, scanner mounts), so a real, emulated or simulated robot renders alike.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robogym_ray.envs.render.canvas import Canvas, RenderConfig, TopDownCamera, TopDownProjection
from robogym_ray.robots.mir100.lasers import BACK, FRONT
from robogym_ray.robots.mir100.model import FOOTPRINT, FOOTPRINT_OFFSET
from robogym_ray.robots.mir100.scenes import CUBE_SIZE, LAB_ORIGIN, LAB_WALLS

WALL, CUBE, ROBOT, HEADING = (90, 90, 100), (70, 110, 200), (60, 60, 60), (250, 200, 40)
TARGET, LASER, PATH = (40, 170, 60), (220, 40, 40), (120, 120, 220)
SUCCESS_RADIUS = 0.2
"""The navigation tasks' success distance (m), drawn around the target."""
_ANGLES = np.concatenate([FRONT.robot_frame_angles(), BACK.robot_frame_angles()])
_MOUNTS = np.concatenate(
    [np.tile((FRONT.x, FRONT.y), (FRONT.count, 1)), np.tile((BACK.x, BACK.y), (BACK.count, 1))]
)
MAX_RANGE = 29.0
"""Ranges at or past this are 'nothing hit' and are not drawn."""


def box_corners(centre: Sequence[float], half: Sequence[float], yaw: float) -> np.ndarray:
    """The four (x, y) corners of a rectangle with half sides ``half``, turned by ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    corners = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]], float) * np.asarray(half, float)
    return np.asarray(centre[:2], float) + corners @ np.array([[c, s], [-s, c]])


def _to_world(pose: np.ndarray, local: np.ndarray) -> np.ndarray:
    x, y, yaw = pose
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([x, y]) + local @ np.array([[c, s], [-s, c]])


def laser_points(state: Sequence[float]) -> np.ndarray:
    """World (x, y) of every laser return in ``state`` (ranges past MAX_RANGE left out)."""
    s = np.asarray(state, dtype=np.float64)
    pose, ranges = s[3:6], s[8:1020]
    hit = np.isfinite(ranges) & (ranges < MAX_RANGE)
    angles = pose[2] + _ANGLES[hit]
    origins = _to_world(pose, _MOUNTS[hit])
    return origins + ranges[hit, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def draw_mir100(
    state: Sequence[float],
    cfg: RenderConfig,
    *,
    walls: bool = True,
    obstacles: np.ndarray | None = None,
    path: np.ndarray | None = None,
    caption: str = "",
) -> np.ndarray:
    """A ``uint8`` H x W x 3 frame of the MiR100 scene in ``state``.

    Args:
        state: the 1030-float MiR100 state (spec c.1).
        cfg: size and camera (default camera: ``TopDownCamera()``, the lab with a margin).
        walls: draw the lab's walls (``lab_6x8``); False for the empty world.
        obstacles: (3, 3) cube poses (x, y, yaw) the env sent in SetState; default: the state's
            1021:1030 (zeros from our servers and robo-gym's: the poses are write-only there).
            All-zero poses (robo-gym's Real env sends them) are not drawn; the laser returns
            still show the cubes.
        path: optional (n, 2) robot positions of the episode so far, drawn as a line.
        caption: text drawn in the top-left corner.
    """
    s = np.asarray(state, dtype=np.float64)
    camera = cfg.camera if isinstance(cfg.camera, TopDownCamera) else TopDownCamera()
    to_px = TopDownProjection(camera, cfg.width, cfg.height)
    canvas = Canvas(cfg)
    if walls:
        for _, (cx, cy), half in LAB_WALLS:
            canvas.polygon(
                to_px(box_corners((LAB_ORIGIN[0] + cx, LAB_ORIGIN[1] + cy), half, 0.0)), WALL
            )
    cubes = np.asarray(s[1021:1030] if obstacles is None else obstacles, float).reshape(-1, 3)
    if np.any(cubes != 0.0):  # robo-gym's Real env sends all-zero poses: nothing known to draw
        for x, y, yaw in cubes:
            canvas.polygon(to_px(box_corners((x, y), (CUBE_SIZE / 2,) * 2, yaw)), CUBE)
    target = to_px(s[0:2])[0]
    canvas.disc(target, SUCCESS_RADIUS * to_px.scale, (200, 235, 200))
    canvas.disc(target, max(3.0, 0.06 * to_px.scale), TARGET)
    if path is not None and len(path) > 1:
        canvas.line(to_px(np.asarray(path)[:, :2]), PATH, width=2)
    pose = s[3:6]
    half = (FOOTPRINT[0] / 2, FOOTPRINT[1] / 2)
    body = _to_world(pose, box_corners(FOOTPRINT_OFFSET[:2], half, 0.0))
    canvas.polygon(to_px(body), ROBOT)
    nose = _to_world(pose, np.array([[0.0, 0.0], [FOOTPRINT[0] / 2 + 0.1, 0.0]]))
    canvas.line(to_px(nose), HEADING, width=max(2, int(0.06 * to_px.scale)))
    canvas.points(to_px(laser_points(s)), LASER, size=2)
    if caption:
        canvas.text((6, 4), caption)
    return canvas.array()
