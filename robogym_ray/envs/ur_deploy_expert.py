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
``run-policy --isaac-lab``. Its kinematics are ``robots/ur/torch_kinematics.py``'s. It imports
torch, so no env module imports it (a Sim env stays without torch).
"""

from __future__ import annotations

import numpy as np
import torch

from robogym_ray.envs.frames import QUAT_ORDERS
from robogym_ray.robots.ur.torch_kinematics import URChain, command_in_base_link, rotation_vector

SCALE = 0.0625
"""Isaac Lab's ``RelativeJointPositionAction`` scale (rad per unit action)."""
DAMPING = 0.05
"""lambda of the damped least squares (m, rad): below it the solve stops trusting J."""
GAIN = 1.0
"""Share of the remaining error asked for per step (2.0 gave the same window ends)."""


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
        self.chain = URChain(model)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        x = obs.to(torch.float64)
        q, quat = x[:, :6], x[:, 15:19]
        if self.wxyz:
            quat = torch.cat([quat[:, 1:], quat[:, :1]], dim=1)
        goal_p, goal_r = command_in_base_link(x[:, 12:15], quat)
        pos, rot, jac = self.kinematics(q)
        err_r = rotation_vector(goal_r @ rot.transpose(1, 2))
        err = torch.cat([(goal_p - pos), err_r], dim=1).unsqueeze(2)
        eye = torch.eye(6, dtype=torch.float64).expand(x.shape[0], 6, 6)
        lhs = jac @ jac.transpose(1, 2) + self.damping * self.damping * eye
        dq = (jac.transpose(1, 2) @ torch.linalg.solve(lhs, err)).squeeze(2)
        action = self.gain * dq / self.scale
        return action.clamp(-1.0, 1.0).to(obs.dtype)

    def kinematics(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``wrist_3_link``'s position and rotation in ``base_link``, and the 6 x 6 Jacobian."""
        return self.chain(q)


def numpy_policy(expert: DeployReachExpert) -> object:
    """The expert as ``obs -> action`` on numpy arrays (one observation)."""

    def act(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = torch.from_numpy(np.asarray(obs, dtype=np.float32).reshape(1, -1))
            return expert(x).numpy().reshape(-1)

    return act
