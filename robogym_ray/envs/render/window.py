"""``render_mode="human"``: the env's frames in a live pygame window.

pygame (SDL 2) is an optional dependency (``pip install "robogym-ray[render]"``); it is only
imported when a human-mode env draws its first frame. ``check_display`` runs at env
construction so a machine without a display fails at once, with a way forward, not on the
first ``reset``.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from robogym_ray.errors import RenderError


def check_display(env_name: str) -> None:
    """Raise RenderError unless a window can be opened here (X11 or Wayland display set)."""
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    raise RenderError(
        f"{env_name}: render_mode='human' needs a display, and neither $DISPLAY nor "
        "$WAYLAND_DISPLAY is set on this machine; use render_mode='rgb_array' for frames "
        "(gymnasium.wrappers.RecordVideo records them), or start a virtual display (Xvfb)"
    )


class HumanWindow:
    """A window that shows each frame given to ``show``, paced to ``fps``."""

    def __init__(self, title: str, fps: float) -> None:
        self.title, self.fps = title, fps
        self._pygame: Any = None
        self._screen: Any = None
        self._clock: Any = None

    def _open(self, width: int, height: int) -> None:
        try:
            import pygame
        except ImportError as exc:  # pragma: no cover - the render extra installs it
            raise RenderError(
                "render_mode='human' needs pygame: pip install 'robogym-ray[render]'"
            ) from exc
        pygame.display.init()
        pygame.display.set_caption(self.title)
        self._pygame = pygame
        self._screen = pygame.display.set_mode((width, height))
        self._clock = pygame.time.Clock()

    def show(self, frame: np.ndarray) -> None:
        height, width = frame.shape[:2]
        if self._screen is None:
            self._open(width, height)
        pygame = self._pygame
        pygame.event.pump()  # keeps the window responsive (and its close button working)
        surface = pygame.surfarray.make_surface(np.ascontiguousarray(frame.swapaxes(0, 1)))
        self._screen.blit(surface, (0, 0))
        pygame.display.flip()
        # Real-time pacing is what a person watching asks for (the one place that sleeps).
        self._clock.tick(self.fps)

    def close(self) -> None:
        if self._pygame is not None:
            self._pygame.display.quit()
            self._pygame = self._screen = None
