"""A UR10e near the ground (reported 2026-11-23), ours against the real arm's collision meshes.

The report: the joints ``[-2.14, -0.13, 0.63, -1.13, 1.63]``, divided by the joint limits (the
observation's normalisation) and sent as the action, collide in EmptyEnvironment but run to
``max_steps`` in EndEffectorPositioning. They are not the same targets: robo-gym's positioning
env maps its wrist_1 action onto [-3.48, 0.31] rad (``restrict_wrist_1``), so there wrist_1 goes
to -1.926 rad, not -1.13. At -1.926 rad the real UR10e does not touch the ground either:

Lowest point above the ground (m) of ur_description's UR10e collision meshes (convex hulls;
ros-industrial/universal_robot a7a2c545 ``ur_description/meshes/ur10e/collision/*.stl``,
byte-identical to jr-robotics/universal_robot 635b5d99, which robo-gym installs), placed with
the URDF's kinematics and the base at z = 0.1 m, measured for this test:

    wrist_1 = -1.926 rad:  wrist_2 +0.0134, wrist_1 +0.0321, forearm +0.0396
    wrist_1 = -1.13 rad:   wrist_2 -0.0702 (in the ground)

Gazebo's collision there comes from its dynamics, not the geometry: robo-gym's effort
controllers let the arm sag under gravity (a 0.011 rad shoulder_lift error alone closes the
13 mm) and latch any contact on the way. Our controller is kinematic (docs/protocol.md), so
the arm is where it was sent. These tests pin our geometry to the meshes' margin. To command a
joint configuration, use the env's own inverse: ``env.unwrapped.action_for(joints)``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from robogym_ray.envs.registration import env_id
from robogym_ray.envs.ur_common import JOINT_MAX
from robogym_ray.robots.base import StateRequest
from robogym_ray.robots.registry import make_robot
from robogym_ray.robots.ur.state import POSITION_KEYS

REPORTED = np.array([-2.14, -0.13, 0.63, -1.926, 1.63, 0.0])
"""The report's joints as robo-gym's positioning env turns them into targets (env order)."""
MESH_CLEARANCE = 0.0134
"""m: the real meshes' lowest point at REPORTED (wrist_2_link)."""
LOWERING = 1.242
"""m per rad: how fast that point drops as shoulder_lift grows (from the same measurement)."""


def _collides(q: np.ndarray, world: str = "empty.world") -> bool:
    robot = make_robot("ur10e", seed=0, options={"world_name": world})
    try:
        goal = dict(zip(POSITION_KEYS, map(float, q), strict=True))
        robot.set_state(StateRequest(state_dict=goal))
        return bool(robot.in_collision)
    finally:
        robot.close()


@pytest.mark.parametrize("world", ["empty.world", "tabletop_sphere50_no_collision.world"])
def test_the_reported_pose_clears_the_ground_by_about_the_meshes_margin(world: str) -> None:
    assert not _collides(REPORTED, world)
    # Lowering the wrist by the meshes' margin +-6 mm (through shoulder_lift) brackets ours.
    for margin, collides in ((MESH_CLEARANCE - 0.006, False), (MESH_CLEARANCE + 0.006, True)):
        q = REPORTED.copy()
        q[1] += margin / LOWERING
        assert _collides(q, world) is collides, (margin, q)


def test_the_sanity_pose_is_in_the_ground_as_the_meshes_are() -> None:
    q = REPORTED.copy()
    q[3] = -1.13
    assert _collides(q)


def _run(task: str, action_of: Callable[[Any], np.ndarray]) -> str:
    import gymnasium as gym

    env = gym.make(env_id(task, "UR10", "Sim"), ur_model="ur10e")
    try:
        env.reset(seed=0)
        action = action_of(env.unwrapped).astype(np.float32)
        for _ in range(300):
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                return str(info["final_status"])
        raise AssertionError("no end in 300 steps")
    finally:
        env.close()


def test_the_two_envs_differ_by_the_wrist_1_mapping_only() -> None:
    q = np.array([-2.14, -0.13, 0.63, -1.13, 1.63, 0.0])

    def normalised(_task: Any) -> np.ndarray:  # what the report sent to both envs
        return q[:5] / JOINT_MAX[:5]

    assert _run("EmptyEnvironment", normalised) == "collision"
    assert _run("EndEffectorPositioningRoboGym", normalised) == "max_steps_exceeded"
    # The env's own inverse (action_for) sends the positioning arm to -1.13 too: it collides.
    assert _run("EndEffectorPositioningRoboGym", lambda task: task.action_for(q)) == "collision"
