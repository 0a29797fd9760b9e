"""The command handler between the robot server and the robot's controller.

It holds a one-slot queue. The server submits commands at the *action* rate; the handler is
ticked at the controller's *actuation* rate. A submitted command is published ``repeat`` times
(one per tick) and the slot is then emptied; a command submitted while the slot is full is
ignored (the caller is told). While the slot is empty every tick publishes ``None``, which the
controller reads as "stop": zero velocity for a differential drive, trajectory preemption for an
arm. This mirrors robo-gym's ROS command handlers, which is what makes an agent trained against
the simulation behave the same against a real robot whose driver stops it when commands cease.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Publisher = Callable[[np.ndarray | None], None]


@dataclass(frozen=True)
class CommandHandlerConfig:
    """Timing of one command handler."""

    action_cycle: float = 0.1
    """Seconds between actions the agent sends (one SendAction per action cycle)."""
    actuation_cycle: float = 0.1
    """Seconds between publications to the controller (the controller's rate)."""
    repeat: int | None = None
    """Times a command is published before the slot empties; None = action/actuation cycles."""

    def __post_init__(self) -> None:
        if not (self.action_cycle > 0 and self.actuation_cycle > 0):
            raise ValueError(
                f"cycles must be positive, got action_cycle={self.action_cycle}, "
                f"actuation_cycle={self.actuation_cycle}"
            )
        if self.actuation_cycle > self.action_cycle + 1e-12:
            raise ValueError(
                f"actuation_cycle ({self.actuation_cycle}) must not exceed "
                f"action_cycle ({self.action_cycle})"
            )
        if self.repeat is not None and self.repeat < 1:
            raise ValueError(f"repeat must be >= 1, got {self.repeat}")

    @property
    def ticks_per_action(self) -> int:
        """Actuation ticks in one action cycle (rounded to the nearest integer, at least 1)."""
        return max(1, round(self.action_cycle / self.actuation_cycle))

    @property
    def effective_repeat(self) -> int:
        return self.repeat if self.repeat is not None else self.ticks_per_action


class CommandHandler:
    """One-slot queue that publishes commands at the actuation rate (thread-safe)."""

    def __init__(self, config: CommandHandlerConfig, publish: Publisher) -> None:
        self.config = config
        self._publish = publish
        self._lock = threading.Lock()
        self._slot: np.ndarray | None = None
        self._remaining = 0
        self.published = 0
        """Total ticks that published a command (not a stop)."""
        self.stops = 0
        """Total ticks that published a stop because the slot was empty."""
        self.ignored = 0
        """Commands dropped because the slot was full."""

    @property
    def busy(self) -> bool:
        with self._lock:
            return self._slot is not None

    def submit(self, command: np.ndarray) -> bool:
        """Put ``command`` in the slot; returns False (and drops it) if the slot is full."""
        with self._lock:
            if self._slot is not None:
                self.ignored += 1
                return False
            self._slot = np.array(command, dtype=np.float64, copy=True)
            self._remaining = self.config.effective_repeat
            return True

    def clear(self) -> None:
        """Empty the slot (used by SetState: a reset cancels whatever was queued)."""
        with self._lock:
            self._slot = None
            self._remaining = 0

    def tick(self) -> np.ndarray | None:
        """Publish once to the controller; returns what was published (None = stop)."""
        with self._lock:
            command = self._slot
            if command is not None:
                self._remaining -= 1
                if self._remaining <= 0:
                    self._slot = None
                self.published += 1
            else:
                self.stops += 1
        # Publish outside the lock: the controller may be slow and submit() must not wait on it.
        self._publish(command)
        return command
