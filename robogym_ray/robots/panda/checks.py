"""The Franka arms' command and goal checks, shared by the simulated arm and the hardware one.

One copy of each check, so a command the PyBullet arm refuses is refused by the real one too,
with the same words: the index, the joint, the value and the allowed range.
"""

from __future__ import annotations

import numpy as np

from robogym_ray.errors import InvalidActionError, InvalidStateError
from robogym_ray.robots.arm import LIMIT_TOLERANCE, check_state_keys
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.panda.model import JOINT_NAMES
from robogym_ray.robots.panda.state import ALL_KEYS, POSITION_KEYS


def check_joint_action(
    action: np.ndarray, action_mode: str, lower: np.ndarray, upper: np.ndarray, robot: str
) -> np.ndarray:
    """One action as float64: 7 finite values, absolute targets within the limits (abs_pos) or
    deltas no larger than a joint's range (delta_pos); else InvalidActionError."""
    a = np.asarray(action, dtype=np.float64).reshape(-1)
    if a.shape != (7,):
        raise InvalidActionError(
            f"{robot} action must have 7 values (joints 1-7, {action_mode}), got {a.size}"
        )
    if action_mode == "abs_pos":
        low, high = lower - LIMIT_TOLERANCE, upper + LIMIT_TOLERANCE
    else:
        high = upper - lower + LIMIT_TOLERANCE
        low = -high
    for i in range(7):
        if not (np.isfinite(a[i]) and low[i] <= a[i] <= high[i]):
            raise InvalidActionError(
                f"action[{i}] ({JOINT_NAMES[i]}, {action_mode}) = {float(a[i])!r} "
                f"is outside [{low[i] + LIMIT_TOLERANCE:.6f}, "
                f"{high[i] - LIMIT_TOLERANCE:.6f}] rad"
            )
    return a


def check_joint_goal(
    request: StateRequest, lower: np.ndarray, upper: np.ndarray, robot: str
) -> np.ndarray:
    """The validated joint goal (joints 1-7) of a SetState: all seven keys, within limits."""
    check_state_keys(robot, request.state_dict, ALL_KEYS, POSITION_KEYS[0])
    missing = [k for k in POSITION_KEYS if k not in request.state_dict]
    if missing:
        raise InvalidStateError(
            f"{robot} SetState needs the joint goal: state_dict lacks {missing}"
        )
    goal = np.array([float(request.state_dict[k]) for k in POSITION_KEYS])
    for i, key in enumerate(POSITION_KEYS):
        low, high = lower[i] - LIMIT_TOLERANCE, upper[i] + LIMIT_TOLERANCE
        if not (np.isfinite(goal[i]) and low <= goal[i] <= high):
            raise InvalidStateError(
                f"joint goal {key} ({JOINT_NAMES[i]}) = {float(goal[i])!r} is outside "
                f"[{lower[i]:.4f}, {upper[i]:.4f}] rad"
            )
    return goal
