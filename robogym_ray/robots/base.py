"""The interface between the robot server and a (simulated or emulated) robot.

The server owns the gRPC side, the command handler and the state buffer; a ``SimRobot`` owns one
PyBullet client (DIRECT mode), its scene, and its low-level controller. The server serialises
every call into a robot, so implementations need no locks of their own.

Data flow of one SendAction in simulation (no real-time pacing)::

    server.send_action(a) -> robot.validate_action(a) -> handler.submit(a)
    repeat ticks_per_action times: handler.tick() -> robot.publish(cmd | None); robot.advance(dt)
    buffer.update(**robot.read_sensors())

GetState composes the buffer's latest consistent snapshot with ``robot.compose(groups)``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from robogym_ray.robots.command_handler import CommandHandlerConfig


@dataclass(frozen=True)
class StateRequest:
    """A decoded SetState request (robo-gym's ``State`` message)."""

    state: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """The flat ``state`` list (float64 copy of the float32 wire values)."""
    state_dict: Mapping[str, float] = field(default_factory=dict)
    float_params: Mapping[str, float] = field(default_factory=dict)
    string_params: Mapping[str, str] = field(default_factory=dict)


POSE_SUFFIXES = (
    "translation_x", "translation_y", "translation_z",
    "rotation_x", "rotation_y", "rotation_z", "rotation_w",
)  # fmt: skip
"""robo-gym's arm servers name a frame's pose ``<frame>_to_ref_<suffix>`` in ``state_dict``."""


def pose_keys(frame: str) -> tuple[str, ...]:
    """The seven ``state_dict`` keys of ``frame``'s pose (``ee``, ``object_0`` ...)."""
    return tuple(f"{frame}_to_ref_{s}" for s in POSE_SUFFIXES)


@dataclass(frozen=True)
class StateSnapshot:
    """A state in robo-gym's layout, ready to be put on the wire."""

    state: np.ndarray
    """The flat ``state`` list (robo-gym layout for this robot and mode)."""
    state_dict: Mapping[str, float] = field(default_factory=dict)
    """Named values (UR arms); empty for robots whose protocol has none (MiR100)."""


@dataclass(frozen=True)
class RobotArguments:
    """What GetArguments reports (robo-gym-server-modules' master ``Arguments``)."""

    action_cycle_rate: float
    """Actions per second the server runs (Hz)."""
    rs_mode: str = ""
    """The ``rs_mode`` launch argument, "" for a robot without one (the MiR100)."""
    action_mode: str = ""
    """The ``action_mode`` launch argument (``abs_pos``, ``delta_pos`` ...), "" where none."""


class SimRobot(ABC):
    """A robot and its scene, stepped in simulated time by the robot server."""

    name: str
    """Registry name, e.g. ``mir100`` or ``ur10``."""
    handler_config: CommandHandlerConfig
    """Action and actuation cycles (and repeat) for this robot's command handler."""
    sensor_periods: Mapping[str, float] = {}
    """Seconds between updates of each sensor group in real-time mode; groups not listed are
    refreshed on every actuation tick. In simulated time all groups refresh after each action."""

    @abstractmethod
    def validate_action(self, action: np.ndarray) -> np.ndarray:
        """Check one action from the wire; return it as float64 or raise InvalidActionError.

        Checks length, NaN/inf and range; the message names the index, value and allowed range.
        """

    @abstractmethod
    def set_state(self, request: StateRequest) -> None:
        """Reset robot and scene as the request says (robo-gym SetState semantics).

        Must validate everything first and raise InvalidStateError *before* changing anything,
        so a bad request leaves the simulation untouched. Returns when the new state is in place.
        """

    @abstractmethod
    def publish(self, command: np.ndarray | None) -> None:
        """Controller input for the next actuation tick; None means stop (zero twist / preempt)."""

    @abstractmethod
    def advance(self, dt: float) -> None:
        """Advance the simulation by ``dt`` seconds of sim time (physics steps, never sleeping)."""

    @abstractmethod
    def read_sensors(self, groups: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        """Current sensor values by group (all groups when ``groups`` is None)."""

    @abstractmethod
    def compose(self, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
        """Build the robo-gym state layout from one consistent set of sensor groups."""

    def arguments(self) -> RobotArguments:
        """The launch arguments GetArguments reports: the action rate, and the arms' modes (their
        configs carry ``rs_mode`` and ``action_mode``; a robot without them reports "")."""
        config = getattr(self, "config", None)
        return RobotArguments(
            1.0 / self.handler_config.action_cycle,
            str(getattr(config, "rs_mode", "")),
            str(getattr(config, "action_mode", "")),
        )

    def recover(self) -> None:  # noqa: B027 - optional hook, default does nothing
        """Clear the robot's errors (RecoverFromErrors, an operator's resume); raise if it
        cannot. A simulated robot has none: hardware backends override this."""

    def close(self) -> None:  # noqa: B027 - optional hook, default does nothing
        """Release the PyBullet client and any other resources."""
