"""robo-gym 2.1.0's modular Panda env ``IsaacReachPandaSim-v0``
(``robo_gym/envs/panda/panda_isaac_reach.py``) and its ``Rob`` variant: ``isaac_reach``'s task
bound to the Panda as 2.1.0's modular envs see it (``panda.yaml``, ``PandaBaseEnv``); with
``panda_model="fr3"`` (ids ``IsaacReachFR3Sim-v0`` / ``...Rob-v0``) the same task on the FR3,
bounded by its joint limits. The start pose suits both arms.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from robogym_ray.envs.isaac_reach import WORLD, IsaacReachTask
from robogym_ray.envs.modular import ModularArmTask
from robogym_ray.envs.panda_tasks import DEFAULT_JOINTS, PandaTask
from robogym_ray.robots.panda.model import JOINT_NAMES

PANDA_WORKSPACE = (0.755, 0.2)
"""``panda.yaml``'s workspace ``r`` / ``min_r`` (m): only for targets outside the box."""
FINGERS = ((0.04, -1.0, 1.0), (0.04, -1.0, 1.0))
"""The Panda's two finger joints as Isaac Lab observes them: (position, low, high), static."""


class Panda2Arm(ModularArmTask, PandaTask):
    """The Panda as robo-gym 2.1.0's modular envs see it (``panda.yaml``, ``PandaBaseEnv``), or
    the FR3 (``panda_model``): ``PandaTask`` sets the limits, ``lower`` / ``upper``, per arm."""

    robo_gym_joints = JOINT_NAMES
    default_joints = DEFAULT_JOINTS
    fixed_by_default = ("panda_joint7",)

    def workspace(self) -> tuple[float, float]:
        return PANDA_WORKSPACE


class IsaacReachPanda(IsaacReachTask, Panda2Arm):
    """robo-gym 2.1.0's ``IsaacReachPandaSim-v0`` (Isaac Lab's ``Isaac-Reach-Franka-v0``), on the
    Panda or the FR3.

    ## Action space
    ``Box((7,), float32)``: joint targets ``joint_position + 0.5 * action`` (rad, joints 1-7),
    bounded by ``(limit - joint_position) / 0.5``. 30 actions per second.

    ## Observation space
    ``Box((32,), float32)``: joint positions minus ``joint_position`` (7) and the two fingers
    (2, always 0, bounds +-1); velocities (7 + 2, the fingers' 0); the target xyz (m, world)
    and quaternion w, x, y, z (7); the previous action (7).

    ## Reward, episode end
    As ``IsaacReachUR`` (panda_hand to the target).

    ## Reset
    Joints ``joint_position`` = ``[0, -0.569, 0, -2.81, 0, 3.037, 0.741]`` every episode
    (``continue_except_collision`` default False). Target as ``IsaacReachUR`` but pitch pi.

    ## Arguments
    ``panda_model`` (``panda``, or ``fr3`` for ``IsaacReachFR3``), ``isaac_scale``,
    ``isaac_extra_static_joints`` (default the fingers ``[[0.04, -1, 1]] * 2``), those of
    ``pose_targets.PoseTaskConfig`` and ``ModularArmTask`` but ``fix_<joint>``, and
    ``RobotServerEnv``'s.
    """

    world = WORLD
    default_joints = (0.0, -0.569, 0.0, -2.81, 0.0, 3.037, 0.741)
    extra_static_default = FINGERS
    pose_defaults: ClassVar[dict[str, Any]] = {
        **IsaacReachTask.pose_defaults,
        "ee_rotation_pitch_range": math.pi,
        "continue_except_collision": False,
    }

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        robot, scene, options = super().server_spec()
        options["z"] = "0.0"  # robo-gym sends it; the Panda's launch file ignores it
        return robot, scene, options
