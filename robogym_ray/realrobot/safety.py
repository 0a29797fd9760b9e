"""The safety filter in front of a real robot: every command is checked against limits from config.

Policy (documented choice): an action **outside the per-element limits is clipped** into them -
RL policies routinely saturate and clipping is what robo-gym's envs already do to their actions -
and the number of clipped commands is counted. An action that is **malformed** (wrong length, NaN
or inf) or that would **jump further than ``max_step``** from the previous command is **refused**
(``UnsafeCommandError``; nothing is sent): those are bugs or dangerous set-point jumps, and
guessing a "nearest safe" command for them would hide the bug while the robot moves.
With ``on_violation="refuse"`` out-of-limit actions are refused too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robogym_ray.envs.registration import env_robot
from robogym_ray.errors import ConfigError, InvalidActionError
from robogym_ray.robots.card import RobotCard
from robogym_ray.robots.registry import robot_card


class UnsafeCommandError(InvalidActionError):
    """A command to a real robot was refused by the safety filter (nothing was sent)."""


@dataclass(frozen=True)
class SafetyConfig:
    """Limits of the commands a real robot accepts (one entry per action element)."""

    low: tuple[float, ...]
    """Lowest allowed value of each action element (velocity in m/s, rad/s or position in rad)."""
    high: tuple[float, ...]
    """Highest allowed value of each action element."""
    max_step: tuple[float, ...] | None = None
    """Largest allowed change of each element from the previous command (None: no limit);
    for position set-points this bounds the commanded joint speed."""
    on_violation: str = "clip"
    """``clip`` (default) or ``refuse`` an action outside [low, high]."""

    def __post_init__(self) -> None:
        if len(self.low) != len(self.high) or any(
            lo > hi for lo, hi in zip(self.low, self.high, strict=True)
        ):
            raise ValueError(f"SafetyConfig: low {self.low} / high {self.high} do not pair up")
        if self.max_step is not None and len(self.max_step) != len(self.low):
            raise ValueError(
                f"SafetyConfig: max_step has {len(self.max_step)} entries, expected {len(self.low)}"
            )
        if self.on_violation not in ("clip", "refuse"):
            raise ValueError(f"on_violation must be 'clip' or 'refuse', got {self.on_violation!r}")

    @classmethod
    def from_card(cls, card: RobotCard, max_step: float | None = None) -> SafetyConfig:
        """The real robot's limits from its card (``RobotCard.safety``), e.g. the MiR100's
        twist limits or the UR's absolute joint targets in ROS order (spec e.1, e.2).

        Args:
            card: the robot's card.
            max_step: one limit on every element's change between commands (overrides the
                card's ``max_step``); None: the card's.

        Raises:
            ConfigError: the card knows no real robot.
        """
        limits = card.safety
        if limits is None:
            raise ConfigError(f"no real-robot safety limits known for robot {card.name!r}")
        step = limits.max_step if max_step is None else (max_step,) * len(limits.low)
        return cls(low=limits.low, high=limits.high, max_step=step)


class SafetyFilter:
    """Applies a ``SafetyConfig`` to each command; remembers the last one for ``max_step``."""

    def __init__(self, config: SafetyConfig) -> None:
        self.config = config
        self.clipped = 0
        self.refused = 0
        self._last: np.ndarray | None = None

    def filter(self, action: Sequence[float] | np.ndarray) -> np.ndarray:
        """The action to send (possibly clipped); raises UnsafeCommandError to refuse it."""
        cfg = self.config
        vec = np.asarray(action, dtype=np.float64)
        if vec.shape != (len(cfg.low),) or not np.all(np.isfinite(vec)):
            self._refuse(f"action {vec.tolist()} must be {len(cfg.low)} finite numbers")
        low, high = np.asarray(cfg.low), np.asarray(cfg.high)
        outside = np.flatnonzero((vec < low) | (vec > high))
        if outside.size:
            i = int(outside[0])
            what = f"action[{i}] = {vec[i]:g} outside [{low[i]:g}, {high[i]:g}]"
            if cfg.on_violation == "refuse":
                self._refuse(what)
            self.clipped += 1
            vec = np.clip(vec, low, high)
        if cfg.max_step is not None and self._last is not None:
            jump = np.abs(vec - self._last)
            big = np.flatnonzero(jump > np.asarray(cfg.max_step))
            if big.size:
                i = int(big[0])
                self._refuse(f"action[{i}] jumps by {jump[i]:g} > max_step {cfg.max_step[i]:g}")
        self._last = vec
        return vec

    def reset(self) -> None:
        """Forget the previous command (after SetState moved the robot elsewhere)."""
        self._last = None

    def _refuse(self, why: str) -> None:
        self.refused += 1
        raise UnsafeCommandError(f"unsafe command refused: {why}")


def safety_for_robot(robot: str, max_step: float | None = None) -> SafetyConfig:
    """Safety limits of the real robot ``robot`` (a registry name), from its card."""
    return SafetyConfig.from_card(robot_card(robot), max_step=max_step)


def safety_for(env_id: str) -> SafetyConfig:
    """Safety limits for the real robot a task's Rob variant drives: the card of the robot the
    env names in its ``server_spec()``."""
    return safety_for_robot(env_robot(env_id))
