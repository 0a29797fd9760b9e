"""Targets of robo-gym 2.1.0's pose tasks (``ManipulatorEePosEnv``): the keyword arguments that
say where targets come from and when an episode succeeds, and the random draws, in 2.1.0's
order (so a seed gives 2.1.0's target), from ``robo_gym/utils/utils.py`` and
``manipulator_model.py``. Poses are ``[x, y, z, qx, qy, qz, qw]`` in the reference frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np
from scipy.spatial.transform import Rotation

from robogym_ray.errors import ConfigError

Range = float | Sequence[float] | None
"""robo-gym's config range: None (not drawn), a value, or ``[low, high]``."""


def positive(name: str, value: float, zero_ok: bool = False) -> float:
    """``value`` as a finite float > 0 (>= 0 with ``zero_ok``), else ConfigError naming it."""
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not zero_ok):
        raise ConfigError(f"{name} must be a {'non-negative' if zero_ok else 'positive'} "
                          f"finite number, got {value!r}")  # fmt: skip
    return v


@dataclass(frozen=True)
class PoseTaskConfig:
    """2.1.0's ``ManipulatorEePosEnv`` keyword arguments (same names, same meaning)."""

    ee_target_pose: Sequence[float] | None = None
    """A fixed target: xyz (m), xyz + roll/pitch/yaw (rad, "xyz"), or xyz + quaternion xyzw."""
    ee_target_volume_bounding_box: bool = False
    """Draw targets in the box of the three ranges below, else in the robot's workspace."""
    ee_rotation_pos_x_range: Range = None
    ee_rotation_pos_y_range: Range = None
    ee_rotation_pos_z_range: Range = None
    """The box (m; 2.1.0's names, "rotation" and all)."""
    ee_rotation_roll_range: Range = None
    ee_rotation_pitch_range: Range = None
    ee_rotation_yaw_range: Range = None
    """Target roll, pitch, yaw (rad); None = 0."""
    ee_rotation_quat_unique: bool = False
    """Target quaternions with w >= 0."""
    ee_rotation_rpy_seq: str = "xyz"
    """Euler sequence of workspace targets (box targets are always "xyz", as Isaac Lab's)."""
    ee_rotation_matters: bool = False
    """Observe and reward the rotation; success needs it within ``ee_rotation_threshold``."""
    ee_distance_threshold: float = 0.1
    ee_rotation_threshold: float = 0.1
    """Success: distance <= this (m) and rotation error < this (rad)."""
    continue_on_success: bool = False
    """After a success, the next episode starts where this one ended."""
    continue_except_collision: bool = False
    """After a success or the step limit, the next episode starts where this one ended."""
    randomize_start: bool = False
    random_joint_offset: Sequence[float] | None = None
    """Start = ``joint_position`` + U(+-offset) per joint when ``randomize_start``."""

    def __post_init__(self) -> None:
        for name in ("ee_distance_threshold", "ee_rotation_threshold"):
            positive(name, getattr(self, name))
        for f in fields(self):
            if f.name.endswith("_range"):
                config_range(f.name, getattr(self, f.name))
        try:
            Rotation.from_euler(self.ee_rotation_rpy_seq, [0.0, 0.0, 0.0])
        except ValueError as err:
            raise ConfigError(f"ee_rotation_rpy_seq {self.ee_rotation_rpy_seq!r}: {err}") from None
        if self.ee_target_pose is not None:
            pose_from_user(self.ee_target_pose)
        if self.randomize_start and self.random_joint_offset is None:
            raise ConfigError("randomize_start needs random_joint_offset")


def config_range(name: str, value: Range) -> np.ndarray | None:
    """2.1.0's ``get_config_range``: None, ``[v, v]`` for a value, ``[lo, max(lo, hi)]``."""
    if value is None:
        return None
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.size == 1:
        arr = np.array([arr[0], arr[0]])
    if arr.size != 2 or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} must be a number or [low, high], got {value!r}")
    return np.array([arr[0], max(arr[0], arr[1])])


def _draw(rng: np.random.Generator, value: np.ndarray | None) -> float:
    """One uniform draw from a range; 0 without drawing for None (2.1.0's draw order)."""
    return 0.0 if value is None else float(rng.uniform(value[0], value[1]))


def workspace_point(rng: np.random.Generator, radius: float, min_radius: float) -> np.ndarray:
    """Uniform in the upper half ball of ``radius`` around the base, outside the cylinder of
    ``min_radius`` about the base's z axis (2.1.0's ``get_random_workspace_pose_rpy``)."""
    while True:
        phi = rng.uniform(0.0, 2 * np.pi)
        theta = np.arccos(rng.uniform(0.0, 1.0))
        r = radius * np.cbrt(rng.uniform(0.0, 1.0))
        p = r * np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
        if p[0] ** 2 + p[1] ** 2 > min_radius**2:
            return p


def sample_target_pose(
    rng: np.random.Generator, cfg: PoseTaskConfig, workspace: tuple[float, float]
) -> np.ndarray:
    """A random target ``[x, y, z, qx, qy, qz, qw]``: position in the box or the workspace,
    then roll, pitch and yaw from their ranges."""
    if cfg.ee_target_volume_bounding_box:
        axes = ("ee_rotation_pos_x_range", "ee_rotation_pos_y_range", "ee_rotation_pos_z_range")
        xyz = np.array([_draw(rng, config_range(a, getattr(cfg, a))) for a in axes])
        seq = "xyz"  # Isaac Lab's quat_from_euler_xyz, whatever ee_rotation_rpy_seq says
    else:
        xyz, seq = workspace_point(rng, *workspace), cfg.ee_rotation_rpy_seq
    angles = ("ee_rotation_roll_range", "ee_rotation_pitch_range", "ee_rotation_yaw_range")
    rpy = [_draw(rng, config_range(a, getattr(cfg, a))) for a in angles]
    quat = Rotation.from_euler(seq, rpy).as_quat(canonical=cfg.ee_rotation_quat_unique)
    return np.concatenate([xyz, quat])


def pose_from_user(pose: Sequence[float]) -> np.ndarray:
    """A user's target as ``[x, y, z, qx, qy, qz, qw]``: 7 values are taken as they are; 3 to 6
    are xyz plus roll, pitch, yaw ("xyz"), missing angles 0 (2.1.0's ``set_ee_target``)."""
    p = np.asarray(pose, dtype=np.float64).reshape(-1)
    if not 3 <= p.size <= 7 or not np.all(np.isfinite(p)):
        raise ConfigError(f"ee_target_pose needs 3 to 7 finite values, got {pose!r}")
    if p.size == 7:
        if np.linalg.norm(p[3:]) < 1e-6:
            raise ConfigError(f"ee_target_pose quaternion {p[3:].tolist()} is zero")
        return p
    rpy = np.concatenate([p[3:], np.zeros(6 - p.size)])
    return np.concatenate([p[:3], Rotation.from_euler("xyz", rpy).as_quat()])
