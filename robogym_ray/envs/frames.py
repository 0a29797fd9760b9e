"""Robot-generic helpers for robo-gym's pose keys and observation boxes.

Every robo-gym arm server reports frames as ``<frame>_to_ref_translation_{x,y,z}`` and
``<frame>_to_ref_rotation_{x,y,z,w}`` in ``state_dict``; the tasks observe targets in spherical
coordinates and declare float32 boxes. Nothing here names a robot.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from gymnasium import spaces
from scipy.spatial.transform import Rotation

from robogym_ray.errors import InvalidStateError


def frame_xyz(sd: Mapping[str, float], prefix: str) -> np.ndarray:
    """Position of frame ``prefix`` (``ee``, ``object_0`` ...) in the reference frame."""
    return np.array([sd[f"{prefix}_to_ref_translation_{a}"] for a in "xyz"], dtype=np.float64)


def frame_quat(sd: Mapping[str, float], prefix: str) -> np.ndarray:
    """Quaternion ``[x, y, z, w]`` of frame ``prefix`` as the server reports it (not renormalised:
    robo-gym observes these values)."""
    return np.array([sd[f"{prefix}_to_ref_rotation_{a}"] for a in "xyzw"], dtype=np.float64)


QUAT_ORDERS = ("xyzw", "wxyz")
"""Quaternion layouts: scipy's and the servers' x-y-z-w; w-x-y-z, Isaac Lab 2.x's and robo-gym's
target observations."""


def quat_to_order(xyzw: np.ndarray, order: str) -> np.ndarray:
    """Quaternions (the last axis) given x-y-z-w, laid out in ``order`` (one of ``QUAT_ORDERS``)."""
    return xyzw if order == "xyzw" else xyzw[..., [3, 0, 1, 2]]


def quat_from_order(quat: np.ndarray, order: str) -> np.ndarray:
    """Quaternions (the last axis) laid out in ``order``, back to x-y-z-w."""
    return quat if order == "xyzw" else quat[..., [1, 2, 3, 0]]


def frame_rotation(sd: Mapping[str, float], prefix: str) -> Rotation:
    """Orientation of frame ``prefix`` in the reference frame.

    Raises:
        InvalidStateError: the quaternion is not finite or (near) zero.
    """
    quat = frame_quat(sd, prefix)
    if not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-6:
        raise InvalidStateError(f"{prefix} rotation quaternion {quat.tolist()} is not valid")
    return Rotation.from_quat(quat)


def spherical(v: np.ndarray) -> np.ndarray:
    """``[r, theta = arccos(z / r), phi = atan2(y, x)]`` (theta = 0 at r = 0)."""
    r = float(np.linalg.norm(v))
    theta = float(np.arccos(np.clip(v[2] / r, -1.0, 1.0))) if r > 0 else 0.0
    return np.array([r, theta, np.arctan2(v[1], v[0])])


def in_frame(sd: Mapping[str, float], point: np.ndarray, prefix: str) -> np.ndarray:
    """``point`` (reference frame) expressed in frame ``prefix`` (ee, forearm)."""
    return frame_rotation(sd, prefix).inv().apply(point - frame_xyz(sd, prefix))


def box(low: Sequence[float], high: Sequence[float]) -> spaces.Box:
    """A float32 ``Box`` from per-element bounds."""
    return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32)
