"""A thread-safe latest-state buffer.

Sensors update at different rates (odometry every actuation tick, lasers at their scan rate in
real-time mode); each writes only its own group of values. A reader always gets one consistent
snapshot: every group as it stood at one instant, never half of one update and half of another.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping

import numpy as np


class StateBuffer:
    """Holds named groups of float values; ``snapshot()`` copies all of them atomically."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._groups: dict[str, np.ndarray] = {}
        self._version = 0

    def update(self, **groups: np.ndarray | float) -> None:
        """Replace the given groups (others keep their last value)."""
        copies = {
            k: np.atleast_1d(np.asarray(v, dtype=np.float64)).copy() for k, v in groups.items()
        }
        with self._lock:
            self._groups.update(copies)
            self._version += 1

    def snapshot(self) -> tuple[int, Mapping[str, np.ndarray]]:
        """Returns (version, {group: copy}); version increases with every update."""
        with self._lock:
            return self._version, {k: v.copy() for k, v in self._groups.items()}

    def __contains__(self, group: str) -> bool:
        with self._lock:
            return group in self._groups
