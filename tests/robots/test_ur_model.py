"""UR kinematics: golden FK of spec e.2 (numpy and PyBullet), URDF content, model table."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from robogym_ray.robots.sim import PyBulletWorld
from robogym_ray.robots.ur.geometry import (
    BASE_LINK_HEIGHT,
    JOINT_NAMES,
    POSITION_LIMITS,
    UR_MODELS,
    forward_kinematics,
    urdf_path,
    urdf_text,
)

EE_RESET = [0.0, -2.5, 1.5, -1.5, -1.4, 0.0]
EMPTY_RESET = [0.0, -2.5, 1.5, 0.0, -1.4, 0.0]
AVOID_RESET = [-1.57, -1.31, -1.31, -2.18, 1.57, 0.0]

# (model, joints env order, frame, xyz, quat xyzw or None) from spec e.2.
GOLDEN = [
    ("ur5", [0.0] * 6, "tool0", (0.8172, 0.1914, -0.0055), (0.0, 0.7071, 0.7071, 0.0)),
    ("ur5", [0.0] * 6, "forearm_link", (0.425, 0.0, 0.0892), None),
    ("ur5", EE_RESET, "tool0", (-0.0069, 0.1231, 0.7009), (0.6569, -0.6028, 0.2618, -0.3696)),
    ("ur5", EMPTY_RESET, "tool0", (-0.0927, 0.1231, 0.5542), None),
    ("ur10", EE_RESET, "tool0", (-0.0391, 0.1796, 1.0135), None),
    ("ur10", [0.0] * 6, "tool0", (1.1843, 0.2561, 0.0116), None),
    ("ur5", AVOID_RESET, "tool0", (0.109, 0.3177, 0.605), None),
    ("ur5", AVOID_RESET, "forearm_link", (0.0001, -0.1096, 0.4998), None),
]


def _same_rotation(q1, q2, atol: float = 1e-3) -> bool:
    """Quaternions q and -q are the same rotation."""
    return bool(abs(abs(float(np.dot(q1, q2))) - 1.0) < atol)


class _Arm:
    """A bare PyBullet body of the generated URDF, placed like the robot server places it."""

    def __init__(self, model: str) -> None:
        self.world = PyBulletWorld()
        self.c = self.world.client
        self.uid = self.world.load_urdf(model, urdf_path(model), (0, 0, BASE_LINK_HEIGHT))
        self.index = {}
        for j in range(self.c.getNumJoints(self.uid)):
            info = self.c.getJointInfo(self.uid, j)
            self.index[info[1].decode()] = j
            self.index[info[12].decode()] = j

    def frame(self, q, name: str) -> tuple[np.ndarray, np.ndarray]:
        for joint, value in zip(JOINT_NAMES, q, strict=True):
            self.c.resetJointState(self.uid, self.index[joint], value)
        state = self.c.getLinkState(self.uid, self.index[name], computeForwardKinematics=1)
        xyz = np.asarray(state[4]) - [0.0, 0.0, BASE_LINK_HEIGHT]
        return xyz, np.asarray(state[5])


@pytest.mark.parametrize(("model", "q", "frame", "xyz", "quat"), GOLDEN)
def test_numpy_fk_matches_golden_values(model, q, frame, xyz, quat):
    pos, rot = forward_kinematics(model, q)[frame]
    np.testing.assert_allclose(pos, xyz, atol=1e-3)
    assert np.isclose(np.linalg.norm(rot), 1.0)
    if quat is not None:
        assert _same_rotation(rot, quat), (rot, quat)


@pytest.mark.parametrize(("model", "q", "frame", "xyz", "quat"), GOLDEN)
def test_pybullet_urdf_matches_golden_values(model, q, frame, xyz, quat):
    arm = _Arm(model)
    try:
        pos, rot = arm.frame(q, frame)
    finally:
        arm.world.close()
    np.testing.assert_allclose(pos, xyz, atol=1e-3)
    if quat is not None:
        assert _same_rotation(rot, quat), (rot, quat)


@pytest.mark.parametrize("model", sorted(UR_MODELS))
def test_numpy_and_pybullet_agree_on_random_poses(model):
    rng = np.random.default_rng(7)
    arm = _Arm(model)
    try:
        for _ in range(10):
            q = rng.uniform(-POSITION_LIMITS, POSITION_LIMITS)
            fk = forward_kinematics(model, q)
            for frame in ("forearm_link", "wrist_2_link", "tool0"):
                pos, rot = arm.frame(q, frame)
                np.testing.assert_allclose(fk[frame][0], pos, atol=1e-5)
                assert _same_rotation(fk[frame][1], rot, atol=1e-5)
    finally:
        arm.world.close()


@pytest.mark.parametrize("model", sorted(UR_MODELS))
def test_zero_pose_extends_along_plus_x_of_base_link(model):
    spec = UR_MODELS[model]
    pos, _ = forward_kinematics(model, np.zeros(6))["tool0"]
    np.testing.assert_allclose(
        pos, (-(spec.a2 + spec.a3), spec.d4 + spec.d6, spec.d1 - spec.d5), atol=1e-9
    )


def test_urdf_joint_limits_and_velocities_follow_the_table():
    for name, spec in UR_MODELS.items():
        world = PyBulletWorld()
        try:
            uid = world.load_urdf(name, urdf_path(name))
            c = world.client
            infos = [c.getJointInfo(uid, j) for j in range(c.getNumJoints(uid))]
            revolute = [i for i in infos if i[2] == p.JOINT_REVOLUTE]
            assert [i[1].decode() for i in revolute] == list(JOINT_NAMES)
            np.testing.assert_allclose([i[8] for i in revolute], -POSITION_LIMITS)
            np.testing.assert_allclose([i[9] for i in revolute], POSITION_LIMITS)
            np.testing.assert_allclose([i[11] for i in revolute], spec.max_velocity)
        finally:
            world.close()


def test_model_table_matches_spec():
    assert sorted(UR_MODELS) == ["ur10", "ur10e", "ur16e", "ur3", "ur3e", "ur5", "ur5e"]
    assert UR_MODELS["ur5"].max_velocity == pytest.approx((3.14159,) * 6)
    assert UR_MODELS["ur10"].max_velocity[:2] == pytest.approx((2.0943951,) * 2)
    assert UR_MODELS["ur3e"].max_velocity[3:] == pytest.approx((6.28319,) * 3)
    radii = {m: (s.workspace_r, s.workspace_min_r) for m, s in UR_MODELS.items()}
    assert radii["ur3"] == (0.45, 0.2) and radii["ur5e"] == (0.75, 0.2)
    assert radii["ur10e"] == (1.3, 0.3) and radii["ur16e"] == (0.8, 0.3)
    np.testing.assert_allclose(POSITION_LIMITS, [2 * np.pi] * 2 + [np.pi] + [2 * np.pi] * 3)


def test_urdf_generation_is_deterministic_and_cached():
    assert urdf_text("ur10") == urdf_text("ur10")
    path = urdf_path("ur10")
    assert path == urdf_path("ur10")
    with open(path) as f:
        assert f.read() == urdf_text("ur10")
