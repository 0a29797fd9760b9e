"""Isaac Lab 3's Sim2Real reach task on a UR10e, ``Isaac-Deploy-Reach-UR10e-v0``, without ROS.

Read from isaac-sim/IsaacLab (``isaaclab_tasks/manager_based/manipulation/deploy/reach/``:
``reach_env_cfg.py``, ``config/ur_10e/joint_pos_env_cfg.py`` and ``ros_inference_env_cfg.py``;
``isaaclab_assets/robots/universal_robots.py``; the ``mdp/rewards.py`` beside them). It differs
from ``Isaac-Reach-UR10-v0`` (``isaac_reach.py``) in every part of its layout: absolute joint
positions, no last action, a relative action from the *measured* joints, 60 Hz, 12-s episodes
with a new pose command every 4 s, the command in UR's ``base`` frame for ``wrist_3_link``, and
a keypoint reward. Target sampling is ``pose_targets``'s box draw (Isaac Lab's
``UniformPoseCommand``: ``quat_from_euler_xyz``, which scipy's "xyz" reproduces sign and all).
The arm is actuated as there and as Isaac ROS deploys it: one joint target per step, streamed to
a PD servo (the UR server's ``action_mode:=servo_pos``, ``robots/ur/servo.py``), not robo-gym's
trajectories.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from scipy.spatial.transform import Rotation

from robogym_ray.envs.base import StepInfo
from robogym_ray.envs.frames import (
    QUAT_ORDERS,
    frame_quat,
    frame_xyz,
    quat_from_order,
    quat_to_order,
)
from robogym_ray.envs.io_descriptors import ActionTermSpec, IOContract, ObsTerm
from robogym_ray.envs.pose_commands import PoseCommands, pose_error
from robogym_ray.envs.ur_common import URTask
from robogym_ray.envs.ur_modular import UR2Arm
from robogym_ray.errors import ConfigError
from robogym_ray.protocol import robot_server_pb2 as pb
from robogym_ray.robots.ur.geometry import JOINT_NAMES
from robogym_ray.robots.ur.servo import PARAMS as SERVO_PARAMS

PI = math.pi
KEYPOINTS = np.array(
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]],
    dtype=np.float64,
)
"""Isaac Lab's ``get_keypoint_offsets_full_6d`` with the centre: the frame's origin and its
axes' ends on both sides, scaled by ``keypoint_scale``."""
KEYPOINT_SCALE = 0.45
TRACKING_WEIGHT, EXP_WEIGHT, ACTION_WEIGHT = -1.5, 1.5, -0.005
EXP_COEFFS = ((50.0, 1e-4), (300.0, 1e-4), (5000.0, 1e-4))
"""``keypoint_command_error_exp``'s ``(a, b)``: ``1 / (exp(a d) + b + exp(-a d))`` each."""
SERVO_MODE = "servo_pos"
"""The UR server's action mode that streams joint targets to a PD servo."""
ACTUATOR_RANDOMISATION = {
    "stiffness_scale": ("scale", 0.9, 1.1),
    "damping_scale": ("scale", 0.75, 1.5),
    "friction": ("add", 0.0, 0.1),
}
"""Isaac Lab's reset events on the arm (``reach_env_cfg.py``: ``randomize_actuator_gains``,
``randomize_joint_parameters``), one draw per joint, as the servo's SetState params."""


def keypoint_error(
    pos: np.ndarray,
    quat: np.ndarray,
    goal_pos: np.ndarray,
    goal_quat: np.ndarray,
    scale: float = KEYPOINT_SCALE,
) -> Any:
    """Mean distance (m) of the seven keypoints of two poses (quaternions x-y-z-w): a float for
    one pair, an array for rows of them (hindsight relabelling scores many at once)."""
    here, there = Rotation.from_quat(quat), Rotation.from_quat(goal_quat)
    gaps = [
        np.asarray(pos) - np.asarray(goal_pos) + here.apply(o) - there.apply(o)
        for o in scale * KEYPOINTS
    ]
    distance = np.linalg.norm(np.stack(gaps, axis=-2), axis=-1).mean(axis=-1)
    return float(distance) if np.ndim(distance) == 0 else distance


def exp_kernel(d: Any, a: float, b: float) -> Any:
    """``1 / (exp(a d) + b + exp(-a d))``, written so that a large ``a d`` cannot overflow."""
    e = np.exp(-a * np.abs(d))
    return e / (1.0 + b * e + e * e)


def tracking_per_second(d: Any) -> Any:
    """The reward's keypoint terms before the dt, of the keypoint error ``d`` (m)."""
    return TRACKING_WEIGHT * d + EXP_WEIGHT * sum(exp_kernel(d, *c) for c in EXP_COEFFS)


MAX_KEYPOINT_ERROR = 3.4
"""A bound on ``d`` (m): the arm reaches 1.3 m and the commands lie within 1.2 m of ``base``, so
the frames' origins are at most 2.5 m apart, and a keypoint 0.45 m out adds at most 0.9 m."""


ACTION_HIGH = np.ones(6)
"""The action bounds: Isaac ROS clamps every action to [-1, 1] before scaling it."""


def step_reward_range(
    action_high: np.ndarray = ACTION_HIGH, rate: float = 60.0
) -> tuple[float, float]:
    """The bounds of one step's reward for actions within ``+-action_high``.

    Best: on target, no action (three exponential terms of 1 / (2 + b) each). Worst: ``d`` at
    ``MAX_KEYPOINT_ERROR`` and every action at a bound with the sign flipped from the step
    before, so ``|a|^2 + |a - a_prev|^2 = 5 |a|^2``. Within [-1, 1] the tracking term
    dominates (the action terms are 3 % of the worst step).
    """
    best = EXP_WEIGHT * sum(1.0 / (2.0 + b) for _, b in EXP_COEFFS)
    squares = float(np.sum(np.square(np.asarray(action_high, dtype=np.float64))))
    worst = TRACKING_WEIGHT * MAX_KEYPOINT_ERROR + ACTION_WEIGHT * 5.0 * squares
    return worst / rate, best / rate


def return_range(discount: float = 0.99) -> tuple[float, float]:
    """The bounds of a discounted return (episodes end only by the time limit, so the horizon is
    1 / (1 - discount)) with the env's action bounds."""
    worst, best = step_reward_range()
    horizon = 1.0 / (1.0 - discount)
    return worst * horizon, best * horizon


class IsaacDeployReachUR(PoseCommands, UR2Arm):
    """Isaac Lab 3's ``Isaac-Deploy-Reach-UR10e-v0``: track a pose command with ``wrist_3_link``.

    ## Action space
    ``Box(-1, 1, (6,), float32)``, clamped there as Isaac ROS clamps: joint offsets from the
    **measured** joints, target = measured + 0.0625 x action (rad; order shoulder_pan ...
    wrist_3; Isaac Lab's ``RelativeJointPositionAction``, ``use_zero_offset``), clipped into
    the joint limits. 60 actions per second (Isaac Lab: physics 120 Hz, decimation 2), each
    target streamed to the server's PD servo (``action_mode:=servo_pos``: Isaac Lab's UR10e
    gains, the UR's speed and acceleration limits), held until the next. A joint moves at
    stiffness / damping x its lag behind the target (0.0625 rad at |action| = 1 when it is
    set, less a step later): at most ~0.9 rad/s for the shoulder and elbow, ~0.45 rad/s for
    the wrists.

    ## Observation space
    ``Box((19,), float32)``; nothing scaled, clipped or noisy.

    | index | meaning | bounds |
    |---|---|---|
    | 0-5 | joint positions (rad, absolute) | limits +- 0.1 x range |
    | 6-11 | joint velocities (rad/s) | free |
    | 12-14 | the command's position (m, UR's ``base`` frame) | free |
    | 15-18 | its quaternion, x-y-z-w (``isaac_quat_order="wxyz"``: w first) | +-1 |

    ## Reward
    Isaac Lab's, per step, times its step dt (1/60 s): ``-1.5 d + 1.5 sum_k 1 / (exp(a_k d) +
    b_k + exp(-a_k d)) - 0.005 |a_t - a_t-1|^2 - 0.005 |a_t|^2`` with ``d`` the mean distance of
    seven keypoints (origin and +-0.45 m along each axis) of ``wrist_3_link`` and the command,
    ``(a_k, b_k)`` = (50, 1e-4), (300, 1e-4), (5000, 1e-4); ``a`` the raw actions. ``info``
    carries ``dist_coord`` (m) and ``dist_rot`` (rad) of ``wrist_3_link`` to the command of the
    step; at the end of each command window also ``window_position_error`` and
    ``window_rotation_error`` (the same two).

    ## Episode end
    Only the time limit: truncated after 720 steps (12 s) with ``max_steps_exceeded``, or
    ``server_restarted``. No collision ends an episode (Isaac Lab's task has none).

    ## Reset and commands
    Joints ``(pi, -pi/2, pi/2, -pi/2, -pi/2, 0)`` plus U(+-0.125) rad each. A new command every
    240 steps (``resampling_time`` 4 s), after the step's reward, before its observation:
    position U((0.6375, 1.1375), (-0.35, -0.1), (0.1, 0.3)) m in ``base`` (``base_link`` turned
    pi about z), rotation from roll U(pi +- pi/6), pitch U(+-pi/6), yaw U(-pi/2 +- 2 pi/3).
    ``randomize_actuators`` (default on, Sim only): each reset draws Isaac Lab's actuator
    randomisation per joint, stiffness x U(0.9, 1.1), damping x U(0.75, 1.5), friction +
    U(0, 0.1), after the start pose and the first command.
    Server: the UR10e, ``reference_frame:=base``, ``ee_frame:=wrist_3_link``, 60 Hz, full speed
    (``max_velocity_scale_factor`` 1.0), ``rs_mode:=only_robot`` (no target object),
    ``action_mode:=servo_pos``; the Rob variant refuses a server that reports another action
    mode through GetArguments, or that does not answer it.

    ## Arguments
    ``isaac_quat_order`` ("xyzw", Isaac Lab 3.x; "wxyz", Isaac Lab 2.x and Isaac ROS),
    ``isaac_scale`` (0.0625), ``resampling_time`` (s), ``randomize_actuators`` (True),
    ``ur_model`` (ur10e), those of
    ``pose_targets.PoseTaskConfig`` and ``ModularArmTask`` but ``fix_<joint>``, and
    ``RobotServerEnv``'s.
    """

    metadata: ClassVar[dict[str, Any]] = {**URTask.metadata, "render_fps": 60}
    # A goal task for hindsight relabelling (experience/relabel.py): info carries the pose
    # reached in the command's layout and the reward's command-free part.
    goal_slice = slice(12, 19)
    reward_info_keys = ("effort",)
    ends_on_goal = False
    needs_arguments = True  # a trajectory server would smear every target over >= 0.5 s
    rs_mode = "only_robot"
    default_joints = (PI, -PI / 2, PI / 2, -PI / 2, -PI / 2, 0.0)
    fixed_by_default = ()
    fixable = False
    max_episode_steps = 720
    action_rate = 60.0
    velocity_scale = 1.0
    pose_defaults: ClassVar[dict[str, Any]] = {
        "ee_target_volume_bounding_box": True,
        "ee_rotation_pos_x_range": (0.8875 - 0.25, 0.8875 + 0.25),
        "ee_rotation_pos_y_range": (-0.225 - 0.125, -0.225 + 0.125),
        "ee_rotation_pos_z_range": (0.2 - 0.1, 0.2 + 0.1),
        "ee_rotation_roll_range": (PI - PI / 6, PI + PI / 6),
        "ee_rotation_pitch_range": (-PI / 6, PI / 6),
        "ee_rotation_yaw_range": (-PI / 2 - 2 * PI / 3, -PI / 2 + 2 * PI / 3),
        "ee_rotation_matters": True,
        "randomize_start": True,
        "random_joint_offset": (0.125,) * 6,
    }

    def __init__(
        self,
        *,
        ur_model: str = "ur10e",
        isaac_quat_order: str = "xyzw",
        isaac_scale: float = 0.0625,
        resampling_time: float = 4.0,
        randomize_actuators: bool = True,
        **kwargs: Any,
    ) -> None:
        if isaac_quat_order not in QUAT_ORDERS:
            raise ConfigError(
                f"isaac_quat_order must be one of {QUAT_ORDERS}, got {isaac_quat_order!r}"
            )
        self.quat_order = isaac_quat_order
        self.scale = float(isaac_scale)
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ConfigError(f"isaac_scale must be a positive number, got {isaac_scale!r}")
        self.randomize_actuators = bool(randomize_actuators)
        super().__init__(ur_model=ur_model, resampling_time=resampling_time, **kwargs)

    # -- spaces (the action space is the arm's [-1, 1]^6) -------------------------------------
    def _obs_bounds(self) -> tuple[list[float], list[float]]:
        widen = self.tolerance * (self.upper - self.lower)
        low = [*(self.lower - widen), *[-np.inf] * 6, *[-np.inf] * 3, *[-1.0] * 4]
        high = [*(self.upper + widen), *[np.inf] * 6, *[np.inf] * 3, *[1.0] * 4]
        return low, high

    def isaac_io(self) -> IOContract:
        """The observation and action terms an Isaac Lab policy of this task was trained with."""
        names = JOINT_NAMES
        return IOContract(
            observations=(
                ObsTerm("joint_pos", 6, names),
                ObsTerm("joint_vel", 6, names),
                ObsTerm("generated_commands", 7),
            ),
            action=ActionTermSpec("RelativeJointPositionAction", names, self.scale, (0.0,) * 6),
            joint_names=names,
            default_joint_pos=tuple(self.joint_position),
            dt=1.0 / self.action_rate,
        )

    # -- actions ---------------------------------------------------------------------------
    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """``measured + isaac_scale * action`` within the limits (rad, env order)."""
        measured = self.start_joints if self._last_msg is None else self.joints(self._last_msg)
        target = measured + self.scale * np.asarray(action, dtype=np.float64)
        return np.clip(target, self.lower, self.upper)

    # -- episode ---------------------------------------------------------------------------
    def _prepare(self, options: Mapping[str, Any]) -> tuple[dict[str, str], dict[str, float]]:
        super()._prepare(options)  # the first command (or the ee_target_pose option)
        # only_robot: no target object to place; a real arm's gains are its own
        return {}, ({} if self.real_robot or not self.randomize_actuators else self._actuator())

    def _actuator(self) -> dict[str, float]:
        """One draw of Isaac Lab's actuator randomisation, as the servo's SetState params."""
        params = {}
        for name, (how, low, high) in ACTUATOR_RANDOMISATION.items():
            nominal = SERVO_PARAMS[name][0]
            draw = self.np_random.uniform(low, high, 6)
            values = nominal * draw if how == "scale" else nominal + draw
            params.update({f"servo_{name}_{j}": float(v) for j, v in enumerate(values)})
        return params

    def _to_obs(self, msg: pb.State) -> np.ndarray:
        parts = [self.joints(msg), self.velocities(msg), self.target_pose[:3],
                 quat_to_order(self.target_pose[3:], self.quat_order)]  # fmt: skip
        return np.concatenate(parts).astype(np.float32)

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Mapping[str, Any]
    ) -> np.ndarray:
        """The step rewards for poses reached and commands (rows in the observation's command
        layout) with ``info["effort"]``, per step (the dt applied), as ``_evaluate`` scores
        the command in force."""
        achieved = np.atleast_2d(np.asarray(achieved_goal, np.float64))
        desired = np.atleast_2d(np.asarray(desired_goal, np.float64))
        order = self.quat_order
        d = keypoint_error(achieved[:, :3], quat_from_order(achieved[:, 3:], order),
                           desired[:, :3], quat_from_order(desired[:, 3:], order))  # fmt: skip
        return (tracking_per_second(d) + np.asarray(info["effort"])) / self.action_rate

    def _evaluate(
        self, msg: pb.State, obs: np.ndarray, action: np.ndarray
    ) -> tuple[float, str | None, StepInfo]:
        sd, goal = msg.state_dict, self.scored_pose
        pos, quat = frame_xyz(sd, "ee"), frame_quat(sd, "ee")
        d = keypoint_error(pos, quat, goal[:3], goal[3:])
        a = np.asarray(action, dtype=np.float64)
        effort = ACTION_WEIGHT * float(np.sum((a - self.prev_action) ** 2) + np.sum(a**2))
        position, rotation = pose_error(pos, Rotation.from_quat(quat), goal)
        info: StepInfo = {
            **self._info(msg),
            "dist_coord": position,
            "dist_rot": rotation,
            "keypoint_error": d,
            "achieved_goal": np.concatenate(
                [pos, quat_to_order(quat / np.linalg.norm(quat), self.quat_order)]
            ),
            "effort": effort,
            **self.window_errors(position, rotation),
        }
        return (float(tracking_per_second(d)) + effort) / self.action_rate, None, info

    def server_spec(self) -> tuple[str, str | None, dict[str, str]]:
        robot, scene, options = super().server_spec()
        options.update(reference_frame="base", ee_frame="wrist_3_link", action_mode=SERVO_MODE)
        return robot, scene, options
