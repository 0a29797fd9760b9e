"""A scripted expert for Isaac Lab's deploy reach (``RoboGymRay/IsaacDeployReachUR10e*``): damped
least-squares IK on our UR10e's kinematics, answering the env's own actions.

It is the proof that the task is controllable at Isaac Lab's action scale (0.0625 rad per unit,
actions clamped to [-1, 1], targets streamed to the servo at 60 Hz) and the reference line of
``experiments/deploy_reach_errors.py``. From the observation alone (the joints and the pose
command), each step:

1. ``wrist_3_link``'s pose and the geometric Jacobian from the joints, in ``base_link``;
2. the pose error to the command (position, and rotation as a rotation vector), the command
   turned from UR's ``base`` frame into ``base_link`` (pi about z);
3. ``dq = J^T (J J^T + lambda^2 I)^-1 e`` (damped: bounded near singularities);
4. the action ``dq / 0.0625``, clamped per joint into [-1, 1] as Isaac ROS clamps (shrinking
   the vector as a whole, to keep its direction, slowed every joint to the slowest's pace and
   was no better at the window ends); the next step's solve corrects the bent direction.

The window ends it misses are rotations of more than ~1.6 rad about the tool's axis: the
servo turns a wrist at most stiffness / damping x 0.0625 = ~0.45 rad/s, so 4 s cover ~1.7 rad.

It is a TorchScript-able ``torch.nn.Module`` (batched ``[B, 19] -> [B, 6]``), so the same
expert runs in the scoring script and, exported like an Isaac Lab policy, through
``run-policy --isaac-lab``. The chain's constant transforms are read off ``geometry``'s
forward kinematics at the zero pose, so the kinematics are written once. It imports torch, so
no env module imports it (a Sim env stays without torch).
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from robogym_ray.envs.frames import QUAT_ORDERS
from robogym_ray.robots.ur.geometry import LINK_NAMES, forward_kinematics

SCALE = 0.0625
"""Isaac Lab's ``RelativeJointPositionAction`` scale (rad per unit action)."""
DAMPING = 0.05
"""lambda of the damped least squares (m, rad): below it the solve stops trusting J."""
GAIN = 1.0
"""Share of the remaining error asked for per step (2.0 gave the same window ends)."""


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


class DeployReachExpert(torch.nn.Module):
    """Observations (19: joints, velocities, command position, quaternion) -> actions (6).

    Args:
        quat_order: the observation's quaternion order, "xyzw" (the env's default) or "wxyz".
        model: the UR model whose kinematics it inverts.
    """

    def __init__(self, quat_order: str = "xyzw", model: str = "ur10e") -> None:
        super().__init__()
        if quat_order not in QUAT_ORDERS:
            raise ValueError(f"quat_order must be one of {QUAT_ORDERS}, got {quat_order!r}")
        self.wxyz = quat_order == "wxyz"
        self.scale, self.damping, self.gain = SCALE, DAMPING, GAIN  # TorchScript reads no globals
        root, fixed = chain(model)
        self.register_buffer("root", torch.from_numpy(root))
        self.register_buffer("fixed", torch.from_numpy(fixed))
        # UR's base frame is base_link turned pi about z: x and y change sign.
        self.register_buffer("flip", torch.tensor([-1.0, -1.0, 1.0], dtype=torch.float64))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        x = obs.to(torch.float64)
        q, goal_p, quat = x[:, :6], x[:, 12:15] * self.flip, x[:, 15:19]
        if self.wxyz:
            quat = torch.cat([quat[:, 1:], quat[:, :1]], dim=1)
        goal_r = self.flip.unsqueeze(1) * _quat_matrix(quat)  # Rz(pi) @ R
        pos, rot, jac = self.kinematics(q)
        err_r = _rotation_vector(goal_r @ rot.transpose(1, 2))
        err = torch.cat([(goal_p - pos), err_r], dim=1).unsqueeze(2)
        eye = torch.eye(6, dtype=torch.float64).expand(x.shape[0], 6, 6)
        lhs = jac @ jac.transpose(1, 2) + self.damping * self.damping * eye
        dq = (jac.transpose(1, 2) @ torch.linalg.solve(lhs, err)).squeeze(2)
        action = self.gain * dq / self.scale
        return action.clamp(-1.0, 1.0).to(obs.dtype)

    def kinematics(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``wrist_3_link``'s position and rotation in ``base_link``, and the 6 x 6 Jacobian."""
        batch = q.shape[0]
        m = self.root.expand(batch, 4, 4)
        axes, origins = [], []
        for i in range(6):
            m = m @ self.fixed[i]
            axes.append(m[:, :3, 2])
            origins.append(m[:, :3, 3])
            m = m @ _rot_z(q[:, i])
        pos = m[:, :3, 3]
        z = torch.stack(axes, dim=2)
        lever = pos.unsqueeze(2) - torch.stack(origins, dim=2)
        jac = torch.cat([torch.linalg.cross(z, lever, dim=1), z], dim=1)
        return pos, m[:, :3, :3], jac


def _rot_z(angle: torch.Tensor) -> torch.Tensor:
    c, s = torch.cos(angle), torch.sin(angle)
    zero, one = torch.zeros_like(angle), torch.ones_like(angle)
    rows = [c, -s, zero, zero, s, c, zero, zero, zero, zero, one, zero, zero, zero, zero, one]
    return torch.stack(rows, dim=1).reshape(-1, 4, 4)


def _quat_matrix(q: torch.Tensor) -> torch.Tensor:
    """Rotation matrices of (normalised) x-y-z-w quaternions."""
    q = q / torch.linalg.vector_norm(q, dim=1, keepdim=True)
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    rows = [
        1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
        2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
        2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
    ]  # fmt: skip
    return torch.stack(rows, dim=1).reshape(-1, 3, 3)


def _rotation_vector(r: torch.Tensor) -> torch.Tensor:
    """Axis x angle of rotation matrices (the log map), by atan2 so that it holds up to pi."""
    skew = torch.stack(
        [r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], dim=1
    )
    sin = 0.5 * torch.linalg.vector_norm(skew, dim=1, keepdim=True)
    cos = 0.5 * (r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2] - 1.0).unsqueeze(1)
    angle = torch.atan2(sin, cos)
    return skew * (angle / (2.0 * sin).clamp(min=1e-9))


def numpy_policy(expert: DeployReachExpert) -> object:
    """The expert as ``obs -> action`` on numpy arrays (one observation)."""

    def act(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = torch.from_numpy(np.asarray(obs, dtype=np.float32).reshape(1, -1))
            return expert(x).numpy().reshape(-1)

    return act
