"""robo-gym 2.1.0's Isaac Lab reach task, robot-agnostic (``IsaacReachEnv`` of
``robo_gym/envs/manipulator/isaac_reach.py``); the envs bind it to an arm:
``ur_modular.IsaacReachUR`` (``IsaacReachURSim-v0``, the UR10) and
``panda_modular.IsaacReachPanda`` (``IsaacReachPandaSim-v0``).

They run policies trained with Isaac Lab's ``Isaac-Reach-UR10-v0`` / ``Isaac-Reach-Franka-v0``:
observations and actions are in those tasks' spaces (joint positions relative to the default
pose, the pose command with a w-x-y-z quaternion, actions as joint offsets scaled by 0.5), on
robo-gym's robot servers in Isaac Lab's table scene. Target sampling, reward and ends are
``modular.PoseTask``'s with the defaults 2.1.0 sets here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from robogym_ray.envs.frames import quat_to_order
from robogym_ray.envs.modular import PoseTask
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb

WORLD = "isaactabletop_sphere50_no_collision.world"
"""robo-gym's world for both arms: Isaac Lab's table, its top at the robot's base."""

COMMAND_QUAT_ORDER = "wxyz"
"""The pose command's quaternion order in the observation: Isaac Lab 2.x's, w first."""


class IsaacReachTask(PoseTask):
    """``IsaacReachEnv``: ``PoseTask`` in Isaac Lab's reach spaces (see the leaf classes).

    Args:
        isaac_scale: action scale (rad per unit; default 0.5).
        isaac_extra_static_joints: rows ``(position, low, high)`` of joints Isaac Lab observes
            but the server does not report (the Panda's fingers): observed as position 0 and
            velocity 0 after the arm's joints, within ``[low, high]``.
        **kwargs: ``PoseTask``'s; ``fix_<joint>`` is refused (every joint moves, as in 2.1.0).
    """

    fixed_by_default = ()
    fixable = False
    max_episode_steps = 600
    action_rate = 30.0
    velocity_scale = 0.2
    extra_static_default: ClassVar[Sequence[Sequence[float]]] = ()
    pose_defaults: ClassVar[dict[str, Any]] = {
        "ee_rotation_matters": True,
        "ee_rotation_threshold": 0.05,
        "ee_distance_threshold": 0.02,
        "ee_target_volume_bounding_box": True,
        "ee_rotation_pos_x_range": (0.35, 0.65),
        "ee_rotation_pos_y_range": (-0.2, 0.2),
        "ee_rotation_pos_z_range": (0.15, 0.5),
        "ee_rotation_roll_range": 0.0,
        "ee_rotation_yaw_range": (-3.14, 3.14),  # Isaac Lab's pi, to two decimals
    }

    def __init__(
        self,
        *,
        isaac_scale: float = 0.5,
        isaac_extra_static_joints: Sequence[Sequence[float]] | None = None,
        **kwargs: Any,
    ) -> None:
        self.scale = float(isaac_scale)
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ConfigError(f"isaac_scale must be a positive number, got {isaac_scale!r}")
        rows = (
            self.extra_static_default
            if isaac_extra_static_joints is None
            else (isaac_extra_static_joints)
        )
        self.extra = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
        if np.any(self.extra[:, 1] > 0) or np.any(self.extra[:, 2] < 0):
            raise ConfigError("isaac_extra_static_joints rows are (position, low <= 0, high >= 0)")
        super().__init__(**kwargs)

    def _action_space(self) -> spaces.Box:
        """Offsets from ``joint_position`` over the scale that stay within the limits."""
        low = (self.lower - self.joint_position) / self.scale
        high = (self.upper - self.joint_position) / self.scale
        return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """``joint_position + isaac_scale * action`` (rad, task order)."""
        return self.joint_position + self.scale * np.asarray(action, dtype=np.float64)

    def _obs_bounds(self) -> tuple[list[float], list[float]]:
        """Positions relative to ``joint_position`` within the limits widened by the tolerance
        (a fraction of each joint's range), then velocities, the command and the last action."""
        widen = self.tolerance * (self.upper - self.lower)
        n, extra = self.lower.size + len(self.extra), self.extra
        low = [*(self.lower - widen - self.joint_position), *extra[:, 1], *[-np.inf] * n]
        high = [*(self.upper + widen - self.joint_position), *extra[:, 2], *[np.inf] * n]
        low += [-np.inf] * 3 + [-1.0] * 4 + self.action_space.low.tolist()
        high += [np.inf] * 3 + [1.0] * 4 + self.action_space.high.tolist()
        return low, high

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        still = np.zeros(len(self.extra))  # the static joints: at their position, not moving
        command = [self.target_pose[:3], quat_to_order(self.target_pose[3:], COMMAND_QUAT_ORDER)]
        parts = [self.joints(msg) - self.joint_position, still, self.velocities(msg), still]
        return np.concatenate([*parts, *command, self.last_action]).astype(np.float32)
