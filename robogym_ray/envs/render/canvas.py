"""Cameras (world metres -> pixels) and a Pillow canvas that draws in world coordinates."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, ImageDraw

from robogym_ray.errors import ConfigError

Color = tuple[int, int, int]


@dataclass(frozen=True)
class TopDownCamera:
    """An orthographic view from above, centred on ``centre``, x to the right and y up.

    The shorter of the image's two sides covers ``span`` metres (the other keeps the aspect).
    """

    centre: tuple[float, float] = (0.0, 0.0)
    span: float = 9.0
    """Metres across the shorter side of the image (default: the 6 x 8 m lab with a margin)."""


@dataclass(frozen=True)
class ViewCamera:
    """A pinhole camera looking from ``eye`` at ``target`` (world metres), z up."""

    eye: tuple[float, float, float] = (2.0, -2.4, 1.6)
    target: tuple[float, float, float] = (0.0, 0.0, 0.45)
    fov_deg: float = 45.0
    """Vertical field of view (deg)."""


@dataclass(frozen=True)
class RenderConfig:
    """Size and camera of an env's ``rgb_array`` / ``human`` frames.

    ``camera=None`` picks the robot family's default (MiR100: the lab from above; UR: a
    three-quarter view scaled to the arm's reach).
    """

    width: int = 640
    height: int = 480
    camera: TopDownCamera | ViewCamera | None = None
    background: Color = field(default=(245, 245, 240))

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if not isinstance(value, int) or not 16 <= value <= 4096:
                raise ConfigError(
                    f"RenderConfig.{name} must be an int in [16, 4096], got {value!r}"
                )


class Canvas:
    """One frame being drawn; ``to_px`` maps world points to pixels (camera-specific)."""

    def __init__(self, cfg: RenderConfig) -> None:
        self.cfg = cfg
        self.image = Image.new("RGB", (cfg.width, cfg.height), cfg.background)
        self.draw = ImageDraw.Draw(self.image)

    def array(self) -> np.ndarray:
        """The frame as ``uint8`` H x W x 3."""
        return np.asarray(self.image, dtype=np.uint8)

    def polygon(self, px: np.ndarray, fill: Color, outline: Color | None = None) -> None:
        self.draw.polygon([tuple(p) for p in px.tolist()], fill=fill, outline=outline)

    def line(self, px: np.ndarray, fill: Color, width: int = 1) -> None:
        self.draw.line([tuple(p) for p in px.tolist()], fill=fill, width=max(1, width))

    def disc(self, centre: Sequence[float], radius: float, fill: Color) -> None:
        x, y = float(centre[0]), float(centre[1])
        r = max(1.0, radius)
        self.draw.ellipse((x - r, y - r, x + r, y + r), fill=fill)

    def points(self, px: np.ndarray, fill: Color, size: int = 1) -> None:
        """Square dots of ``size`` pixels (one C-level ``point`` call per pixel offset)."""
        for dx in range(size):
            for dy in range(size):
                self.draw.point([tuple(p) for p in (px + (dx, dy)).tolist()], fill=fill)

    def text(self, xy: tuple[int, int], text: str, fill: Color = (40, 40, 40)) -> None:
        self.draw.text(xy, text, fill=fill)


class TopDownProjection:
    """World (x, y) -> pixel (column, row) for a ``TopDownCamera``; x right, y up."""

    def __init__(self, camera: TopDownCamera, width: int, height: int) -> None:
        self.scale = min(width, height) / camera.span  # px per metre
        self.cx, self.cy = camera.centre
        self.w2, self.h2 = width / 2, height / 2

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        col = self.w2 + (xy[:, 0] - self.cx) * self.scale
        row = self.h2 - (xy[:, 1] - self.cy) * self.scale
        return np.stack([col, row], axis=1)


class PerspectiveProjection:
    """World (x, y, z) -> pixel (column, row) and depth for a ``ViewCamera``."""

    def __init__(self, camera: ViewCamera, width: int, height: int) -> None:
        eye, target = np.asarray(camera.eye, float), np.asarray(camera.target, float)
        forward = target - eye
        if np.linalg.norm(forward) < 1e-9:
            raise ConfigError(f"ViewCamera: eye {camera.eye} and target {camera.target} coincide")
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, (0.0, 0.0, 1.0))
        if np.linalg.norm(right) < 1e-9:  # looking straight down: any horizontal right will do
            right = np.array([1.0, 0.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        self.eye, self.axes = eye, np.stack([right, up, forward])
        self.focal = (height / 2) / np.tan(np.radians(camera.fov_deg) / 2)
        self.w2, self.h2 = width / 2, height / 2

    def __call__(self, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (n, 2) and depths (n,) of world points (n, 3); depth <= 0 is behind."""
        cam = (np.atleast_2d(np.asarray(xyz, float)) - self.eye) @ self.axes.T
        depth = cam[:, 2]
        safe = np.where(depth > 1e-6, depth, 1e-6)
        col = self.w2 + self.focal * cam[:, 0] / safe
        row = self.h2 - self.focal * cam[:, 1] / safe
        return np.stack([col, row], axis=1), depth
