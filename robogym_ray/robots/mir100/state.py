"""The MiR100's flat 1030-value state (spec c.1): layout, SetState validation, composition.

=========  =====  ===================================================
index      count  content
=========  =====  ===================================================
0:3        3      target x, y, yaw (echo of the last SetState)
3:6        3      pose x, y, yaw of the drive-axle centre, yaw in (-pi, pi]
6:8        2      twist v (m/s), omega (rad/s), robot frame
8:509      501    front laser ranges
509:1020   511    back laser ranges
1020       1      collision flag (any contact during the latest tick)
1021:1030  9      zeros (obstacle poses are write-only, as in the ROS server)
=========  =====  ===================================================
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from robogym_ray.errors import InvalidStateError
from robogym_ray.robots.validation import check_range

STATE_LEN = 1030
MIN_SET_STATE_LEN = 6
TARGET = slice(0, 3)
POSE = slice(3, 6)
TWIST = slice(6, 8)
F_SCAN = slice(8, 509)
B_SCAN = slice(509, 1020)
COLLISION = 1020
OBSTACLES = slice(1021, 1030)

GROUPS: Mapping[str, slice] = {
    "target": TARGET,
    "pose": POSE,
    "twist": TWIST,
    "f_scan": F_SCAN,
    "b_scan": B_SCAN,
    "collision": slice(COLLISION, COLLISION + 1),
}
"""Sensor groups (``read_sensors`` keys) and where each goes in the state."""

_FIELD_NAMES = ("x", "y", "yaw")
MAX_ABS_YAW = 4 * math.pi
"""SetState refuses a yaw (target, robot, cube) beyond +-this (rad). robo-gym's envs send angles in
[-pi, pi]; two turns either way leaves room for a client that adds angles without wrapping, while
a yaw of 1e5 or 3.4e38 (which the target slots would echo back unchanged, and which loses all
precision when wrapped) is a client bug to report, not a pose."""


@dataclass(frozen=True)
class SetStateRequest:
    """A validated MiR100 SetState: each pose is (x, y, yaw)."""

    target: tuple[float, float, float]
    pose: tuple[float, float, float]
    obstacles: tuple[tuple[float, float, float], ...]
    """Empty when the request carried only target and pose."""


def parse_set_state(state: np.ndarray, max_abs_position: float) -> SetStateRequest:
    """Validate a SetState vector and split it into poses; raise InvalidStateError if malformed.

    Accepted lengths: 6 (target + pose only) or exactly 1030 (the layout robo-gym's envs send;
    obstacle poses then come from 1021:1030). Anything else is refused instead of being partly
    used: the ROS server would raise IndexError for 1022..1029 and silently ignore the tail of
    other lengths, and both mostly hide a client bug. Only the values that are consumed are
    checked (the laser/twist slots a client fills with zeros are ignored, as in the reference).

    Args:
        state: the flat ``state`` list of the request.
        max_abs_position: bound on |x| and |y| of every pose (m).
    """
    values = np.asarray(state, dtype=np.float64).ravel()
    n = len(values)
    if n not in (MIN_SET_STATE_LEN, STATE_LEN):
        raise InvalidStateError(
            f"MiR100 SetState state has length {n}; expected {MIN_SET_STATE_LEN} "
            f"(target x, y, yaw + robot x, y, yaw) or {STATE_LEN} (full layout)"
        )
    target = _pose_at(values, TARGET.start, "target", max_abs_position)
    pose = _pose_at(values, POSE.start, "robot pose", max_abs_position)
    obstacles: tuple[tuple[float, float, float], ...] = ()
    if n == STATE_LEN:
        obstacles = tuple(
            _pose_at(values, OBSTACLES.start + 3 * k, f"obstacle_{k}", max_abs_position)
            for k in range(3)
        )
    return SetStateRequest(target, pose, obstacles)


def _pose_at(values: np.ndarray, start: int, what: str, bound: float) -> tuple[float, float, float]:
    pose = tuple(float(v) for v in values[start : start + 3])
    for offset, (name, value) in enumerate(zip(_FIELD_NAMES, pose, strict=True)):
        field = f"state[{start + offset}] ({what} {name})"
        if name == "yaw":
            check_range(field, value, -MAX_ABS_YAW, MAX_ABS_YAW, "rad")
        else:
            check_range(field, value, -bound, bound, "m")
    return pose  # type: ignore[return-value]  # length 3 by construction


def compose_state(groups: Mapping[str, np.ndarray]) -> np.ndarray:
    """Assemble the 1030-value state from the sensor groups (zeros in 1021:1030)."""
    missing = [g for g in GROUPS if g not in groups]
    if missing:
        raise InvalidStateError(
            f"MiR100 state cannot be composed: sensor groups {missing} missing; "
            f"expected all of {list(GROUPS)}"
        )
    state = np.zeros(STATE_LEN, dtype=np.float64)
    for name, where in GROUPS.items():
        value = np.asarray(groups[name], dtype=np.float64).ravel()
        expected = where.stop - where.start
        if len(value) != expected:
            raise InvalidStateError(
                f"MiR100 sensor group {name!r} has {len(value)} values; expected {expected}"
            )
        state[where] = value
    return state
