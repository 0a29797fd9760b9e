"""robo-gym 2.1.0's modular UR envs: ``EmptyEnvironment2URSim-v0``,
``EndEffectorPositioning2URSim-v0`` and ``IsaacReachURSim-v0`` (``robo_gym/envs/ur/ur_base.py``,
``ur_ee_pos.py``, ``ur_isaac_reach.py``), and their ``Rob`` variants. The semantics are
``envs/modular.py``'s and ``envs/isaac_reach.py``'s; this file binds them to the UR (robo-gym's
``ur_utils.UR`` model) and sets the envs' defaults.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from robogym_ray.envs.io_descriptors import ActionTermSpec, IOContract, ObsTerm
from robogym_ray.envs.isaac_reach import WORLD, IsaacReachTask
from robogym_ray.envs.modular import ModularArmTask, PoseTask
from robogym_ray.envs.ur_common import JOINT_MAX, URTask
from robogym_ray.robots.ur.geometry import BASE_HEIGHT_OPTION, JOINT_NAMES

ROBO_GYM_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_joint", "wrist_1", "wrist_2", "wrist_3")
"""robo-gym 2.1.0's UR joint names (``ur_parameters/*.yaml``), env order: ``fix_<name>``."""
START_OFFSET = (1.5, 0.25, 0.5, 1.0, 0.4, 3.14)
"""``EndEffectorPositioning2UR``'s default ``random_joint_offset`` (rad)."""


class UR2Arm(ModularArmTask, URTask):
    """The UR as robo-gym 2.1.0's modular envs see it (``URBaseEnv2.set_robot_defaults``):
    symmetric limits (+-2pi, the elbow +-pi), wrist_3 fixed, 300 steps, start
    ``[0, -2.5, 1.5, 0, -1.4, 0]``."""

    robo_gym_joints = ROBO_GYM_JOINTS
    lower, upper = -JOINT_MAX, JOINT_MAX
    default_joints = (0.0, -2.5, 1.5, 0.0, -1.4, 0.0)
    fixed_by_default = ("wrist_3",)
    max_episode_steps = 300

    def workspace(self) -> tuple[float, float]:
        return self.model.workspace_r, self.model.workspace_min_r


class EmptyEnvironment2UR(UR2Arm):
    """robo-gym 2.1.0's ``EmptyEnvironment2URSim-v0``: move freely, do not collide.

    ## Action space
    ``Box(-1, 1, (5,), float32)`` (wrist_3 fixed at its start; ``fix_<joint>``): absolute joint
    targets, normalised by the limits ``[2pi, 2pi, pi, 2pi, 2pi, 2pi]`` (env order
    shoulder_pan ... wrist_3). 20 actions per second at 0.2 of the joint speed limits.

    ## Observation space
    ``Box((12,), float32)``: joint positions normalised by the limits (6, saturating at +-1,
    bounds +-1.1), joint velocities (6, rad/s, free).

    ## Reward
    0 on every step.

    ## Episode end
    terminated: ``collision`` (self or ground; Sim only). Truncated after 300 steps with
    final_status ``success`` (robo-gym: done), or ``server_restarted``.

    ## Reset
    Joints ``joint_position`` (default ``[0, -2.5, 1.5, 0, -1.4, 0]``; option
    ``joint_positions``). Scene: empty.

    ## Arguments
    ``ur_model`` (default ur5), ``fix_<joint>``, ``joint_position``, ``rs_state_to_info``,
    ``joint_position_tolerance_normalized``, ``action_rate``, ``max_velocity_scale_factor`` and
    ``RobotServerEnv``'s.
    """


class EndEffectorPositioning2UR(PoseTask, UR2Arm):
    """robo-gym 2.1.0's ``EndEffectorPositioning2URSim-v0``: bring tool0 to a target.

    ## Action space
    As ``EmptyEnvironment2UR``: ``Box(-1, 1, (5,), float32)``, wrist_3 fixed.

    ## Observation space
    ``Box((26,), float32)``, or ``(34,)`` with ``ee_rotation_matters``

    | part | meaning | bounds |
    |---|---|---|
    | 3 | target in the tool0 frame, ``[r, arccos(z/r), atan2(y, x)]`` | free |
    | 6 + 6 | normalised joint positions, joint velocities (rad/s) | +-1.1, free |
    | 3 (+ 4) | target xyz in base_link (+ its quaternion xyzw) | free (+-1) |
    | 3 (+ 4) | tool0 xyz in base_link (+ its quaternion xyzw) | free (+-1) |
    | 5 | the previous action (zeros after a reset) | [-1, 1] |

    ## Reward
    ``-0.005 * distance`` (m; ``-0.05 * rotation error`` (rad) added with
    ``ee_rotation_matters``); 2 instead on success (distance <= ``ee_distance_threshold`` 0.1 m,
    rotation error < ``ee_rotation_threshold`` 0.1 rad); -1 instead on a collision.

    ## Episode end
    terminated: ``success``, ``collision`` (Sim only; wins over success); truncated:
    ``max_steps_exceeded`` after 300 steps (robo-gym: done), ``server_restarted``.

    ## Reset
    Joints ``[0, -2.5, 1.5, 0, -1.4, 0]``; ``randomize_start`` adds U(+-``random_joint_offset``,
    default ``[1.5, 0.25, 0.5, 1.0, 0.4, 3.14]``); ``continue_on_success`` /
    ``continue_except_collision`` start from where the last episode ended. Target: uniform in
    the upper half ball of the model's radius (ur5 0.75 m, ur10 1.3 m) outside the base's
    singular cylinder (ur5 0.2 m, ur10 0.3 m), rotation from the ``ee_rotation_*_range``
    (default none); or in the ``ee_target_volume_bounding_box``; or ``ee_target_pose``. Scene:
    the tabletop; 20 actions per second at 0.1 of the joint speed limits.

    ## Arguments
    ``EmptyEnvironment2UR``'s and those of ``pose_targets.PoseTaskConfig``.
    """

    scene = "tabletop_no_collision"
    velocity_scale = 0.1
    # 2.1.0 sets 10 Hz after URBaseEnv2 has set 20 Hz with setdefault: 20 Hz is what it runs.
    action_rate = 20.0
    pose_defaults: ClassVar[dict[str, Any]] = {"random_joint_offset": START_OFFSET}

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        robot, scene, options = super().server_spec()
        options["object_0_model_name"] = "sphere50_no_collision"
        return robot, scene, options


class IsaacReachUR(IsaacReachTask, UR2Arm):
    """robo-gym 2.1.0's ``IsaacReachURSim-v0`` (Isaac Lab's ``Isaac-Reach-UR10-v0``).

    ## Action space
    ``Box((6,), float32)``: joint targets ``joint_position + 0.5 * action`` (rad, env order
    shoulder_pan ... wrist_3), bounded so that they stay within the limits: ``(limit -
    joint_position) / 0.5``. 30 actions per second at 0.2 of the joint speed limits.

    ## Observation space
    ``Box((25,), float32)``

    | index | meaning | bounds |
    |---|---|---|
    | 0-5 | joint positions minus ``joint_position`` (rad) | limits +- 0.1 x range, shifted |
    | 6-11 | joint velocities (rad/s) | free |
    | 12-18 | the target: xyz (m, base_link) and quaternion w, x, y, z | free, +-1 |
    | 19-24 | the previous action (zeros after a reset) | the action space |

    ## Reward
    ``-0.005 * distance - 0.05 * rotation error`` (tool1 to the target, m and rad); 2 instead
    on success (within 0.02 m and 0.05 rad); -1 instead on a collision.

    ## Episode end
    terminated: ``success``, ``collision`` (self, table, ground; Sim only); truncated:
    ``max_steps_exceeded`` after 600 steps (robo-gym: done), ``server_restarted``.

    ## Reset
    Joints ``joint_position`` = ``[0, -1.712, 1.712, 0, 0, 0]``, or where the last episode
    ended unless it was a collision (``continue_except_collision``, default True). Target: x
    0.35-0.65, y -0.2-0.2, z 0.15-0.5 m, roll 0, pitch pi/2, yaw U(-3.14, 3.14). Server: the UR
    in Isaac Lab's table world, base_link on the table top (``z:=0.0``), the end effector
    Isaac Lab's ``tool1``.

    ## Arguments
    ``ur_model`` (default ur10), ``isaac_scale``, ``isaac_extra_static_joints``, those of
    ``pose_targets.PoseTaskConfig`` and ``ModularArmTask`` but ``fix_<joint>``, and
    ``RobotServerEnv``'s.
    """

    metadata: ClassVar[dict[str, Any]] = {**URTask.metadata, "render_fps": 30}
    default_joints = (0.0, -1.712, 1.712, 0.0, 0.0, 0.0)
    pose_defaults: ClassVar[dict[str, Any]] = {
        **IsaacReachTask.pose_defaults,
        "ee_rotation_pitch_range": math.pi / 2,
        "continue_except_collision": True,
    }

    def __init__(self, *, ur_model: str = "ur10", **kwargs: Any) -> None:
        super().__init__(ur_model=ur_model, **kwargs)

    def isaac_io(self) -> IOContract:
        """``Isaac-Reach-UR10-v0``'s terms (``JointPositionAction`` with the default offset)."""
        names, default = JOINT_NAMES, tuple(float(q) for q in self.joint_position)
        observations = (
            ObsTerm("joint_pos_rel", 6, names, default),
            ObsTerm("joint_vel_rel", 6, names),
            ObsTerm("generated_commands", 7),
            ObsTerm("last_action", 6),
        )
        action = ActionTermSpec("JointPositionAction", names, self.scale, default)
        return IOContract(observations, action, names, default, 1.0 / self.action_rate)

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        robot, _, options = super().server_spec()
        options.update(
            world_name=WORLD, ee_frame="tool1", object_0_model_name="sphere50_no_collision"
        )
        options[BASE_HEIGHT_OPTION] = "0.0"
        return robot, None, options
