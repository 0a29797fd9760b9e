"""The deploy reach's scripted expert: its torch kinematics are ``geometry``'s, it reads either
quaternion order, answers the env's [-1, 1] actions, and scripts (the 100-episode score is in
docs/results/isaac-deploy-reach-ur10e-servo/; run-policy drives it in test_io_descriptors)."""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from robogym_ray.envs.ur_deploy_expert import DeployReachExpert
from robogym_ray.robots.ur.geometry import forward_kinematics


def test_kinematics_and_jacobian_are_geometrys() -> None:
    expert = DeployReachExpert()
    q = np.random.default_rng(0).uniform(-3.0, 3.0, 6)
    pos, rot, jac = (t.numpy()[0] for t in expert.kinematics(torch.from_numpy(q)[None]))
    xyz, quat = forward_kinematics("ur10e", q)["wrist_3_link"]
    np.testing.assert_allclose(pos, xyz, atol=1e-12)
    np.testing.assert_allclose(rot, Rotation.from_quat(quat).as_matrix(), atol=1e-12)
    for i in range(6):  # each column: how wrist_3_link moves and turns with joint i
        dq = np.zeros(6)
        dq[i] = 1e-6
        xyz2, quat2 = forward_kinematics("ur10e", q + dq)["wrist_3_link"]
        turn = (Rotation.from_quat(quat2) * Rotation.from_quat(quat).inv()).as_rotvec()
        np.testing.assert_allclose(jac[:, i], np.r_[(xyz2 - xyz), turn] / 1e-6, atol=1e-5)


def test_either_quaternion_order_gives_the_same_bounded_actions() -> None:
    obs = np.random.default_rng(1).normal(size=(4, 19)).astype(np.float32)
    obs[:, 15:] /= np.linalg.norm(obs[:, 15:], axis=1, keepdims=True)
    wxyz = obs.copy()
    wxyz[:, 15:] = obs[:, [18, 15, 16, 17]]
    xyzw_expert, wxyz_expert = DeployReachExpert(), torch.jit.script(DeployReachExpert("wxyz"))
    a = xyzw_expert(torch.from_numpy(obs))
    np.testing.assert_allclose(a.numpy(), wxyz_expert(torch.from_numpy(wxyz)).numpy(), atol=1e-6)
    assert a.dtype == torch.float32 and float(a.abs().max()) <= 1.0
