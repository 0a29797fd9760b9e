"""Our UR arms' forward kinematics in torch: batched, differentiable and TorchScript-able.

Used where a network needs the arm's kinematics: the deploy reach's scripted expert
(``envs/ur_deploy_expert.py``) and the critic's pose features (``learner/features.py``). The
chain's constant transforms are read off ``geometry``'s forward kinematics at the zero pose, so
the kinematics are written once. It imports torch, so no env module imports it (a Sim env stays
without torch).
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from robogym_ray.robots.ur.geometry import LINK_NAMES, forward_kinematics


def _matrix(xyz: np.ndarray, quat_xyzw: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(quat_xyzw).as_matrix()
    m[:3, 3] = xyz
    return m


def chain(model: str = "ur10e") -> tuple[np.ndarray, np.ndarray]:
    """``base_link_inertia``'s pose and each joint's fixed transform from its parent link, read
    off the forward kinematics at q = 0 (each joint turns about its own z after it)."""
    frames = forward_kinematics(model, np.zeros(6))
    poses = [_matrix(*frames["base_link_inertia"])] + [_matrix(*frames[n]) for n in LINK_NAMES]
    fixed = [np.linalg.inv(a) @ b for a, b in zip(poses[:-1], poses[1:], strict=True)]
    return poses[0], np.stack(fixed)


class URChain(torch.nn.Module):
    """Joints ``[B, 6]`` (env order) -> ``wrist_3_link``'s position ``[B, 3]`` and rotation
    ``[B, 3, 3]`` in ``base_link``, and the geometric Jacobian ``[B, 6, 6]`` (linear rows, then
    angular), in ``dtype``.

    The transforms are non-persistent buffers: a module holding a chain saves no kinematics in
    its state dict, and loads one saved without it.
    """

    def __init__(self, model: str = "ur10e", dtype: torch.dtype = torch.float64) -> None:
        super().__init__()
        root, fixed = chain(model)
        self.register_buffer("root", torch.from_numpy(root).to(dtype), persistent=False)
        self.register_buffer("fixed", torch.from_numpy(fixed).to(dtype), persistent=False)

    def forward(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        m, axes, origins = self._walk(q)
        pos = m[:, :3, 3]
        z = torch.stack(axes, dim=2)
        lever = pos.unsqueeze(2) - torch.stack(origins, dim=2)
        jac = torch.cat([torch.linalg.cross(z, lever, dim=1), z], dim=1)
        return pos, m[:, :3, :3], jac

    def pose(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The position and rotation alone: :meth:`forward` without the Jacobian."""
        m, _, _ = self._walk(q)
        return m[:, :3, 3], m[:, :3, :3]

    def _walk(self, q: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor], list[torch.Tensor]]:
        """The chain's last transform, and each joint's axis and origin on the way."""
        m = self.root.expand(q.shape[0], 4, 4)
        axes: list[torch.Tensor] = []
        origins: list[torch.Tensor] = []
        for i in range(6):
            m = m @ self.fixed[i]
            axes.append(m[:, :3, 2])
            origins.append(m[:, :3, 3])
            m = m @ rot_z(q[:, i])
        return m, axes, origins


def command_in_base_link(
    position: torch.Tensor, quat_xyzw: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """A pose command given in UR's ``base`` frame (``base_link`` turned pi about z: x and y
    change sign), as position ``[B, 3]`` and rotation ``[B, 3, 3]`` in ``base_link``."""
    flip = torch.tensor([-1.0, -1.0, 1.0], dtype=position.dtype, device=position.device)
    return position * flip, flip.unsqueeze(1) * quat_matrix(quat_xyzw)  # Rz(pi) @ R


def rot_z(angle: torch.Tensor) -> torch.Tensor:
    """Homogeneous transforms ``[B, 4, 4]`` turning by ``angle`` ``[B]`` about z."""
    c, s = torch.cos(angle), torch.sin(angle)
    zero, one = torch.zeros_like(angle), torch.ones_like(angle)
    rows = [c, -s, zero, zero, s, c, zero, zero, zero, zero, one, zero, zero, zero, zero, one]
    return torch.stack(rows, dim=1).reshape(-1, 4, 4)


def quat_matrix(q: torch.Tensor) -> torch.Tensor:
    """Rotation matrices of (normalised) x-y-z-w quaternions."""
    q = q / torch.linalg.vector_norm(q, dim=1, keepdim=True)
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    rows = [
        1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
        2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
        2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
    ]  # fmt: skip
    return torch.stack(rows, dim=1).reshape(-1, 3, 3)


def rotation_vector(r: torch.Tensor) -> torch.Tensor:
    """Axis x angle of rotation matrices (the log map), by atan2 so that it holds up to pi."""
    skew = torch.stack(
        [r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], dim=1
    )
    sin = 0.5 * torch.linalg.vector_norm(skew, dim=1, keepdim=True)
    cos = 0.5 * (r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2] - 1.0).unsqueeze(1)
    angle = torch.atan2(sin, cos)
    return skew * (angle / (2.0 * sin).clamp(min=1e-9))
