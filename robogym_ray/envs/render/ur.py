"""A UR arm from a three-quarter view: the links from forward kinematics of the joint state,
the target, the objects the task moves, and the ground.

The arm is drawn from the joint positions in the state message with the same numpy forward
kinematics the robot side builds its URDF from (``robots.ur_model``), so a real arm renders as
its twin. Points are in ``base_link``. What the arm stands on is a ``Stand``: by default the
ground 0.1 m below it (``BASE_LINK_HEIGHT``, the launch file's default base height), or, from an
env's ``server_spec()`` (``stand_of``), its world's ground and tables moved by the base height
the env launches with (the ``isaactabletop`` worlds: the demo table's top at the base, the floor
1 m below).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from robogym_ray.envs.render.canvas import Canvas, PerspectiveProjection, RenderConfig, ViewCamera
from robogym_ray.robots.scenes import SCENES, Box
from robogym_ray.robots.ur.config import parse_options
from robogym_ray.robots.ur.geometry import BASE_LINK_HEIGHT, UR_MODELS, forward_kinematics

LINK, JOINT, TOOL = (110, 130, 160), (50, 55, 70), (240, 150, 30)
TARGET, OBJECT, GRID, COLLIDED = (40, 170, 60), (210, 60, 60), (200, 200, 195), (220, 40, 40)
TABLE, EDGE = (228, 222, 208), (170, 160, 140)
_CHAIN = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link",
          "wrist_3_link", "tool0")  # fmt: skip


@dataclass(frozen=True)
class Stand:
    """What the arm stands on, in ``base_link`` (m): the ground's height and the tables."""

    ground_z: float = -BASE_LINK_HEIGHT
    tables: tuple[Box, ...] = ()

    def support_z(self) -> float:
        """Height of the surface right under the base: the highest table top under it (1 mm
        above it at most: the base stands on it), else the ground; the pedestal reaches it."""
        tops = [
            t.centre[2] + t.half_extents[2]
            for t in self.tables
            if all(abs(t.centre[i]) <= t.half_extents[i] for i in (0, 1))
        ]
        return max([z for z in tops if z <= 1e-3], default=self.ground_z)


def stand_of(spec: tuple[str, str | None, Mapping[str, str]]) -> Stand:
    """The ``Stand`` of an env's ``server_spec()``: its scene (``scene`` or the ``world_name``
    option) and base height (the ``z`` option), parsed as the UR server parses them."""
    cfg = parse_options(*spec)
    scene, down = SCENES[cfg.scene], -cfg.base_height  # world z -> base_link z
    tables = tuple(
        Box(t.half_extents, (t.centre[0], t.centre[1], t.centre[2] + down)) for t in scene.tables
    )
    return Stand(scene.ground_z + down, tables)


def default_camera(model: str) -> ViewCamera:
    """A three-quarter view that fits the arm's reach."""
    spec = UR_MODELS[model]
    reach = spec.d1 + abs(spec.a2) + abs(spec.a3) + spec.d5
    return ViewCamera(
        eye=(1.15 * reach, -1.45 * reach, 0.95 * reach), target=(0.0, 0.0, 0.25 * reach)
    )


def arm_points(
    model: str, q_env: Sequence[float], support_z: float = -BASE_LINK_HEIGHT
) -> np.ndarray:
    """The arm's skeleton in ``base_link``: the pedestal's foot (at ``support_z``), base,
    joints (and elbow corner), tool0."""
    frames = forward_kinematics(model, np.asarray(q_env, dtype=np.float64))
    spec = UR_MODELS[model]
    points = [np.array([0.0, 0.0, support_z]), np.zeros(3)]  # pedestal, base_link
    for name in _CHAIN:
        xyz, quat = frames[name]
        if name == "wrist_1_link":  # the forearm runs along a3, then steps sideways by d4
            fxyz, fquat = frames["forearm_link"]
            points.append(fxyz + Rotation.from_quat(fquat).apply((spec.a3, 0.0, 0.0)))
        points.append(xyz)
    return np.array(points)


def _grid(
    canvas: Canvas,
    project: PerspectiveProjection,
    centre: Sequence[float],
    half: Sequence[float],
    lines: int = 9,
) -> None:
    """A horizontal grid of ``lines`` x ``lines`` lines: ``centre`` +- ``half`` (x, y) at the
    height ``centre[2]``; a table's top, or the ground around the arm."""
    (cx, cy, z), (hx, hy) = centre, half[:2]
    xs, ys = np.linspace(cx - hx, cx + hx, lines), np.linspace(cy - hy, cy + hy, lines)
    for x, y in zip(xs, ys, strict=True):
        for a, b in (((x, cy - hy, z), (x, cy + hy, z)), ((cx - hx, y, z), (cx + hx, y, z))):
            px, depth = project(np.array([a, b]))
            if np.all(depth > 0):
                canvas.line(px, GRID, width=1)


def _table_top(canvas: Canvas, project: PerspectiveProjection, table: Box) -> None:
    """A table's top: filled over the ground (so the grid below does not show through it),
    edged, with a coarser grid."""
    (cx, cy, cz), (hx, hy, hz) = table.centre, table.half_extents
    top = (cx, cy, cz + hz)
    corners = [
        (cx + sx * hx, cy + sy * hy, top[2]) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))
    ]
    px, depth = project(np.array(corners))
    if np.all(depth > 0):
        canvas.polygon(px, TABLE, outline=EDGE)
    _grid(canvas, project, top, table.half_extents, lines=5)


def draw_ur(
    model: str,
    q_env: Sequence[float],
    cfg: RenderConfig,
    *,
    target: Sequence[float] | None = None,
    objects: Sequence[Sequence[float]] = (),
    collided: bool = False,
    caption: str = "",
    stand: Stand = Stand(),
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
        stand: the ground and tables (default: the ground 0.1 m below ``base_link``;
            ``stand_of(env.server_spec())`` draws the env's scene).
    """
    camera = cfg.camera if isinstance(cfg.camera, ViewCamera) else default_camera(model)
    project = PerspectiveProjection(camera, cfg.width, cfg.height)
    canvas = Canvas(cfg)
    spec = UR_MODELS[model]
    half = 1.2 * (abs(spec.a2) + abs(spec.a3))
    _grid(canvas, project, (0.0, 0.0, stand.ground_z), (half, half))
    for table in stand.tables:
        _table_top(canvas, project, table)
    points = arm_points(model, q_env, stand.support_z())
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
