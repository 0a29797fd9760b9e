"""The critic's pose features for Isaac Lab's UR10 reach on its own reward (``learner/
features.py`` names them ``ur10-isaac-reach-pose``). It imports torch, so no env module
imports it."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from robogym_ray.envs.ur_modular import IsaacReachUR
from robogym_ray.robots.ur.torch_kinematics import URChain, quat_matrix, rotation_angle


class IsaacReachPose(nn.Module):
    """``tool1``'s pose errors to the command in Isaac Lab's UR10 reach
    (``RoboGymRay/IsaacReach*UR10Sim-v0``, the default ``joint_position``), twice: where the
    joints are, and at the joint targets the action sets.

    The observation is ``IsaacReachUR``'s (joints relative to the default pose, velocities, the
    command's position and w-x-y-z quaternion in ``base_link``, the last action). The action is
    on the critic's [-1, 1] scale over the env's whole Box, whose bounds are the joint limits
    less the default pose over the action scale: so the target it sets is ``action x limit``.
    For each of the two joint vectors: the position error (3), the difference of the command's
    and the frame's axes (9), the distance (1) and the angle between them (1); 28 numbers.

    Why: the reward prices the distance and the angle of ``tool1`` to the command; the
    observation holds them only through the kinematics. The targets say where the arm goes
    (at 0.2 of the joint speed limits it gets there over several steps).
    """

    OBS_DIM, ACT_DIM = 25, 6
    dim = 2 * (3 + 9 + 1 + 1)

    def __init__(self) -> None:
        super().__init__()
        self.chain = URChain("ur10", torch.float32, frame="tool1")  # IsaacReachUR's default
        default = np.asarray(IsaacReachUR.default_joints, np.float32)
        limit = np.asarray(IsaacReachUR.upper, np.float32)
        self.register_buffer("default", torch.from_numpy(default), persistent=False)
        self.register_buffer("limit", torch.from_numpy(limit), persistent=False)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        with torch.autocast(obs.device.type, enabled=False):  # kinematics in float32
            x, a = obs.float(), action.float().clamp(-1.0, 1.0)
            goal_p, goal_r = x[:, 12:15], quat_matrix(x[:, [16, 17, 18, 15]])  # w-x-y-z
            parts = []
            for joints in (x[:, :6] + self.default, a * self.limit):
                pos, rot = self.chain.pose(joints)
                e_p = goal_p - pos
                distance = torch.sqrt(e_p.square().sum(1, keepdim=True) + 1e-12)
                angle = rotation_angle(goal_r.transpose(1, 2) @ rot)
                parts += [e_p, (goal_r - rot).flatten(1), distance, angle]
            return torch.cat(parts, dim=1)
