"""A UR arm from a three-quarter view: the links from forward kinematics of the joint state,
the target, the objects the task moves, and the ground.

The arm is drawn from the joint positions in the state message with the same numpy forward
kinematics the robot side builds its URDF from (``robots.ur_model``), so a real arm renders as
its twin. Points are in ``base_link``; the ground lies 0.1 m below it (``BASE_LINK_HEIGHT``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from robogym_ray.envs.render.canvas import Canvas, PerspectiveProjection, RenderConfig, ViewCamera
from robogym_ray.robots.ur.geometry import BASE_LINK_HEIGHT, UR_MODELS, forward_kinematics

LINK, JOINT, TOOL = (110, 130, 160), (50, 55, 70), (240, 150, 30)
TARGET, OBJECT, GRID, COLLIDED = (40, 170, 60), (210, 60, 60), (200, 200, 195), (220, 40, 40)
_CHAIN = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link",
          "wrist_3_link", "tool0")  # fmt: skip


def default_camera(model: str) -> ViewCamera:
    """A three-quarter view that fits the arm's reach."""
    spec = UR_MODELS[model]
    reach = spec.d1 + abs(spec.a2) + abs(spec.a3) + spec.d5
    return ViewCamera(
        eye=(1.15 * reach, -1.45 * reach, 0.95 * reach), target=(0.0, 0.0, 0.25 * reach)
    )


def arm_points(model: str, q_env: Sequence[float]) -> np.ndarray:
    """The arm's skeleton in ``base_link``: ground, base, joints (and elbow corner), tool0."""
    frames = forward_kinematics(model, np.asarray(q_env, dtype=np.float64))
    spec = UR_MODELS[model]
    points = [np.array([0.0, 0.0, -BASE_LINK_HEIGHT]), np.zeros(3)]  # pedestal, base_link
    for name in _CHAIN:
        xyz, quat = frames[name]
        if name == "wrist_1_link":  # the forearm runs along a3, then steps sideways by d4
            fxyz, fquat = frames["forearm_link"]
            points.append(fxyz + Rotation.from_quat(fquat).apply((spec.a3, 0.0, 0.0)))
        points.append(xyz)
    return np.array(points)


def _ground(canvas: Canvas, project: PerspectiveProjection, half: float) -> None:
    z = -BASE_LINK_HEIGHT
    for v in np.linspace(-half, half, 9):
        for a, b in (((v, -half, z), (v, half, z)), ((-half, v, z), (half, v, z))):
            px, depth = project(np.array([a, b]))
            if np.all(depth > 0):
                canvas.line(px, GRID, width=1)


def draw_ur(
    model: str,
    q_env: Sequence[float],
    cfg: RenderConfig,
    *,
    target: Sequence[float] | None = None,
    objects: Sequence[Sequence[float]] = (),
    collided: bool = False,
    caption: str = "",
) -> np.ndarray:
    """A ``uint8`` H x W x 3 frame of a UR arm.

    Args:
        model: ur3 ... ur16e.
        q_env: joint positions (rad), env order.
        cfg: size and camera (default: ``default_camera(model)``).
        target: the end-effector target in ``base_link`` (m), if the task has one.
        objects: positions of the task's other objects (obstacles) in ``base_link``.
        collided: draw the arm in red (the server reported a collision).
        caption: text drawn in the top-left corner.
    """
    camera = cfg.camera if isinstance(cfg.camera, ViewCamera) else default_camera(model)
    project = PerspectiveProjection(camera, cfg.width, cfg.height)
    canvas = Canvas(cfg)
    spec = UR_MODELS[model]
    _ground(canvas, project, 1.2 * (abs(spec.a2) + abs(spec.a3)))
    points = arm_points(model, q_env)
    px, depth = project(points)
    # Painter's order: the farthest pieces first, so nearer links cover them.
    items: list[tuple[float, str, np.ndarray, float]] = []
    for i in range(len(points) - 1):
        seg_depth = float(depth[i : i + 2].mean())
        items.append((seg_depth, "link", px[i : i + 2], spec.link_radius))
    for i in range(1, len(points) - 1):
        items.append((float(depth[i]) - 1e-3, "joint", px[i : i + 1], spec.link_radius * 1.2))
    spheres = [(o, "object", 0.1) for o in objects]
    if target is not None:
        spheres.append((target, "target", 0.05))
    for xyz, kind, radius in spheres:
        opx, odepth = project(np.asarray(xyz, float)[None])
        items.append((float(odepth[0]), kind, opx, radius))
    items.append((float(depth[-1]) - 2e-3, "tool", px[-1:], spec.link_radius * 0.9))
    for d, kind, pts, radius in sorted(items, key=lambda item: -item[0]):
        if d <= 0:
            continue
        size = project.focal * radius / d
        if kind == "link":
            canvas.line(pts, COLLIDED if collided else LINK, width=int(2 * size))
        else:
            color = {"joint": JOINT, "tool": TOOL, "target": TARGET, "object": OBJECT}[kind]
            canvas.disc(pts[0], size, color)
    if caption:
        canvas.text((6, 4), caption)
    return canvas.array()
