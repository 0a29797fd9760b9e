"""The UR state on the wire (spec c.2.1): key sets per rs_mode, sensor groups, composition.

Sensor groups (what ``read_sensors`` returns and the state buffer holds), all in the reference
frame:

==============  =====  ==========================================================
group           count  content
==============  =====  ==========================================================
``joints``      12     positions (rad) then velocities (rad/s), env order
``ee``          7      tool0 pose: x, y, z, qx, qy, qz, qw
``forearm``     7      forearm_link pose (modes with two points)
``object_<i>``  7      object i position, identity rotation (modes with objects)
``collision``   1      latched contact flag, 0.0 / 1.0
==============  =====  ==========================================================
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from robogym_ray.robots.base import StateSnapshot, pose_keys
from robogym_ray.robots.ur.geometry import ROS_FROM_ENV

JOINT_KEYS: tuple[str, ...] = ("base", "shoulder", "elbow", "wrist_1", "wrist_2", "wrist_3")
"""state_dict joint name stems in env order (``base`` = shoulder_pan, ``shoulder`` = lift)."""
POSITION_KEYS = tuple(f"{k}_joint_position" for k in JOINT_KEYS)
VELOCITY_KEYS = tuple(f"{k}_joint_velocity" for k in JOINT_KEYS)
_ROBOT_KEYS = POSITION_KEYS + VELOCITY_KEYS + pose_keys("ee") + ("in_collision",)
RS_MODE_KEYS: dict[str, tuple[str, ...]] = {
    "only_robot": _ROBOT_KEYS,
    "1object": _ROBOT_KEYS + pose_keys("object_0"),
    "1moving2points": _ROBOT_KEYS + pose_keys("object_0") + pose_keys("forearm"),
    "2objects2points": (
        _ROBOT_KEYS + pose_keys("object_0") + pose_keys("forearm") + pose_keys("object_1")
    ),
}
"""The exact state_dict keys of each rs_mode (20 / 27 / 34 / 41)."""
RS_MODES = tuple(RS_MODE_KEYS)
ALL_KEYS = frozenset(k for keys in RS_MODE_KEYS.values() for k in keys)
"""Every key any mode knows: what SetState accepts (robo-gym sends its whole composition)."""
N_OBJECTS = {"only_robot": 0, "1object": 1, "1moving2points": 1, "2objects2points": 2}
HAS_FOREARM = {"only_robot": False, "1object": False, "1moving2points": True,
               "2objects2points": True}  # fmt: skip


def sensor_groups(rs_mode: str) -> tuple[str, ...]:
    """The groups a robot in ``rs_mode`` produces."""
    groups = ["joints", "ee", "collision"]
    if HAS_FOREARM[rs_mode]:
        groups.append("forearm")
    groups += [f"object_{i}" for i in range(N_OBJECTS[rs_mode])]
    return tuple(groups)


def _dict_order(rs_mode: str) -> tuple[str, ...]:
    """Keys in the order ``compose_state`` concatenates values: joints, ee, collision, extras."""
    keys = POSITION_KEYS + VELOCITY_KEYS + pose_keys("ee") + ("in_collision",)
    keys += tuple(k for i in range(N_OBJECTS[rs_mode]) for k in pose_keys(f"object_{i}"))
    return keys + (pose_keys("forearm") if HAS_FOREARM[rs_mode] else ())


_DICT_ORDER = {mode: _dict_order(mode) for mode in RS_MODES}
_ROS = list(ROS_FROM_ENV)


def compose_state(rs_mode: str, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
    """Build state_dict and the flat ``state`` list from one consistent set of groups.

    Flat order (spec c.2.1): [object_0 (7)] + positions (6, ROS order) + velocities (6, ROS order)
    + ee (7) + collision [+ forearm (7)]. For 2objects2points, which no robo-gym env uses, object_1
    (7) follows object_0 (our choice; the ROS bridge's order is unspecified).
    """
    joints = np.asarray(groups["joints"], dtype=np.float64)
    ee = np.asarray(groups["ee"], dtype=np.float64)
    collision = np.asarray(groups["collision"], dtype=np.float64).reshape(1)
    objects = [np.asarray(groups[f"object_{i}"]) for i in range(N_OBJECTS[rs_mode])]
    extras = [*objects, groups["forearm"]] if HAS_FOREARM[rs_mode] else objects
    values = np.concatenate([joints, ee, collision, *extras])
    state_dict = dict(zip(_DICT_ORDER[rs_mode], values.tolist(), strict=True))
    flat = [*objects, joints[:6][_ROS], joints[6:12][_ROS], ee, collision]
    if HAS_FOREARM[rs_mode]:
        flat.append(groups["forearm"])
    return StateSnapshot(state=np.concatenate(flat).astype(np.float64), state_dict=state_dict)
