"""The Panda state on the wire, as robo-gym-robot-servers 2.1.0's Panda ROS bridge composes it.

``state_dict`` keys (the bridge builds them by name; protobuf maps have no order):

* ``joint1_position`` ... ``joint7_position``, ``joint1_velocity`` ...,
  ``joint1_effort`` ... (rad, rad/s, N m);
* ``ee_to_ref_translation_{x,y,z}``, ``ee_to_ref_rotation_{x,y,z,w}``: ``panda_hand`` in the
  reference frame (launch argument ``reference_frame``; robo-gym's envs send ``world``);
* ``in_collision``: 0.0 / 1.0, any contact sensor since the last SetState;
* rs_mode ``1object`` adds ``object_0_to_ref_translation_*`` / ``_rotation_*`` (the target).

Flat ``state`` (29 values, 36 with the object)::

    [object_0 pose (7), 1object only] + positions (7) + velocities (7) + efforts (7)
    + ee pose (7) + collision (1)

Sensor groups (``read_sensors``): ``joints`` (21: positions, velocities, efforts), ``ee`` (7),
``collision`` (1), ``object_0`` (7, rs_mode 1object).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from robogym_ray.robots.base import StateSnapshot, pose_keys

JOINT_STEMS: tuple[str, ...] = tuple(f"joint{i}" for i in range(1, 8))
POSITION_KEYS = tuple(f"{j}_position" for j in JOINT_STEMS)
VELOCITY_KEYS = tuple(f"{j}_velocity" for j in JOINT_STEMS)
EFFORT_KEYS = tuple(f"{j}_effort" for j in JOINT_STEMS)
_ROBOT_KEYS = POSITION_KEYS + VELOCITY_KEYS + EFFORT_KEYS + pose_keys("ee") + ("in_collision",)
RS_MODE_KEYS: dict[str, tuple[str, ...]] = {
    "only_robot": _ROBOT_KEYS,
    "1object": pose_keys("object_0") + _ROBOT_KEYS,
}
"""The exact state_dict keys of each rs_mode (29 / 36), in flat-state order."""
RS_MODES = tuple(RS_MODE_KEYS)
ALL_KEYS = frozenset(k for keys in RS_MODE_KEYS.values() for k in keys)
"""Every key SetState accepts (robo-gym 2.1.0 sends only the seven positions)."""
N_OBJECTS = {"only_robot": 0, "1object": 1}


def sensor_groups(rs_mode: str) -> tuple[str, ...]:
    return ("joints", "ee", "collision") + tuple(f"object_{i}" for i in range(N_OBJECTS[rs_mode]))


def compose_state(rs_mode: str, groups: Mapping[str, np.ndarray]) -> StateSnapshot:
    """The flat state and state_dict from one consistent set of sensor groups."""
    objects = [np.asarray(groups[f"object_{i}"], np.float64) for i in range(N_OBJECTS[rs_mode])]
    flat = np.concatenate(
        [
            *objects,
            np.asarray(groups["joints"], np.float64).reshape(21),
            np.asarray(groups["ee"], np.float64).reshape(7),
            np.asarray(groups["collision"], np.float64).reshape(1),
        ]
    )
    return StateSnapshot(
        state=flat, state_dict=dict(zip(RS_MODE_KEYS[rs_mode], flat.tolist(), strict=True))
    )
