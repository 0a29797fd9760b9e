"""The critic's pose features for Isaac Lab 3's deploy reach (``learner/features.py`` names
them ``ur10e-deploy-pose``). It imports torch, so no env module imports it."""

from __future__ import annotations

import torch
from torch import nn

from robogym_ray.envs.ur_deploy_expert import SCALE
from robogym_ray.envs.ur_deploy_reach import KEYPOINT_SCALE
from robogym_ray.robots.ur.torch_kinematics import URChain, command_in_base_link


class DeployReachPose(nn.Module):
    """The deploy reach's (``RoboGymRay/IsaacDeployReachUR10eSim-v0``) pose errors, twice: of
    ``wrist_3_link`` where the joints are and where the action sends them.

    The observation is the env's default layout (joints, velocities, the command's position and
    x-y-z-w quaternion in UR's ``base`` frame); the action moves the joint targets 0.0625 rad a
    unit from the measured joints. For each of the two joint vectors: the position error (3),
    the error of the frame's axes scaled as the reward's keypoints (0.45 m, 9), and the
    reward's keypoint error itself (the mean distance of the seven keypoints, 1).

    Why: the return depends on the arm's pose relative to the command, which the observation
    gives only through the kinematics; a critic that must learn them from a million steps
    values a few centimetres' difference no better than its fit of the kinematics.
    """

    OBS_DIM, ACT_DIM = 19, 6
    dim = 2 * (3 + 9 + 1)

    def __init__(self) -> None:
        super().__init__()
        self.chain = URChain("ur10e", torch.float32)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        with torch.autocast(obs.device.type, enabled=False):  # kinematics in float32
            x, a = obs.float(), action.float().clamp(-1.0, 1.0)
            q = x[:, :6]
            goal_p, goal_r = command_in_base_link(x[:, 12:15], x[:, 15:19])
            parts = []
            for joints in (q, q + SCALE * a):
                pos, rot = self.chain.pose(joints)
                e_p = goal_p - pos
                e_axes = KEYPOINT_SCALE * (goal_r - rot)  # column i: the +i keypoint's gap
                gaps = torch.cat(
                    [e_p.unsqueeze(2), e_p.unsqueeze(2) + e_axes, e_p.unsqueeze(2) - e_axes], 2
                )
                # sqrt with a floor: a norm's gradient at exactly zero is undefined.
                distance = torch.sqrt(gaps.square().sum(1) + 1e-12).mean(1, keepdim=True)
                parts += [e_p, e_axes.flatten(1), distance]
            return torch.cat(parts, dim=1)
