"""Real robots behind our robot server: the backends a card names, and how they are reached.

``robogym-ray serve --robot fr3 --hardware franky --fci-host HOST`` builds the robot through the
card's ``hardware`` entry instead of its simulation factory; the server, its command handler and
its state buffer stay the same, paced by the wall clock. Plain data here: nothing imports a
vendor's library until a backend is built.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from robogym_ray.errors import ConfigError
from robogym_ray.robots.base import SimRobot
from robogym_ray.robots.card import load
from robogym_ray.robots.registry import robot_card
from robogym_ray.robots.serve import is_loopback
from robogym_ray.text import quote


@dataclass(frozen=True)
class HardwareConfig:
    """How the server reaches and drives the real robot."""

    backend: str
    """The card's backend that drives it (``franky`` for a Franka arm)."""
    fci_host: str
    """The arm's address (Franka: the robot's IP with FCI enabled in Desk)."""
    dynamics_factor: float = 0.1
    """Reset moves (SetState) run at this fraction of the arm's limits, in (0, 1]; the card
    caps it (the FR3's at 0.3)."""
    realtime: str = "auto"
    """libfranka's real-time check: ``enforce`` (a real arm: its control loop needs a real-time
    kernel), ``ignore`` (a simulator), or ``auto``: ignore for a loopback address (a simulator
    on this machine, such as franky-sim), enforce for any other."""

    @property
    def enforce_realtime(self) -> bool:
        if self.realtime == "auto":
            return not is_loopback(self.fci_host)
        return self.realtime == "enforce"

    def __post_init__(self) -> None:
        if not self.fci_host:
            raise ConfigError("a hardware robot needs its address: --fci-host HOST")
        if self.realtime not in ("auto", "enforce", "ignore"):
            raise ConfigError(f"--realtime must be auto, enforce or ignore, got {self.realtime!r}")
        f = self.dynamics_factor
        if not (isinstance(f, int | float) and math.isfinite(f) and 0 < f <= 1):
            raise ConfigError(f"--dynamics-factor must be in (0, 1], got {f!r}")


def make_hardware_robot(
    robot: str, options: Mapping[str, str], hardware: HardwareConfig
) -> SimRobot:
    """The real ``robot`` through ``hardware.backend``; ConfigError for a robot without that
    backend or a dynamics factor above the card's cap, before anything is connected."""
    backend = hardware.backend
    card = robot_card(robot)
    backends = card.hardware
    if backends is None or backend not in backends.factories:
        known = ", ".join(sorted(backends.factories)) if backends else "none"
        raise ConfigError(
            f"robot {quote(robot)} has no hardware backend {quote(backend)}; its backends: {known}"
        )
    if hardware.dynamics_factor > backends.max_dynamics_factor:
        raise ConfigError(
            f"--dynamics-factor {hardware.dynamics_factor} is above {robot}'s cap "
            f"{backends.max_dynamics_factor} for resets on the real arm"
        )
    return load(backends.factories[backend])(robot, options, hardware)
